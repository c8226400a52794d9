"""Map sync: map deltas lost on the radio are recovered while robots stay in contact.

Both papers whose allocators assume a common map take map sharing for granted: MinPos (Bautin et al. 2012,
section 4.3: coordination "is achieved only by cooperatively building the map and by sharing robots
locations"; section 2 assumes a WiFi network covering the whole area) and the trade-based exploration (Yan et
al. 2011, section 3: "all robots share a joint occupancy grid map"; section 4.3). Neither says how a map
survives a lossy radio; the emulator's robots share maps only over it. The brain broadcasts, each
tick, a delta of the cells it newly learned; one delta lost on a link (the radio's loss, or a link that broke
for a few ticks) was never sent again while the two robots kept hearing each other, and the receiver could
miss those cells for the rest of the run.

The scheme is a negative acknowledgement (NACK) with selective repeat, the usual choice for broadcast over a
lossy shared medium (an ACK per receiver and delta would cost a message per pair and tick even when nothing
is lost):

- The sender numbers its broadcast deltas 1, 2, ... (``MapDelta.n``) and every pose beacon carries the latest
  number (``PoseBeacon.maps``), so a receiver sees a lost delta at the next delta or the next beacon it hears,
  even when the sender has learned nothing since (a robot that has finished exploring).
- A receiver missing deltas from a teammate it heard within the last ``retry_after`` ticks (in contact) asks
  that teammate for the oldest :data:`~fleet_emu.agents.protocol.MAX_SEQS` missing numbers (the rest in the
  next ticks), or for its whole map when more than that went missing at once (out of range a long while).
  The request rides on the pose beacon the receiver broadcasts every tick anyway
  (``PoseBeacon.want``, a list of numbers per teammate asked), delivered to that teammate or lost like any
  radio message: an envelope of its own would cost its header, most of a request's bytes.
- The sender puts the cells of the deltas asked for (it keeps the cell indices of its last ``history``
  deltas) in its next broadcast delta, with their values now, and lists their numbers in it
  (``MapDelta.covers``): a delta is broadcast anyway, and one emission reaches every teammate that missed
  the same delta, so a resent delta costs its cells and nothing else. When a number asked for is no longer
  kept, the requester gets the whole known map instead (a :class:`~fleet_emu.agents.protocol.MapFill`
  addressed to it). A request or a resent delta lost on the radio is retried: a number still missing
  ``retry_after`` ticks after it was asked is asked again (the round trip is two ticks at the usual latency
  of one). Only the lost news is sent again, plus a few bytes of request.
- A teammate heard for the first time, or again after ``resync_after`` silent ticks, still gets the sender's
  whole map unasked (the brain's rule before map sync), now as a fill that stands for every delta so far;
  the receiver, which hears the sender again at the same time, holds its own requests to it for
  ``retry_after`` ticks rather than ask for what is on its way. (Pulling instead, the deltas missed or the
  whole map past ``MAX_SEQS`` of them, took 13 % fewer bytes on the wall radio, office, 3 robots, loss 0.3,
  8 seeds, with the beliefs no closer: a mean gap of 443 cells against 420 with the push, both within the
  noise of the 377 before map sync. The push, the rule before map sync, is kept.) A silence shorter than
  ``resync_after`` costs only the deltas missed.

Choices the papers leave open, as parameters (:class:`SyncConfig`): ``retry_after`` (3 ticks: one round trip
plus one tick), ``history`` (512 deltas kept per robot). Map sync is on when the radio can lose a message
(``brain_config``: every model but ``ideal``, and ``full`` only with a loss): on a radio that delivers
everything it would only add bytes, and runs there stay bit-identical to runs before it existed. The
scenario's ``map_sync = false`` turns it off on any radio: the papers' robots share map updates by message and
a lost one is lost, which is what a study of loss (Yan et al. 2011, Tables 3-4) measures; the brain then
still broadcasts its new cells every tick and pushes its whole map to a teammate heard again after
``resync_after`` silent ticks, and nothing more.

A functional core: the state below is plain data stepped by the brain; no clock, no I/O.
"""

from __future__ import annotations

import dataclasses
from collections import OrderedDict

import numpy as np

from fleet_emu.agents.belief import Belief
from fleet_emu.agents.protocol import MAX_SEQS, MapFill
from fleet_emu.core.grid import distinct


@dataclasses.dataclass(frozen=True)
class SyncConfig:
    """``retry_after``: ticks after which a number still missing is asked again, and within which a teammate
    must have been heard to be asked at all; ``history``: how many of its own deltas' cells a robot keeps to
    answer with."""

    retry_after: int = 3
    history: int = 512


