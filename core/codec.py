"""A small typed msgpack codec for frozen dataclasses.

Each message type is a frozen dataclass with a ``KIND`` class variable; subclasses register themselves
by kind. Field types drive encoding and validation: ``int``, ``float``, ``str``, ``bool``, ``Cell``
(two ints), ``np.ndarray`` (packed as bytes + dtype + shape), ``dict[str, Cell]``, ``dict[str, float]``,
``tuple[str, ...]``, nested message tuples and ``X | None``. Decoding never raises anything but
:class:`DecodeError`.
"""

from __future__ import annotations

import dataclasses
import functools
import types
import typing
from collections.abc import Callable
from typing import Any, ClassVar, TypeVar, cast

import msgpack
import numpy as np

from fleet_emu.core.errors import DecodeError
from fleet_emu.core.version import SCHEMA_VERSION

ALLOWED_DTYPES = frozenset({"int8", "uint8", "int16", "int32", "int64", "float32", "float64", "bool"})
MAX_ARRAY_BYTES = 64 * 1024 * 1024
M = TypeVar("M", bound="Message")


R = TypeVar("R")


class Record:
    """A typed, frozen dataclass that encodes to a msgpack map. Each family root (:class:`Message`,
    :class:`Payload`) keeps its own registry by ``KIND``; a subclass with a ``KIND`` registers in its family's."""

    KIND: ClassVar[str] = ""
    REGISTRY: ClassVar[dict[str, type[Record]]] = {}
    __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]  # every record class is a dataclass

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if "REGISTRY" in cls.__dict__ or not cls.__dict__.get("KIND"):
            return
        registry = cls.REGISTRY  # the nearest family root's
        if cls.KIND in registry:
            raise TypeError(f"{cls.family_name()} kind {cls.KIND!r} defined twice")
        registry[cls.KIND] = cls

    @classmethod
    def family_name(cls) -> str:
        return next(c.__name__ for c in cls.__mro__ if "REGISTRY" in c.__dict__)

    def validate(self, ctx: Context | None) -> None:
        """Check cross-field constraints; raise DecodeError. Subclasses extend this."""

    def fields_obj(self) -> dict[str, Any]:
        """The msgpack-ready map of this record's fields (nested records become maps)."""
        names = _names(type(self))  # type: ignore[arg-type]  # mypy#11470: to it a type[X] variable is unhashable
        return {name: _to_obj(getattr(self, name)) for name in names}

    def to_obj(self) -> dict[str, Any]:
        """:meth:`fields_obj` with the record's ``kind``."""
        return {"kind": self.KIND, **self.fields_obj()}

    def encode(self) -> bytes:
        return msgpack.packb(self.to_obj(), use_bin_type=True)


@dataclasses.dataclass(frozen=True)
class Message(Record):
    """A message on the bus. Envelope shared by every message: ``kind`` (class-level), ``src``, ``tick``,
    ``seq`` (one counter per sender), and ``v``, the schema version."""

    REGISTRY: ClassVar[dict[str, type[Record]]] = {}

    src: str
    tick: int
    seq: int

    def validate(self, ctx: Context | None) -> None:
        if self.tick < 0 or self.seq < 0:
            raise DecodeError("negative tick or seq")
        if ctx is not None and ctx.senders is not None and self.src not in ctx.senders:
            raise DecodeError(f"unknown sender {self.src!r}")

    def to_obj(self) -> dict[str, Any]:
        return {"kind": self.KIND, "v": SCHEMA_VERSION, **self.fields_obj()}


@dataclasses.dataclass(frozen=True)
class Payload(Record):
    """The body of a radio message: opaque bytes to netem and relays, decoded only by the robot protocol that
    owns its ``KIND`` (the brain's pose and map sharing, an allocator's messages). Encoded without its kind,
    which travels in the envelope."""

    REGISTRY: ClassVar[dict[str, type[Record]]] = {}

    def encode(self) -> bytes:
        return msgpack.packb(self.fields_obj(), use_bin_type=True)


@dataclasses.dataclass(frozen=True)
class Context:
    """What a receiver knows to validate against: allowed senders and the grid shape."""

    senders: frozenset[str] | None = None
    shape: tuple[int, int] | None = None


