"""A small typed msgpack codec for frozen dataclasses.

Each message type is a frozen dataclass with a ``KIND`` class variable; subclasses register themselves
by kind. Field types drive encoding and validation: ``int``, ``float``, ``str``, ``bool``, ``Cell``
(two ints), ``np.ndarray`` (packed as bytes + dtype + shape), ``dict[str, Cell]``, ``dict[str, float]``,
``tuple[str, ...]``, nested message tuples and ``X | None``. Decoding never raises anything but
:class:`DecodeError`.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any, ClassVar

import msgpack
import numpy as np

from fleet_emu.core.errors import DecodeError

ALLOWED_DTYPES = frozenset({"int8", "uint8", "int16", "int32", "int64", "float32", "float64", "bool"})
MAX_ARRAY_BYTES = 64 * 1024 * 1024


@dataclasses.dataclass(frozen=True)
class Message:
    """Envelope shared by every message: ``kind`` (class-level), ``src``, ``tick``, ``seq``."""

    KIND: ClassVar[str] = ""
    REGISTRY: ClassVar[dict[str, type[Message]]] = {}

    src: str
    tick: int
    seq: int

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        if cls.__dict__.get("KIND"):
            if cls.KIND in Message.REGISTRY:
                raise TypeError(f"message kind {cls.KIND!r} defined twice")
            Message.REGISTRY[cls.KIND] = cls

    def validate(self, ctx: Context | None) -> None:
        """Check cross-field constraints; raise DecodeError. Subclasses extend this."""
        if self.tick < 0 or self.seq < 0:
            raise DecodeError("negative tick or seq")
        if ctx is not None and ctx.senders is not None and self.src not in ctx.senders:
            raise DecodeError(f"unknown sender {self.src!r}")

    def to_obj(self) -> dict[str, Any]:
        """The msgpack-ready map of this message (nested messages become maps)."""
        out: dict[str, Any] = {"kind": self.KIND}
        for f in dataclasses.fields(self):
            out[f.name] = _to_obj(getattr(self, f.name))
        return out

    def encode(self) -> bytes:
        return msgpack.packb(self.to_obj(), use_bin_type=True)


@dataclasses.dataclass(frozen=True)
class Context:
    """What a receiver knows to validate against: allowed senders and the grid shape."""

    senders: frozenset[str] | None = None
    shape: tuple[int, int] | None = None


def _to_obj(value: Any) -> Any:
    if isinstance(value, Message):
        return value.to_obj()
    if isinstance(value, np.ndarray):
        arr = np.ascontiguousarray(value)
        return {"dtype": arr.dtype.name, "shape": list(arr.shape), "data": arr.tobytes()}
    if isinstance(value, tuple):
        return [_to_obj(v) for v in value]
    if isinstance(value, dict):
        return {k: _to_obj(v) for k, v in value.items()}
    if isinstance(value, np.generic):
        return value.item()
    return value


_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    if cls not in _HINTS:
        _HINTS[cls] = typing.get_type_hints(cls)
    return _HINTS[cls]


def _from_obj(hint: Any, value: Any, name: str, ctx: Context | None) -> Any:
    origin = typing.get_origin(hint)
    if origin in (types.UnionType, typing.Union):
        args = typing.get_args(hint)
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        return _from_obj(inner[0], value, name, ctx)
    if hint is bool:
        if not isinstance(value, bool):
            raise DecodeError(f"{name}: expected bool")
        return value
    if hint is int:
        if not isinstance(value, int) or isinstance(value, bool):
            raise DecodeError(f"{name}: expected int")
        return value
    if hint is float:
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise DecodeError(f"{name}: expected number")
        return float(value)
    if hint is str:
        if not isinstance(value, str):
            raise DecodeError(f"{name}: expected str")
        return value
    if hint is np.ndarray:
        return _array(value, name)
    if isinstance(hint, type) and issubclass(hint, Message):
        return _decode_obj(value, ctx, expected=hint)
    if origin is tuple:
        args = typing.get_args(hint)
        if not isinstance(value, (list, tuple)):
            raise DecodeError(f"{name}: expected a list")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_from_obj(args[0], v, name, ctx) for v in value)
        if len(value) != len(args):
            raise DecodeError(f"{name}: expected {len(args)} items")
        return tuple(_from_obj(a, v, name, ctx) for a, v in zip(args, value, strict=True))
    if origin is dict:
        key_t, val_t = typing.get_args(hint)
        if not isinstance(value, dict):
            raise DecodeError(f"{name}: expected a map")
        return {_from_obj(key_t, k, name, ctx): _from_obj(val_t, v, name, ctx) for k, v in value.items()}
    if hint is Any:
        return value
    raise DecodeError(f"{name}: unsupported field type {hint!r}")


def _array(value: Any, name: str) -> np.ndarray:
    if not isinstance(value, dict) or set(value) != {"dtype", "shape", "data"}:
        raise DecodeError(f"{name}: expected a packed array")
    dtype, shape, data = value["dtype"], value["shape"], value["data"]
    if dtype not in ALLOWED_DTYPES or not isinstance(data, bytes) or not isinstance(shape, list):
        raise DecodeError(f"{name}: bad packed array")
    if not all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in shape) or len(shape) > 3:
        raise DecodeError(f"{name}: bad array shape")
    dt = np.dtype(dtype)
    count = int(np.prod(shape, dtype=np.int64)) if shape else 1
    if count * dt.itemsize != len(data) or len(data) > MAX_ARRAY_BYTES:
        raise DecodeError(f"{name}: array data does not match its shape")
    return np.frombuffer(data, dtype=dt).reshape(shape)


def _decode_obj(obj: Any, ctx: Context | None, expected: type[Message] | None = None) -> Message:
    if not isinstance(obj, dict):
        raise DecodeError("message is not a map")
    kind = obj.get("kind")
    cls = Message.REGISTRY.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise DecodeError(f"unknown message kind {kind!r}")
    if expected is not None and not issubclass(cls, expected):
        raise DecodeError(f"expected {expected.KIND or expected.__name__}, got {kind!r}")
    hints = _hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    extra = set(obj) - names - {"kind"}
    if extra:
        raise DecodeError(f"{kind}: unexpected fields {sorted(map(str, extra))}")
    values = {}
    for f in dataclasses.fields(cls):
        if f.name not in obj:
            if f.default is not dataclasses.MISSING:
                continue
            if f.default_factory is not dataclasses.MISSING:
                continue
            raise DecodeError(f"{kind}: missing field {f.name!r}")
        values[f.name] = _from_obj(hints[f.name], obj[f.name], f"{kind}.{f.name}", ctx)
    msg = cls(**values)
    msg.validate(ctx)
    return msg


def decode(data: bytes, ctx: Context | None = None, expected: type[Message] | None = None) -> Message:
    """Decode bytes into a registered message, validating it; only ever raises DecodeError."""
    try:
        obj = msgpack.unpackb(data, raw=False, strict_map_key=True)
    except Exception as exc:  # msgpack raises several unrelated types on garbage
        raise DecodeError(f"not msgpack: {type(exc).__name__}") from None
    try:
        return _decode_obj(obj, ctx, expected)
    except DecodeError:
        raise
    except Exception as exc:  # a constructor or validator tripped on odd but well-typed data
        raise DecodeError(f"invalid message: {exc}") from None


def peek_tick(data: bytes) -> int | None:
    """The envelope tick of an encoded message, or None (used by the recorder for log times)."""
    try:
        obj = msgpack.unpackb(data, raw=False)
    except Exception:
        return None
    tick = obj.get("tick") if isinstance(obj, dict) else None
    return tick if isinstance(tick, int) and not isinstance(tick, bool) and tick >= 0 else None
