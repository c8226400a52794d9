"""Every message declared once, as a frozen :class:`msgspec.Struct`, and its codec derived from the declaration.

A :class:`Message` (on the bus: ``kind``, ``v`` the schema version, ``src``, ``tick``, ``seq``, then its own fields)
or a :class:`Payload` (inside a radio envelope: its fields only) is encoded by msgspec as a msgpack map of its
fields in their order, and decoded and type-checked in one pass in C, unknown keys refused, ranges as declared on
the fields; :meth:`Record.validate` adds what needs several fields or the receiver's :class:`Context`. Arrays
travel packed (dtype, shape, bytes) and decode as read-only views. Each class is declared ``kw_only=True`` (its
fields after its base's); ``omit_defaults=True`` leaves fields at their defaults out of its bytes. Decoding only
ever raises :class:`DecodeError` (``docs/reference/protocol.md``).
"""
from __future__ import annotations

import dataclasses
import functools
import itertools
import math
from typing import Annotated, Any, ClassVar, TypeVar, Union, cast

import msgpack
import msgspec
import numpy as np

from fleet_emu.core.errors import DecodeError
from fleet_emu.core.version import SCHEMA_VERSION

ALLOWED_DTYPES = frozenset({"int8", "uint8", "int16", "int32", "int64", "float32", "float64", "bool"})
MAX_ARRAY_BYTES = 64 * 1024 * 1024
M = TypeVar("M", bound="Message")
R = TypeVar("R", bound="Record")

#: Each message class's kind by class name: msgspec's tag for it (the ``kind`` key of its map).
_TAGS: dict[str, str] = {}


class _RecordMeta(msgspec.StructMeta):
    def __setattr__(cls, name: str, value: Any) -> None:
        if name == "__dataclass_params__":  # the first thing @dataclasses.dataclass sets
            raise TypeError(f"{cls.__name__} is declared `class {cls.__name__}({cls.__mro__[1].__name__}, kw_only=True,"
                            " frozen=True)`, not with @dataclasses.dataclass (docs/writing-an-allocator.md)")
        super().__setattr__(name, value)


class Record(msgspec.Struct, frozen=True, kw_only=True, forbid_unknown_fields=True, metaclass=_RecordMeta):
    """A typed, frozen record that encodes to a msgpack map. Each family root (:class:`Message`,
    :class:`Payload`) keeps its own registry by ``KIND``; a subclass with a ``KIND`` registers in its family's."""

    KIND: ClassVar[str] = ""
    REGISTRY: ClassVar[dict[str, type[Record]]] = {}

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        kind = cls.__dict__.get("KIND")
        if "REGISTRY" in cls.__dict__ or not kind:
            return
        if kind in cls.REGISTRY:  # the nearest family root's
            raise TypeError(f"{cls.__mro__[1].__name__} kind {kind!r} defined twice")
        cls.REGISTRY[kind] = cls
        _TAGS[cls.__name__] = kind

    def validate(self, ctx: Context | None) -> None:
        """Check what the field types cannot (several fields, the receiver's context); raise DecodeError. A class
        that defines :meth:`validate_many` instead is checked by it, as a batch of one."""
        cls = type(self)
        if cls.validate_many.__func__ is not Record.validate_many.__func__:  # type: ignore[attr-defined]
            cls.validate_many([self], ctx, {name: getattr(self, name) for name in _array_fields(cls)})

    @classmethod
    def validate_many(cls, records: list[Any], ctx: Context | None, arrays: dict[str, np.ndarray]) -> None:
        """:meth:`validate` of each of ``records`` (:func:`decode_many`'s), whose array fields are slices of
        ``arrays``, each field's arrays one after the other: a class may check those at once instead."""
        for r in records:
            r.validate(ctx)

    def to_obj(self) -> dict[str, Any]:
        """The record as msgpack-ready builtins (its arrays packed), as :meth:`encode` writes it."""
        return cast(dict[str, Any], msgspec.to_builtins(self, enc_hook=_enc_hook, builtin_types=(bytes,)))

    def fields_obj(self) -> dict[str, Any]:
        """:meth:`to_obj` without a message's ``kind`` and ``v``: its own fields."""
        return {key: value for key, value in self.to_obj().items() if key not in ("kind", "v")}

    def encode(self) -> bytes:
        return _ENCODER.encode(self)


