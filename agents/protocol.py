"""The brain's own radio protocol: pose beacons and map deltas (docs/design/architecture.md: a robot knows only what
its sensor and its radio tell it), and the map recovery's fill (``agents/mapsync.py``). Each is a
:class:`~fleet_emu.core.codec.Payload`, sealed in an envelope by the brain; netem never decodes them.

The recovery's fields (``PoseBeacon.maps`` and ``want``, ``MapDelta.n``) are optional and left out of the
encoding when absent, so that a fleet without map sync (an ideal radio) sends exactly the bytes it sent
before they existed."""

from __future__ import annotations

import dataclasses
import itertools
import operator
from typing import Annotated, Any

import msgspec
import numpy as np

from fleet_emu.core import kernels
from fleet_emu.core.codec import MAX_ARRAY_BYTES, Context, Payload, array_of, fast_decoder, packed_array, typed_decoder
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
    # strictly ascending from at least 1 (each number >= 1 follows), pairs compared in one pass in C
    if seqs and (seqs[0] < 1 or not all(map(operator.lt, seqs, itertools.islice(seqs, 1, None)))):
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
        if self.want:
            senders = ctx.senders if ctx is not None else None
            if senders is not None and not self.want.keys() <= senders:
                robot = next(r for r in self.want if r not in senders)
                raise DecodeError(f"pose: request to an unknown robot {robot!r}")
            for seqs in self.want.values():
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


# --- fast decoders -------------------------------------------------------------------------------------
# Every robot decodes every teammate's beacon and delta each tick, so these are the codec's hot path at 100
# robots. Each accepts a payload's map only when every field has exactly its type and the payload validates
# (the checks of ``validate``, in one pass where they can be), and returns None otherwise: the generic decode
# then checks it and raises the error (:data:`fleet_emu.core.codec._FAST`).

_POSE_KEYS = frozenset({"cell", "next", "maps", "want"})
_MAP_KEYS = frozenset({"cells", "values", "n", "covers"})
_FILL_KEYS = frozenset({"cells", "values", "seqs", "upto"})
_KERNEL_CELLS = (np.dtype(np.int32), np.dtype(np.int64))  # cell index types cells_valid is warmed up for
_KERNEL_DTYPES = {dt.name: dt for dt in _KERNEL_CELLS}


def _cell_of(value: Any, shape: tuple[int, int] | None) -> Cell | None:
    """``value`` as a cell inside ``shape`` when it is a list of two ints there, else None."""
    if type(value) is not list or len(value) != 2:
        return None
    r, c = value
    if type(r) is not int or type(c) is not int:
        return None
    if shape is not None and not (0 <= r < shape[0] and 0 <= c < shape[1]):
        return None
    return r, c


def _seqs_of(value: Any) -> tuple[int, ...] | None:
    """``value`` as delta numbers (:func:`check_seqs`) when it is a list of them, else None."""
    if type(value) is not list or len(value) > MAX_SEQS or not set(map(type, value)) <= {int}:
        return None
    if value and (value[0] < 1 or not all(map(operator.lt, value, itertools.islice(value, 1, None)))):
        return None
    return tuple(value)


def _wants_of(want: dict) -> dict[str, tuple[int, ...]] | None:
    """A beacon's requests (robot -> a list of delta numbers) with each list checked as :func:`_seqs_of` does,
    in passes over all of them at once (every number an int >= 1) and, only for the lists of more than one
    number (most hold one), each list's order. None for anything else."""
    if not want:
        return {}
    lists = list(want.values())
    if not set(map(type, lists)) <= {list}:
        return None
    flat = list(itertools.chain.from_iterable(lists))
    if flat and (not set(map(type, flat)) <= {int} or min(flat) < 1):
        return None
    if max(map(len, lists)) > 1:
        for seqs in lists:
            if len(seqs) > 1 and (len(seqs) > MAX_SEQS
                                  or not all(map(operator.lt, seqs, itertools.islice(seqs, 1, None)))):
                return None
    return dict(zip(want, map(tuple, lists), strict=True))


