"""Compiled grid kernels: BFS wavefront, 360-degree ray casting, wall counting along a segment.

Compiled with numba (``cache=True``, so each process loads the machine code from the kernel cache,
:func:`core.jit.cache_dir`, instead of recompiling), on the first call of any kernel (:mod:`core.jit`). All
kernels take plain numpy arrays and flat row-major indices.
"""

from __future__ import annotations

import numpy as np

from fleet_emu.core import cluster_kernels
from fleet_emu.core.jit import njit


@njit(cache=True, inline="always")
def _neighbour(cur: int, k: int, rows: int, cols: int) -> int:
    """Flat index of the k-th 4-neighbour of ``cur`` (up, down, left, right: :data:`core.grid.MOVES`), or -1
    off the grid."""
    r = cur // cols
    c = cur - r * cols
    if k == 0:
        return cur - cols if r > 0 else -1
    if k == 1:
        return cur + cols if r < rows - 1 else -1
    if k == 2:
        return cur - 1 if c > 0 else -1
    return cur + 1 if c < cols - 1 else -1


@njit(cache=True)
def wavefront(passable: np.ndarray, sources: np.ndarray, stop: int = -1) -> np.ndarray:
    """BFS distance (4-connected, unit cost) from every source over ``passable`` cells.

    ``passable`` is a 2-D bool array, ``sources`` flat indices (impassable ones are still seeded:
    a frontier cell next to the unknown is a valid source). Unreached cells hold ``-1``.
    With ``stop >= 0`` the propagation ends as soon as that flat index is assigned its distance
    (MinPos section 4.3, "wavefront propagation stopping").
    """
    rows, cols = passable.shape
    dist = np.full(rows * cols, -1, dtype=np.int32)
    wavefront_into(passable, sources, stop, dist, np.empty(rows * cols, dtype=np.int64))
    return dist.reshape(rows, cols)


@njit(cache=True)
def wavefront_into(passable: np.ndarray, sources: np.ndarray, stop: int, dist: np.ndarray, queue: np.ndarray
                   ) -> int:
    """:func:`wavefront` into ``dist`` (flat, every cell -1 on entry), with ``queue`` (flat, as long) for its
    queue: how many cells it reached, whose flat indices are then ``queue[:count]``. A caller that keeps both
    arrays sets those cells back to -1 and pays for the cells the wavefront reached, not for the grid."""
    rows, cols = passable.shape
    n = rows * cols
    head = 0
    tail = 0
    flat_pass = passable.ravel()
    for s in sources:
        if 0 <= s < n and dist[s] < 0:
            dist[s] = 0
            queue[tail] = s
            tail += 1
            if s == stop:
                return tail
    while head < tail:
        cur = queue[head]
        head += 1
        d = dist[cur] + 1
        for k in range(4):
            nxt = _neighbour(cur, k, rows, cols)
            if nxt < 0:
                continue
            if dist[nxt] < 0 and flat_pass[nxt]:
                dist[nxt] = d
                queue[tail] = nxt
                tail += 1
                if nxt == stop:
                    return tail
    return tail


@njit(cache=True)
def _trace(occupied: np.ndarray, r0: int, c0: int, r1: int, c1: int, radius2: float, mark: np.ndarray,
           out: np.ndarray, count: int) -> int:
    """Bresenham from (r0, c0) toward (r1, c1); marks cells until the first occupied one (included)."""
    dr = abs(r1 - r0)
    dc = abs(c1 - c0)
    sr = 1 if r1 > r0 else -1
    sc = 1 if c1 > c0 else -1
    err = dc - dr
    r = r0
    c = c0
    rows, cols = occupied.shape
    while True:
        if r < 0 or r >= rows or c < 0 or c >= cols:
            return count
        if (r - r0) * (r - r0) + (c - c0) * (c - c0) > radius2:
            return count
        idx = r * cols + c
        if not mark[idx]:
            mark[idx] = True
            out[count] = idx
            count += 1
        if occupied[r, c]:
            return count
        if r == r1 and c == c1:
            return count
        e2 = 2 * err
        if e2 > -dr:
            err -= dr
            c += sc
        if e2 < dc:
            err += dc
            r += sr