@functools.cache
def _names(cls: type[Record]) -> tuple[str, ...]:
    """A record class's field names, in order."""
    return tuple(f.name for f in dataclasses.fields(cls))


def _to_obj(value: Any) -> Any:
    if isinstance(value, Record):
        return value.to_obj()
    if isinstance(value, np.ndarray):
        arr = np.ascontiguousarray(value)
        dt = arr.dtype
        return {"dtype": _DTYPE_NAMES.get(dt) or dt.name, "shape": list(arr.shape), "data": arr.tobytes()}
    if isinstance(value, tuple):
        return [_to_obj(v) for v in value]
    if isinstance(value, dict):
        return {k: _to_obj(v) for k, v in value.items()}
    if isinstance(value, np.generic):
        return value.item()
    return value


Convert = Callable[[Any, str, "Context | None"], Any]


def _from_obj(hint: Any, value: Any, name: str, ctx: Context | None) -> Any:
    """``value`` (as msgpack decoded it) checked against the field type ``hint``; DecodeError otherwise."""
    return _converter(hint)(value, name, ctx)


@functools.cache
def _converter(hint: Any) -> Convert:
    """The checking converter of one field type, built once per type (decoding a message then costs a call per
    field, not a walk of its type hints)."""
    origin = typing.get_origin(hint)
    if origin in (types.UnionType, typing.Union):
        args = typing.get_args(hint)
        optional = type(None) in args
        inner = _converter(next(a for a in args if a is not type(None)))

        def union(value: Any, name: str, ctx: Context | None) -> Any:
            if value is None and optional:
                return None
            return inner(value, name, ctx)
        return union
    if hint in _SCALARS:
        return _SCALARS[hint]
    if hint is np.ndarray:
        return lambda value, name, ctx: _array(value, name)
    if isinstance(hint, type) and issubclass(hint, Message):
        return lambda value, name, ctx: _decode_obj(value, ctx, expected=hint)
    if origin is tuple:
        return _tuple_converter(typing.get_args(hint))
    if origin is dict:
        key_c, val_c = (_converter(a) for a in typing.get_args(hint))

        str_keys = key_c is _str

        def mapping(value: Any, name: str, ctx: Context | None) -> Any:
            if not isinstance(value, dict):
                raise DecodeError(f"{name}: expected a map")
            if str_keys and _all_of(value, str):
                return {k: val_c(v, name, ctx) for k, v in value.items()}
            return {key_c(k, name, ctx): val_c(v, name, ctx) for k, v in value.items()}
        return mapping
    if hint is Any:
        return lambda value, name, ctx: value

    def unsupported(value: Any, name: str, ctx: Context | None) -> Any:
        raise DecodeError(f"{name}: unsupported field type {hint!r}")
    return unsupported


def _tuple_converter(args: tuple[Any, ...]) -> Convert:
    if len(args) == 2 and args[1] is Ellipsis:
        item = _converter(args[0])
        exact = _EXACT.get(item)  # a list of exactly that scalar type is checked in one pass

        def homogeneous(value: Any, name: str, ctx: Context | None) -> Any:
            if not isinstance(value, (list, tuple)):
                raise DecodeError(f"{name}: expected a list")
            if exact is not None and _all_of(value, exact):
                return tuple(value)
            return tuple(item(v, name, ctx) for v in value)
        return homogeneous
    items = [_converter(a) for a in args]
    fixed = fixed_of(items)
    exact_items = [_EXACT.get(c) for c in items]
    if items and all(e is int for e in exact_items):  # a Cell (or any tuple of ints): the common case in one pass
        n = len(items)

        def ints(value: Any, name: str, ctx: Context | None) -> Any:
            if type(value) is list and len(value) == n and _all_of(value, int):
                return tuple(value)
            return fixed(value, name, ctx)
        return ints
    return fixed


def fixed_of(items: list[Convert]) -> Convert:
    """The converter of a fixed-length tuple whose items have the converters ``items``."""
    def fixed(value: Any, name: str, ctx: Context | None) -> Any:
        if not isinstance(value, (list, tuple)):
            raise DecodeError(f"{name}: expected a list")
        if len(value) != len(items):
            raise DecodeError(f"{name}: expected {len(items)} items")
        return tuple(c(v, name, ctx) for c, v in zip(items, value, strict=True))
    return fixed


