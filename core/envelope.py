"""The radio envelope, which carries one message's header and its opaque payload (:func:`open_envelope`), and
the bundles of envelopes a robot sends (:class:`TxBundle`) and netem delivers (:class:`RxBundle`) in a tick
(docs/reference/protocol.md; ``core/messages.py`` re-exports every name here)."""

from __future__ import annotations

import dataclasses
import zlib
from typing import TYPE_CHECKING, Annotated, Any, cast

import msgpack
import msgspec
import numpy as np

from fleet_emu.core.codec import Context, DecodeError, Message, NoMessage, Payload, decode_payload, unpack_array
from fleet_emu.core.limits import MAX_PAYLOAD_BYTES, MAX_TTL

#: Payload kinds that are bulk map data: a bandwidth-limited radio sends them after everything else a robot
#: queued (``netem/medium.py``), and sends them compact (:func:`seal`).
BULK_KINDS = frozenset({"map", "mapfill"})

#: The first byte of a compact payload (a zlib stream's header, 32 KiB window). An encoded payload is a
#: msgpack map, whose first byte is 0x80-0x8f, 0xde or 0xdf, so the two never meet.
_ZLIB_HEAD = 0x78
_DEFLATE_LEVEL = 1


class Envelope(Message, kw_only=True, frozen=True, dict=True):
    """One radio message as netem and relays see it: who sent this hop (``src``), who made it (``origin``),
    for whom (``dst``: a robot id, ``base`` or ``*`` for everyone), hops left (``ttl``), and an opaque
    ``payload`` of ``payload_kind`` that only the protocol owning that kind decodes. ``(origin, seq)`` is the
    message's id; ``seq`` comes from the origin's one counter. What a receiver decodes of its payload is kept
    with it (:func:`open_envelope`)."""

    KIND = "radio"
    origin: str
    dst: str
    ttl: Annotated[int, msgspec.Meta(ge=0, le=MAX_TTL)]
    payload_kind: str
    payload: Annotated[bytes, msgspec.Meta(max_length=MAX_PAYLOAD_BYTES)]

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if ctx is not None and ctx.senders is not None and self.origin not in ctx.senders:
            raise DecodeError(f"radio: unknown origin {self.origin!r}")


@dataclasses.dataclass(frozen=True)
class RadioMsg:
    """A radio message as a robot's protocols see it: a decoded :class:`~fleet_emu.core.codec.Payload` and its
    envelope's header. A protocol that sends gives ``body`` and ``dst`` (and ``ttl``); the sender's brain
    fills in the rest when it seals the envelope."""

    body: Payload
    dst: str = "*"
    ttl: int = 0
    src: str = ""
    origin: str = ""
    tick: int = 0
    seq: int = 0

    @property
    def kind(self) -> str:
        return self.body.KIND


def seal(msg: RadioMsg, src: str, tick: int, seq: int, deflate: bool = False) -> Envelope:
    """The envelope of a message ``src`` makes at ``tick``. With ``deflate`` (a bandwidth-limited radio),
    bulk map data (:data:`BULK_KINDS`) goes in its :func:`compact` form: the same payload in fewer bytes of
    airtime (docs/guides/radio.md, "Bandwidth, queues and delay")."""
    payload = msg.body.encode()
    if deflate and msg.kind in BULK_KINDS:
        payload = compact(payload)
    return Envelope(src=src, tick=tick, seq=seq, origin=src, dst=msg.dst, ttl=msg.ttl, payload_kind=msg.kind,
                    payload=payload)


def _cells_of(obj: Any) -> np.ndarray | None:
    """A payload map's ``cells`` when they are a packed 1-D array of flat indices (int32 or int64): the array
    :func:`compact` delta-codes."""
    try:
        cells = unpack_array(obj.get("cells") if type(obj) is dict else None)
    except ValueError:
        return None
    return cells if cells.ndim == 1 and cells.dtype in (np.int32, np.int64) else None


def compact(payload: bytes) -> bytes:
    """A payload's compact form when it is smaller, else the payload: its ``cells`` delta-coded (each index
    less the one before, wrapping in its own type: sorted cells become runs of small numbers), then deflated
    (zlib, level 1: within 2 % of level 6's size at half its time on map deltas)."""
    obj = msgpack.unpackb(payload, raw=False)
    cells = _cells_of(obj)
    if cells is not None:
        steps = cells.copy()
        steps[1:] -= cells[:-1]
        obj["cells"] = {**obj["cells"], "data": steps.tobytes()}
    packed = zlib.compress(msgpack.packb(obj, use_bin_type=True), _DEFLATE_LEVEL)
    return packed if len(packed) < len(payload) else payload


