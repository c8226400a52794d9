"""The radio envelope and the bundles that carry it (docs/reference/protocol.md; split out of
``core/messages.py``, which re-exports every name here).

An :class:`Envelope` carries one radio message: its header (who sent this hop, who made it, for whom, hops
left, the message id) and an opaque payload that only the protocol owning its kind decodes
(:func:`open_envelope`). A robot's :class:`TxBundle` holds what it sends in a tick, netem's :class:`RxBundle`
what reaches a robot; both are packed from each envelope's kept bytes.
"""

from __future__ import annotations

import dataclasses
import zlib
from typing import Annotated, Any, Literal, cast

import msgpack
import msgspec
import numpy as np

from fleet_emu.core.codec import (
    MAX_ARRAY_BYTES,
    Context,
    DecodeError,
    Message,
    Payload,
    decode_payload,
    decode_payload_obj,
    fast_decoder,
    typed_decoder,
)
from fleet_emu.core.codec import _to_obj as to_obj
from fleet_emu.core.codec import _unpack as unpack

# --- radio (inside bundles) --------------------------------------------------------------------------
from fleet_emu.core.limits import MAX_PAYLOAD_BYTES, MAX_TTL
from fleet_emu.core.version import SCHEMA_VERSION

#: Payload kinds that are bulk map data: a bandwidth-limited radio sends them after everything else a robot
#: queued (``netem/medium.py``), and sends them compact (:func:`seal`).
BULK_KINDS = frozenset({"map", "mapfill"})

#: The first byte of a compact payload (a zlib stream's header, 32 KiB window). An encoded payload is a
#: msgpack map, whose first byte is 0x80-0x8f, 0xde or 0xdf, so the two never meet.
_ZLIB_HEAD = 0x78
_DEFLATE_LEVEL = 1


@dataclasses.dataclass(frozen=True)
class Envelope(Message):
    """One radio message as netem and relays see it: who sent this hop (``src``), who made it (``origin``),
    for whom (``dst``: a robot id, ``base`` or ``*`` for everyone), hops left (``ttl``), and an opaque
    ``payload`` of ``payload_kind`` that only the protocol owning that kind decodes. ``(origin, seq)`` is the
    message's id; ``seq`` comes from the origin's one counter."""

    KIND = "radio"
    origin: str
    dst: str
    ttl: int
    payload_kind: str
    payload: bytes

    def encode(self) -> bytes:
        """The envelope's bytes, packed once and kept (an envelope is immutable): netem puts each broadcast
        envelope in every receiver's rx bundle, and counts its size."""
        packed = self.__dict__.get("_packed")
        if packed is None:
            src, tick, seq, origin, dst, ttl = self.src, self.tick, self.seq, self.origin, self.dst, self.ttl
            kind, payload = self.payload_kind, self.payload
            if (type(tick) is int and type(seq) is int and type(ttl) is int and type(src) is str
                    and type(origin) is str and type(dst) is str and type(kind) is str and type(payload) is bytes):
                # to_obj's map, written out: the same keys in the same order, so the same bytes
                packed = msgpack.packb({"kind": self.KIND, "v": SCHEMA_VERSION, "src": src, "tick": tick, "seq": seq,
                                        "origin": origin, "dst": dst, "ttl": ttl, "payload_kind": kind,
                                        "payload": payload}, use_bin_type=True)
            else:  # numpy scalars, or anything odd: the generic conversion
                packed = super().encode()
            object.__setattr__(self, "_packed", packed)
        return packed

    def validate(self, ctx: Context | None) -> None:
        senders = ctx.senders if ctx is not None else None
        if (senders is not None and self.src in senders and self.origin in senders and self.tick >= 0
                and self.seq >= 0 and 0 <= self.ttl <= MAX_TTL and len(self.payload) <= MAX_PAYLOAD_BYTES):
            return  # the common case in one expression: a robot checks every envelope it hears
        super().validate(ctx)
        if not 0 <= self.ttl <= MAX_TTL:
            raise DecodeError("radio: ttl out of range")
        if len(self.payload) > MAX_PAYLOAD_BYTES:
            raise DecodeError("radio: payload too large")
        if ctx is not None and ctx.senders is not None and self.origin not in ctx.senders:
            raise DecodeError(f"radio: unknown origin {self.origin!r}")


