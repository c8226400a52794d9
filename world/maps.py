"""Ground-truth maps: built-in generators, the registry's public maps by name, PNG/PGM bitmaps and ROS map_server
YAML files.

Every map becomes an ``int8`` grid of ``0`` (free) and ``100`` (occupied) at the scenario's cell size,
bordered by walls, with a suggested start cell (see :func:`choose_start`).

An image is read as ROS map_server reads it (:func:`classify`): with the default thresholds a pixel of gray
level below 90 (of 255) is occupied, one above 205 is free, and the greys between are unknown; a transparent
pixel is white. Pixels are then pooled into cells (:func:`resample`): a
cell is occupied when any of its pixels is (max-pooling keeps walls drawn one pixel thick), and free only
when at least half of its pixels are free, so unknown space (map_server's grey) becomes wall.

A bitmap's scale comes from its ROS YAML (``resolution``, metres per pixel), from the registry (a map by
name), or, for a bare PNG/PGM, from the cell size the user gives: it is then read one pixel per cell. A bare
bitmap without a cell size given is refused (:func:`load_map`, ``cell_size_given``).
"""

from __future__ import annotations

import math
from collections import deque
from pathlib import Path

import numpy as np
from PIL import Image

from fleet_emu.core import jit
from fleet_emu.core.errors import MapError
from fleet_emu.core.grid import FREE, MOVES, OCCUPIED, Cell, MapData, nearest_cells
from fleet_emu.core.setting_names import near
from fleet_emu.world.mapsize import builtin_shape, check_cells, image_size, pooled_shape, read_ros_yaml, snapped
from fleet_emu.world.registry import local_map, registry

BUILTIN_MAPS: dict[str, str] = {
    "office": "40 x 25 m office: two rows of rooms with doors off a corridor, crossed by a vertical corridor",
    "maze": "30 x 30 m perfect maze with 2 m wide corridors (layout from the seed)",
    "grid": "30 x 30 m regular grid of 4 m square blocks separated by 2 m streets",
    "hall": "30 x 20 m open hall with scattered rectangular obstacles (placed from the seed)",
}

#: The map_server defaults, for a bitmap without a YAML.
DEFAULT_OCCUPIED_THRESH = 0.65
DEFAULT_FREE_THRESH = 0.196
#: The file suffixes read as a YAML descriptor; any other file is read as an image.
YAML_SUFFIXES = (".yaml", ".yml")
#: The start cell's neighbourhood: cells within this BFS distance are counted as room for robots.
START_RADIUS = 4
#: How many of those cells (at most 41) a start needs, when some cell of the component has that many.
START_ROOM = 24


def _cells(metres: float, cell_size: float, minimum: int = 1) -> int:
    return max(minimum, round(metres / cell_size))


def _bordered(grid: np.ndarray) -> np.ndarray:
    """Add a one-cell wall border when any edge cell is free."""
    g = grid.astype(np.int8)
    edges = np.concatenate([g[0], g[-1], g[:, 0], g[:, -1]])
    return np.pad(g, 1, constant_values=OCCUPIED) if (edges == FREE).any() else g


def _components(free: np.ndarray) -> tuple[np.ndarray, int]:
    """Labels of the 4-connected free components and the label of the largest (lowest label on ties)."""
    from fleet_emu.core.kernels import label  # numba: imported on first use, not with ``fleet maps``

    labels, n = label(free)
    if n == 0:
        return labels, 0
    return labels, int(np.argmax(np.bincount(labels.ravel())[1:])) + 1