@njit(cache=True)
def visible_cells(occupied: np.ndarray, row: int, col: int, radius: float) -> np.ndarray:
    """Flat indices of the cells a 360-degree range sensor at ``(row, col)`` sees.

    Rays go from the sensor to every cell on the border of the square of half-side ``ceil(radius)``;
    each ray stops at the first occupied cell (which is seen) or beyond ``radius`` cells (Euclidean).
    A radius beyond the grid's diagonal (``hypot(rows, cols)``, infinity included) is clamped to it, where
    every cell of the grid is already in range; a negative or NaN radius sees nothing. Sorted ascending.
    """
    rows, cols = occupied.shape
    mark = np.zeros(rows * cols, dtype=np.bool_)
    limit = np.hypot(rows, cols)
    if not radius >= 0.0:  # negative or NaN
        return np.empty(0, dtype=np.int64)
    if radius > limit:
        radius = limit
    R = int(np.ceil(radius))
    out = np.empty(min((2 * R + 1) * (2 * R + 1), rows * cols) + 1, dtype=np.int64)  # each cell marked once
    radius2 = radius * radius
    count = 0
    for k in range(-R, R + 1):
        count = _trace(occupied, row, col, row - R, col + k, radius2, mark, out, count)
        count = _trace(occupied, row, col, row + R, col + k, radius2, mark, out, count)
        count = _trace(occupied, row, col, row + k, col - R, radius2, mark, out, count)
        count = _trace(occupied, row, col, row + k, col + R, radius2, mark, out, count)
    seen = np.empty(count, dtype=np.int64)  # the marked cells in raster order: ascending, without a sort
    k = 0
    for r in range(max(0, row - R), min(rows, row + R + 1)):
        for c in range(max(0, col - R), min(cols, col + R + 1)):
            if mark[r * cols + c]:
                seen[k] = r * cols + c
                k += 1
    return seen


@njit(cache=True)
def count_walls(occupied: np.ndarray, r0: int, c0: int, r1: int, c1: int) -> int:
    """Number of walls the straight segment between two cells crosses.

    A wall is a maximal run of occupied cells along the Bresenham line (docs/guides/radio.md); cells off
    the grid count as free.
    """
    dr = abs(r1 - r0)
    dc = abs(c1 - c0)
    sr = 1 if r1 > r0 else -1
    sc = 1 if c1 > c0 else -1
    err = dc - dr
    r = r0
    c = c0
    rows, cols = occupied.shape
    walls = 0
    inside = False
    while True:
        if 0 <= r < rows and 0 <= c < cols and occupied[r, c]:  # off the grid is open space
            if not inside:
                walls += 1
                inside = True
        else:
            inside = False
        if r == r1 and c == c1:
            return walls
        e2 = 2 * err
        if e2 > -dr:
            err -= dr
            c += sc
        if e2 < dc:
            err += dc
            r += sr


@njit(cache=True)
def cells_valid(cells: np.ndarray, values: np.ndarray, size: int) -> bool:
    """Whether every index of ``cells`` lies in ``[0, size)`` and every value of ``values`` (as long) is -1, 0
    or 100: :func:`fleet_emu.core.messages.check_cells`'s verdict on 1-D arrays of equal length, in one pass
    instead of four numpy calls (a robot checks every teammate's map delta every tick)."""
    for i in range(cells.shape[0]):
        c = cells[i]
        if c < 0 or c >= size:
            return False
        v = values[i]
        if v != -1 and v != 0 and v != 100:
            return False
    return True


@njit(cache=True)
def merge_parts(flat: np.ndarray, cells: np.ndarray, values: np.ndarray, bounds: np.ndarray,
                unknown: int) -> tuple[np.ndarray, int]:
    """Merge parts ``bounds[p]:bounds[p + 1]`` of ``cells`` and ``values`` into the grid ``flat`` in turn, as
    :meth:`fleet_emu.agents.belief.Belief.merge` does each: an unknown value is skipped, a part's values are
    compared with the grid as it was before that part, and its last value of a cell is the one written.
    Returns the changed cells (in part order, then the parts' own order) and how many merged values found
    their cell unknown."""
    changed = np.empty(cells.shape[0], dtype=np.int64)
    before = np.empty(cells.shape[0], dtype=np.int8)
    n = 0
    unknowns = 0
    for p in range(bounds.shape[0] - 1):
        for i in range(bounds[p], bounds[p + 1]):
            before[i] = flat[cells[i]]
        for i in range(bounds[p], bounds[p + 1]):
            v = values[i]
            if v == unknown:
                continue
            if before[i] == unknown:
                unknowns += 1
            if before[i] != v:
                changed[n] = cells[i]
                n += 1
            flat[cells[i]] = v
    return changed[:n], unknowns


