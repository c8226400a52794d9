"""What a robot hears in a tick, decoded at once: its teammates' pose beacons, map deltas and fills read straight
from their payloads into light structs, checked against the team and the grid, with no record built per message.

At 100 robots a robot hears about 60 beacons and 60 map deltas a tick; decoding each into a
:class:`~fleet_emu.agents.protocol.PoseBeacon` or :class:`~fleet_emu.agents.protocol.MapDelta` and a
:class:`~fleet_emu.core.messages.RadioMsg` cost several microseconds of Python per message, most of the brain's
CPU outside the allocator. Here the beacons, map deltas and fills of an inbox are read from their bytes and
checked in one compiled pass (:mod:`~fleet_emu.agents.hearing_kernels`), which also picks out the requests
(``want``) addressed to the robot (:attr:`Hearing.asks`), and the brain reads the structs (:meth:`Brain.open`).

This decides nothing: :func:`hear` accepts only what the message decoders accept (``agents/protocol.py``; the
tests compare them on mutated payloads), gives their values, and returns None for an inbox holding anything
else (a header or payload that does not validate, a kind it does not batch that fails to open, an unusual
but valid encoding): the brain then opens the inbox message by message as before, which drops and counts
what does not validate, in the order it came.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple, cast

import msgspec
import numpy as np

from fleet_emu.agents.hearing_kernels import read, team
from fleet_emu.agents.protocol import MAX_SEQS, PoseBeacon
from fleet_emu.core.codec import MAX_ARRAY_BYTES, Context
from fleet_emu.core.envelope import MAX_PAYLOAD_BYTES, MAX_TTL, AnyEnvelope, WireEnvelope, as_envelope
from fleet_emu.core.errors import DecodeError
from fleet_emu.core.messages import Envelope, RadioMsg, open_envelope

#: The envelope attribute under which a message heard is kept with its context (and a beacon's request map's
#: bytes, which each receiver reads for itself): the memory engine hands one broadcast envelope object to every
#: receiver, and the next receiver of the same team and grid reads it as it is (as
#: :func:`~fleet_emu.core.envelope.open_envelope` keeps its opened message).
CACHE = "_heard"

#: One message heard: its origin, its envelope's tick, and its body (a :class:`Beacon`, a :class:`Delta`, a
#: :class:`Fill`, or a :class:`RadioMsg` for every other kind).
Heard = tuple[str, int, Any]


class Hearing(NamedTuple):
    """What a robot heard in a tick: the messages in the order they came, and the delta numbers some of them
    ask this robot for again (a beacon's :attr:`~fleet_emu.agents.protocol.PoseBeacon.want` addressed to it),
    by their place in ``messages``."""

    messages: list[Heard]
    asks: dict[int, tuple[int, ...]]


class Beacon(msgspec.Struct, gc=False):
    """A pose beacon's fields as heard (:class:`~fleet_emu.agents.protocol.PoseBeacon`'s names and meanings) but
    its requests (``want``): a robot reads only those addressed to it (:attr:`Hearing.asks`)."""

    cell: tuple[int, int]
    next: tuple[int, int] | None = None
    maps: int | None = None


class _Part(msgspec.Struct, gc=False):
    """Cells and values heard, ``start:end`` of ``all_cells`` (int32) and ``all_values`` (int8): every delta and
    fill of the inbox's in turn, read only (the brain merges a run of them at once, without a copy of each)."""

    all_cells: np.ndarray
    all_values: np.ndarray
    start: int
    end: int

    @property
    def cells(self) -> np.ndarray:
        return self.all_cells[self.start:self.end]

    @property
    def values(self) -> np.ndarray:
        return self.all_values[self.start:self.end]


class Delta(_Part, gc=False):
    """A map delta's fields as heard (:class:`~fleet_emu.agents.protocol.MapDelta`'s), its cells and values a
    :class:`_Part`."""

    n: int | None = None
    covers: tuple[int, ...] | None = None


class Fill(_Part, gc=False):
    """A map fill's fields as heard (:class:`~fleet_emu.agents.protocol.MapFill`'s), its cells and values a
    :class:`_Part`."""

    seqs: tuple[int, ...] = ()
    upto: int = 0