def _all_of(values: Any, kind: type) -> bool:
    """Every item of ``values`` is exactly of type ``kind`` (not a subclass: never a bool for an int): one pass
    in C, the fast path of the checking converters, which fall back to their item-by-item check otherwise."""
    return set(map(type, values)) <= {kind}


def _bool(value: Any, name: str, ctx: Context | None) -> bool:
    if not isinstance(value, bool):
        raise DecodeError(f"{name}: expected bool")
    return value


def _int(value: Any, name: str, ctx: Context | None) -> int:
    if type(value) is int:
        return value
    if not isinstance(value, int) or isinstance(value, bool):
        raise DecodeError(f"{name}: expected int")
    return value


def _float(value: Any, name: str, ctx: Context | None) -> float:
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        raise DecodeError(f"{name}: expected number")
    return float(value)


def _str(value: Any, name: str, ctx: Context | None) -> str:
    if type(value) is str:
        return value
    if not isinstance(value, str):
        raise DecodeError(f"{name}: expected str")
    return value


def _bytes(value: Any, name: str, ctx: Context | None) -> bytes:
    if not isinstance(value, bytes) or len(value) > MAX_ARRAY_BYTES:
        raise DecodeError(f"{name}: expected bytes")
    return value


_SCALARS: dict[Any, Convert] = {bool: _bool, int: _int, float: _float, str: _str, bytes: _bytes}
#: The scalar converters that accept a value of exactly this type as it is (their fast path).
_EXACT: dict[Convert, type] = {_int: int, _str: str}


def _array(value: Any, name: str) -> np.ndarray:
    if not isinstance(value, dict) or set(value) != {"dtype", "shape", "data"}:
        raise DecodeError(f"{name}: expected a packed array")
    dtype, shape, data = value["dtype"], value["shape"], value["data"]
    if dtype not in ALLOWED_DTYPES or not isinstance(data, bytes) or not isinstance(shape, list):
        raise DecodeError(f"{name}: bad packed array")
    if not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in shape) or len(shape) > 3:
        raise DecodeError(f"{name}: bad array shape")
    dt = _DTYPES[dtype]
    count = 1
    for s in shape:  # Python ints: no overflow for any shape
        count *= s
    if count * dt.itemsize != len(data) or len(data) > MAX_ARRAY_BYTES:
        raise DecodeError(f"{name}: array data does not match its shape")
    arr = np.frombuffer(data, dtype=dt)
    return arr if len(shape) == 1 else arr.reshape(shape)


_DTYPES = {name: np.dtype(name) for name in ALLOWED_DTYPES}
#: The allowed dtypes' names (``dtype.name`` is a Python property of numpy's, slow for every array encoded).
_DTYPE_NAMES = {dt: name for name, dt in _DTYPES.items()}


#: Fast decoders, by record class: a function of the record's msgpack map (a message's with
#: ``kind`` and ``v``, a payload's without) and the context that returns the record when the map is well formed
#: and valid in the common way, and None otherwise, in which case the generic, checking decode runs (and
#: raises the error). So a fast decoder decides nothing: it only accepts sooner what the generic decode
#: accepts (``tests/core/test_fast_decode.py`` checks the two agree on mutated maps). Registered with
#: :func:`fast_decoder` by the module that defines the record.
FastDecoder = Callable[[dict, "Context | None"], "Record | None"]
_FAST: dict[type, FastDecoder] = {}

#: Typed decoders, by record class: a function of the record's encoded bytes and the context that returns the
#: record when the bytes are well formed and valid, and None otherwise (or raises anything: it is treated as
#: None), in which case the dict decode above runs (fast decoder, then the generic one, which raises the
#: error). They decode the msgpack bytes straight into typed structs (msgspec: one pass in C, the types and
#: ranges checked there), the hot path of the messages a robot hears from every teammate every tick; like the
#: fast decoders they decide nothing, only accept sooner (``tests/core/test_fast_decode.py`` checks them the
#: same way). Registered with :func:`typed_decoder`; :func:`generic_decode` turns them off too.
TypedDecoder = Callable[[bytes, "Context | None"], "Record | None"]
_TYPED: dict[type, TypedDecoder] = {}


F = TypeVar("F", bound=FastDecoder)


def fast_decoder(cls: type[Record]) -> Callable[[F], F]:
    """Register the decorated function as ``cls``'s fast decoder (see :data:`_FAST`)."""
    def register(fn: F) -> F:
        _FAST[cls] = fn
        return fn
    return register