def expand(payload: bytes) -> bytes:
    """A payload as :func:`seal` encoded it, compact or not, in its plain msgpack form (the compact form's cells
    restored). DecodeError for a compact one that is corrupt or would inflate beyond :data:`MAX_PAYLOAD_BYTES`
    (checked while inflating, so a small bomb never grows in memory); what it holds is then checked like any
    payload."""
    if not payload or payload[0] != _ZLIB_HEAD:
        return payload
    unzip = zlib.decompressobj()
    try:
        data = unzip.decompress(payload, MAX_PAYLOAD_BYTES)
    except zlib.error as exc:
        raise DecodeError(f"radio: compact payload is corrupt ({exc})") from None
    if unzip.unconsumed_tail or not unzip.eof:
        raise DecodeError("radio: compact payload inflates beyond the payload limit or is cut short")
    try:
        obj = msgpack.unpackb(data, raw=False, strict_map_key=True)
    except Exception as exc:  # msgpack raises several unrelated types on garbage
        raise DecodeError(f"radio: compact payload is not msgpack ({type(exc).__name__})") from None
    cells = _cells_of(obj)
    if cells is not None:
        obj["cells"] = {**obj["cells"], "data": np.cumsum(cells, dtype=cells.dtype).tobytes()}
    return msgpack.packb(obj, use_bin_type=True)


def open_envelope(env: Envelope, ctx: Context | None = None) -> RadioMsg:
    """Decode an envelope's payload; raises DecodeError (an unknown kind included). The message is kept on the
    envelope with the context it was checked against (:func:`keep_opened`), and given as it is (immutable) to
    the next receiver with an equal context: in the memory engine one broadcast envelope object reaches every
    teammate."""
    msg = opened(env, ctx)
    return msg if msg is not None else keep_opened(env, ctx, decode_payload(env.payload_kind, expand(env.payload),
                                                                             ctx))


def opened(env: Envelope, ctx: Context | None) -> RadioMsg | None:
    """The message kept on ``env`` for a context of the same team and grid as ``ctx``, or None."""
    cached = env.__dict__.get("_opened")
    if cached is None:
        return None
    seen = cached[0]
    same = seen is ctx or (seen is not None and ctx is not None and seen.senders is ctx.senders
                           and seen.shape == ctx.shape) or seen == ctx
    return cast(RadioMsg, cached[1]) if same else None


def keep_opened(env: Envelope, ctx: Context | None, body: Payload) -> RadioMsg:
    """``env``'s message with its decoded ``body``, kept on it for the next receiver with a context like ``ctx``."""
    msg = object.__new__(RadioMsg)  # RadioMsg(...) without the frozen dataclass's setattr per field
    msg.__dict__.update(body=body, dst=env.dst, ttl=env.ttl, src=env.src, origin=env.origin, tick=env.tick,
                        seq=env.seq)
    env.__dict__["_opened"] = (ctx, msg)
    return msg


if TYPE_CHECKING:
    Envelopes = tuple[Envelope, ...]
else:  # every envelope with its kind: msgspec requires it of a union's members
    Envelopes = tuple[Envelope | NoMessage, ...]


class TxBundle(Message, kw_only=True, frozen=True):
    """Everything one robot sends at ``tick`` (radio/tx/<robot>); sent even when empty."""

    KIND = "tx"
    msgs: Envelopes

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if any(m.src != self.src for m in self.msgs):
            raise DecodeError("tx: a message's src differs from the bundle's")
        _check_origins(self.msgs, ctx)


class RxBundle(Message, kw_only=True, frozen=True):
    """What netem delivers to robot ``dst`` at ``tick`` (radio/rx/<robot>); sent even when empty."""

    KIND = "rx"
    dst: str
    msgs: Envelopes

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        _check_origins(self.msgs, ctx)


def _check_origins(msgs: tuple[Envelope, ...], ctx: Context | None) -> None:
    """Every envelope of a bundle from and made by one of the context's senders (its numbers are checked as
    declared, when decoded)."""
    senders = ctx.senders if ctx is not None else None
    if senders is not None:
        for m in msgs:
            if m.src not in senders or m.origin not in senders:
                m.validate(ctx)  # raises, saying which