_ENVELOPE_KEYS = frozenset({"kind", "v", "src", "tick", "seq", "origin", "dst", "ttl", "payload_kind", "payload"})


@fast_decoder(Envelope)
def _fast_envelope(obj: dict, ctx: Context | None) -> Envelope | None:
    """An envelope straight from its map when every field has exactly its type and it validates
    (:meth:`Envelope.validate`'s checks, inlined); None for anything else, which the generic decode then
    checks (an rx bundle holds every teammate's envelopes)."""
    if obj.keys() != _ENVELOPE_KEYS:
        return None
    src, tick, seq, origin, dst = obj["src"], obj["tick"], obj["seq"], obj["origin"], obj["dst"]
    v, ttl, kind, payload = obj["v"], obj["ttl"], obj["payload_kind"], obj["payload"]
    if not (type(v) is int and v <= SCHEMA_VERSION and type(src) is str and type(tick) is int and tick >= 0
            and type(seq) is int and seq >= 0 and type(origin) is str and type(dst) is str and type(ttl) is int
            and 0 <= ttl <= MAX_TTL and type(kind) is str and type(payload) is bytes
            and len(payload) <= min(MAX_PAYLOAD_BYTES, MAX_ARRAY_BYTES)):
        return None
    senders = ctx.senders if ctx is not None else None
    if senders is not None and (src not in senders or origin not in senders):
        return None
    env = object.__new__(Envelope)
    env.__dict__.update(src=src, tick=tick, seq=seq, origin=origin, dst=dst, ttl=ttl, payload_kind=kind,
                        payload=payload)
    return env


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


_CELL_DTYPES: dict[Any, np.dtype] = {"int32": np.dtype(np.int32), "int64": np.dtype(np.int64)}


def _cells_of(obj: Any) -> tuple[dict[str, Any], np.dtype] | None:
    """A payload map's ``cells`` when they are a packed 1-D array of flat indices (int32 or int64), with its
    dtype: the array :func:`compact` delta-codes."""
    cells = obj.get("cells") if type(obj) is dict else None
    if type(cells) is not dict:
        return None
    dt = _CELL_DTYPES.get(cells.get("dtype"))
    shape, data = cells.get("shape"), cells.get("data")
    if dt is None or type(shape) is not list or len(shape) != 1 or type(data) is not bytes:
        return None
    return (cells, dt) if len(data) == shape[0] * dt.itemsize else None


def compact(payload: bytes) -> bytes:
    """A payload's compact form when it is smaller, else the payload: its ``cells`` delta-coded (each index
    less the one before, wrapping in its own type: sorted cells become runs of small numbers), then deflated
    (zlib, level 1: within 2 % of level 6's size at half its time on map deltas)."""
    obj = msgpack.unpackb(payload, raw=False)
    found = _cells_of(obj)
    if found is not None:
        cells, dt = found
        a = np.frombuffer(cells["data"], dt)
        d = a.copy()
        d[1:] -= a[:-1]
        obj["cells"] = {**cells, "data": d.tobytes()}
    packed = zlib.compress(msgpack.packb(obj, use_bin_type=True), _DEFLATE_LEVEL)
    return packed if len(packed) < len(payload) else payload


