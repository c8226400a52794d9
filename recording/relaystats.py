"""End-to-end delivery of relayed radio messages, folded from envelope headers in the tx and rx bundles
(issue 10 part 2; the relaying itself is ``agents/relay.py``).

The bundles are on the bus in every engine and in a recording, so the same fold gives the same numbers for a
run over Zenoh, in memory, or recomputed by ``fleet report``; it reads headers only, never a payload, and it
does not depend on the order the bundles arrive in (everything is computed in :meth:`RelayStats.result`).

Definitions, per payload kind:

- ``sent``: the messages robots made (an envelope in its origin's own tx bundle); ``transmissions``: every
  envelope of the kind in any tx bundle (the originals and each relay's forwarded copy).
- A *delivery* is the first copy of a message ``(origin, seq)`` to reach an intended receiver: its ``dst``,
  or for a broadcast (``dst = "*"``) any radio endpoint other than its origin (the other robots, and the base
  station in a run with one). Later copies (duplicates) are not deliveries.
- ``delivery_ratio``: deliveries over intended (message, receiver) pairs: for addressed messages delivered
  over sent; for broadcasts the mean over receivers of the fraction each got.
- ``hops``: histogram of the links a delivered copy crossed, ``ttl_sealed - ttl_received + 1``.
- ``latency_ticks``: rx tick minus the tick the origin made the message (mean, p50, max).
- ``tx_per_delivered``: transmissions over deliveries (None with no delivery).
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from fleet_emu.core.messages import RxBundle, TxBundle


@dataclasses.dataclass
class RelayStats:
    """The fold; ``endpoints`` is the number of radio endpoints (robots, plus the base when there is one)."""

    endpoints: int
    made: dict[tuple[str, int], tuple[str, str, int, int]] = dataclasses.field(default_factory=dict)
    transmissions: dict[str, int] = dataclasses.field(default_factory=dict)
    arrivals: dict[tuple[str, int, str], tuple[int, int]] = dataclasses.field(default_factory=dict)

    def fold_tx(self, b: TxBundle) -> None:
        for env in b.msgs:
            self.transmissions[env.payload_kind] = self.transmissions.get(env.payload_kind, 0) + 1
            if env.origin == b.src:  # (kind, dst, ttl as sealed, tick made)
                self.made[(env.origin, env.seq)] = (env.payload_kind, env.dst, env.ttl, env.tick)

    def fold_rx(self, b: RxBundle) -> None:
        for env in b.msgs:
            if env.origin == b.dst or env.dst not in ("*", b.dst):
                continue  # an echo of its own, or overheard on the way to someone else
            key = (env.origin, env.seq, b.dst)
            prev = self.arrivals.get(key)
            if prev is None or b.tick < prev[0]:
                self.arrivals[key] = (b.tick, env.ttl)

    def result(self) -> dict[str, dict[str, Any]]:
        """Per payload kind: ``sent``, ``transmissions``, ``delivered``, ``delivery_ratio``, ``hops``,
        ``latency_ticks {mean, p50, max}``, ``tx_per_delivered``."""
        intended: dict[str, int] = {}
        sent: dict[str, int] = {}
        for kind, dst, _, _ in self.made.values():
            sent[kind] = sent.get(kind, 0) + 1
            intended[kind] = intended.get(kind, 0) + (self.endpoints - 1 if dst == "*" else 1)
        hops: dict[str, dict[int, int]] = {}
        latency: dict[str, list[int]] = {}
        for (origin, seq, _), (tick, ttl) in self.arrivals.items():
            made = self.made.get((origin, seq))
            if made is None:  # its origin's bundle never reached the fold (a crash, an interrupted run)
                continue
            kind, _, ttl0, tick0 = made
            h = hops.setdefault(kind, {})
            h[ttl0 - ttl + 1] = h.get(ttl0 - ttl + 1, 0) + 1
            latency.setdefault(kind, []).append(tick - tick0)
        out = {}
        for kind in sorted(set(sent) | set(self.transmissions)):
            lat = np.array(latency.get(kind, []), dtype=float)
            n = len(lat)
            tx = self.transmissions.get(kind, 0)
            out[kind] = {
                "sent": sent.get(kind, 0), "transmissions": tx, "delivered": n,
                "delivery_ratio": round(n / intended[kind], 6) if intended.get(kind) else None,
                "hops": {str(k): v for k, v in sorted(hops.get(kind, {}).items())},
                "latency_ticks": ({"mean": round(float(lat.mean()), 4), "p50": float(np.percentile(lat, 50)),
                                   "max": int(lat.max())} if n else None),
                "tx_per_delivered": round(tx / n, 4) if n else None}
        return out


def relay_line(relay: dict[str, Any]) -> str:
    """One line for the run summary and ``fleet report``: policy, ttl and, per kind, delivery ratio, mean
    hops, mean latency and transmissions per delivery."""
    parts = []
    for kind, k in relay["kinds"].items():
        n = sum(k["hops"].values())
        mean_hops = sum(int(h) * c for h, c in k["hops"].items()) / n if n else 0.0
        ratio = "-" if k["delivery_ratio"] is None else f"{k['delivery_ratio']:.2f}"
        lat = "-" if k["latency_ticks"] is None else f"{k['latency_ticks']['mean']:.1f}"
        tpd = "-" if k["tx_per_delivered"] is None else f"{k['tx_per_delivered']:.2f}"
        parts.append(f"{kind} {ratio} ({mean_hops:.1f} hops, {lat} ticks, {tpd} tx/dlv)")
    return f"relay {relay['policy']} ttl {relay['ttl']}: " + "; ".join(parts)
