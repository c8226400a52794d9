"""What a robot hears in a tick, decoded at once: its teammates' pose beacons and map deltas read straight from
their payloads into light structs, checked against the team and the grid, with no record built per message.

At 100 robots a robot hears about 90 beacons and 90 map deltas a tick; decoding each into a
:class:`~fleet_emu.agents.protocol.PoseBeacon` or :class:`~fleet_emu.agents.protocol.MapDelta` and a
:class:`~fleet_emu.core.messages.RadioMsg` cost several microseconds of Python per message, most of the brain's
CPU outside the allocator. Here the checks that depend on the receiver are in the decoders themselves (a cell
inside the grid, a request addressed to a teammate: per grid and team, built once), the map deltas' cells are
checked in one compiled pass over all of them, and the brain reads the structs (:meth:`Brain.open`).

This decides nothing: :func:`hear` accepts only what the message decoders accept (``agents/protocol.py``; the
tests compare them on mutated payloads), gives their values, and returns None for an inbox holding anything
else (a header or payload that does not validate, a kind it does not batch that fails to open, an unusual
but valid encoding): the brain then opens the inbox message by message as before, which drops and counts
what does not validate, in the order it came.
"""

from __future__ import annotations

import functools
import itertools
import operator
from collections.abc import Sequence
from typing import Annotated, Any, Literal, cast

import msgspec
import numpy as np

from fleet_emu.agents.protocol import MAX_SEQS
from fleet_emu.core import kernels
from fleet_emu.core.codec import MAX_ARRAY_BYTES, Context
from fleet_emu.core.envelope import MAX_PAYLOAD_BYTES, MAX_TTL
from fleet_emu.core.errors import DecodeError
from fleet_emu.core.messages import Envelope, RadioMsg, open_envelope

#: The envelope attribute under which a message heard is kept with its context: the memory engine hands one
#: broadcast envelope object to every receiver, and the next receiver of the same team and grid reads it as
#: it is (as :func:`~fleet_emu.core.envelope.open_envelope` keeps its opened message).
CACHE = "_heard"

#: One message heard: its origin, its envelope's tick, and its body (a :class:`Beacon`, a :class:`Delta`, or
#: a :class:`RadioMsg` for every other kind).
Heard = tuple[str, int, Any]

_Seq = Annotated[int, msgspec.Meta(ge=1)]
_Seqs = Annotated[tuple[_Seq, ...], msgspec.Meta(max_length=MAX_SEQS)]
_Count = Annotated[int, msgspec.Meta(ge=0)]
_Bytes = Annotated[bytes, msgspec.Meta(max_length=MAX_ARRAY_BYTES)]


class Beacon(msgspec.Struct, gc=False):
    """A pose beacon's fields as heard (:class:`~fleet_emu.agents.protocol.PoseBeacon`'s names and meanings)."""

    cell: tuple[int, int]
    next: tuple[int, int] | None = None
    maps: int | None = None
    want: dict[str, tuple[int, ...]] | None = None


class Delta(msgspec.Struct, gc=False):
    """A map delta's fields as heard (:class:`~fleet_emu.agents.protocol.MapDelta`'s): its cells and values are
    ``start:end`` of ``all_cells`` (int32) and ``all_values`` (int8), every delta of the inbox's in turn, read
    only (the brain merges a run of them at once, without a copy of each)."""

    all_cells: np.ndarray
    all_values: np.ndarray
    start: int
    end: int
    n: int | None = None
    covers: tuple[int, ...] | None = None

    @property
    def cells(self) -> np.ndarray:
        return self.all_cells[self.start:self.end]

    @property
    def values(self) -> np.ndarray:
        return self.all_values[self.start:self.end]


class _Cells(msgspec.Struct, forbid_unknown_fields=True, gc=False):
    dtype: Literal["int32"]
    shape: tuple[_Count]
    data: _Bytes


class _Values(msgspec.Struct, forbid_unknown_fields=True, gc=False):
    dtype: Literal["int8"]
    shape: tuple[_Count]
    data: _Bytes


class _DeltaWire(msgspec.Struct, forbid_unknown_fields=True, gc=False):
    """A map delta as the brain sends it (int32 cells, int8 values); any other encoding goes the long way."""

    cells: _Cells
    values: _Values
    n: _Seq | None = None
    covers: _Seqs | None = None


_DELTA = msgspec.msgpack.Decoder(_DeltaWire)


@functools.lru_cache(maxsize=16)
def _beacon_decoder(shape: tuple[int, int], senders: frozenset[str]) -> msgspec.msgpack.Decoder:
    """A beacon decoder for one grid and team: a cell's row and column in range and every request's robot one
    of the team, checked by msgspec (:meth:`~fleet_emu.agents.protocol.PoseBeacon.validate`'s checks but the
    next cell's distance and the requests' order)."""
    cell = tuple[Annotated[int, msgspec.Meta(ge=0, lt=shape[0])], Annotated[int, msgspec.Meta(ge=0, lt=shape[1])]]
    robot = Literal[tuple(sorted(senders))]  # type: ignore[valid-type]
    wire = msgspec.defstruct("BeaconWire", [("cell", cell), ("next", cell | None, None),
                                            ("maps", _Count | None, None),
                                            ("want", dict[robot, _Seqs] | None, None)],  # type: ignore[valid-type]
                             bases=(Beacon,), forbid_unknown_fields=True, gc=False)
    return msgspec.msgpack.Decoder(wire)