def unpack_payload(payload: bytes) -> Any:
    """A payload as :func:`seal` encoded it, compact or not, unpacked from msgpack (the compact form's cells
    restored). DecodeError for one that is not msgpack, or a compact one that is corrupt or would inflate
    beyond :data:`MAX_PAYLOAD_BYTES` (checked while inflating, so a small bomb never grows in memory); what
    it holds is then checked like any payload."""
    if not payload or payload[0] != _ZLIB_HEAD:
        return unpack(payload)
    unzip = zlib.decompressobj()
    try:
        data = unzip.decompress(payload, MAX_PAYLOAD_BYTES)
    except zlib.error as exc:
        raise DecodeError(f"radio: compact payload is corrupt ({exc})") from None
    if unzip.unconsumed_tail:
        raise DecodeError("radio: compact payload inflates beyond the payload limit")
    if not unzip.eof:
        raise DecodeError("radio: compact payload is cut short")
    obj = unpack(data)
    found = _cells_of(obj)
    if found is not None:
        cells, dt = found
        obj["cells"] = {**cells, "data": np.cumsum(np.frombuffer(cells["data"], dt), dtype=dt).tobytes()}
    return obj


def expand(payload: bytes) -> bytes:
    """A payload as :func:`seal` encoded it, compact or not, in its plain msgpack form (see
    :func:`unpack_payload`)."""
    if not payload or payload[0] != _ZLIB_HEAD:
        return payload
    return msgpack.packb(unpack_payload(payload), use_bin_type=True)


def open_envelope(env: Envelope, ctx: Context | None = None) -> RadioMsg:
    """Decode an envelope's payload; raises DecodeError (an unknown kind included).

    The decoded payload is kept on the envelope with the context it was checked against, and given again to
    the next receiver with an equal context: in the memory engine one broadcast envelope object reaches every
    teammate, and decoding it once is enough (a payload is immutable: frozen, its arrays read-only views of
    the message bytes), and so is the message it returns, which the next receiver gets as it is. Over Zenoh every
    receiver decodes its own copy, so nothing changes there."""
    cached = env.__dict__.get("_opened")
    if cached is not None:
        seen = cached[0]
        if seen is ctx or (seen is not None and ctx is not None and seen.senders is ctx.senders
                           and seen.shape == ctx.shape) or seen == ctx:
            return cast(RadioMsg, cached[1])  # the message too is immutable: every receiver gets the same
    payload = env.payload
    if payload and payload[0] != _ZLIB_HEAD:  # plain msgpack: its typed decoder reads the bytes at once
        body = decode_payload(env.payload_kind, payload, ctx)
    else:
        body = decode_payload_obj(env.payload_kind, unpack_payload(payload), ctx)
    msg = object.__new__(RadioMsg)  # RadioMsg(...) without the frozen dataclass's setattr per field
    msg.__dict__.update(body=body, dst=env.dst, ttl=env.ttl, src=env.src, origin=env.origin, tick=env.tick,
                        seq=env.seq)
    object.__setattr__(env, "_opened", (ctx, msg))
    return msg


def _pack_bundle(bundle: TxBundle | RxBundle) -> bytes:
    """A bundle's bytes as ``msgpack.packb(bundle.to_obj())`` gives them, with each envelope's kept bytes
    (:meth:`Envelope.encode`) put in as they are rather than packed again."""
    obj = {"kind": bundle.KIND, "v": SCHEMA_VERSION,
           **{name: to_obj(getattr(bundle, name)) for name in _BUNDLE_HEAD[type(bundle)]}}
    head = msgpack.packb(obj, use_bin_type=True)
    n = len(obj) + 1  # a map header of 0x80 + n (n < 16 here), then the fields; msgs is the last field
    assert head[0] == 0x80 + n - 1 and n < 16
    body = msgpack.packb("msgs") + _array_header(len(bundle.msgs)) + b"".join(e.encode() for e in bundle.msgs)
    return bytes([0x80 + n]) + head[1:] + body


def _bundle_head(cls: type) -> tuple[str, ...]:
    """A bundle class's fields before ``msgs``, its last."""
    names = tuple(f.name for f in dataclasses.fields(cls))
    assert names[-1] == "msgs"
    return names[:-1]


def _array_header(n: int) -> bytes:
    """msgpack's header of an array of ``n`` items."""
    if n < 16:
        return bytes([0x90 + n])
    if n < 1 << 16:
        return b"\xdc" + n.to_bytes(2, "big")
    return b"\xdd" + n.to_bytes(4, "big")