def _tag(name: str) -> str:
    """A message class's kind, msgspec's tag (an abstract class's is one no map carries)."""
    return _TAGS.get(name, f"\0{name}")


class Message(Record, tag_field="kind", tag=_tag, kw_only=True, frozen=True):
    """A message on the bus: ``kind``, ``v`` (the schema version it was written with), ``src``, ``tick``,
    ``seq`` (one counter per sender)."""

    REGISTRY: ClassVar[dict[str, type[Record]]] = {}

    v: Annotated[int, msgspec.Meta(le=SCHEMA_VERSION)] = SCHEMA_VERSION
    src: str
    tick: Annotated[int, msgspec.Meta(ge=0)]
    seq: Annotated[int, msgspec.Meta(ge=0)]

    def validate(self, ctx: Context | None) -> None:
        if ctx is not None and ctx.senders is not None and self.src not in ctx.senders:
            raise DecodeError(f"unknown sender {self.src!r}")


class Payload(Record, kw_only=True, frozen=True, gc=False):
    """The body of a radio message: opaque bytes to netem and relays, decoded only by the robot protocol that
    owns its ``KIND``. Encoded without its kind, which travels in the envelope."""

    REGISTRY: ClassVar[dict[str, type[Record]]] = {}


@dataclasses.dataclass(frozen=True)
class Context:
    """What a receiver knows to validate against: allowed senders and the grid shape."""

    senders: frozenset[str] | None = None
    shape: tuple[int, int] | None = None


# --- arrays ----------------------------------------------------------------------------------------------

_DTYPES = {name: np.dtype(name) for name in ALLOWED_DTYPES}
_DTYPE_NAMES = {dt: name for name, dt in _DTYPES.items()}  # dtype.name is a slow property
_PACKED = frozenset({"dtype", "shape", "data"})


