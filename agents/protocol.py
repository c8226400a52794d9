"""The brain's own radio protocol: pose beacons and map deltas (DESIGN.md "What it is": a robot knows only what
its sensor and its radio tell it), and the map recovery's fill (``agents/mapsync.py``). Each is a
:class:`~fleet_emu.core.codec.Payload`, sealed in an envelope by the brain; netem never decodes them.

The recovery's fields (``PoseBeacon.maps`` and ``want``, ``MapDelta.n``) are optional and left out of the
encoding when absent, so that a fleet without map sync (an ideal radio) sends exactly the bytes it sent
before they existed."""

from __future__ import annotations

import dataclasses
import itertools
from typing import Any

import numpy as np

from fleet_emu.core.codec import Context, Payload
from fleet_emu.core.errors import DecodeError
from fleet_emu.core.grid import Cell
from fleet_emu.core.messages import check_cell, check_cells

#: At most this many delta numbers in a request or a fill (a receiver missing more asks again next tick).
MAX_SEQS = 64


def _without_none(obj: dict[str, Any], *names: str) -> dict[str, Any]:
    """The encoded fields without the optional ``names`` that are None (absent, not nil, on the radio)."""
    return {k: v for k, v in obj.items() if not (k in names and v is None)}


def check_seqs(seqs: tuple[int, ...], what: str) -> None:
    """Delta numbers: at most :data:`MAX_SEQS`, each >= 1, strictly ascending."""
    if len(seqs) > MAX_SEQS:
        raise DecodeError(f"{what}: more than {MAX_SEQS} delta numbers")
    if any(s < 1 for s in seqs) or any(b <= a for a, b in itertools.pairwise(seqs)):
        raise DecodeError(f"{what}: delta numbers must be >= 1 and strictly ascending")


@dataclasses.dataclass(frozen=True)
class PoseBeacon(Payload):
    """A robot's own pose, broadcast every tick: ``cell``, where it stands at the beacon's tick, and ``next``,
    the cell its command of that same tick moves it to (``cell`` when it stays). The beacon arrives a tick
    later, when the robot has made that move, so ``next`` is where a teammate should expect it (MinPos
    section 4.3 compares every robot's cost at the moment of the decision). ``next`` is absent (None) in a
    schema-2 recording made before it existed: the teammate is then expected at ``cell``. ``maps``, with map
    sync on, is the number of map deltas the robot has broadcast so far, that of this tick included (a
    receiver that has fewer asks for the missing ones); ``want``, the robot's requests for deltas it missed,
    per teammate: the numbers it asks that teammate for (empty: its whole map), piggybacked on the beacon it
    sends anyway rather than each in an envelope of its own. Both absent without map sync (and ``want``
    when the robot misses nothing)."""

    KIND = "pose"
    cell: Cell
    next: Cell | None = None
    maps: int | None = None
    want: dict[str, tuple[int, ...]] | None = None

    def fields_obj(self) -> dict[str, Any]:
        return _without_none(super().fields_obj(), "maps", "want")

    @property
    def expected(self) -> Cell:
        """Where the robot stands once its command of the beacon's tick is applied, if the move succeeds."""
        return self.cell if self.next is None else self.next

    def validate(self, ctx: Context | None) -> None:
        check_cell(self.cell, ctx.shape if ctx else None, "pose")
        if self.next is not None:
            check_cell(self.next, ctx.shape if ctx else None, "pose")
            if abs(self.next[0] - self.cell[0]) + abs(self.next[1] - self.cell[1]) > 1:
                raise DecodeError(f"pose: next cell {self.next} is not one step from {self.cell}")
        if self.maps is not None and self.maps < 0:
            raise DecodeError("pose: negative map delta count")
        for robot, seqs in (self.want or {}).items():
            if ctx is not None and ctx.senders is not None and robot not in ctx.senders:
                raise DecodeError(f"pose: request to an unknown robot {robot!r}")
            check_seqs(seqs, "pose")


@dataclasses.dataclass(frozen=True)
class MapDelta(Payload):
    """Cells a robot learned (flat indices and their values): the news of one tick, or (without map sync) its
    whole known map for a teammate heard again after a silence. With map sync on, ``n`` numbers the robot's
    broadcast deltas 1, 2, ..., and ``covers`` lists earlier deltas whose cells this one carries again
    because a teammate asked for them (:attr:`PoseBeacon.want`); both absent without map sync."""

    KIND = "map"
    cells: np.ndarray
    values: np.ndarray
    n: int | None = None
    covers: tuple[int, ...] | None = None

    def fields_obj(self) -> dict[str, Any]:
        return _without_none(super().fields_obj(), "n", "covers")

    def validate(self, ctx: Context | None) -> None:
        check_cells(self.cells, self.values, ctx.shape if ctx else None, "map")
        if self.n is not None and self.n < 1:
            raise DecodeError("map: delta number must be >= 1")
        if self.covers is not None:
            check_seqs(self.covers, "map")
            if self.n is None or (self.covers and self.covers[-1] >= self.n):
                raise DecodeError("map: covers a delta not before its own")


@dataclasses.dataclass(frozen=True)
class MapFill(Payload):
    """Map sync: the whole known map, addressed to a teammate that asked (:attr:`PoseBeacon.want`) for the
    whole map or for a delta no longer kept. It stands for the deltas ``seqs`` and for every delta numbered up
    to ``upto`` (a whole map has ``upto`` = the deltas sent so far, ``seqs`` empty)."""

    KIND = "mapfill"
    cells: np.ndarray
    values: np.ndarray
    seqs: tuple[int, ...] = ()
    upto: int = 0

    def validate(self, ctx: Context | None) -> None:
        check_cells(self.cells, self.values, ctx.shape if ctx else None, "mapfill")
        check_seqs(self.seqs, "mapfill")
        if self.upto < 0:
            raise DecodeError("mapfill: negative upto")
