"""A map's size in cells, known before its grid is built: from a built-in map's extent in metres, or from an image's
pixel size (read from its header alone) and its resolution, at the run's cell size.

A map whose grid would not fit in memory is refused here with one line, before any array of its size exists:
:func:`load_map` refuses one of more than :data:`MAX_CELLS` cells, and ``fleet run`` first checks
:func:`map_shape` against the machine's memory budget (``launch/budget.py``). The values of a ROS map YAML are
read and checked here too (:func:`read_ros_yaml`): every number finite and in its range.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import yaml
from PIL import Image

from fleet_emu.core.errors import MapError

#: The most cells a map may have at any machine's memory: a 16384 x 16384 grid (its int8 grid and the world's
#: and every robot's arrays over it need several GB even so; ``fleet run`` checks the actual machine first).
MAX_CELLS = 1 << 28
#: The coarsest resolution a map YAML may give, in metres per pixel.
MAX_RESOLUTION = 1000.0
#: The extent in metres (rows, cols) of each built-in map before its border.
BUILTIN_EXTENT: dict[str, tuple[float, float]] = {"office": (25, 40), "maze": (30, 30), "grid": (30, 30),
                                                  "hall": (20, 30)}


@dataclasses.dataclass(frozen=True)
class RosMeta:
    """A ROS map_server YAML's values: the image file (resolved beside the YAML) and how to read it."""

    image: Path
    resolution: float
    negate: bool
    occupied_thresh: float
    free_thresh: float
    mode: str


def _number(meta: dict[str, Any], key: str, default: float | None, lo: float, hi: float, where: Path) -> float:
    value = meta.get(key, default)
    if value is None:
        raise MapError(f"map YAML {where} has no '{key}'")
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) \
            or not lo <= value <= hi:
        raise MapError(f"map YAML {where}: '{key}' must be a finite number in [{lo:g}, {hi:g}], not {value!r}")
    return float(value)


def read_ros_yaml(path: Path) -> RosMeta:
    """The YAML's values, each checked (a MapError naming the first bad one); ``origin``, which the map does not
    use, must still be three finite numbers when given."""
    try:
        meta = yaml.safe_load(path.read_text())
    except (OSError, UnicodeDecodeError, yaml.YAMLError, RecursionError) as exc:
        raise MapError(f"cannot read map YAML {path}: {type(exc).__name__ if isinstance(exc, RecursionError) else exc}"
                       ) from None
    if not isinstance(meta, dict):
        raise MapError(f"map YAML {path} is not a mapping of keys to values")
    image = meta.get("image")
    if not isinstance(image, str) or not image.strip() or len(image) > 4096:
        raise MapError(f"map YAML {path} has no 'image' file name")
    origin = meta.get("origin", [0.0, 0.0, 0.0])
    if not isinstance(origin, list) or len(origin) != 3 or not all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in origin):
        raise MapError(f"map YAML {path}: 'origin' must be three finite numbers [x, y, yaw]")
    resolution = _number(meta, "resolution", None, 1e-9, MAX_RESOLUTION, path)
    negate = _number(meta, "negate", 0, 0, 1, path)
    occ_t = _number(meta, "occupied_thresh", 0.65, 0, 1, path)
    free_t = _number(meta, "free_thresh", 0.196, 0, 1, path)
    mode = str(meta.get("mode", "trinary")).strip().lower()
    if mode not in ("trinary", "scale", "raw"):
        raise MapError(f"map YAML {path}: unknown mode {mode!r} (trinary, scale or raw)")
    return RosMeta((path.parent / image).expanduser(), resolution, bool(negate), occ_t, free_t, mode)


def image_size(path: Path) -> tuple[int, int]:
    """An image's (rows, cols) from its header, without decoding its pixels."""
    try:
        with Image.open(path) as im:
            width, height = im.size
    except Exception as exc:  # Pillow raises many types for bad files
        raise MapError(f"cannot read image {path}: {exc}") from None
    return height, width


def snapped(factor: float) -> float:
    """A pooling factor (cell size over resolution) with float noise around a whole number removed."""
    return float(round(factor)) if abs(factor - round(factor)) < 1e-6 else factor


def pooled_shape(pixels: tuple[int, int], factor: float) -> tuple[int, int]:
    """The cells (rows, cols) that :func:`~fleet_emu.world.maps.resample` makes of ``pixels`` at ``factor``."""
    factor = snapped(factor)
    if not (math.isfinite(factor) and factor > 0):
        raise MapError(f"a cell of {factor!r} pixels cannot be made")
    return max(1, math.ceil(pixels[0] / factor - 1e-9)), max(1, math.ceil(pixels[1] / factor - 1e-9))


def builtin_shape(name: str, cell_size: float) -> tuple[int, int]:
    """About the (rows, cols) of a built-in map at ``cell_size``, its border included."""
    rows, cols = BUILTIN_EXTENT[name]
    return round(rows / cell_size) + 2, round(cols / cell_size) + 2


def check_cells(shape: tuple[int, int], name: str, cell_size: float) -> None:
    """A MapError when a map of ``shape`` cells has more than :data:`MAX_CELLS`."""
    cells = shape[0] * shape[1]
    if cells > MAX_CELLS:
        raise MapError(f"map {name} at {cell_size:g} m cells would be {shape[0]} x {shape[1]} = {cells:,} cells, more "
                       f"than the {MAX_CELLS:,} any machine holds; use larger cells (--cell-size)")
