"""The radio channel as a pure function of links, bundles and a seeded generator (docs/guides/radio.md).

Counting convention: every (message, intended receiver) pair is one transmission, so
``sent == delivered + dropped_loss + dropped_signal``; ``bytes_sent`` counts each emission's encoded size once
(its whole envelope as sent, a deflated map message compact; one radio emission reaches every receiver; a message
dropped at a full queue, or still queued when the run ends, was never emitted), in total and per sender
(``bytes_by``); the base station, in a run with one, is a receiver like a robot.
Messages are :class:`~fleet_emu.core.messages.Envelope` s, routed
by their header; their payloads are never decoded here. A message for one receiver reaches only it, unless it
may still be relayed (``ttl > 0``, ``agents/relay.py``): a radio emission is heard by everyone in range, and
a relay must hear a message that is not for it to forward it; only relaying runs seal messages with a ttl.
"""

from __future__ import annotations

import collections
import dataclasses
from collections import defaultdict
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from fleet_emu.core.grid import Cell
from fleet_emu.core.keys import BASE
from fleet_emu.core.messages import Envelope, Links, RxBundle, WorldState
from fleet_emu.core.radio import RadioConfig, connected, link_matrix
from fleet_emu.core.rng import generator
from fleet_emu.core.shadowing import Shadowing, shadowing
from fleet_emu.netem.medium import Medium

UNLIMITED = 1 << 62  # a medium's capacity when only a jitter is set


@dataclasses.dataclass
class Counters:
    sent: int = 0
    delivered: int = 0
    dropped_loss: int = 0
    dropped_signal: int = 0
    bytes_sent: int = 0
    bytes_by: collections.Counter[str] = dataclasses.field(default_factory=collections.Counter)  # per sender
    delay: collections.Counter[int] = dataclasses.field(default_factory=collections.Counter)  # emissions by delay
    pair_ticks: int = 0  # with shadowing: robot pairs over ticks, and eq. 4's wrong calls (count_predictions)
    false_links: int = 0
    missed_links: int = 0


def endpoint_links(occupied: np.ndarray, robots: tuple[str, ...], cells: list[tuple[int, int]],
                   base: tuple[int, int] | None, cell_size: float, radio: RadioConfig,
                   shadow: np.ndarray | None = None) -> tuple[tuple[str, ...], np.ndarray, np.ndarray]:
    """The radio endpoints of a tick (the live ``robots`` at ``cells``, then the base station at its fixed
    cell ``base`` when the run has one) and their signal (dB) and link matrices, in that order; ``shadow``: the
    shadowing term of each pair of them (:meth:`Shadowing.pair_db`), added to the signal."""
    nodes = robots + ((BASE,) if base is not None else ())
    strength, link = link_matrix(occupied, [*cells, *([base] if base is not None else [])], cell_size, radio,
                                 shadow)
    return nodes, strength, link


def count_predictions(counters: Counters, strength: np.ndarray, shadow: np.ndarray, link: np.ndarray, n: int,
                      radio: RadioConfig) -> None:
    """Add a tick's robot pairs (the first ``n`` endpoints) to ``counters``, and those whose link eq. 4 without
    the shadowing (the connectivity allocator's model, on the true map and cells) calls wrongly: a link where
    there is none (``false_links``), none where there is one (``missed_links``). Only the ``wall`` model decides
    links by the signal; on the others the field changes no link."""
    upper = np.triu_indices(n, 1)
    actual = link[:n, :n][upper]
    eq4 = (strength[:n, :n] - shadow[:n, :n])[upper]
    predicted = eq4 >= radio.threshold if radio.comm == "wall" else actual
    counters.pair_ticks += len(actual)
    counters.false_links += int(np.count_nonzero(predicted & ~actual))
    counters.missed_links += int(np.count_nonzero(~predicted & actual))


def links_message(tick: int, seq: int, nodes: tuple[str, ...], strength: np.ndarray, link: np.ndarray,
                  counters: Counters, dropped: int = 0, medium: Medium | None = None) -> Links:
    """netem's :class:`Links` of a tick: the robots' graph (the base left out of ``connected`` and of the
    matrices, so that a run without a base publishes what it always did) and, with a base, each robot's
    signal and link to it."""
    has_base = bool(nodes) and nodes[-1] == BASE
    n = len(nodes) - has_base
    c = counters
    return Links(
        src="netem", tick=tick, seq=seq, robots=nodes[:n], strength=strength[:n, :n].astype(np.float32),
        link=link[:n, :n], connected=bool(connected(link[:n, :n])), sent=c.sent, delivered=c.delivered,
        dropped_loss=c.dropped_loss, dropped_signal=c.dropped_signal, bytes_sent=c.bytes_sent, dropped=dropped,
        bytes_by=dict(c.bytes_by),
        base_strength=strength[:n, n].astype(np.float32) if has_base else None,
        base_link=link[:n, n].copy() if has_base else None, pair_ticks=c.pair_ticks, false_links=c.false_links,
        missed_links=c.missed_links, **airtime(counters, medium))


