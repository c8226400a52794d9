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
from typing import Annotated, Any, Literal

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
    """A pose beacon's fields as heard (:class:`PoseBeacon`'s names and meanings)."""

    cell: tuple[int, int]
    next: tuple[int, int] | None = None
    maps: int | None = None
    want: dict[str, tuple[int, ...]] | None = None


class Delta(msgspec.Struct, gc=False):
    """A map delta's fields as heard (:class:`MapDelta`'s): ``cells`` int32 and ``values`` int8, read-only."""

    cells: np.ndarray
    values: np.ndarray
    n: int | None = None
    covers: tuple[int, ...] | None = None


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
    of the team, checked by msgspec (:meth:`PoseBeacon.validate`'s checks but the next cell's distance and the
    requests' order)."""
    cell = tuple[Annotated[int, msgspec.Meta(ge=0, lt=shape[0])], Annotated[int, msgspec.Meta(ge=0, lt=shape[1])]]
    robot = Literal[tuple(sorted(senders))]  # type: ignore[valid-type]
    wire = msgspec.defstruct("BeaconWire", [("cell", cell), ("next", cell | None, None),
                                            ("maps", _Count | None, None),
                                            ("want", dict[robot, _Seqs] | None, None)],  # type: ignore[valid-type]
                             bases=(Beacon,), forbid_unknown_fields=True, gc=False)
    return msgspec.msgpack.Decoder(wire)


def hear(inbox: Sequence[Envelope], ctx: Context) -> list[Heard] | None:
    """The messages of ``inbox`` in order, each checked as :meth:`Envelope.validate` and
    :func:`~fleet_emu.core.envelope.open_envelope` check it; None when one does not pass (or is not in a form
    decoded here and does not open), and the caller opens the inbox message by message instead."""
    senders, shape = ctx.senders, ctx.shape
    if not senders or shape is None:
        return None
    out: list[Any] = []
    poses: list[int] = []  # indices in out of the beacons and deltas to decode
    maps: list[int] = []
    fresh: list[tuple[int, Envelope]] = []
    for env in inbox:
        cached = env.__dict__.get(CACHE)
        if cached is not None:
            seen = cached[0]
            if seen is ctx or (seen.senders is senders and seen.shape == shape):
                out.append(cached[1])
                continue
        src, origin, payload = env.src, env.origin, env.payload
        if not (src in senders and origin in senders and env.tick >= 0 and env.seq >= 0
                and 0 <= env.ttl <= MAX_TTL and len(payload) <= MAX_PAYLOAD_BYTES):
            return None  # Envelope.validate's common case, inlined; anything else goes the long way
        kind = env.payload_kind
        if kind == "pose":
            poses.append(len(out))
        elif kind == "map":
            maps.append(len(out))
        else:
            try:
                msg = open_envelope(env, ctx)
            except DecodeError:
                return None
            out.append((origin, env.tick, msg))
            continue
        fresh.append((len(out), env))
        out.append((origin, env.tick, env))
    if (poses and not _beacons(out, poses, shape, senders)) or (maps and not _deltas(out, maps, shape)):
        return None
    for i, env in fresh:
        env.__dict__[CACHE] = (ctx, out[i])
    return out


def _beacons(out: list[Any], at: list[int], shape: tuple[int, int], senders: frozenset[str]) -> bool:
    """Decode the beacons whose envelopes are at ``at`` in ``out`` in place; False when one does not pass."""
    decode = _beacon_decoder(shape, senders).decode
    try:
        for i in at:
            origin, tick, env = out[i]
            out[i] = (origin, tick, decode(env.payload))
    except msgspec.MsgspecError:
        return False
    multi: list[tuple[int, ...]] = []  # the requests of more than one number, whose order is checked below in one pass
    for i in at:
        b = out[i][2]
        nxt, want = b.next, b.want
        if nxt is not None and abs(nxt[0] - b.cell[0]) + abs(nxt[1] - b.cell[1]) > 1:
            return False
        if want and max(map(len, want.values())) > 1:
            multi.extend(s for s in want.values() if len(s) > 1)
    return not multi or all(map(operator.lt, itertools.chain.from_iterable(s[:-1] for s in multi),
                                itertools.chain.from_iterable(s[1:] for s in multi)))


def _ascending(seqs: tuple[int, ...]) -> bool:
    return len(seqs) < 2 or all(map(operator.lt, seqs, itertools.islice(seqs, 1, None)))


def _deltas(out: list[Any], at: list[int], shape: tuple[int, int]) -> bool:
    """Decode the map deltas whose envelopes are at ``at`` in ``out`` in place, their cells and values checked
    in one compiled pass over all of them; False when one does not pass."""
    decode = _DELTA.decode
    try:
        wires = [decode(out[i][2].payload) for i in at]
    except msgspec.MsgspecError:
        return False
    bounds = [0]
    for w in wires:
        c, v, n, covers = w.cells, w.values, w.n, w.covers
        k = c.shape[0]
        if v.shape[0] != k or len(c.data) != 4 * k or len(v.data) != k:
            return False
        if covers is not None and (n is None or not _ascending(covers) or (covers and covers[-1] >= n)):
            return False
        bounds.append(bounds[-1] + k)
    cells = np.frombuffer(b"".join([w.cells.data for w in wires]), np.int32)
    values = np.frombuffer(b"".join([w.values.data for w in wires]), np.int8)
    if not kernels.cells_valid(cells, values, shape[0] * shape[1]):
        return False
    for i, w, a, b in zip(at, wires, bounds, bounds[1:], strict=False):
        origin, tick, _ = out[i]
        out[i] = (origin, tick, Delta(cells[a:b], values[a:b], w.n, w.covers))
    return True


def as_heard(msgs: Sequence[RadioMsg]) -> list[Heard]:
    """Messages opened one by one (:meth:`Brain.open`'s long way) in :func:`hear`'s form."""
    return [(m.origin, m.tick, m) for m in msgs]