T = TypeVar("T", bound=TypedDecoder)


def typed_decoder(cls: type[Record]) -> Callable[[T], T]:
    """Register the decorated function as ``cls``'s typed decoder (see :data:`_TYPED`)."""
    def register(fn: T) -> T:
        _TYPED[cls] = fn
        return fn
    return register


def _typed(cls: type[Record], data: bytes, ctx: Context | None) -> Record | None:
    """``cls``'s typed decode of ``data``, or None (no typed decoder, or it did not accept the bytes)."""
    fn = _TYPED.get(cls)
    if fn is None:
        return None
    try:
        return fn(data, ctx)
    except Exception:  # msgspec's errors, or anything odd: the checking decode decides and says why
        return None


def generic_decode(data: bytes, ctx: Context | None = None, expected: type[M] | None = None,
                   kind: str | None = None) -> Any:
    """:func:`decode` (or, with ``kind``, :func:`decode_payload`) without the fast decoders: the definition
    they are tested against."""
    saved, saved_typed = dict(_FAST), dict(_TYPED)
    _FAST.clear()
    _TYPED.clear()
    try:
        return decode_payload(kind, data, ctx) if kind is not None else decode(data, ctx, expected)
    finally:
        _FAST.update(saved)
        _TYPED.update(saved_typed)


def packed_array(value: Any) -> np.ndarray | None:
    """A packed array (:func:`_to_obj`'s form) as a read-only view of its bytes, or None when ``value`` is not
    a valid one (for fast decoders, which leave the error to the generic decode)."""
    if type(value) is dict and len(value) == 3:  # a 1-D array, the common case, checked in one expression
        dtype, shape, data = value.get("dtype"), value.get("shape"), value.get("data")
        dt = _DTYPES.get(dtype) if type(dtype) is str else None
        if (dt is not None and type(data) is bytes and type(shape) is list and len(shape) == 1
                and type(shape[0]) is int and shape[0] * dt.itemsize == len(data) <= MAX_ARRAY_BYTES):
            return np.frombuffer(data, dtype=dt)
    try:
        return _array(value, "")
    except DecodeError:
        return None


def array_of(dtype: str, shape: list[int], data: bytes) -> np.ndarray | None:
    """A packed array from its three parts as a typed decoder has them (``shape`` a list of ints), as
    :func:`packed_array` gives it: a read-only view of ``data``, or None when they are not a valid one."""
    dt = _DTYPES.get(dtype)
    if dt is not None and len(shape) == 1 and shape[0] >= 0 and shape[0] * dt.itemsize == len(data) <= MAX_ARRAY_BYTES:
        return np.frombuffer(data, dtype=dt)
    return packed_array({"dtype": dtype, "shape": shape, "data": data})


def _decode_obj(obj: Any, ctx: Context | None, expected: type[Message] | None = None) -> Record:
    if not isinstance(obj, dict):
        raise DecodeError("message is not a map")
    kind = obj.get("kind")
    cls = Message.REGISTRY.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise DecodeError(f"unknown message kind {kind!r}")
    fast = _FAST.get(cls)
    if fast is not None and (expected is None or issubclass(cls, expected)):
        record = fast(obj, ctx)
        if record is not None:
            return record
    if expected is not None and not issubclass(cls, expected):
        raise DecodeError(f"expected {expected.KIND or expected.__name__}, got {kind!r}")
    version = obj.get("v", 1)
    if not isinstance(version, int) or isinstance(version, bool) or version > SCHEMA_VERSION:
        raise DecodeError(f"{kind}: schema version {version!r} is newer than this fleet_emu's {SCHEMA_VERSION}")
    return _build(cls, {k: v for k, v in obj.items() if k not in ("kind", "v")}, ctx)


@dataclasses.dataclass(frozen=True)
class _Field:
    name: str
    label: str  # ``kind.name``, for the error messages
    optional: bool  # it has a default
    convert: Convert


@functools.cache
def _fields(cls: type[Record]) -> tuple[tuple[_Field, ...], frozenset[str]]:
    """The decoding plan of a record class: each field's converter, and the set of field names."""
    hints = typing.get_type_hints(cls)
    plan = tuple(_Field(f.name, f"{cls.KIND}.{f.name}", f.default is not dataclasses.MISSING
                        or f.default_factory is not dataclasses.MISSING, _converter(hints[f.name]))
                 for f in dataclasses.fields(cls))
    return plan, frozenset(f.name for f in plan)