@dataclasses.dataclass(frozen=True)
class TxBundle(Message):
    """Everything one robot sends at ``tick`` (radio/tx/<robot>); sent even when empty."""

    KIND = "tx"
    msgs: tuple[Envelope, ...]

    def encode(self) -> bytes:
        return _pack_bundle(self)

    def validate(self, ctx: Context | None) -> None:
        super().validate(ctx)
        if any(m.src != self.src for m in self.msgs):
            raise DecodeError("tx: a message's src differs from the bundle's")


@dataclasses.dataclass(frozen=True)
class RxBundle(Message):
    """What netem delivers to robot ``dst`` at ``tick`` (radio/rx/<robot>); sent even when empty."""

    KIND = "rx"
    dst: str
    msgs: tuple[Envelope, ...]

    def encode(self) -> bytes:
        return _pack_bundle(self)


_BUNDLE_HEAD = {cls: _bundle_head(cls) for cls in (TxBundle, RxBundle)}


_BUNDLE_KEYS = {TxBundle: frozenset({"kind", "v", "src", "tick", "seq", "msgs"}),
                RxBundle: frozenset({"kind", "v", "src", "tick", "seq", "dst", "msgs"})}


def _fast_bundle(cls: type[TxBundle] | type[RxBundle], obj: dict, ctx: Context | None) -> TxBundle | RxBundle | None:
    """A bundle straight from its map when its header has exactly its types and every envelope is one the fast
    envelope decoder takes; None for anything else (the generic decode then checks it). A robot decodes its rx
    bundle every tick and netem every robot's tx bundle: the generic decode's field walk per envelope was a
    good part of a robot's shell CPU."""
    if obj.keys() != _BUNDLE_KEYS[cls]:
        return None
    v, src, tick, seq, msgs = obj["v"], obj["src"], obj["tick"], obj["seq"], obj["msgs"]
    if not (type(v) is int and v <= SCHEMA_VERSION and type(src) is str and type(tick) is int and tick >= 0
            and type(seq) is int and seq >= 0 and type(msgs) is list):
        return None
    senders = ctx.senders if ctx is not None else None
    if senders is not None and src not in senders:
        return None
    envelopes = []
    for m in msgs:
        if type(m) is not dict or m.get("kind") != Envelope.KIND:
            return None
        env = _fast_envelope(m, ctx)
        if env is None or (cls is TxBundle and env.src != src):
            return None
        envelopes.append(env)
    bundle = object.__new__(cls)
    bundle.__dict__.update(src=src, tick=tick, seq=seq, msgs=tuple(envelopes))
    if cls is RxBundle:
        dst = obj["dst"]
        if type(dst) is not str:
            return None
        bundle.__dict__["dst"] = dst
    return bundle


fast_decoder(TxBundle)(lambda obj, ctx: _fast_bundle(TxBundle, obj, ctx))
fast_decoder(RxBundle)(lambda obj, ctx: _fast_bundle(RxBundle, obj, ctx))


# --- typed decoders (core.codec.typed_decoder): a bundle's bytes straight into structs, in one pass in C -------

_NonNeg = Annotated[int, msgspec.Meta(ge=0)]
_Version = Annotated[int, msgspec.Meta(le=SCHEMA_VERSION)]


