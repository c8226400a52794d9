"""MHM's Wavefront Expansion geometry (Mukhija et al., section III-A), as plain functions on belief grids.

A node at cell ``p`` owns a *cell*: the area within ``r_comm`` of it (section III: "the area within r_comm of
a node is termed as a node cell"). The *cell boundary* is its periphery "just within r_comm". The
*Exploration Wavefront* (EW) of a tree node C_i is the set of boundary points of the leaf cells of its
subtree T_i that have an exploration frontier within the sensor range R_s. The EW is ordered by bearing from
the base station (the ordered set B); the first point is a node position P_i, every point within r_comm of
P_i is removed, and so on until B is empty. The H positions found are hinged only if eq. (1),
``H <= X_available - X_min``, holds.

Distances are Euclidean, in cells (the paper's pixels). Choices where the paper is silent, and why:

- *Within r_comm* is ``d < r_comm`` everywhere (cells, the boundary, the r_comm filter), as eq. (2) writes
  it, so that one rule decides what is in range.
- A cell is the known-free area within r_comm that is 4-connected to the node's position inside that disk:
  a boundary point a robot cannot reach from the node without leaving the cell is no place to hinge.
- The boundary is the cell's points at ``r_comm - 1 <= d < r_comm``: a ring one cell wide, the outermost
  grid cells "just within r_comm".
- A frontier is a known-free cell 4-adjacent to an unknown one (the project's, ``agents/frontiers.py``); a
  boundary point has one "within R_s" when the Euclidean distance is ``<= R_s``, walls ignored (the paper
  says "within a distance R_s").
- Bearing from the base station is measured clockwise from north (row decreasing), in ``[0, 2*pi)``; the
  paper does not say where the sweep starts. Ties (points on one ray) go nearer the base first, then by
  (row, col), so the order is total and a seed reproduces it.
- Points where a node is already hinged are not candidates (two robots cannot share a grid cell).
- ``hinges`` caps H: ``0`` means no cap (MHM); ``1`` keeps only the first position of B, a single hinge per
  iteration, still on the wavefront (a cap, not the paper's SHM baseline: that is ``shm.py``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np

from fleet_emu.agents.frontiers import frontier_mask
from fleet_emu.core.grid import FREE, Cell
from fleet_emu.core.kernels import label


def _window(shape: tuple[int, int], center: Cell, radius: float) -> tuple[slice, slice]:
    """The rows and columns a disk of ``radius`` around ``center`` can touch, clipped to the grid."""
    k = max(0, math.ceil(radius))
    return (slice(max(0, center[0] - k), min(shape[0], center[0] + k + 1)),
            slice(max(0, center[1] - k), min(shape[1], center[1] + k + 1)))


def disk(shape: tuple[int, int], center: Cell, radius: float) -> np.ndarray:
    """Bool mask of the grid cells at Euclidean distance ``< radius`` from ``center``."""
    out = np.zeros(shape, dtype=bool)
    win, inside = disk_window(shape, center, radius)
    out[win] = inside
    return out


def disk_window(shape: tuple[int, int], center: Cell, radius: float) -> tuple[tuple[slice, slice], np.ndarray]:
    """:func:`disk` as the window it can touch and the mask inside that window (no whole-grid array)."""
    rs, cs = _window(shape, center, radius)
    rows, cols = np.ogrid[rs, cs]
    return (rs, cs), (rows - center[0]) ** 2 + (cols - center[1]) ** 2 < radius * radius


def cell_window(grid: np.ndarray, center: Cell, r_comm: float) -> tuple[tuple[slice, slice], np.ndarray]:
    """:func:`cell_area` as the window it can touch and the mask inside that window."""
    (rs, cs), inside = disk_window(grid.shape, center, r_comm)
    inside &= grid[rs, cs] == FREE
    local = (center[0] - rs.start, center[1] - cs.start)
    inside[local] = True
    labels, _ = label(inside)
    return (rs, cs), labels == labels[local]


def cell_area(grid: np.ndarray, center: Cell, r_comm: float) -> np.ndarray:
    """The node cell of a node at ``center``: known-free cells within r_comm, 4-connected to ``center``
    inside the disk (``center`` itself always belongs)."""
    out = np.zeros(grid.shape, dtype=bool)
    win, inside = cell_window(grid, center, r_comm)
    out[win] = inside
    return out


def cell_boundary(grid: np.ndarray, center: Cell, r_comm: float) -> np.ndarray:
    """The cell's boundary points (k x 2 array of cells, row-major order): its cells at
    ``r_comm - 1 <= d < r_comm``."""
    area = cell_area(grid, center, r_comm)
    ring = area & ~disk(grid.shape, center, r_comm - 1.0)
    return np.argwhere(ring)


def frontier_distance(grid: np.ndarray, where: np.ndarray | None = None) -> np.ndarray:
    """Euclidean distance (cells) from every cell to the nearest frontier cell (only those in ``where``, when
    given); ``inf`` with no frontier."""
    mask = frontier_mask(grid) if where is None else frontier_mask(grid) & where
    if not mask.any():
        return np.full(grid.shape, np.inf)
    from scipy import ndimage  # imported on use: only the MHM planner needs it, and it costs 0.4 s to load

    return ndimage.distance_transform_edt(~mask)


def exploration_wavefront(grid: np.ndarray, leaves: Iterable[Cell], r_comm: float, sensor_range: float,
                          fdist: np.ndarray | None = None) -> np.ndarray:
    """The EW of a subtree whose leaf cells have their nodes at ``leaves``: every boundary point of a leaf
    cell with a frontier within ``sensor_range``; unique cells, k x 2, row-major order."""
    if fdist is None:
        fdist = frontier_distance(grid)
    points = [b[fdist[b[:, 0], b[:, 1]] <= sensor_range] for b in (cell_boundary(grid, p, r_comm) for p in leaves)]
    points = [p for p in points if len(p)]
    if not points:
        return np.empty((0, 2), dtype=np.int64)
    return np.unique(np.concatenate(points), axis=0)


def bearing(point: Cell, base: Cell) -> float:
    """Bearing of ``point`` seen from ``base``: clockwise from north (row decreasing), in ``[0, 2*pi)``."""
    b = math.atan2(point[1] - base[1], base[0] - point[0])
    return b + 2 * math.pi if b < 0 else b


def bearing_order(points: Iterable[Sequence[int]], base: Cell) -> list[Cell]:
    """The ordered set B: points by bearing from the base, then nearer first, then by (row, col)."""
    cells = [(int(p[0]), int(p[1])) for p in points]
    return sorted(cells, key=lambda c: (bearing(c, base), math.dist(c, base), c))


def filter_positions(ordered: Sequence[Cell], r_comm: float) -> list[Cell]:
    """Section III-A's r_comm filter: take the first point of B as a node position, drop every point within
    r_comm of it (itself included), repeat until B is empty."""
    left = list(ordered)
    chosen: list[Cell] = []
    while left:
        p = left[0]
        chosen.append(p)
        left = [q for q in left if math.dist(p, q) >= r_comm]
    return chosen


def hinging_allowed(h: int, x_available: int, x_min: int) -> bool:
    """Eq. (1): H hinges are allowed while ``H <= X_available - X_min``."""
    return h <= x_available - x_min


def hinge_positions(grid: np.ndarray, leaves: Sequence[Cell], base: Cell, r_comm: float, sensor_range: float,
                    hinges: int = 0, taken: Iterable[Cell] = (), fdist: np.ndarray | None = None) -> list[Cell]:
    """The node positions one Wavefront Expansion iteration proposes for a subtree with leaf nodes at
    ``leaves``: the EW less the ``taken`` cells, in bearing order, r_comm-filtered, capped at ``hinges``
    (0: no cap). ``fdist``: :func:`frontier_distance` when the caller has it."""
    taken = set(taken)
    ew = [c for c in bearing_order(exploration_wavefront(grid, leaves, r_comm, sensor_range, fdist), base)
          if c not in taken]
    chosen = filter_positions(ew, r_comm)
    return chosen[:hinges] if hinges > 0 else chosen