def _enc_hook(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        arr = np.ascontiguousarray(value)
        return {"dtype": _DTYPE_NAMES.get(arr.dtype) or arr.dtype.name, "shape": list(arr.shape),
                "data": arr.tobytes()}
    if isinstance(value, np.generic):
        return value.item()
    for base in (float, int, str):  # a subclass of one (a marked default), as msgpack packs it
        if isinstance(value, base):
            return base(value)
    raise NotImplementedError(f"cannot encode {type(value).__name__}")


def unpack_array(value: Any) -> np.ndarray:
    """A packed array (a map of ``dtype``, ``shape`` and ``data``) as a read-only view of its bytes; ValueError
    when it is not one (a shape of at most 3 sizes, as many bytes as it says)."""
    if type(value) is not dict or value.keys() != _PACKED:
        raise ValueError("expected a packed array")
    dtype, shape, data = value["dtype"], value["shape"], value["data"]
    dt = _DTYPES.get(dtype) if type(dtype) is str else None
    if dt is None or type(data) is not bytes or type(shape) is not list or len(shape) > 3:
        raise ValueError("bad packed array")
    if not all(type(s) is int and s >= 0 for s in shape):  # Python ints: no overflow for any shape
        raise ValueError("bad array shape")
    if math.prod(shape) * dt.itemsize != len(data) or len(data) > MAX_ARRAY_BYTES:
        raise ValueError("array data does not match its shape")
    arr = np.frombuffer(data, dtype=dt)
    return arr if len(shape) == 1 else arr.reshape(shape)


def _dec_hook(kind: type, value: Any) -> Any:
    if kind is np.ndarray:
        return unpack_array(value)
    raise NotImplementedError(f"cannot decode {kind!r}")


_ENCODER = msgspec.msgpack.Encoder(enc_hook=_enc_hook)


# --- decoding ----------------------------------------------------------------------------------------------

class NoMessage(Message, kw_only=True, frozen=True):
    """No message: a union with it makes msgspec require a message's ``kind`` even when one kind is expected
    (a field of messages of one kind is declared so: ``tuple[Envelope | NoMessage, ...]``)."""


@functools.cache
def decoder(cls: type[Record]) -> msgspec.msgpack.Decoder[Any]:
    """The msgspec decoder of ``cls`` (a message's requires its ``kind``); TypeError for a class whose fields
    do not follow its base's (declared without ``kw_only=True``)."""
    for base in cls.__mro__[1:]:
        names = base.__struct_fields__ if issubclass(base, Record) else ()
        if cls.__struct_fields__[:len(names)] != names:
            raise TypeError(f"{cls.__name__} must be declared with kw_only=True: its fields would precede its base's")
    return msgspec.msgpack.Decoder(cls | NoMessage if issubclass(cls, Message) else cls, dec_hook=_dec_hook)


@functools.cache
def _any_message(kinds: frozenset[str]) -> msgspec.msgpack.Decoder[Any]:
    for cls in Message.REGISTRY.values():
        decoder(cls)  # the layout check
    return msgspec.msgpack.Decoder(Union[tuple(Message.REGISTRY.values())], dec_hook=_dec_hook)  # noqa: UP007


def _checked(record: R, ctx: Context | None, what: str) -> R:
    try:
        record.validate(ctx)
    except DecodeError:
        raise
    except Exception as exc:  # a validator tripped on odd but well-typed data
        raise DecodeError(f"{what}: invalid message: {exc}") from None
    return record


def _error(what: str, exc: Exception) -> DecodeError:
    if str(exc).endswith(".v`"):  # the schema version, above this fleet_emu's
        return DecodeError(f"{what}: schema version is newer than this fleet_emu's {SCHEMA_VERSION} ({exc})")
    return DecodeError(f"{what}: {exc}")


class _Peek(msgspec.Struct):
    kind: Any = None
    tick: Any = None


_PEEK = msgspec.msgpack.Decoder(_Peek)


def _peek(data: bytes) -> _Peek:
    """A message's ``kind`` and ``tick`` as its bytes claim them (None where they are not a map)."""
    try:
        return _PEEK.decode(data)
    except (msgspec.MsgspecError, UnicodeDecodeError):
        return _Peek()


def decode(data: bytes, ctx: Context | None = None, expected: type[M] | None = None) -> M:
    """Decode bytes into a registered message (of ``expected``, when given), validating it."""
    cls = expected if expected is not None and expected.KIND else None
    try:
        msg = (decoder(cls) if cls is not None else _any_message(frozenset(Message.REGISTRY))).decode(data)
    except (msgspec.MsgspecError, UnicodeDecodeError) as exc:
        claimed = _peek(data).kind
        kind = claimed if type(claimed) is str else None
        if cls is not None and kind is not None and kind != cls.KIND:
            raise DecodeError(f"expected {cls.KIND}, got {kind!r}") from None
        raise _error(cls.KIND if cls is not None else kind or "message", exc) from None
    if expected is not None and not isinstance(msg, expected):
        raise DecodeError(f"expected {expected.__name__}, got {msg.KIND!r}")
    return cast(M, _checked(msg, ctx, msg.KIND))


def decode_payload(kind: str, data: bytes, ctx: Context | None = None) -> Payload:
    """Decode a radio payload of ``kind`` (an unknown kind is a DecodeError too)."""
    cls = Payload.REGISTRY.get(kind)
    if cls is None:
        raise DecodeError(f"unknown payload kind {kind!r}")
    try:
        body = decoder(cls).decode(data)
    except (msgspec.MsgspecError, UnicodeDecodeError) as exc:
        raise _error(kind, exc) from None
    return cast(Payload, _checked(body, ctx, kind))


class Packed(msgspec.Struct, forbid_unknown_fields=True):
    """An array field as :func:`decode_many` reads it: the packed array's parts, its bytes not yet viewed."""

    dtype: str
    shape: list[int]
    data: bytes


@functools.cache
def _array_fields(cls: type[Record]) -> tuple[str, ...]:
    return tuple(f.name for f in msgspec.structs.fields(cls) if f.type is np.ndarray)


@functools.cache
def _packed_form(cls: type[Record]) -> type[msgspec.Struct]:
    """``cls``'s fields with each array as :class:`Packed` (``cls`` itself when it has no array)."""
    fields = msgspec.structs.fields(cls)
    if not _array_fields(cls):
        return cls
    spec = [(f.name, Packed if f.type is np.ndarray else f.type,
             msgspec.field(default=f.default, default_factory=f.default_factory))  # type: ignore[call-overload]
            for f in fields]
    return msgspec.defstruct(f"{cls.__name__}Packed", spec, kw_only=True, forbid_unknown_fields=True)


@functools.cache
def _list_decoder(form: type[msgspec.Struct]) -> msgspec.msgpack.Decoder[Any]:
    return msgspec.msgpack.Decoder(list[form], dec_hook=_dec_hook)  # type: ignore[valid-type]


_RAWS = msgspec.msgpack.Decoder(list[msgspec.Raw])
_array_header = msgpack.Packer().pack_array_header  # msgpack's header of an array of n items


def _viewed(cls: type[R], items: list[Any]) -> tuple[list[R], dict[str, np.ndarray]] | None:
    """Records of ``cls`` from items of its :func:`_packed_form`: each array field's bytes of every item
    viewed at once and sliced (1-D arrays of one dtype per field; None for anything else)."""
    rows = list(map(msgspec.structs.asdict, items))
    arrays = {}
    for name in _array_fields(cls):
        dtypes, shapes, datas = zip(*map(msgspec.structs.astuple, [row[name] for row in rows]), strict=True)
        dt = _DTYPES.get(dtypes[0])
        if dt is None or dtypes.count(dtypes[0]) != len(dtypes) or set(map(len, shapes)) != {1}:
            return None
        counts = [shape[0] for shape in shapes]
        if list(map(len, datas)) != [n * dt.itemsize for n in counts] or sum(counts) * dt.itemsize > MAX_ARRAY_BYTES:
            return None
        arrays[name] = whole = np.frombuffer(b"".join(datas), dt)
        bounds = list(itertools.accumulate(counts, initial=0))
        for row, view in zip(rows, map(whole.__getitem__, map(slice, bounds, bounds[1:])), strict=False):
            row[name] = view
    return [cls(**row) for row in rows], arrays


def decode_many(kind: str, payloads: list[bytes], ctx: Context | None = None) -> list[Payload] | None:
    """Radio payloads of one ``kind`` decoded and validated together, in one pass of msgspec over them all
    (a robot hears each teammate's beacon and map delta every tick): what :func:`decode_payload` gives each,
    or None when one of them is not accepted so (each is then decoded on its own, to drop and count it)."""
    cls = Payload.REGISTRY.get(kind)
    if cls is None or not payloads:
        return None if cls is None else []
    data = _array_header(len(payloads)) + b"".join(payloads)
    try:  # each payload one msgpack item of its own bytes, not a part of its neighbours'
        if list(map(len, _RAWS.decode(data))) != list(map(len, payloads)):
            return None
        form = _packed_form(cls)
        items = _list_decoder(form).decode(data)
        got = _viewed(cls, items) if form is not cls else (items, {})
        if got is None:
            return None
        cls.validate_many(got[0], ctx, got[1])
    except Exception:  # msgspec's errors, a DecodeError, an odd value: one by one, each says why
        return None
    return cast(list[Payload], got[0])


def peek_tick(data: bytes) -> int | None:
    """The tick of an encoded message, or None (the recorder's log time)."""
    tick = _peek(data).tick
    return tick if type(tick) is int and tick >= 0 else None