@fast_decoder(PoseBeacon)
def _fast_pose(obj: dict, ctx: Context | None) -> PoseBeacon | None:
    if not obj.keys() <= _POSE_KEYS:
        return None
    shape = ctx.shape if ctx is not None else None
    cell = _cell_of(obj.get("cell"), shape)
    if cell is None:
        return None
    nxt = obj.get("next")
    if nxt is not None:
        nxt = _cell_of(nxt, shape)
        if nxt is None or abs(nxt[0] - cell[0]) + abs(nxt[1] - cell[1]) > 1:
            return None
    maps = obj.get("maps")
    if maps is not None and (type(maps) is not int or maps < 0):
        return None
    want = obj.get("want")
    if want is not None:
        if type(want) is not dict:
            return None
        senders = ctx.senders if ctx is not None else None
        # msgpack's keys are str or bytes (strict_map_key), and senders are str: within them, each is a str
        if not (want.keys() <= senders if senders is not None else set(map(type, want)) <= {str}):
            return None
        want = _wants_of(want)
        if want is None:
            return None
    beacon = object.__new__(PoseBeacon)
    beacon.__dict__.update(cell=cell, next=nxt, maps=maps, want=want)
    return beacon


def _fast_cells(cls: type[MapDelta] | type[MapFill], obj: dict, ctx: Context | None
                ) -> tuple[np.ndarray, np.ndarray] | None:
    """The checked cells and values of a map delta or fill, or None."""
    cells = packed_array(obj.get("cells"))
    values = packed_array(obj.get("values"))
    if cells is None or values is None:
        return None
    shape = ctx.shape if ctx is not None else None
    if (shape is not None and cells.ndim == 1 and values.ndim == 1 and len(cells) == len(values)
            and cells.dtype in _KERNEL_CELLS and values.dtype == np.int8):  # the common case, compiled
        return (cells, values) if kernels.cells_valid(cells, values, shape[0] * shape[1]) else None
    try:
        check_cells(cells, values, shape, cls.KIND)
    except DecodeError:
        return None
    return cells, values


@fast_decoder(MapDelta)
def _fast_map(obj: dict, ctx: Context | None) -> MapDelta | None:
    if not obj.keys() <= _MAP_KEYS:
        return None
    n, covers = obj.get("n"), obj.get("covers")
    if n is not None and (type(n) is not int or n < 1):
        return None
    if covers is not None:
        covers = _seqs_of(covers)
        if covers is None or n is None or (covers and covers[-1] >= n):
            return None
    got = _fast_cells(MapDelta, obj, ctx)
    if got is None:
        return None
    delta = object.__new__(MapDelta)
    delta.__dict__.update(cells=got[0], values=got[1], n=n, covers=covers)
    return delta


@fast_decoder(MapFill)
def _fast_fill(obj: dict, ctx: Context | None) -> MapFill | None:
    if not obj.keys() <= _FILL_KEYS:
        return None
    seqs, upto = obj.get("seqs", []), obj.get("upto", 0)
    seqs = _seqs_of(seqs)
    if seqs is None or type(upto) is not int or upto < 0:
        return None
    got = _fast_cells(MapFill, obj, ctx)
    if got is None:
        return None
    fill = object.__new__(MapFill)
    fill.__dict__.update(cells=got[0], values=got[1], seqs=seqs, upto=upto)
    return fill


# --- typed decoders ------------------------------------------------------------------------------------
# The same payloads straight from their bytes into structs (msgspec checks the types, the ranges and the list
# lengths in C), then the checks that need the context or several fields, as above; None for anything else,
# and the dict decoders then decide (:data:`fleet_emu.core.codec._TYPED`).

_Seq = Annotated[int, msgspec.Meta(ge=1)]
_Seqs = Annotated[tuple[_Seq, ...], msgspec.Meta(max_length=MAX_SEQS)]


class _PoseWire(msgspec.Struct, forbid_unknown_fields=True, gc=False):
    cell: tuple[int, int]
    next: tuple[int, int] | None = None
    maps: Annotated[int, msgspec.Meta(ge=0)] | None = None
    want: dict[str, _Seqs] | None = None


class _PackedWire(msgspec.Struct, forbid_unknown_fields=True, gc=False):
    dtype: str
    shape: list[int]
    data: bytes


