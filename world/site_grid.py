"""A measured site drawn as a map: its wall polyline on an occupancy grid, so that the walls between an anchor and
a reading are counted by the emulator's own wall counter (:func:`fleet_emu.core.kernels.count_walls`, the one
netem uses), not by a second implementation of eq. 4.

The grid has square cells of ``resolution`` metres (0.05 by default) over the walls' box and a cell beyond it.
A cell is occupied when the polyline passes through it (every cell the segment touches, so that a wall is
4-connected and no straight line slips through it) or when its centre lies outside the polyline (even-odd rule):
the polyline goes around the free space, so a thick wall drawn as its two faces is one solid run, one wall. A
position whose cell is occupied (an anchor on a wall, a reading against one) is counted from the nearest free
cell. Distances are between true positions in three dimensions (anchor heights count), not between cells.
"""

from __future__ import annotations

import dataclasses
import itertools
import math

import numpy as np

from fleet_emu.core.errors import ConfigError

#: The grid's default cell, in metres.
DEFAULT_RESOLUTION = 0.05
#: The most cells a site's grid may have (a 100 x 100 m site at 5 cm).
MAX_CELLS = 4_000_000


@dataclasses.dataclass(frozen=True)
class SiteGrid:
    """The site's occupancy grid: ``occupied`` (rows along y, columns along x), the world position of cell
    (0, 0)'s corner and the cell size in metres."""

    occupied: np.ndarray
    origin: tuple[float, float]
    resolution: float


def inside(layout: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Whether each point of ``xy`` (K x 2) lies inside the closed polyline ``layout`` (even-odd rule)."""
    x, y = xy[:, 0], xy[:, 1]
    out = np.zeros(len(xy), dtype=bool)
    for (x0, y0), (x1, y1) in itertools.pairwise(layout):
        if y0 == y1:
            continue
        crosses = (y0 > y) != (y1 > y)
        xc = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
        out ^= crosses & (x < xc)
    return out


def draw(layout: np.ndarray, resolution: float = DEFAULT_RESOLUTION) -> SiteGrid:
    """The occupancy grid of the walls ``layout`` (the module docstring says how it is drawn)."""
    if not (math.isfinite(resolution) and 0.001 <= resolution <= 1.0):
        raise ConfigError(f"--resolution must be within [0.001, 1] m (got {resolution!r})")
    lo = layout.min(axis=0) - resolution
    span = layout.max(axis=0) + resolution - lo
    cols, rows = (math.ceil(v / resolution) + 1 for v in span)
    if rows * cols > MAX_CELLS:
        raise ConfigError(f"a {span[0]:.4g} x {span[1]:.4g} m site at {resolution:g} m is {rows * cols} cells, more "
                          f"than {MAX_CELLS}: give a coarser --resolution")
    cy, cx = np.mgrid[0:rows, 0:cols]
    centres = np.stack([lo[0] + (cx.ravel() + 0.5) * resolution, lo[1] + (cy.ravel() + 0.5) * resolution], axis=1)
    occupied = ~inside(layout, centres).reshape(rows, cols)
    for a, b in itertools.pairwise(layout):
        for r, c in _segment_cells((a - lo) / resolution, (b - lo) / resolution):
            if 0 <= r < rows and 0 <= c < cols:
                occupied[r, c] = True
    return SiteGrid(occupied, (float(lo[0]), float(lo[1])), resolution)


def _segment_cells(a: np.ndarray, b: np.ndarray) -> list[tuple[int, int]]:
    """Every cell (row, col) the segment from ``a`` to ``b`` (in cell units, x then y) passes through: a grid
    traversal (Amanatides and Woo 1987), so consecutive cells share a side."""
    c, r = math.floor(a[0]), math.floor(a[1])
    c1, r1 = math.floor(b[0]), math.floor(b[1])
    d = b - a
    step = [1 if v > 0 else -1 for v in d]
    t_max, t_delta = [], []
    for i, pos in enumerate((a[0], a[1])):
        if d[i] == 0:
            t_max.append(math.inf)
            t_delta.append(math.inf)
        else:
            edge = math.floor(pos) + (1 if d[i] > 0 else 0)
            t_max.append((edge - pos) / d[i])
            t_delta.append(abs(1 / d[i]))
    out = [(r, c)]
    for _ in range(abs(c1 - c) + abs(r1 - r)):
        if t_max[0] < t_max[1]:
            c += step[0]
            t_max[0] += t_delta[0]
        else:
            r += step[1]
            t_max[1] += t_delta[1]
        out.append((r, c))
    return out


def cells_of(grid: SiteGrid, xy: np.ndarray) -> tuple[np.ndarray, int]:
    """The cells (K x 2, row and column) of the positions ``xy``, an occupied one replaced by the nearest free
    cell; and how many were moved so."""
    from scipy.ndimage import distance_transform_edt

    shape = np.array(grid.occupied.shape)
    rc = np.floor((xy[:, ::-1] - np.array(grid.origin[::-1])) / grid.resolution).astype(np.int64)
    rc = np.clip(rc, 0, shape - 1)
    blocked = grid.occupied[rc[:, 0], rc[:, 1]]
    if blocked.any():
        if grid.occupied.all():
            raise ConfigError("the walls leave no free cell: is the layout a closed polyline around the free space?")
        _, (near_r, near_c) = distance_transform_edt(grid.occupied, return_indices=True)
        moved = rc[blocked]
        rc[blocked] = np.stack([near_r[moved[:, 0], moved[:, 1]], near_c[moved[:, 0], moved[:, 1]]], axis=1)
    return rc, int(blocked.sum())


@dataclasses.dataclass(frozen=True)
class Geometry:
    """Every (position, anchor) pair's distance in metres (K x N, in three dimensions) and the walls between
    them (K x N, counted on the grid by the emulator's wall counter); ``moved``: positions counted from a
    nearby free cell because theirs was a wall."""

    distance: np.ndarray
    walls: np.ndarray
    moved: int


def geometry(grid: SiteGrid, anchors: np.ndarray, xy: np.ndarray, z: np.ndarray) -> Geometry:
    """The distances and wall counts between the positions ``xy`` (heights ``z``) and the ``anchors`` (N x 3)."""
    from fleet_emu.core.kernels import count_walls  # numba: imported on first use

    cells, moved = cells_of(grid, xy)
    anchor_cells, moved_anchors = cells_of(grid, anchors[:, :2])
    dx = xy[:, None, 0] - anchors[None, :, 0]
    dy = xy[:, None, 1] - anchors[None, :, 1]
    dz = z[:, None] - anchors[None, :, 2]
    distance = np.sqrt(dx * dx + dy * dy + dz * dz)
    walls = np.zeros(distance.shape, dtype=np.int64)
    occ = np.ascontiguousarray(grid.occupied)
    for j, (ar, ac) in enumerate(anchor_cells):
        for i, (r, c) in enumerate(cells):
            walls[i, j] = count_walls(occ, int(ar), int(ac), int(r), int(c))
    return Geometry(distance, walls, moved + moved_anchors)