def airtime(counters: Counters, medium: Medium | None) -> dict[str, Any]:
    """The :class:`Links` airtime fields: cumulative ``airtime_bytes``, ``dropped_queue``, ``queued_max_bytes``
    and ``delays`` (emissions by delay in ticks, from hand-off to delivery); with a medium, each medium's bytes
    at the last tick served (``medium_load``), each endpoint's medium then (``medium_of``) and a medium's
    capacity a tick (``medium_capacity``)."""
    hist = counters.delay
    delays = tuple(hist.get(d, 0) for d in range(max(hist) + 1)) if hist else ()
    if medium is None:
        return {"airtime_bytes": counters.bytes_sent, "delays": delays}
    return {"airtime_bytes": medium.airtime_bytes, "dropped_queue": medium.dropped_queue,
            "queued_max_bytes": medium.queued_max_bytes, "delays": delays, "medium_load": medium.load,
            "medium_of": dict(medium.medium_of),
            "medium_capacity": medium.capacity if medium.capacity < UNLIMITED else 0}


def make_channel(seed: int, radio: RadioConfig, tick_s: float, shape: tuple[int, int] | None = None,
                 cell_size: float = 0.5) -> Channel:
    """A run's channel, as both engines build it: its seeded loss draws (``netem``, and ``netem/base`` for the
    base station's pairs), with a bandwidth or a jitter a :class:`Medium` on generators of its own (the loss
    draws stay those of an unlimited radio's stream), and with ``shadowing_db`` the shadowing field over a map
    of ``shape`` cells of ``cell_size`` metres, from a generator of its own too (``netem/shadowing``)."""
    if radio.shadowing_db > 0 and shape is None:
        raise ValueError("a radio with shadowing needs the map's shape")
    medium = None
    if radio.limited or radio.jitter:
        capacity = max(1, int(radio.capacity(tick_s))) if radio.limited else UNLIMITED
        medium = Medium(capacity, radio.queue_bytes, radio.latency, radio.jitter, generator(seed, "netem", "medium"),
                        generator(seed, "netem", "jitter"))
    field = shadowing(generator(seed, "netem", "shadowing"), shape, cell_size, radio.shadowing_db,
                      radio.shadowing_m) if shape is not None else None
    return Channel(radio.applied_loss, generator(seed, "netem"), radio.latency, generator(seed, "netem", BASE), medium,
                   field)