def _build(cls: type[Record], fields: dict[Any, Any], ctx: Context | None) -> Record:
    """A record of ``cls`` from its decoded field map, every field checked against its type, then validated."""
    names = _fields(cls)[1]  # type: ignore[arg-type]  # mypy#11470
    if not names.issuperset(fields):
        extra = set(fields) - names
        raise DecodeError(f"{cls.KIND}: unexpected fields {sorted(map(str, extra))}")
    values = {}
    for name, label, optional, convert in _steps(cls):  # type: ignore[arg-type]  # mypy#11470
        if name in fields:
            values[name] = convert(fields[name], label, ctx)
        elif not optional:
            raise DecodeError(f"{cls.KIND}: missing field {name!r}")
    record = cls(**values)
    record.validate(ctx)
    return record


@functools.cache
def _steps(cls: type[Record]) -> tuple[tuple[str, str, bool, Convert], ...]:
    """:func:`_fields`'s plan as plain tuples (the decoding loop unpacks them rather than read attributes)."""
    plan = _fields(cls)[0]  # type: ignore[arg-type]  # mypy#11470
    return tuple((f.name, f.label, f.optional, f.convert) for f in plan)


def _guarded(build: Callable[..., R], *args: Any) -> R:
    """``build(*args)``, a decoder; anything but DecodeError (a constructor or validator tripped on odd but
    well-typed data) becomes a DecodeError."""
    try:
        return build(*args)
    except DecodeError:
        raise
    except Exception as exc:
        raise DecodeError(f"invalid message: {exc}") from None


def _unpack(data: bytes) -> Any:
    try:
        return msgpack.unpackb(data, raw=False, strict_map_key=True)
    except Exception as exc:  # msgpack raises several unrelated types on garbage
        raise DecodeError(f"not msgpack: {type(exc).__name__}") from None


def decode(data: bytes, ctx: Context | None = None, expected: type[M] | None = None) -> M:
    """Decode bytes into a registered message, validating it; only ever raises DecodeError."""
    if expected is not None:
        record = _typed(expected, data, ctx)
        if record is not None:
            return cast(M, record)
    obj = _unpack(data)
    # a Message: Message.REGISTRY holds only message classes, and _decode_obj checks ``expected``
    return cast(M, _guarded(_decode_obj, obj, ctx, expected))


def decode_payload(kind: str, data: bytes, ctx: Context | None = None) -> Payload:
    """Decode a radio payload of ``kind``; only ever raises DecodeError (an unknown kind included)."""
    cls = Payload.REGISTRY.get(kind)
    if cls is None:
        raise DecodeError(f"unknown payload kind {kind!r}")
    typed = _TYPED.get(cls)
    if typed is not None:  # :func:`_typed`, inlined: every teammate's beacon and delta of every tick come here
        try:
            record = typed(data, ctx)
        except Exception:
            record = None
        if record is not None:
            return cast(Payload, record)
    return decode_payload_obj(kind, _unpack(data), ctx)


def decode_payload_obj(kind: str, obj: Any, ctx: Context | None = None) -> Payload:
    """:func:`decode_payload` of a payload already unpacked from msgpack (``obj``)."""
    cls = Payload.REGISTRY.get(kind)
    if cls is None:
        raise DecodeError(f"unknown payload kind {kind!r}")
    if type(obj) is not dict:
        raise DecodeError(f"{kind}: payload is not a map")
    fast = _FAST.get(cls)
    record = _guarded(fast, obj, ctx) if fast is not None else None
    if record is None:
        record = _guarded(_build, cls, obj, ctx)
    return cast(Payload, record)  # Payload.REGISTRY holds only payload classes


def peek_tick(data: bytes) -> int | None:
    """The envelope tick of an encoded message, or None (used by the recorder for log times)."""
    try:
        obj = msgpack.unpackb(data, raw=False)
    except Exception:
        return None
    tick = obj.get("tick") if isinstance(obj, dict) else None
    return tick if isinstance(tick, int) and not isinstance(tick, bool) and tick >= 0 else None
