"""The ROS 2 message types the fleet publishes, from ``rosbags``' Jazzy type store: classes, CDR and RIHS01
hashes are the library's, never hand-written tables. :func:`make` builds a message from the fields given and
the type's zero values for the rest (a ``visualization_msgs/Marker`` has some twenty fields)."""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from fleet_emu.core.errors import ConfigError

CLOCK = "rosgraph_msgs/msg/Clock"
GRID = "nav_msgs/msg/OccupancyGrid"
POSE = "geometry_msgs/msg/PoseStamped"
PATH = "nav_msgs/msg/Path"
MARKERS = "visualization_msgs/msg/MarkerArray"
TF = "tf2_msgs/msg/TFMessage"

_NUMPY = {"bool": np.bool_, "int8": np.int8, "uint8": np.uint8, "byte": np.uint8, "char": np.uint8,
          "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32, "int64": np.int64,
          "uint64": np.uint64, "float32": np.float32, "float64": np.float64}


@functools.cache
def typestore() -> Any:
    """rosbags' ROS 2 Jazzy type store (a ConfigError naming the extra when rosbags is not installed)."""
    try:
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise ConfigError("ROS 2 support needs the ros2 extra: pip install 'fleet-emu[ros2]'") from None
    return get_typestore(Stores.ROS2_JAZZY)


def type_hash(typename: str) -> str:
    """The type's RIHS01 hash (``RIHS01_<64 hex>``), as rmw_zenoh puts it in key expressions."""
    return str(typestore().hash_rihs01(typename))


def msgdef(typename: str) -> str:
    """The type's full definition (ROS 2 ``.msg`` text with its dependencies), for a bag's metadata."""
    return str(typestore().generate_msgdef(typename, ros_version=2)[0])


def cdr(msg: Any, typename: str) -> bytes:
    """The message's CDR bytes (little-endian, with the 4-byte encapsulation header)."""
    return bytes(typestore().serialize_cdr(msg, typename))


def decode(data: bytes, typename: str) -> Any:
    return typestore().deserialize_cdr(data, typename)


def make(typename: str, **fields: Any) -> Any:
    """A ``typename`` message: ``fields`` as given, every other field its zero value (nested messages too)."""
    ts = typestore()
    _, defs = ts.fielddefs[typename]
    values = {name: fields[name] if name in fields else _zero(spec) for name, spec in defs}
    return ts.types[typename](**values)


def _zero(spec: tuple[Any, Any]) -> Any:
    kind, detail = spec
    name = getattr(kind, "name", str(kind))
    if name == "BASE":
        prim = detail[0]
        return "" if prim in ("string", "wstring") else False if prim == "bool" else \
            0.0 if prim.startswith("float") else 0
    if name == "NAME":
        return make(detail)
    (inner_kind, inner), size = detail
    if getattr(inner_kind, "name", "") == "BASE" and inner[0] in _NUMPY:
        return np.zeros(size, dtype=_NUMPY[inner[0]])
    return [_zero((inner_kind, inner)) for _ in range(size)]