@dataclasses.dataclass
class Peer:
    """What a robot knows of one teammate's deltas: ``top``, the highest number it knows exists; ``missing``,
    the numbers up to ``top`` neither received nor filled, each with the tick it was last asked for (None:
    not yet). A gap of more than :data:`~fleet_emu.agents.protocol.MAX_SEQS` numbers at once (the teammate
    was out of range a long while, or a corrupt number) is not listed: the robot asks for the whole map
    instead (``whole``: the number a whole map must reach, ``whole_asked``: when it was asked); the numbers
    after it are listed as usual."""

    top: int = 0
    missing: dict[int, int | None] = dataclasses.field(default_factory=dict)
    whole: int | None = None
    whole_asked: int | None = None

    def exists(self, n: int) -> None:
        """Delta ``n`` was sent (a delta or a beacon said so): every number above ``top`` up to it is missing."""
        if n <= self.top:
            return
        if n == self.top + 1:  # the usual case: the next number
            self.missing[n] = None
        elif n - self.top > MAX_SEQS:
            self.missing.clear()  # a whole map stands for them too
            self.whole = n
        else:
            self.missing.update(dict.fromkeys(range(self.top + 1, n + 1)))
        self.top = n

    def received(self, n: int) -> None:
        """Delta ``n`` arrived."""
        if n > self.top:  # not announced yet (its beacon comes first, as a rule)
            self.exists(n)
        self.missing.pop(n, None)

    def filled(self, seqs: tuple[int, ...], upto: int) -> None:
        """A fill arrived, standing for the deltas ``seqs`` and every delta up to ``upto``."""
        for n in seqs:
            self.missing.pop(n, None)
        if upto:
            self.missing = {n: at for n, at in self.missing.items() if n > upto}
            if self.whole is not None and upto >= self.whole:
                self.whole = self.whole_asked = None
            if upto > self.top:
                self.top = upto

    def hold(self, t: int) -> None:
        """Count everything missing now as asked at ``t`` (the teammate's whole map is on its way)."""
        self.missing = dict.fromkeys(self.missing, t)
        if self.whole is not None:
            self.whole_asked = t

    def request(self, t: int, retry_after: int) -> tuple[int, ...] | None:
        """The numbers to ask for at ``t`` (empty: the whole map, first), None for none: the oldest
        :data:`MAX_SEQS` never asked, or asked ``retry_after`` ticks ago or more (the rest in the next ticks)."""
        if self.whole is not None:
            if self.whole_asked is not None and t - self.whole_asked < retry_after:
                return None
            self.whole_asked = t
            return ()
        if not self.missing:  # the common case: nothing to ask for
            return None
        due = sorted(n for n, at in self.missing.items() if at is None or t - at >= retry_after)[:MAX_SEQS]
        if not due:
            return None
        for n in due:
            self.missing[n] = t
        return tuple(due)


class MapSync:
    """One robot's map sync: its own deltas' numbers and cells, and a :class:`Peer` per teammate."""

    def __init__(self, config: SyncConfig) -> None:
        self.config = config
        self.sent = 0
        self.history: OrderedDict[int, np.ndarray] = OrderedDict()
        self.peers: dict[str, Peer] = {}
        self.pending: set[int] = set()  # numbers asked for, to send again in the next delta
        self.asked = 0  # for tests and benchmarks: requests made, whole maps sent, deltas and cells sent again
        self.wholes = 0
        self.resent = 0
        self.resent_cells = 0

    def peer(self, robot: str) -> Peer:
        p = self.peers.get(robot)  # not setdefault: it would build a Peer for every call
        if p is None:
            p = self.peers[robot] = Peer()
        return p

    def number(self, cells: np.ndarray) -> int:
        """Number the delta about to be broadcast, keeping its news ``cells`` to send them again on request
        (not the cells it carries again: a teammate that missed this delta and those it covers asks for
        them as well)."""
        self.sent += 1
        self.history[self.sent] = cells
        while len(self.history) > self.config.history:
            self.history.popitem(last=False)
        return self.sent

    def whole(self, belief: Belief) -> MapFill:
        """The whole known map, standing for every delta sent so far."""
        self.wholes += 1
        cells, values = belief.known()
        return MapFill(cells=cells, values=values, upto=self.sent)

    def answer(self, seqs: tuple[int, ...], belief: Belief) -> MapFill | None:
        """A teammate asks for the deltas ``seqs``: they go again in the next broadcast delta (None), or the
        whole map goes to the teammate when ``seqs`` is empty or one of them is no longer kept (or was never
        sent)."""
        if self.sends_whole(seqs):
            return self.whole(belief)
        self.pending.update(seqs)
        return None

    def sends_whole(self, seqs: tuple[int, ...]) -> bool:
        """Whether :meth:`answer` answers ``seqs`` with the whole map (the only answer that reads the belief)."""
        return not seqs or any(n not in self.history for n in seqs)

    def news(self, cells: np.ndarray) -> tuple[np.ndarray, tuple[int, ...] | None]:
        """The cells of the delta about to be broadcast: this tick's news, and the cells of the oldest
        :data:`MAX_SEQS` deltas asked for again (the rest in the next ticks), with their numbers (``covers``;
        None when none is)."""
        if not self.pending:
            return cells, None
        again = tuple(sorted(self.pending)[:MAX_SEQS])
        self.pending.difference_update(again)
        again = tuple(n for n in again if n in self.history)  # one left pending may have been forgotten since
        if not again:
            return cells, None
        extra = np.concatenate([self.history[n] for n in again])
        out = distinct(np.concatenate((cells, extra))).astype(np.int32)
        self.resent += len(again)
        self.resent_cells += len(out) - len(cells)
        return out, again

    def requests(self, t: int, heard: dict[str, int]) -> dict[str, tuple[int, ...]] | None:
        """The requests to send at ``t`` (``PoseBeacon.want``), to teammates heard within ``retry_after``
        ticks, in id order; None when there is none."""
        out = {}
        retry = self.config.retry_after
        for robot in sorted(self.peers):
            p = self.peers[robot]
            if (p.missing or p.whole is not None) and robot in heard and t - heard[robot] <= retry:
                req = p.request(t, retry)  # (nothing missing: None, without the call)
                if req is not None:
                    self.asked += 1
                    out[robot] = req
        return out or None
