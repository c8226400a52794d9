"""End-to-end delivery of relayed radio messages, folded from envelope headers in the tx and rx bundles
(the relaying itself is ``agents/relay.py``).

The bundles are on the bus in every engine and in a recording, so the same fold gives the same numbers for a
run over Zenoh, in memory, or recomputed by ``fleet report``; it reads headers only, never a payload, and it
does not depend on the order the bundles arrive in (within :attr:`RelayStats.horizon` ticks).

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
from collections import Counter
from typing import Any

import numpy as np

from fleet_emu.core.messages import Message, RxBundle, TxBundle


@dataclasses.dataclass
class _Kind:
    """One payload kind's settled totals: messages made and intended (message, receiver) pairs, and the
    histograms of hops and latency over deliveries."""

    sent: int = 0
    intended: int = 0
    hops: Counter[int] = dataclasses.field(default_factory=Counter)
    latency: Counter[int] = dataclasses.field(default_factory=Counter)


@dataclasses.dataclass
class RelayStats:
    """The fold; ``endpoints`` is the number of radio endpoints (robots, plus the base when there is one).

    Memory stays bounded over a long run: a message made ``horizon`` ticks before the newest tick folded is
    settled (its deliveries enter its kind's histograms, its per-receiver records are forgotten). A copy of it
    arriving later still would be lost to the fold, so ``horizon`` must exceed the longest a copy can take
    (``(relay_ttl + 1) * latency`` ticks in lockstep); the default leaves a wide margin. Settling happens
    only when a message is old enough, so any arrival order within the horizon gives the same result.
    """

    endpoints: int
    horizon: int = 256
    made: dict[tuple[str, int], tuple[str, str, int, int]] = dataclasses.field(default_factory=dict)
    transmissions: dict[str, int] = dataclasses.field(default_factory=dict)
    arrivals: dict[tuple[str, int], dict[str, tuple[int, int]]] = dataclasses.field(default_factory=dict)
    kinds: dict[str, _Kind] = dataclasses.field(default_factory=dict)
    newest: int = -1
    settled_to: int = -1

    def fold(self, msg: Message) -> None:
        """One decoded message (a ``MessageFold``, ``core/fold.py``): a robot's tx bundle, or netem's rx bundle
        to a receiver; any other message is not this fold's."""
        if isinstance(msg, TxBundle):
            self.fold_tx(msg)
        elif isinstance(msg, RxBundle) and msg.src == "netem":
            self.fold_rx(msg)

    def fold_tx(self, b: TxBundle) -> None:
        for env in b.msgs:
            self.transmissions[env.payload_kind] = self.transmissions.get(env.payload_kind, 0) + 1
            if env.origin == b.src:  # (kind, dst, ttl as sealed, tick made)
                self.made[(env.origin, env.seq)] = (env.payload_kind, env.dst, env.ttl, env.tick)
        self._advance(b.tick)

    def fold_rx(self, b: RxBundle) -> None:
        for env in b.msgs:
            if env.origin == b.dst or env.dst not in ("*", b.dst):
                continue  # an echo of its own, or overheard on the way to someone else
            got = self.arrivals.setdefault((env.origin, env.seq), {})
            prev = got.get(b.dst)
            if prev is None or b.tick < prev[0]:
                got[b.dst] = (b.tick, env.ttl)
        self._advance(b.tick)

    def _advance(self, tick: int) -> None:
        """Settle the messages made before ``tick - horizon``, every ``horizon // 4`` ticks (amortized)."""
        self.newest = max(self.newest, tick)
        if self.newest - self.settled_to >= max(1, self.horizon // 4):
            self._settle(self.newest - self.horizon)

    def _settle(self, before: int | None) -> None:
        """Fold the messages made before tick ``before`` (all of them when None) into the kinds' totals."""
        old = [k for k, m in self.made.items() if before is None or m[3] < before]
        for key in old:
            kind, dst, ttl0, tick0 = self.made.pop(key)
            k = self.kinds.setdefault(kind, _Kind())
            k.sent += 1
            k.intended += self.endpoints - 1 if dst == "*" else 1
            for tick, ttl in self.arrivals.pop(key, {}).values():
                k.hops[ttl0 - ttl + 1] += 1
                k.latency[tick - tick0] += 1
        if before is not None:  # arrivals whose message was never made (its origin's bundle never came)
            stale = [k for k, got in self.arrivals.items() if min(t for t, _ in got.values()) < before]
            for key in stale:
                del self.arrivals[key]
            self.settled_to = self.newest

    def result(self) -> dict[str, dict[str, Any]]:
        """Per payload kind: ``sent``, ``transmissions``, ``delivered``, ``delivery_ratio``, ``hops``,
        ``latency_ticks {mean, p50, max}``, ``tx_per_delivered``. Settles every message: fold nothing after."""
        self._settle(None)
        out = {}
        for kind in sorted(set(self.kinds) | set(self.transmissions)):
            k = self.kinds.get(kind, _Kind())
            n = sum(k.latency.values())
            tx = self.transmissions.get(kind, 0)
            out[kind] = {
                "sent": k.sent, "transmissions": tx, "delivered": n,
                "delivery_ratio": round(n / k.intended, 6) if k.intended else None,
                "hops": {str(h): c for h, c in sorted(k.hops.items())},
                "latency_ticks": ({"mean": round(sum(t * c for t, c in k.latency.items()) / n, 4),
                                   "p50": median(k.latency), "max": max(k.latency)} if n else None),
                "tx_per_delivered": round(tx / n, 4) if n else None}
        return out


def median(hist: Counter[int]) -> float:
    """The median of the values a histogram counts, as ``numpy.percentile(values, 50)`` gives it."""
    values = sorted(hist)
    counts = np.cumsum([hist[v] for v in values])
    n = int(counts[-1])
    lo, hi = (n - 1) // 2, n // 2
    at = np.searchsorted(counts, [lo + 1, hi + 1])
    return float((values[at[0]] + values[at[1]]) / 2)


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