def hear(inbox: Sequence[AnyEnvelope], ctx: Context, robot: str, keep: bool = False) -> Hearing | None:
    """What ``robot`` hears of ``inbox``: its messages in order, each checked as :meth:`Envelope.validate` and
    :func:`~fleet_emu.core.envelope.open_envelope` check it; None when one does not pass (or is not in a form
    decoded here and does not open), and the caller opens the inbox message by message instead. With
    ``keep`` (the memory engine, whose receivers of a broadcast share its envelope object), each message
    decoded is kept on its envelope for the next receiver of the same team and grid, and one kept is used
    (an envelope as read from an rx bundle, a :class:`~fleet_emu.core.envelope.WireEnvelope`, keeps nothing)."""
    senders, shape = ctx.senders, ctx.shape
    if not senders or shape is None:
        return None
    out: list[Any] = []
    maps: list[bytes] = []  # the map deltas' and fills' payloads, read at the end
    fills: list[bool] = []
    map_places: list[int] = []  # their places in out
    beacons: list[bytes] = []  # the beacons' payloads, read with them
    beacon_places: list[int] = []
    wants: list[bytes] = []  # the requests of beacons kept on a shared envelope, read for this robot
    want_places: list[int] = []
    fresh: list[tuple[int, AnyEnvelope]] = []
    add, max_ttl, max_bytes = out.append, MAX_TTL, MAX_PAYLOAD_BYTES
    for env in inbox:
        if keep:
            cached = _kept(env, ctx)
            if cached is not None:
                heard, want = cached
                if want:
                    want_places.append(len(out))
                    wants.append(want)
                add(heard)
                continue
            fresh.append((len(out), env))
        origin, tick, payload, kind = env.origin, env.tick, env.payload, env.payload_kind
        if not (env.src in senders and origin in senders and (type(env) is WireEnvelope or (
                tick >= 0 and env.seq >= 0 and 0 <= env.ttl <= max_ttl and len(payload) <= max_bytes))):
            return None  # Envelope.validate's common case (a wire's numbers checked when read), inlined
        if kind == "pose":
            beacon_places.append(len(out))
            beacons.append(payload)
        elif kind == "map" or kind == "mapfill":
            map_places.append(len(out))
            maps.append(payload)
            fills.append(kind == "mapfill")
        else:
            try:
                add((origin, tick, open_envelope(as_envelope(env), ctx)))
            except (msgspec.MsgspecError, DecodeError, UnicodeDecodeError):  # msgspec: a string not UTF-8
                return None
            continue
        add((origin, tick, None))
    asks: dict[int, tuple[int, ...]] = {}
    requests: dict[int, bytes] = {}
    if maps or beacons or wants:
        got = _read_into(out, asks, (map_places, maps, fills), (beacon_places, beacons), (want_places, wants),
                         ctx, robot, keep)
        if got is None:
            return None
        requests = got
    for i, env in fresh:
        if type(env) is Envelope:
            env.__dict__[CACHE] = (ctx, out[i], requests.get(i))
    return Hearing(out, asks)


def _kept(env: AnyEnvelope, ctx: Context) -> tuple[Heard, bytes | None] | None:
    """What :func:`hear` kept on ``env`` for a context of the same team and grid as ``ctx``, with a beacon's
    request map's bytes (read again for each robot), or None."""
    cached = env.__dict__.get(CACHE) if type(env) is Envelope else None
    if cached is not None:
        seen = cached[0]
        if seen is ctx or (seen.senders is ctx.senders and seen.shape == ctx.shape):
            return cast(Heard, cached[1]), cached[2]
    return None


def _read_into(out: list[Any], asks: dict[int, tuple[int, ...]],
               maps: tuple[list[int], list[bytes], list[bool]], beacons: tuple[list[int], list[bytes]],
               wants: tuple[list[int], list[bytes]], ctx: Context, robot: str, own: bool
               ) -> dict[int, bytes] | None:
    """The map deltas and fills (their places in ``out``, payloads, whether each is a fill), the beacons
    (places, payloads) and the lone requests of beacons kept on a shared envelope (places, bytes) read and
    checked in one compiled pass (:func:`~fleet_emu.agents.hearing_kernels.read`): each delta, fill or beacon
    becomes its :class:`Delta`, :class:`Fill` or :class:`Beacon` in ``out`` (the cells and values of all in two
    arrays, each message a slice read by the brain's merge without a copy, or with ``own`` arrays of its own:
    its receivers' runs of messages are not this inbox's); what a request asks ``robot`` for goes in ``asks``.
    With ``own``, the beacons' request maps' bytes by place (for the next receiver); None when one does not
    pass or is not in the robots' own encoding."""
    (map_places, payloads, fills), (beacon_places, poses), (want_places, requests) = maps, beacons, wants
    assert ctx.senders is not None and ctx.shape is not None
    got = read(payloads, fills, poses, requests, ctx.shape, team(ctx.senders), robot, MAX_ARRAY_BYTES, MAX_SEQS)
    if got is None:
        return None
    cells, values, seqs = got.cells, got.values, got.seqs
    a = 0
    for i, fill, (end, n, s0, s1) in zip(map_places, fills, got.maps, strict=True):
        all_cells, all_values, start, stop = (cells[a:end], values[a:end], 0, end - a) if own \
            else (cells, values, a, end)
        origin, tick, _ = out[i]
        if fill:
            out[i] = (origin, tick, Fill(all_cells, all_values, start, stop, tuple(seqs[s0:s1]), n))
        else:
            out[i] = (origin, tick, Delta(all_cells, all_values, start, stop, n or None,
                                          tuple(seqs[s0:s1]) if s0 >= 0 else None))
        a = end
    for i, (r, c, nr, nc, count, _) in zip(beacon_places, got.poses, strict=True):
        origin, tick, _ = out[i]
        out[i] = (origin, tick, Beacon((r, c), (nr, nc) if nr >= 0 else None, count if count >= 0 else None))
    places = beacon_places + want_places
    for j, s0, s1 in got.asked:
        asks[places[j]] = tuple(seqs[s0:s1])
    if not own:
        return {}
    return {i: payload[w:] for i, payload, (*_, w) in zip(beacon_places, poses, got.poses, strict=True) if w >= 0}


def as_heard(msgs: Sequence[RadioMsg], robot: str) -> Hearing:
    """Messages opened one by one (:meth:`Brain.open`'s long way) in :func:`hear`'s form, as ``robot`` hears
    them."""
    asks = {i: m.body.want[robot] for i, m in enumerate(msgs)
            if isinstance(m.body, PoseBeacon) and m.body.want and robot in m.body.want}
    return Hearing([(m.origin, m.tick, m) for m in msgs], asks)