def largest_component(free: np.ndarray, tries: int = 4) -> np.ndarray | None:
    """The mask of the largest 4-connected component of ``free`` (the lowest-labelled on ties, as
    :func:`_components`), None when there is no free cell.

    In a process that has not loaded the kernels (a launcher checking a scenario), a numpy search from the first
    free cell not yet reached finds it when it holds more than half of the free cells, as a map's floor does, in at
    most ``tries`` searches, so that building a map never loads numba there. Otherwise (or once the kernels are
    loaded: they are several times faster) the compiled labels decide."""
    total = int(free.sum())
    if total == 0:
        return None
    inside, reached = free.ravel(), np.zeros(free.size, dtype=bool)
    for _ in range(0 if jit.loaded() else tries):
        left = np.flatnonzero(inside & ~reached)
        if left.size == 0:
            break
        cells = nearest_cells(free, free, int(left[0]))
        if 2 * cells.size > total:
            mask = np.zeros(free.size, dtype=bool)
            mask[cells] = True
            return mask.reshape(free.shape)
        reached[cells] = True
    labels, best = _components(free)
    return labels == best


def diamond_sums(mask: np.ndarray, k: int) -> np.ndarray:
    """For every cell, how many ``mask`` cells lie within Manhattan distance ``k`` of it (none off the grid):
    a convolution with a diamond, as shifted sums."""
    rows, cols = mask.shape
    padded = np.pad(mask.astype(np.int32), k)
    out = np.zeros((rows, cols), dtype=np.int32)
    for dr in range(-k, k + 1):
        w = k - abs(dr)
        for dc in range(-w, w + 1):
            out += padded[k + dr:k + dr + rows, k + dc:k + dc + cols]
    return out


def _ball(mask: np.ndarray, cell: Cell, radius: int) -> int:
    """The number of ``mask`` cells within BFS distance ``radius`` of ``cell``."""
    seen = {cell}
    todo = deque([(cell, 0)])
    while todo:
        (r, c), d = todo.popleft()
        if d == radius:
            continue
        for dr, dc in MOVES:
            n = (r + dr, c + dc)
            if 0 <= n[0] < mask.shape[0] and 0 <= n[1] < mask.shape[1] and mask[n] and n not in seen:
                seen.add(n)
                todo.append((n, d + 1))
    return len(seen)


def choose_start(grid: np.ndarray, room: int | None = None, tries: int = 2000) -> Cell:
    """A deterministic start cell with room around it, in the largest free component, near its centroid.

    Among the cells of the largest 4-connected free component that have at least ``room`` component
    cells within BFS distance :data:`START_RADIUS` (capped by the best any cell has), it takes the one
    nearest the component's centroid (ties: row, then col). Candidates are pre-filtered by a vectorised
    upper bound (component cells within that Manhattan distance) and then checked by BFS. The default
    room, 24 of at most 41 cells, is met at the crossing of two 3-cell-wide corridors or in any open
    area, so the world can place ~16 robots around the start by BFS.
    """
    comp = largest_component(grid == FREE)
    if comp is None:
        raise MapError("the map has no free cell")
    k, need = START_RADIUS, START_ROOM if room is None else room
    bound = diamond_sums(comp, k)
    rows, cols = np.nonzero(comp)
    bound = bound[rows, cols]
    d2 = (rows - rows.mean()) ** 2 + (cols - cols.mean()) ** 2
    need = min(need, int(bound.max()))
    order = np.lexsort((cols, rows, d2))  # nearest the centroid first
    for i in order[bound[order] >= need][:tries]:
        if _ball(comp, (int(rows[i]), int(cols[i])), k) >= need:
            return int(rows[i]), int(cols[i])
    # the bound overestimated everywhere we looked: take the roomiest of the most promising cells
    top = np.lexsort((cols, rows, d2, -bound))[:64]
    i = min(top, key=lambda i: (-_ball(comp, (int(rows[i]), int(cols[i])), k), d2[i], rows[i], cols[i]))
    return int(rows[i]), int(cols[i])


# ----------------------------------------------------------------------------------------------- generators


def _split(lo: int, hi: int, wmin: int, wmax: int, rng: np.random.Generator) -> list[tuple[int, int]]:
    """Split the inclusive span ``lo..hi`` into rooms ``(a, b)`` of width wmin..wmax, one wall cell apart."""
    rooms, a = [], lo
    while a <= hi:
        w = int(rng.integers(wmin, wmax + 1))
        b = hi if hi - (a + w) < wmin else a + w - 1
        rooms.append((a, b))
        a = b + 2
    return rooms


