"""The radio channel as a pure function of links, bundles and a seeded generator (DESIGN.md radio model).

Counting convention: every (message, intended receiver) pair is one transmission, so
``sent == delivered + dropped_loss + dropped_signal``; ``bytes_sent`` counts each message's encoded size once
(one radio emission reaches every receiver). Messages are :class:`~fleet_emu.core.messages.Envelope` s, routed
by their header; their payloads are never decoded here.
"""

from __future__ import annotations

import dataclasses
from collections import defaultdict

import numpy as np

from fleet_emu.core.messages import Envelope


@dataclasses.dataclass
class Counters:
    sent: int = 0
    delivered: int = 0
    dropped_loss: int = 0
    dropped_signal: int = 0
    bytes_sent: int = 0


class Channel:
    """Decides, per receiver, whether each radio message arrives, and when (``latency`` ticks later)."""

    def __init__(self, loss: float, rng: np.random.Generator, latency: int = 1) -> None:
        self.loss = loss
        self.rng = rng
        self.latency = latency
        self.counters = Counters()
        self._pending: dict[int, dict[str, list[Envelope]]] = defaultdict(lambda: defaultdict(list))

    def transmit(self, tick: int, robots: tuple[str, ...], link: np.ndarray,
                 bundles: dict[str, tuple[Envelope, ...]]) -> None:
        """Send every robot's bundle of ``tick`` over the link matrix (rows/cols in ``robots`` order).

        Draw order is fixed (senders by id order, messages in bundle order, receivers in id order), and a loss
        draw is made for every pair whether or not a link exists, so the generator's stream does not depend
        on the link graph.
        """
        index = {r: i for i, r in enumerate(robots)}
        due = self._pending[tick + self.latency]
        c = self.counters
        for src in robots:
            for msg in bundles.get(src, ()):
                c.bytes_sent += len(msg.encode())
                receivers = [r for r in robots if r != src and (msg.dst == "*" or msg.dst == r)]
                for dst in receivers:
                    lost = self.rng.random() < self.loss
                    c.sent += 1
                    if not link[index[src], index[dst]]:
                        c.dropped_signal += 1
                    elif lost:
                        c.dropped_loss += 1
                    else:
                        c.delivered += 1
                        due[dst].append(msg)

    def deliver(self, tick: int) -> dict[str, list[Envelope]]:
        """What arrives at ``tick``, per receiver (and forget it)."""
        return dict(self._pending.pop(tick, {}))
