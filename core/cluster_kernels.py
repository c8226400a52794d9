"""Compiled kernels of the incremental frontier clustering (``agents/clusters.py``; MinPos section 4.1).

Like :mod:`core.kernels`: numba with ``cache=True``, plain numpy arrays and flat row-major indices. A frontier
cell is a known-free cell with an unknown 4-neighbour; frontier groups are 8-connected. ``labels`` holds each
frontier cell's group label (0 off the frontier).
"""

from __future__ import annotations

import numpy as np

from fleet_emu.core.grid import distinct
from fleet_emu.core.jit import njit

FREE = 0
UNKNOWN = -1


@njit(cache=True, inline="always")
def _is_frontier(grid: np.ndarray, x: int, rows: int, cols: int) -> bool:
    if grid[x] != FREE:
        return False
    r = x // cols
    c = x - r * cols
    return ((r > 0 and grid[x - cols] == UNKNOWN) or (r < rows - 1 and grid[x + cols] == UNKNOWN)
            or (c > 0 and grid[x - 1] == UNKNOWN) or (c < cols - 1 and grid[x + 1] == UNKNOWN))


@njit(cache=True)
def update_mask(grid: np.ndarray, rows: int, cols: int, mask: np.ndarray, changed: np.ndarray) -> np.ndarray:
    """Recompute the frontier ``mask`` (flat bool, updated in place) on the ``changed`` cells and their
    4-neighbours, the only cells whose frontier status a change of ``changed`` can alter; the cells whose
    status flipped (each once)."""
    out = np.empty(5 * len(changed), dtype=np.int64)
    k = 0
    for i in range(len(changed)):
        cur = changed[i]
        r = cur // cols
        c = cur - r * cols
        for j in range(5):
            if j == 0:
                x = cur
            elif j == 1:
                x = cur - cols if r > 0 else -1
            elif j == 2:
                x = cur + cols if r < rows - 1 else -1
            elif j == 3:
                x = cur - 1 if c > 0 else -1
            else:
                x = cur + 1 if c < cols - 1 else -1
            if x < 0:
                continue
            now = _is_frontier(grid, x, rows, cols)
            if now != mask[x]:
                mask[x] = now
                out[k] = x
                k += 1
    return out[:k]


def touched_labels(labels: np.ndarray, rows: int, cols: int, flips: np.ndarray) -> np.ndarray:
    """The (old) group labels of the flipped cells and of their 8-neighbours: every group that lost a cell or
    is 8-adjacent to a new frontier cell (unique, ascending: numpy's sort here, not compiled, since a
    compiled sort costs seconds to build in every fresh checkout)."""
    return distinct(_touched_labels(labels, rows, cols, flips))


@njit(cache=True)
def _touched_labels(labels: np.ndarray, rows: int, cols: int, flips: np.ndarray) -> np.ndarray:
    out = np.empty(9 * len(flips), dtype=np.int32)
    k = 0
    for i in range(len(flips)):
        cur = flips[i]
        r = cur // cols
        c = cur - r * cols
        for dr in range(-1, 2):
            for dc in range(-1, 2):
                rr = r + dr
                cc = c + dc
                if 0 <= rr < rows and 0 <= cc < cols:
                    lab = labels[rr * cols + cc]
                    if lab != 0:
                        out[k] = lab
                        k += 1
    return out[:k]


@njit(cache=True)
def walk(mask: np.ndarray, labels: np.ndarray, rows: int, cols: int, start: int, lab: int,
         out: np.ndarray, at: int, eight: bool) -> int:
    """Breadth-first (8-connected, or 4-connected without ``eight``; neighbours row-major) from ``start`` over
    ``mask`` cells not yet labelled, labelling them ``lab`` and writing them to ``out`` from ``at``; the end in
    ``out``. The frontier groups' walk here, and :func:`~fleet_emu.core.kernels.label`'s."""
    labels[start] = lab
    out[at] = start
    head = at
    tail = at + 1
    while head < tail:
        cur = out[head]
        head += 1
        r = cur // cols
        c = cur - r * cols
        for dr in range(-1, 2):
            rr = r + dr
            if rr < 0 or rr >= rows:
                continue
            for dc in range(-1, 2):
                cc = c + dc
                if (dr == 0 and dc == 0) or cc < 0 or cc >= cols or (not eight and dr != 0 and dc != 0):
                    continue
                nxt = rr * cols + cc
                if mask[nxt] and labels[nxt] == 0:
                    labels[nxt] = lab
                    out[tail] = nxt
                    tail += 1
    return tail


@njit(cache=True)
def relabel(mask: np.ndarray, labels: np.ndarray, rows: int, cols: int, seeds: np.ndarray, first: int,
            cluster_max: int) -> tuple[np.ndarray, np.ndarray]:
    """Label the groups of the unlabelled frontier cells reachable from ``seeds`` (labels ``first``, ``first``
    + 1, ...). Returns every new group's cells, concatenated, and the group boundaries (``k``-th group:
    ``cells[bounds[k]:bounds[k + 1]]``, label ``first + k``). A group of more than ``cluster_max`` cells is
    given in breadth-first order from its smallest flat index (the order ``find_clusters`` splits it along),
    a smaller one in any order."""
    out = np.empty(len(seeds), dtype=np.int64)
    bounds = np.empty(len(seeds) + 1, dtype=np.int64)
    bounds[0] = 0
    groups = 0
    end = 0
    for i in range(len(seeds)):
        s = seeds[i]
        if not mask[s] or labels[s] != 0:
            continue
        lab = first + groups
        stop = walk(mask, labels, rows, cols, s, lab, out, end, True)
        if stop - end > cluster_max:
            low = out[end]
            for j in range(end + 1, stop):
                low = min(low, out[j])
            for j in range(end, stop):
                labels[out[j]] = 0
            walk(mask, labels, rows, cols, low, lab, out, end, True)
        end = stop
        groups += 1
        bounds[groups] = end
    return out[:end], bounds[:groups + 1]


@njit(cache=True)
def target(cells: np.ndarray, cols: int) -> tuple[int, int]:
    """A piece's cell nearest its mean, the first on ties: ``agents.frontiers._target`` bit for bit (the sums
    of integer coordinates are exact in float64 whatever the order, so the mean is the same one rounding of
    the exact sum divided by the count, and the rest is the same IEEE arithmetic element by element)."""
    n = len(cells)
    sr = 0.0
    sc = 0.0
    for i in range(n):
        r = cells[i] // cols
        sr += float(r)
        sc += float(cells[i] - r * cols)
    mr = sr / n
    mc = sc / n
    best = 0
    best_d = np.inf
    for i in range(n):
        r = cells[i] // cols
        dr = float(r) - mr
        dc = float(cells[i] - r * cols) - mc
        d = dr * dr + dc * dc
        if d < best_d:
            best = i
            best_d = d
    r = cells[best] // cols
    return r, cells[best] - r * cols


def warm_up() -> None:
    """Compile (or load from cache) the kernels once."""
    grid = np.array([0, -1, 0, 0], dtype=np.int8)
    mask = np.zeros(4, dtype=np.bool_)
    labels = np.zeros(4, dtype=np.int32)
    flips = update_mask(grid, 2, 2, mask, np.arange(4, dtype=np.int64))
    touched_labels(labels, 2, 2, flips)
    relabel(mask, labels, 2, 2, flips, 1, 1)
    cells = np.arange(3, dtype=np.int64)
    cells.flags.writeable = False  # as FrontierClusters keeps its pieces: numba compiles read-only arrays apart
    target(cells, 2)