class WireEnvelope(msgspec.Struct, forbid_unknown_fields=True, gc=False, kw_only=True):
    """An envelope's map as the wire has it, each field's type and range checked by msgspec (``kind`` a field,
    not msgspec's tag, which a lone struct does not require). A robot hears its rx bundle's envelopes as these
    (:func:`read_rx`), with :class:`Envelope`'s fields, and builds an :class:`Envelope` (:meth:`envelope`)
    only for one it opens message by message or relays."""

    kind: Literal["radio"]
    v: _Version = 1
    src: str
    tick: _NonNeg
    seq: _NonNeg
    origin: str
    dst: str
    ttl: Annotated[int, msgspec.Meta(ge=0, le=MAX_TTL)]
    payload_kind: str
    payload: Annotated[bytes, msgspec.Meta(max_length=min(MAX_PAYLOAD_BYTES, MAX_ARRAY_BYTES))]

    def envelope(self) -> Envelope:
        """The :class:`Envelope` of these fields."""
        env = object.__new__(Envelope)
        d = env.__dict__  # its fields set one by one: a third faster than update() with keywords, per envelope
        d["src"], d["tick"], d["seq"], d["origin"] = self.src, self.tick, self.seq, self.origin
        d["dst"], d["ttl"], d["payload_kind"], d["payload"] = self.dst, self.ttl, self.payload_kind, self.payload
        return env


class _TxWire(msgspec.Struct, forbid_unknown_fields=True, gc=False, kw_only=True):
    kind: Literal["tx"]
    v: _Version = 1
    src: str
    tick: _NonNeg
    seq: _NonNeg
    msgs: list[WireEnvelope]


class RxWire(msgspec.Struct, forbid_unknown_fields=True, gc=False, kw_only=True):
    """An rx bundle's map as the wire has it (:class:`RxBundle`'s fields, its envelopes as read)."""

    kind: Literal["rx"]
    v: _Version = 1
    src: str
    tick: _NonNeg
    seq: _NonNeg
    dst: str
    msgs: list[WireEnvelope]


_TX_DECODER = msgspec.msgpack.Decoder(_TxWire)
_RX_DECODER = msgspec.msgpack.Decoder(RxWire)


def _envelopes(wire: _TxWire | RxWire, ctx: Context | None, same_src: bool) -> tuple[Envelope, ...] | None:
    """A decoded bundle's envelopes as :class:`Envelope` records, when every sender and origin is one of the
    context's (and, with ``same_src``, every envelope's ``src`` the bundle's); None otherwise."""
    senders = ctx.senders if ctx is not None else None
    if senders is not None and wire.src not in senders:
        return None
    src = wire.src
    for w in wire.msgs:
        if (senders is not None and (w.src not in senders or w.origin not in senders)) or (same_src and w.src != src):
            return None
    return tuple([w.envelope() for w in wire.msgs])


#: What a robot hears: envelopes as built (the memory engine, relays) or as read from an rx bundle.
AnyEnvelope = Envelope | WireEnvelope


def as_envelope(env: AnyEnvelope) -> Envelope:
    """``env`` as an :class:`Envelope` (built from a :class:`WireEnvelope`)."""
    return env.envelope() if isinstance(env, WireEnvelope) else env


def read_rx(data: bytes) -> RxWire | None:
    """An rx bundle's bytes read as :class:`RxWire` (its envelopes :class:`WireEnvelope`, not built into
    :class:`Envelope`): what :func:`~fleet_emu.core.codec.decode` accepts of them without its context, the
    same fields; None for bytes in another form, which ``decode`` then decides on."""
    try:
        return _RX_DECODER.decode(data)
    except Exception:  # msgspec's errors, a string not UTF-8: the checking decode says why
        return None


@typed_decoder(TxBundle)
def _typed_tx(data: bytes, ctx: Context | None) -> TxBundle | None:
    wire = _TX_DECODER.decode(data)
    msgs = _envelopes(wire, ctx, True)
    if msgs is None:
        return None
    bundle = object.__new__(TxBundle)
    bundle.__dict__.update(src=wire.src, tick=wire.tick, seq=wire.seq, msgs=msgs)
    return bundle


@typed_decoder(RxBundle)
def _typed_rx(data: bytes, ctx: Context | None) -> RxBundle | None:
    wire = read_rx(data)
    msgs = _envelopes(wire, ctx, False) if wire is not None else None
    if wire is None or msgs is None:
        return None
    bundle = object.__new__(RxBundle)
    bundle.__dict__.update(src=wire.src, tick=wire.tick, seq=wire.seq, dst=wire.dst, msgs=msgs)
    return bundle