class _MapWire(msgspec.Struct, forbid_unknown_fields=True, gc=False):
    cells: _PackedWire
    values: _PackedWire
    n: _Seq | None = None
    covers: _Seqs | None = None


class _FillWire(msgspec.Struct, forbid_unknown_fields=True, gc=False):
    cells: _PackedWire
    values: _PackedWire
    seqs: _Seqs = ()
    upto: Annotated[int, msgspec.Meta(ge=0)] = 0


_POSE_DECODER = msgspec.msgpack.Decoder(_PoseWire)
_MAP_DECODER = msgspec.msgpack.Decoder(_MapWire)
_FILL_DECODER = msgspec.msgpack.Decoder(_FillWire)


def _inside(cell: tuple[int, int], shape: tuple[int, int] | None) -> bool:
    return shape is None or (0 <= cell[0] < shape[0] and 0 <= cell[1] < shape[1])


def _ascending(seqs: tuple[int, ...]) -> bool:
    """Strictly ascending (each number already >= 1)."""
    return len(seqs) < 2 or all(map(operator.lt, seqs, itertools.islice(seqs, 1, None)))


@typed_decoder(PoseBeacon)
def _typed_pose(data: bytes, ctx: Context | None) -> PoseBeacon | None:
    w = _POSE_DECODER.decode(data)
    shape = ctx.shape if ctx is not None else None
    cell, nxt, want = w.cell, w.next, w.want
    r, c = cell
    if shape is not None and not (0 <= r < shape[0] and 0 <= c < shape[1]):
        return None
    if nxt is not None and (abs(nxt[0] - r) + abs(nxt[1] - c) > 1 or not _inside(nxt, shape)):
        return None
    if want:
        senders = ctx.senders if ctx is not None else None
        if senders is not None and not want.keys() <= senders:
            return None
        if max(map(len, want.values())) > 1 and not all(_ascending(seqs) for seqs in want.values() if len(seqs) > 1):
            return None
    beacon = object.__new__(PoseBeacon)
    beacon.__dict__.update(cell=cell, next=nxt, maps=w.maps, want=want)
    return beacon


def _typed_cells(w: _MapWire | _FillWire, ctx: Context | None) -> tuple[np.ndarray, np.ndarray] | None:
    """The checked cells and values of a decoded map delta or fill, or None (:func:`_fast_cells`)."""
    c, v = w.cells, w.values
    shape = ctx.shape if ctx is not None else None
    dt = _KERNEL_DTYPES.get(c.dtype)
    if (shape is not None and dt is not None and v.dtype == "int8" and c.shape == v.shape and len(c.shape) == 1
            and len(c.data) == c.shape[0] * dt.itemsize <= MAX_ARRAY_BYTES and len(v.data) == v.shape[0]):  # compiled
        flat, vals = np.frombuffer(c.data, dt), np.frombuffer(v.data, np.int8)
        return (flat, vals) if kernels.cells_valid(flat, vals, shape[0] * shape[1]) else None
    cells, values = array_of(c.dtype, c.shape, c.data), array_of(v.dtype, v.shape, v.data)
    if cells is None or values is None:
        return None
    check_cells(cells, values, shape, "map")  # raises: the dict decoders decide
    return cells, values


@typed_decoder(MapDelta)
def _typed_map(data: bytes, ctx: Context | None) -> MapDelta | None:
    w = _MAP_DECODER.decode(data)
    n, covers = w.n, w.covers
    if covers is not None and (n is None or not _ascending(covers) or (covers and covers[-1] >= n)):
        return None
    got = _typed_cells(w, ctx)
    if got is None:
        return None
    delta = object.__new__(MapDelta)
    delta.__dict__.update(cells=got[0], values=got[1], n=n, covers=covers)
    return delta


@typed_decoder(MapFill)
def _typed_fill(data: bytes, ctx: Context | None) -> MapFill | None:
    w = _FILL_DECODER.decode(data)
    if not _ascending(w.seqs):
        return None
    got = _typed_cells(w, ctx)
    if got is None:
        return None
    fill = object.__new__(MapFill)
    fill.__dict__.update(cells=got[0], values=got[1], seqs=w.seqs, upto=w.upto)
    return fill