def _office(cs: float, rng: np.random.Generator) -> tuple[np.ndarray, Cell | None]:
    """Rooms above and below a 2 m corridor, a 2 m vertical corridor across; starts at their crossing."""
    h, w, cw, dw = _cells(25, cs, 7), _cells(40, cs, 9), _cells(2.0, cs), _cells(1.0, cs)
    g = np.zeros((h, w), dtype=np.int8)
    g[[0, -1], :] = g[:, [0, -1]] = OCCUPIED
    c0, v0 = (h - cw) // 2, (w - cw) // 2  # first row of the horizontal corridor, first col of the vertical one
    g[[c0 - 1, c0 + cw], :] = OCCUPIED
    g[:, [v0 - 1, v0 + cw]] = OCCUPIED
    g[c0:c0 + cw, 1:-1] = FREE
    g[1:-1, v0:v0 + cw] = FREE
    wmin, wmax = _cells(4.0, cs, 2), _cells(7.0, cs, 2)

    def door(r0: int, r1: int, col: int) -> None:  # a gap in a vertical wall, rows r0..r1
        d = min(dw, r1 - r0 + 1)
        s = int(rng.integers(r0, r1 - d + 2))
        g[s:s + d, col] = FREE

    for (r0, r1), door_row in (((1, c0 - 2), c0 - 1), ((c0 + cw + 1, h - 2), c0 + cw)):
        for lo, hi, side_col in ((1, v0 - 2, v0 - 1), (v0 + cw + 1, w - 2, v0 + cw)):
            if r1 < r0 or hi < lo:
                continue
            rooms = _split(lo, hi, wmin, wmax, rng)
            for _, b in rooms[:-1]:
                g[r0:r1 + 1, b + 1] = OCCUPIED
            for i, (a, b) in enumerate(rooms):
                d = min(dw, b - a + 1)
                s = int(rng.integers(a, b - d + 2))
                g[door_row, s:s + d] = FREE  # every room opens onto the horizontal corridor
                if i + 1 < len(rooms) and rng.random() < 0.35:  # some open into the next room
                    door(r0, r1, b + 1)
                if side_col in (a - 1, b + 1) and rng.random() < 0.5:  # or onto the vertical corridor
                    door(r0, r1, side_col)
    return g, (c0 + (cw - 1) // 2, v0 + (cw - 1) // 2)


def _maze(cs: float, rng: np.random.Generator) -> tuple[np.ndarray, Cell | None]:
    """A perfect maze of 2 m passages by randomized depth-first search (the recursive backtracker)."""
    pw = _cells(2.0, cs)
    p = pw + 1
    n = max(2, round((30 / cs - 1) / p))
    g = np.full((n * p + 1, n * p + 1), OCCUPIED, dtype=np.int8)
    for i in range(n):
        for j in range(n):
            g[1 + i * p:1 + i * p + pw, 1 + j * p:1 + j * p + pw] = FREE
    seen = np.zeros((n, n), dtype=bool)
    cell = (int(rng.integers(n)), int(rng.integers(n)))
    seen[cell] = True
    stack = [cell]
    while stack:  # recursive backtracker (iterative)
        i, j = stack[-1]
        nbrs = [(i + di, j + dj) for di, dj in MOVES
                if 0 <= i + di < n and 0 <= j + dj < n and not seen[i + di, j + dj]]
        if not nbrs:
            stack.pop()
            continue
        ni, nj = nbrs[int(rng.integers(len(nbrs)))]
        if ni != i:  # knock out the wall row between the two cells
            g[1 + max(i, ni) * p - 1, 1 + j * p:1 + j * p + pw] = FREE
        else:
            g[1 + i * p:1 + i * p + pw, 1 + max(j, nj) * p - 1] = FREE
        seen[ni, nj] = True
        stack.append((ni, nj))
    return g, None


def _grid(cs: float, rng: np.random.Generator) -> tuple[np.ndarray, Cell | None]:
    """A regular city-block grid (the seed does not change it)."""
    s, b = _cells(2.0, cs), _cells(4.0, cs)
    k = max(1, math.floor((30 / cs - 2 - s) / (b + s) + 0.5))
    size = 2 + s + k * (b + s)
    g = np.zeros((size, size), dtype=np.int8)
    g[[0, -1], :] = g[:, [0, -1]] = OCCUPIED
    for i in range(k):
        for j in range(k):
            r, c = 1 + s + i * (b + s), 1 + s + j * (b + s)
            g[r:r + b, c:c + b] = OCCUPIED
    return g, None


def _hall(cs: float, rng: np.random.Generator) -> tuple[np.ndarray, Cell | None]:
    """Up to 15 rectangles of 1-3 m by 1-4 m, each with a 1 m free margin, never disconnecting free space."""
    h, w, gap = _cells(20, cs, 5), _cells(30, cs, 5), _cells(1.0, cs)
    g = np.zeros((h, w), dtype=np.int8)
    g[[0, -1], :] = g[:, [0, -1]] = OCCUPIED
    wanted, placed = round(30 * 20 / 40), 0
    for _ in range(40 * wanted):
        if placed == wanted:
            break
        oh = int(rng.integers(_cells(1.0, cs), _cells(3.0, cs) + 1))
        ow = int(rng.integers(_cells(1.0, cs), _cells(4.0, cs) + 1))
        if h - 2 - 2 * gap - oh < 1 or w - 2 - 2 * gap - ow < 1:
            continue
        r, c = int(rng.integers(1 + gap, h - 1 - gap - oh + 1)), int(rng.integers(1 + gap, w - 1 - gap - ow + 1))
        if g[r - gap:r + oh + gap, c - gap:c + ow + gap].any():
            continue  # keep a free margin around every obstacle
        trial = g.copy()
        trial[r:r + oh, c:c + ow] = OCCUPIED
        if _components(trial == FREE)[0].max() == 1:  # never disconnect free space (the kernel: many checks)
            g, placed = trial, placed + 1
    return g, None


_GENERATORS = {"office": _office, "maze": _maze, "grid": _grid, "hall": _hall}


def generate(name: str, cell_size: float, seed: int) -> MapData:
    """A built-in map by name, its layout drawn from ``np.random.default_rng(seed)``."""
    grid, start = _GENERATORS[name](cell_size, np.random.default_rng(seed))
    grid = _bordered(grid)
    return MapData(name, grid, cell_size, start if start is not None else choose_start(grid))


# ------------------------------------------------------------------------------------------------ map files


def _read_gray(path: Path) -> np.ndarray:
    """An image file as a uint8 gray array (transparent pixels count as white, i.e. free)."""
    try:
        with Image.open(path) as im:
            im.load()
            if im.mode in ("I;16", "I;16B", "I;16L", "I", "F"):
                a = np.asarray(im, dtype=np.float64)
                return np.clip(a / (257.0 if im.mode.startswith("I;16") else 1.0), 0, 255).astype(np.uint8)
            if im.mode in ("RGBA", "LA", "PA") or "transparency" in im.info:
                white = Image.new("RGBA", im.size, (255, 255, 255, 255))
                return np.asarray(Image.alpha_composite(white, im.convert("RGBA")).convert("L"))
            return np.asarray(im.convert("L"))
    except Exception as exc:  # Pillow raises many types for bad files
        raise MapError(f"cannot read image {path}: {exc}") from None


def classify(gray: np.ndarray, negate: bool = False, occupied_thresh: float = DEFAULT_OCCUPIED_THRESH,
             free_thresh: float = DEFAULT_FREE_THRESH, mode: str = "trinary") -> tuple[np.ndarray, np.ndarray]:
    """Occupied and free pixel masks, as ROS map_server reads an image (everything else is unknown).

    trinary/scale: ``p = (255 - x) / 255`` (``x / 255`` when negated); occupied if ``p > occupied_thresh``,
    free if ``p < free_thresh``. raw: the (possibly negated) value is the occupancy 0..100; occupied from
    ``occupied_thresh * 100``, free below it, unknown above 100.
    """
    x = np.arange(256, dtype=np.float64)  # a lookup table over the gray levels
    if mode == "raw":
        v = 255.0 - x if negate else x
        occ, fre = (v >= occupied_thresh * 100) & (v <= 100), v < occupied_thresh * 100
    else:
        p = x / 255.0 if negate else (255.0 - x) / 255.0
        occ, fre = p > occupied_thresh, p < free_thresh
    return occ[gray], fre[gray]


def resample(occupied: np.ndarray, free: np.ndarray, factor: float) -> np.ndarray:
    """Pool pixel masks into cells of ``factor`` pixels a side (ceil: every pixel lands in a cell).

    A cell is occupied if any of its pixels is occupied (max-pool keeps one-pixel walls); it is free only
    when it has no occupied pixel and at least half of its pixels are free; otherwise (mostly unknown) occupied.
    """
    factor = snapped(factor)
    shape = pooled_shape(occupied.shape, factor)
    if factor < 1:  # cells smaller than pixels: each cell takes the pixel it lies in
        rows = np.minimum((np.arange(shape[0]) * factor).astype(int), occupied.shape[0] - 1)
        cols = np.minimum((np.arange(shape[1]) * factor).astype(int), occupied.shape[1] - 1)
        occ, fre = occupied[np.ix_(rows, cols)], free[np.ix_(rows, cols)]
        return np.where(occ | ~fre, OCCUPIED, FREE).astype(np.int8)
    starts = [np.unique(np.floor(np.arange(n) / factor + 1e-9).astype(int), return_index=True)[1]
              for n in occupied.shape]

    def pool(a: np.ndarray) -> np.ndarray:
        return np.add.reduceat(np.add.reduceat(a.astype(np.int32), starts[0], axis=0), starts[1], axis=1)

    sizes = [np.diff(np.append(st, n)) for st, n in zip(starts, occupied.shape, strict=True)]
    total = np.outer(sizes[0], sizes[1])
    ok = (pool(occupied) == 0) & (2 * pool(free) >= total)
    return np.where(ok, FREE, OCCUPIED).astype(np.int8)


def _finish(name: str, grid: np.ndarray, cell_size: float) -> MapData:
    grid = _bordered(grid)
    if not (grid == FREE).any():
        raise MapError(f"map {name} has no free cell at cell size {cell_size} m")
    return MapData(name, grid, cell_size, choose_start(grid))


def load_bitmap(path: str | Path, cell_size: float, *, resolution: float | None = None,
                name: str | None = None) -> MapData:
    """A PNG/PGM bitmap (dark is occupied, map_server default thresholds) at ``resolution`` m/px;
    ``resolution=None``: drawn at the cell size, one pixel per cell."""
    if resolution is None:
        resolution = cell_size
    check_cells(pooled_shape(image_size(Path(path)), cell_size / resolution), name or str(path), cell_size)
    gray = _read_gray(Path(path))
    occ, fre = classify(gray)
    return _finish(name or str(path), resample(occ, fre, cell_size / resolution), cell_size)


def load_ros_yaml(path: str | Path, cell_size: float, *, name: str | None = None) -> MapData:
    """A ROS map_server YAML: ``image`` (relative to the YAML), ``resolution``, ``negate``, thresholds, ``mode``."""
    path = Path(path)
    meta = read_ros_yaml(path)
    if not meta.image.is_file():
        raise MapError(f"map image not found: {meta.image} (named in {path})")
    factor = cell_size / meta.resolution
    check_cells(pooled_shape(image_size(meta.image), factor), name or str(path), cell_size)
    occ, fre = classify(_read_gray(meta.image), meta.negate, meta.occupied_thresh, meta.free_thresh, meta.mode)
    return _finish(name or str(path), resample(occ, fre, factor), cell_size)


def map_shape(name_or_path: str, cell_size: float) -> tuple[int, int] | None:
    """The (rows, cols) the map will have at ``cell_size`` at most (its wall border included), from its extent or
    its image's header alone (about, for a built-in map); None when it cannot be told without loading it
    (:func:`load_map` then says why)."""
    if name_or_path in BUILTIN_MAPS:
        return builtin_shape(name_or_path, cell_size)
    if name_or_path in registry():
        entry, path = registry()[name_or_path], local_map(name_or_path)
        if entry.yaml is None:
            return _border(pooled_shape(image_size(path), cell_size / entry.resolution)) if path.is_file() else None
    else:
        path = Path(name_or_path).expanduser()
        if not path.is_file():
            return None
        if path.suffix.lower() not in YAML_SUFFIXES:
            return _border(image_size(path))
    meta = read_ros_yaml(path) if path.is_file() else None
    if meta is None or not meta.image.is_file():
        return None
    return _border(pooled_shape(image_size(meta.image), cell_size / meta.resolution))


def _border(shape: tuple[int, int]) -> tuple[int, int]:
    """``shape`` with room for the wall border :func:`_bordered` may add."""
    return shape[0] + 2, shape[1] + 2


def is_bare_bitmap(name_or_path: str) -> bool:
    """Whether ``name_or_path`` is an image file given alone: not a built-in or registry name, not a YAML."""
    if name_or_path in BUILTIN_MAPS or name_or_path in registry():
        return False
    path = Path(name_or_path).expanduser()
    return path.suffix.lower() not in YAML_SUFFIXES and path.is_file()


def no_scale_error(name_or_path: str) -> MapError:
    """The refusal of a bare bitmap without a cell size: its scale is unknown."""
    return MapError(f"map {name_or_path} is a bitmap without a scale: give the cell size it is drawn at "
                    "(--cell-size M, or cell_size in a scenario: one pixel per cell of M metres), or a ROS map "
                    "YAML beside it with its resolution in metres per pixel (image, resolution)")


def load_map(name_or_path: str, cell_size: float, seed: int, *, cell_size_given: bool = True) -> MapData:
    """A built-in map or a registry map by name, or a PNG/PGM bitmap or ROS map_server YAML by path; raises
    :class:`MapError`. A registry map must have been fetched (``fleet maps fetch NAME``). A bare bitmap is
    read one pixel per cell; with ``cell_size_given=False`` (the scenario's default cell size, not the
    user's) it is refused, as its scale would be a guess."""
    if not (isinstance(cell_size, int | float) and math.isfinite(cell_size) and cell_size > 0):
        raise MapError(f"cell size must be a positive number of metres, not {cell_size!r}")
    cell_size = float(cell_size)
    if name_or_path in BUILTIN_MAPS:
        check_cells(builtin_shape(name_or_path, cell_size), name_or_path, cell_size)
        return generate(name_or_path, cell_size, seed)
    if name_or_path in registry():
        entry, path = registry()[name_or_path], local_map(name_or_path)
        if entry.yaml is not None:
            return load_ros_yaml(path, cell_size, name=name_or_path)
        return load_bitmap(path, cell_size, resolution=entry.resolution, name=name_or_path)
    path = Path(name_or_path).expanduser()
    if path.is_file():
        if path.suffix.lower() in YAML_SUFFIXES:
            return load_ros_yaml(path, cell_size, name=name_or_path)
        if not cell_size_given:
            raise no_scale_error(name_or_path)
        return load_bitmap(path, cell_size, name=name_or_path)
    raise missing_map(name_or_path)


def missing_map(name_or_path: str) -> MapError:
    """Why ``name_or_path`` names no map (neither a built-in's nor a registry map's name, nor a file): a path that
    is not a file, a file not found, or an unknown name with the names there are."""
    path = Path(name_or_path).expanduser()
    if path.exists():
        return MapError(f"map path is not a file: {name_or_path}")
    if "/" in name_or_path or "\\" in name_or_path or path.suffix:
        return MapError(f"map file not found: {name_or_path}")
    hint = near(name_or_path, [*BUILTIN_MAPS, *registry()])
    return MapError(f"unknown map {name_or_path!r}{hint} (built-in: {', '.join(BUILTIN_MAPS)}; registry: "
                    f"{', '.join(registry())} (`fleet maps`); or a PNG/PGM/YAML path)")