@njit(cache=True)
def known_grown(idx: np.ndarray, new: np.ndarray, flat: np.ndarray, unknown: int
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ascending known cells of ``flat`` from ``idx``, those known before (ascending, int64), and ``new``,
    the cells changed since (int64, any order, repeats allowed; a cell never turns unknown again): the union
    of ``idx`` and the known cells of ``new``, as int64 and int32, and their values. One pass instead of a
    scan of the grid (:meth:`fleet_emu.agents.belief.Belief.known`)."""
    s = np.sort(new)
    out = np.empty(idx.shape[0] + s.shape[0], dtype=np.int64)
    i = j = n = 0
    last = -1
    while i < idx.shape[0] or j < s.shape[0]:
        if j >= s.shape[0] or (i < idx.shape[0] and idx[i] <= s[j]):
            v = idx[i]
            i += 1
        else:
            v = s[j]
            j += 1
            if flat[v] == unknown:
                continue
        if v != last:
            out[n] = v
            n += 1
            last = v
    cells = np.empty(n, dtype=np.int32)
    values = np.empty(n, dtype=flat.dtype)
    for k in range(n):
        cells[k] = out[k]
        values[k] = flat[out[k]]
    return out[:n], cells, values


def warm_up() -> None:
    """Compile (or load from cache) every kernel once, so the first tick does not pay for it."""
    for dtype in (np.int32, np.int64):  # read-only, as decoded from a message's bytes
        cells, values = np.frombuffer(np.zeros(1, dtype).tobytes(), dtype), np.frombuffer(b"\0", np.int8)
        cells_valid(cells, values, 1)
        merge_parts(np.zeros(1, np.int8), np.zeros(1, dtype), np.zeros(1, np.int8), np.array([0, 1]), -1)
        merge_parts(np.zeros(1, np.int8), cells, values, np.array([0, 1]), -1)  # map deltas merged as heard
    known_grown(np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1, np.int8), -1)
    occ = np.zeros((3, 3), dtype=np.bool_)
    sources = np.array([0], dtype=np.int64)
    wavefront(~occ, sources, -1)
    wavefront_into(~occ, sources, 4, np.full(9, -1, dtype=np.int32), np.empty(9, dtype=np.int64))  # navigation
    sources.flags.writeable = False  # a frontier cluster's cells (MinPos with stopped wavefronts)
    wavefront(~occ, sources, -1)
    visible_cells(occ, 1, 1, 1.5)
    count_walls(occ, 0, 0, 2, 2)
    label(occ, eight=True)
    cluster_kernels.warm_up()


@njit(cache=True)
def _label(flat: np.ndarray, rows: int, cols: int, eight: bool) -> tuple[np.ndarray, int]:
    labels = np.zeros(rows * cols, dtype=np.int32)
    queue = np.empty(rows * cols, dtype=np.int64)
    count = 0
    for start in range(rows * cols):
        if flat[start] and labels[start] == 0:
            count += 1
            cluster_kernels.walk(flat, labels, rows, cols, start, count, queue, 0, eight)
    return labels, count


def label(mask: np.ndarray, eight: bool = False) -> tuple[np.ndarray, int]:
    """The connected components of a 2-D bool mask (4-connected, or 8-connected with ``eight``): an int32
    array of labels 1..n (0 off the mask), numbered in the raster order of each component's first cell, and
    n. The same labels as ``scipy.ndimage.label`` with a cross or a full 3 x 3 structure (tested), without
    importing scipy.ndimage, about 0.4 s of every process's start."""
    m = np.ascontiguousarray(mask, dtype=np.bool_)
    rows, cols = m.shape
    labels, n = _label(m.ravel(), rows, cols, eight)
    return labels.reshape(rows, cols), int(n)