def hear(inbox: Sequence[Envelope], ctx: Context, keep: bool = False) -> list[Heard] | None:
    """The messages of ``inbox`` in order, each checked as :meth:`Envelope.validate` and
    :func:`~fleet_emu.core.envelope.open_envelope` check it; None when one does not pass (or is not in a form
    decoded here and does not open), and the caller opens the inbox message by message instead. With
    ``keep`` (the memory engine, whose receivers of a broadcast share its envelope object), each message
    decoded is kept on its envelope for the next receiver of the same team and grid, and one kept is used."""
    senders, shape = ctx.senders, ctx.shape
    if not senders or shape is None:
        return None
    beacon, delta = _beacon_decoder(shape, senders).decode, _DELTA.decode
    out: list[Any] = []
    wants: list[dict[str, tuple[int, ...]]] = []  # the beacons' requests, their order checked at the end
    deltas: list[tuple[int, _DeltaWire]] = []  # the map deltas (index in out, wire), checked at the end
    fresh: list[tuple[int, Envelope]] = []
    add, max_ttl, max_bytes = out.append, MAX_TTL, MAX_PAYLOAD_BYTES
    try:
        for env in inbox:
            if keep:
                cached = _kept(env, ctx)
                if cached is not None:
                    add(cached)
                    continue
                fresh.append((len(out), env))
            origin, tick, payload, kind = env.origin, env.tick, env.payload, env.payload_kind
            if not (env.src in senders and origin in senders and tick >= 0 and env.seq >= 0
                    and 0 <= env.ttl <= max_ttl and len(payload) <= max_bytes):
                return None  # Envelope.validate's common case, inlined; anything else goes the long way
            if kind == "pose":
                b = beacon(payload)
                nxt = b.next
                if nxt is not None and abs(nxt[0] - b.cell[0]) + abs(nxt[1] - b.cell[1]) > 1:
                    return None
                if b.want:
                    wants.append(b.want)
                add((origin, tick, b))
            elif kind == "map":
                deltas.append((len(out), delta(payload)))
                add((origin, tick, None))
            else:
                add((origin, tick, open_envelope(env, ctx)))
    except (msgspec.MsgspecError, DecodeError):
        return None
    if (wants and not _in_order(wants)) or (deltas and not _deltas(out, deltas, shape, keep)):
        return None
    for i, env in fresh:
        env.__dict__[CACHE] = (ctx, out[i])
    return out


def _kept(env: Envelope, ctx: Context) -> Heard | None:
    """What :func:`hear` kept on ``env`` for a context of the same team and grid as ``ctx``, or None."""
    cached = env.__dict__.get(CACHE)
    if cached is not None:
        seen = cached[0]
        if seen is ctx or (seen.senders is ctx.senders and seen.shape == ctx.shape):
            return cast(Heard, cached[1])
    return None


def _in_order(wants: list[dict[str, tuple[int, ...]]]) -> bool:
    """Every request of more than one number strictly ascending (each number is >= 1 already)."""
    return _pairs_ascending([s for w in wants for s in w.values() if len(s) > 1])


def _pairs_ascending(multi: list[tuple[int, ...]]) -> bool:
    """Every tuple of ``multi`` strictly ascending, their pairs compared in one pass in C."""
    return not multi or all(map(operator.lt, itertools.chain.from_iterable([s[:-1] for s in multi]),
                                itertools.chain.from_iterable([s[1:] for s in multi])))


def _deltas(out: list[Any], deltas: list[tuple[int, _DeltaWire]], shape: tuple[int, int], keep: bool) -> bool:
    """Check the decoded map deltas (their index in ``out`` and wire) and put them in ``out``; their cells and
    values checked in one compiled pass over all of them. False when one does not pass. With ``keep`` each
    delta gets arrays of its own (its receivers' runs of deltas are not this inbox's)."""
    wires = [w for _, w in deltas]
    ks = [w.cells.shape[0] for w in wires]
    if ([w.values.shape[0] for w in wires] != ks or [len(w.values.data) for w in wires] != ks
            or [len(w.cells.data) for w in wires] != [4 * k for k in ks]):
        return False
    covered = [(w.covers, w.n) for w in wires if w.covers is not None]
    if covered and (any([n is None or (c and c[-1] >= n) for c, n in covered])
                    or not _pairs_ascending([c for c, _ in covered if len(c) > 1])):
        return False
    cells = np.frombuffer(b"".join([w.cells.data for w in wires]), np.int32)
    values = np.frombuffer(b"".join([w.values.data for w in wires]), np.int8)
    if not kernels.cells_valid(cells, values, shape[0] * shape[1]):
        return False
    a = 0
    for (i, w), k in zip(deltas, ks, strict=True):
        origin, tick, _ = out[i]
        d = Delta(cells[a:a + k], values[a:a + k], 0, k, w.n, w.covers) if keep else \
            Delta(cells, values, a, a + k, w.n, w.covers)
        out[i] = (origin, tick, d)
        a += k
    return True


def as_heard(msgs: Sequence[RadioMsg]) -> list[Heard]:
    """Messages opened one by one (:meth:`Brain.open`'s long way) in :func:`hear`'s form."""
    return [(m.origin, m.tick, m) for m in msgs]

