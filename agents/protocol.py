"""The brain's own radio protocol: pose beacons and map deltas (docs/design/architecture.md: a robot knows only what
its sensor and its radio tell it), and the map recovery's fill (``agents/mapsync.py``). Each is a
:class:`~fleet_emu.core.codec.Payload`, sealed in an envelope by the brain; netem never decodes them.

The recovery's fields (``PoseBeacon.maps`` and ``want``, ``MapDelta.n``) are optional and left out of the
encoding when absent, so that a fleet without map sync (an ideal radio) sends exactly the bytes it sent
before they existed."""

from __future__ import annotations

import itertools
import operator
from typing import Annotated, Any

import msgspec
import numpy as np

from fleet_emu.core.codec import Context, Payload
from fleet_emu.core.errors import DecodeError
from fleet_emu.core.grid import Cell
from fleet_emu.core.messages import check_cell, check_cells

#: At most this many delta numbers in a request or a fill (a receiver missing more asks again next tick).
MAX_SEQS = 64


#: Delta numbers as declared: each >= 1, at most :data:`MAX_SEQS`, and strictly ascending (:func:`ascending`).
Seqs = Annotated[tuple[Annotated[int, msgspec.Meta(ge=1)], ...], msgspec.Meta(max_length=MAX_SEQS)]
#: A move from a cell to the next: a step or none (:attr:`PoseBeacon.next`).
_STEPS = frozenset({(0, 0), (0, 1), (0, -1), (1, 0), (-1, 0)})
#: A count, 0 or more, as declared.
NonNegative = Annotated[int, msgspec.Meta(ge=0)]


def ascending(lists: list[tuple[int, ...]]) -> bool:
    """Whether each of ``lists`` is strictly ascending (most hold one number: only the others are compared)."""
    longer = [seqs for seqs in lists if len(seqs) > 1]
    return not longer or all(all(map(operator.lt, seqs, seqs[1:])) for seqs in longer)


class PoseBeacon(Payload, kw_only=True, frozen=True, omit_defaults=True):
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
    maps: NonNegative | None = None
    want: dict[str, Seqs] | None = None

    @property
    def expected(self) -> Cell:
        """Where the robot stands once its command of the beacon's tick is applied, if the move succeeds."""
        return self.cell if self.next is None else self.next

    @classmethod
    def validate_many(cls, records: list[Any], ctx: Context | None, arrays: dict[str, np.ndarray]) -> None:
        """Every beacon of ``records`` checked in a few passes over them all (a robot hears every teammate's
        each tick): its cells on the grid, ``next`` a step from ``cell``, its requests to teammates."""
        shape, senders = (ctx.shape, ctx.senders) if ctx is not None else (None, None)
        cells = list(map(_cell, records))
        moves = [(n, c) for n, c in zip(map(_next, records), cells, strict=True) if n is not None]
        if shape is not None:
            rows, cols = zip(*cells, *(n for n, _ in moves), strict=True)
            if min(rows) < 0 or min(cols) < 0 or max(rows) >= shape[0] or max(cols) >= shape[1]:
                for cell in (*cells, *(n for n, _ in moves)):
                    check_cell(cell, shape, "pose")  # raises, naming it
        if moves and not {(n[0] - c[0], n[1] - c[1]) for n, c in moves} <= _STEPS:
            n, c = next(m for m in moves if (m[0][0] - m[1][0], m[0][1] - m[1][1]) not in _STEPS)
            raise DecodeError(f"pose: next cell {n} is not one step from {c}")
        wants = [w for w in map(_want, records) if w]
        if senders is not None and not all(map(senders.issuperset, wants)):
            robot = next(r for w in wants for r in w if r not in senders)
            raise DecodeError(f"pose: request to an unknown robot {robot!r}")
        if not ascending(list(itertools.chain.from_iterable(map(dict.values, wants)))):
            raise DecodeError("pose: delta numbers must be strictly ascending")


class MapDelta(Payload, kw_only=True, frozen=True, omit_defaults=True):
    """Cells a robot learned (flat indices and their values): the news of one tick, or (without map sync) its
    whole known map for a teammate heard again after a silence. With map sync on, ``n`` numbers the robot's
    broadcast deltas 1, 2, ..., and ``covers`` lists earlier deltas whose cells this one carries again
    because a teammate asked for them (:attr:`PoseBeacon.want`); both absent without map sync."""

    KIND = "map"
    cells: np.ndarray
    values: np.ndarray
    n: Annotated[int, msgspec.Meta(ge=1)] | None = None
    covers: Seqs | None = None

    @classmethod
    def validate_many(cls, records: list[Any], ctx: Context | None, arrays: dict[str, np.ndarray]) -> None:
        """Every delta's cells on the grid and values known (all at once: ``arrays`` holds every record's
        cells and values one after the other), and what it covers numbered before it."""
        _check_all_cells(records, ctx, arrays, "map")
        covering = [(c, r.n) for r, c in zip(records, map(_covers, records), strict=True) if c is not None]
        if any(n is None or (c and c[-1] >= n) for c, n in covering):
            raise DecodeError("map: covers a delta not before its own")
        if not ascending([c for c, _ in covering]):
            raise DecodeError("map: delta numbers must be strictly ascending")


class MapFill(Payload, kw_only=True, frozen=True):
    """Map sync: the whole known map, addressed to a teammate that asked (:attr:`PoseBeacon.want`) for the
    whole map or for a delta no longer kept. It stands for the deltas ``seqs`` and for every delta numbered up
    to ``upto`` (a whole map has ``upto`` = the deltas sent so far, ``seqs`` empty)."""

    KIND = "mapfill"
    cells: np.ndarray
    values: np.ndarray
    seqs: Seqs = ()
    upto: NonNegative = 0

    @classmethod
    def validate_many(cls, records: list[Any], ctx: Context | None, arrays: dict[str, np.ndarray]) -> None:
        _check_all_cells(records, ctx, arrays, "mapfill")
        if not ascending([r.seqs for r in records]):
            raise DecodeError("mapfill: delta numbers must be strictly ascending")


def _check_all_cells(records: list[Any], ctx: Context | None, arrays: dict[str, np.ndarray], what: str) -> None:
    """:func:`check_cells` of every record's cells and values (``arrays``: theirs one after the other)."""
    if list(map(len, map(_cells, records))) != list(map(len, map(_values, records))):
        raise DecodeError(f"{what}: cells and values differ in length")
    check_cells(arrays["cells"], arrays["values"], ctx.shape if ctx else None, what)


_cell, _next, _want, _covers, _cells, _values = (
    operator.attrgetter(name) for name in ("cell", "next", "want", "covers", "cells", "values"))
