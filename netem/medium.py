"""Airtime: a radio that charges for what is sent (docs/guides/radio.md, "Bandwidth, queues and delay").

With a ``bandwidth`` (kbit/s) set, robots that hear each other share one medium: by default one medium per connected
component of the tick's link graph (the base station an endpoint like a robot). A medium carries ``floor(bandwidth *
1000 / 8 * tick_s)`` bytes a tick. Each sender has a drop-tail queue of ``queue_bytes``; a message that does not fit
is dropped (``dropped_queue``). Each tick every medium serves its senders' queues round-robin, one message per turn,
in a seeded order drawn afresh each tick, until its capacity is spent: a message larger than what is left waits for
the next tick (the sender's turn ends), and one larger than a whole tick's capacity takes what is left and goes on
over several ticks (airtime). A message is delivered, over the links of the tick its last byte went on the air (its
loss draws in the order an unlimited radio makes them), ``latency`` ticks later plus a seeded ``jitter`` draw
(``0..jitter`` ticks, uniform).

A sender's queue has two classes: beacons and protocol messages go before bulk map data (payload kinds in
:data:`BULK_KINDS`), so that map sharing under a rate limit does not starve coordination; a message already partly
on the air finishes first. Within a class, first in, first out. This changes how a robot's messages leave, never
what its allocator decides.

Pure code on the channel's own seeded generators: both engines step it identically.
"""

from __future__ import annotations

import collections
import dataclasses

import numpy as np

from fleet_emu.core.messages import BULK_KINDS, Envelope


@dataclasses.dataclass(slots=True)
class Queued:
    """A message waiting in its sender's queue (``src``): its encoded ``size``, the tick it was handed to the
    radio, and the bytes still to go on the air."""

    src: str
    msg: Envelope
    size: int
    handed: int
    left: int
    pos: int = 0  # its place in its sender's bundle


@dataclasses.dataclass
class SenderQueue:
    """One sender's queue: the message partly on the air, then control messages, then bulk map data."""

    current: Queued | None = None
    control: collections.deque[Queued] = dataclasses.field(default_factory=collections.deque)
    bulk: collections.deque[Queued] = dataclasses.field(default_factory=collections.deque)
    nbytes: int = 0

    def head(self) -> Queued | None:
        if self.current is not None:
            return self.current
        if self.control:
            return self.control[0]
        return self.bulk[0] if self.bulk else None

    def pop(self, item: Queued) -> None:
        """Take ``item`` (the head) off the queue: it is wholly on the air."""
        if self.current is item:
            self.current = None
        elif self.control and self.control[0] is item:
            self.control.popleft()
        else:
            self.bulk.popleft()
        self.nbytes -= item.size

    def start(self, item: Queued) -> None:
        """``item`` (the head) went partly on the air: it finishes before anything else of this sender."""
        if self.current is not item:
            (self.control if self.control and self.control[0] is item else self.bulk).popleft()
            self.current = item


def components(link: np.ndarray) -> list[list[int]]:
    """The connected components of an undirected link graph, each in index order, ordered by their first
    index: the media of a tick. (Plain lists: a team is a few dozen endpoints, where one numpy call per
    endpoint cost more than the search.)"""
    rows = link.tolist()
    label = [-1] * len(rows)
    media: list[list[int]] = []
    for i in range(len(rows)):
        if label[i] >= 0:
            continue
        label[i] = len(media)
        members, stack = [i], [i]
        while stack:
            for j, linked in enumerate(rows[stack.pop()]):
                if linked and label[j] < 0:
                    label[j] = label[i]
                    members.append(j)
                    stack.append(j)
        media.append(sorted(members))
    return media


class Medium:
    """The senders' queues and the shared media of a bandwidth-limited radio; :meth:`serve` says which messages
    finished going on the air this tick and when each is due."""

    def __init__(self, capacity: int, queue_bytes: int, latency: int, jitter: int,
                 order_rng: np.random.Generator, jitter_rng: np.random.Generator) -> None:
        self.capacity = capacity
        self.queue_bytes = queue_bytes
        self.latency = latency
        self.jitter = jitter
        self.order_rng = order_rng
        self.jitter_rng = jitter_rng
        self.queues: dict[str, SenderQueue] = collections.defaultdict(SenderQueue)
        self.airtime_bytes = 0
        self.dropped_queue = 0
        self.queued_max_bytes = 0
        self.load: tuple[int, ...] = ()  # bytes each medium carried at the last tick served
        self.medium_of: dict[str, int] = {}  # each endpoint's medium at that tick

    def enqueue(self, tick: int, bundles: dict[str, tuple[Envelope, ...]]) -> None:
        """Each sender's new messages, in bundle order, at the tail of its queue (drop-tail)."""
        for src in sorted(bundles):
            q = self.queues[src]
            for pos, msg in enumerate(bundles[src]):
                size = len(msg.encode())
                if q.nbytes + size > self.queue_bytes:
                    self.dropped_queue += 1
                    continue
                item = Queued(src, msg, size, tick, size, pos)
                (q.bulk if msg.payload_kind in BULK_KINDS else q.control).append(item)
                q.nbytes += size
            self.queued_max_bytes = max(self.queued_max_bytes, q.nbytes)

    def serve(self, tick: int, nodes: tuple[str, ...], link: np.ndarray) -> list[tuple[Queued, int]]:
        """One tick of airtime over the media of ``link`` (rows in ``nodes`` order): the messages whose last
        byte went on the air, each with its delivery tick, in the order an unlimited radio sends (the tick they
        were handed over, then their sender's place in ``nodes``, then their place in its bundle), so that a
        limit that never binds gives the unlimited run's loss draws and deliveries."""
        done: list[tuple[Queued, int]] = []
        load: list[int] = []
        self.medium_of = {}
        for m, members in enumerate(components(link)):
            senders = [nodes[i] for i in members if nodes[i] in self.queues and self.queues[nodes[i]].head()]
            for i in members:
                self.medium_of[nodes[i]] = m
            if len(senders) > 1:
                senders = [senders[k] for k in self.order_rng.permutation(len(senders)).tolist()]
            load.append(self._serve_medium(tick, senders, done))
        self.load = tuple(load)
        place = {r: i for i, r in enumerate(nodes)}
        done.sort(key=lambda d: (d[0].handed, place[d[0].src], d[0].pos))
        return done

    def _serve_medium(self, tick: int, senders: list[str], done: list[tuple[Queued, int]]) -> int:
        """Round-robin over ``senders`` until the medium's capacity is spent; the bytes it carried."""
        left = self.capacity
        active = senders
        while active and left > 0:
            still: list[str] = []
            for src in active:
                q = self.queues[src]
                item = q.head()
                if item is None:
                    continue
                if item.left <= left:  # the rest of it fits: wholly on the air this tick
                    left -= item.left
                    self.airtime_bytes += item.left
                    item.left = 0
                    q.pop(item)
                    done.append((item, self._due(tick)))
                    still.append(src)
                elif item.left > self.capacity and left > 0:  # longer than a tick: what is left, then on
                    item.left -= left
                    self.airtime_bytes += left
                    left = 0
                    q.start(item)
                if left <= 0:
                    break
            active = still
        return self.capacity - left

    def _due(self, tick: int) -> int:
        return tick + self.latency + (int(self.jitter_rng.integers(0, self.jitter + 1)) if self.jitter else 0)