class Channel:
    """Decides, per receiver, whether each radio message arrives, and when (``latency`` ticks later); with a
    :class:`~fleet_emu.netem.medium.Medium` (a bandwidth or a jitter set) messages queue for airtime first.
    ``shadowing``: the run's field (:mod:`fleet_emu.core.shadowing`), which :func:`radio_tick` adds to the
    links' signal."""

    def __init__(self, loss: float, rng: np.random.Generator, latency: int = 1,
                 base_rng: np.random.Generator | None = None, medium: Medium | None = None,
                 shadowing: Shadowing | None = None) -> None:
        self.loss = loss
        self.rng = rng
        self.base_rng = base_rng if base_rng is not None else rng
        self.latency = latency
        self.medium = medium
        self.shadowing = shadowing
        self.counters = Counters()
        self._pending: dict[int, dict[str, list[Envelope]]] = defaultdict(lambda: defaultdict(list))

    def transmit(self, tick: int, robots: tuple[str, ...], link: np.ndarray,
                 bundles: dict[str, tuple[Envelope, ...]]) -> None:
        """Send every robot's bundle of ``tick`` over the link matrix (rows/cols in ``robots`` order).

        Draw order is fixed (senders by id order, messages in bundle order, receivers in id order), and a loss
        draw is made for every pair whether or not a link exists, so the generator's stream does not depend
        on the link graph. A pair with the base station (:data:`~fleet_emu.core.keys.BASE` among ``robots``)
        draws from ``base_rng``, so that the robots' own deliveries are the same with or without a base.
        With a medium, the messages whose last byte went on the air this tick are sent instead, in that order.
        """
        index = {r: i for i, r in enumerate(robots)}
        if self.medium is not None:
            self.medium.enqueue(tick, {r: b for r, b in bundles.items() if b})
            for item, at in self.medium.serve(tick, robots, link):
                src = item.src
                if src in index:  # a sender that failed mid-air is gone
                    self._send(src, item.msg, self._heard(src, robots, index, link), index, self._pending[at])
                    self.counters.delay[at - item.handed] += 1
            return
        due = self._pending[tick + self.latency]
        for src in robots:
            msgs = bundles.get(src, ())
            if msgs:
                heard = self._heard(src, robots, index, link)
                for msg in msgs:
                    self._send(src, msg, heard, index, due)
                self.counters.delay[self.latency] += len(msgs)

    @staticmethod
    def _heard(src: str, robots: tuple[str, ...], index: dict[str, int], link: np.ndarray
               ) -> tuple[np.ndarray, list[str], np.ndarray]:
        """``src``'s row of the link matrix, every other endpoint and whether ``src`` is linked to each."""
        row = link[index[src]]
        others = [r for r in robots if r != src]
        return row, others, row[[index[r] for r in others]] if others else np.zeros(0, dtype=bool)

    def _send(self, src: str, msg: Envelope, heard: tuple[np.ndarray, list[str], np.ndarray],
              index: dict[str, int], due: dict[str, list[Envelope]]) -> None:
        """One emission of ``src``'s message (``heard``: :meth:`_heard`): its loss draws and deliveries."""
        c = self.counters
        row, others, others_linked = heard
        size = len(msg.encode())
        c.bytes_sent += size
        c.bytes_by[src] += size
        if msg.dst == "*" or msg.ttl > 0:
            receivers, linked = others, others_linked
        else:
            receivers = [msg.dst] if msg.dst in index and msg.dst != src else []
            linked = row[[index[r] for r in receivers]] if receivers else others_linked[:0]
        if BASE in index and (src == BASE or BASE in receivers):
            draws = np.array([(self.base_rng if BASE in (src, dst) else self.rng).random() for dst in receivers])
        else:  # one draw per receiver in turn, taken at once: the same numbers
            draws = self.rng.random(len(receivers))
        ok = linked & (draws >= self.loss) if len(receivers) else linked
        n_linked, n_ok = int(np.count_nonzero(linked)), int(np.count_nonzero(ok))
        c.sent += len(receivers)
        c.dropped_signal += len(receivers) - n_linked
        c.dropped_loss += n_linked - n_ok
        c.delivered += n_ok
        for j in np.flatnonzero(ok).tolist():
            due[receivers[j]].append(msg)

    def deliver(self, tick: int) -> dict[str, list[Envelope]]:
        """What arrives at ``tick``, per receiver (and forget it)."""
        return dict(self._pending.pop(tick, {}))


@dataclasses.dataclass(frozen=True)
class RadioTick:
    """netem's start of a tick: the radio endpoints and their link matrix (which the tick's sends go over), and
    the messages it publishes, built once for both engines (``netem/node.py``, ``launch/memory.py``): the
    links, then each endpoint's rx bundle in endpoint order (none once the run is over)."""

    nodes: tuple[str, ...]
    link: np.ndarray
    links: Links
    rx: tuple[RxBundle, ...]


def radio_tick(channel: Channel, occupied: np.ndarray, robots: Sequence[str], base: Cell | None, cell_size: float,
               radio: RadioConfig, state: WorldState, seq: Callable[[], int], dropped: int) -> RadioTick:
    """The links of the world's ``state`` (its live ``robots``, in robot order, at their true cells, and the
    base station at ``base``), and the deliveries due at its tick; ``seq`` draws netem's sequence numbers
    (the links first); ``dropped``: the messages netem has dropped so far as malformed or spoofed."""
    live = tuple(r for r in robots if r in state.live)
    cells = [state.poses[r] for r in live]
    field = channel.shadowing
    shadow = field.pair_db([*cells, *([base] if base is not None else [])]) if field is not None else None
    nodes, strength, link = endpoint_links(occupied, live, cells, base, cell_size, radio, shadow)
    if shadow is not None:
        count_predictions(channel.counters, strength, shadow, link, len(live), radio)
    t = state.tick
    links = links_message(t, seq(), nodes, strength, link, channel.counters, dropped, channel.medium)
    if state.done:
        return RadioTick(nodes, link, links, ())
    arriving = channel.deliver(t)
    rx = tuple(RxBundle(src="netem", tick=t, seq=seq(), dst=r, msgs=tuple(arriving.get(r, ()))) for r in nodes)
    return RadioTick(nodes, link, links, rx)
