"""Yan's tasks: the regions of a topological segmentation of the known free space (Yan et al. 2011, section 4.2).

Yan et al.: "The task is to explore an unknown region which can be identified by topologizing the grid map of the
environment (Wurm et al., 2008) ... The robot is capable to extract critical points (Thrun, 1998) for a given map
to distinguish corridors, doorways and rooms", and a task's cost is the distance "between its current position
and target position (for example, a critical point)". The paper gives no more; what we chose, once:

1. **Clearance and basis points** (Thrun 1998, section 4's Voronoi diagram). ``clearance`` is each cell's
   Euclidean distance to the nearest *occupied* cell of the belief, and its *basis point* that cell
   (``scipy.ndimage.distance_transform_edt``). Unknown cells count as open: an opening onto the unknown is not a
   narrowing.
2. **Critical points** (Thrun's "critical points" on the Voronoi diagram, which Wurm et al. 2008 use to segment
   the explored map). A known-free cell ``c`` is on the (grid) Voronoi diagram when a neighbour's basis point
   ``q``, about as near to ``c`` as its own ``p`` (within a cell more), lies on the far side of ``c``: the angle
   ``p c q`` is at least 120 degrees (``OPPOSITE``) and ``|p - q| >= 2`` (a corner's bisector, whose basis points
   are 90 degrees apart, is not). ``c`` is *critical* when its clearance is a local minimum along the passage
   (the direction perpendicular to ``p - q``: not above either next cell, and below one of them) and the passage
   widens on both sides: within ``REACH`` cells each way, the clearance of *known* space (unknown counted as
   occupied here: only what is sure to be wider counts, so that a critical point once found stays as more is
   seen) reaches ``clearance(c) + WIDEN``. A corridor of even width has none; a door between a corridor and a
   room has one. A passage at most two cells wide (``clearance(c) <= NARROW``) need only widen on one side, and
   need not be below either next cell: a door onto a hallway as narrow as itself (the autolab map's) is no
   local minimum of the clearance, yet a doorway; and such a hallway is cut where it opens into a room.
3. **Critical lines and regions** (Thrun's "critical lines"). Each critical point is joined to its two basis
   points by straight lines; the known-free cells off those lines fall into 4-connected components, the
   *regions*; a component of fewer than ``MIN_REGION`` cells is not one. Each line cell then joins a region
   it touches (the one of higher label), so every known-free cell connected to a region belongs to one.
4. **Tasks.** A region holding frontier cells is a task (:class:`RegionTask`): ``cells`` are its frontier
   cells (so the wavefront cost, eq. 2, is the distance to the nearest of them, which a robot outside the
   region reaches through its entry), ``target`` its *entry point*: of the critical points on its border, the
   one of least clearance (then least flat index), and the region's cell nearest it off the critical lines
   (a line cell joins one of the regions it touches, which may change as labels do); a region without one
   (the region the robots start in, before any door is seen) is entered where it is, its target the frontier
   cell nearest its frontier cells' mean, as a frontier cluster's. ``region`` lists its cells, so that a
   robot holding a task knows it while the region is explored, wherever its frontier goes.

The segmentation is a few passes over the grid (two distance transforms, shifted comparisons, one labelling):
about 3 ms of CPU on the built-in office and on autolab at 0.5 m cells, mostly numpy's per-call overhead
(``benchmarks/regions_picture.py`` prints it), so it is redone whole once per belief (:class:`RegionTasks` keeps
the last) rather than updated.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from fleet_emu.agents.frontiers import Cluster, _target, frontier_mask
from fleet_emu.core.grid import FREE, OCCUPIED, Cell

#: A Voronoi cell's two basis points lie at least 120 degrees apart as seen from it (the cosine at most this).
OPPOSITE = -0.5
#: Cells looked at along the passage on each side of a candidate critical point.
REACH = 6
#: Clearance (cells) the passage must gain on both sides for a critical point: a door two cells narrower.
WIDEN = 0.5
#: A passage of at most this clearance (cells: two cells wide) is cut where it opens into a wider space, even
#: when it does not widen on its other side (a door onto a hallway as narrow as it).
NARROW = 1.5
#: Components smaller than this (cells) between critical lines are no region of their own.
MIN_REGION = 4

_EIGHT = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))
_FOUR = ((-1, 0), (1, 0), (0, -1), (0, 1))


@dataclasses.dataclass(frozen=True, eq=False)
class RegionTask(Cluster):
    """A region to explore: ``cells`` its frontier cells, ``target`` its entry point, ``region`` its cells
    (flat indices, ascending)."""

    region: np.ndarray


@dataclasses.dataclass(frozen=True, eq=False)
class Regions:
    """A segmentation: ``labels`` (int32, 0 off every region) numbered by smallest flat index from 1,
    ``critical`` the critical points (k x 2), ``cuts`` the critical lines' cells, ``clearance``."""

    labels: np.ndarray
    count: int
    critical: np.ndarray
    cuts: np.ndarray
    clearance: np.ndarray


def segment(grid: np.ndarray) -> Regions:
    """The regions of a belief grid (module docstring, steps 1-3)."""
    from scipy import ndimage  # imported on use: only the region allocators need it

    open_ = grid != OCCUPIED
    clearance, basis = ndimage.distance_transform_edt(open_, return_indices=True)
    free = grid == FREE
    certain = ndimage.distance_transform_edt(free)  # unknown as occupied: what is known to be that wide
    critical, ends = _critical_points(free, open_, clearance, basis, certain)
    cuts = _lines(critical, ends, open_)
    labels, count = ndimage.label(free & ~cuts)
    sizes = np.bincount(labels.ravel(), minlength=count + 1)
    keep = sizes >= MIN_REGION
    keep[0] = False
    remap = np.zeros(count + 1, dtype=np.int32)
    remap[keep] = np.arange(1, int(keep.sum()) + 1, dtype=np.int32)
    labels = remap[labels]
    count = int(keep.sum())
    _spread(labels, free)
    rest, more = ndimage.label(free & (labels == 0))  # pieces touching no region: regions of their own
    if more:
        labels = np.where(rest > 0, rest + count, labels).astype(np.int32)
    return Regions(labels=labels, count=count + more, critical=critical, cuts=cuts & free, clearance=clearance)


def _shifted(a: np.ndarray, dr: int, dc: int, fill: float | bool) -> np.ndarray:
    """``a`` moved so that ``out[r, c] = a[r + dr, c + dc]`` (``fill`` off the grid)."""
    out = np.full_like(a, fill)
    rows, cols = a.shape
    out[max(0, -dr):rows - max(0, dr), max(0, -dc):cols - max(0, dc)] = \
        a[max(0, dr):rows - max(0, -dr), max(0, dc):cols - max(0, -dc)]
    return out


def _critical_points(free: np.ndarray, open_: np.ndarray, clearance: np.ndarray, basis: np.ndarray,
                     certain: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The critical points (k x 2) and their basis points ((k x 2) p, (k x 2) q, stacked as k x 4)."""
    br, bc = basis[0].astype(np.float64), basis[1].astype(np.float64)
    rr, cc = np.indices(clearance.shape)
    pr, pc = br - rr, bc - cc  # c to its basis point p
    reach2 = (clearance + 1.0) ** 2
    cos = np.ones_like(clearance)
    qr, qc = br.copy(), bc.copy()
    for dr, dc in _EIGHT:  # the neighbour's basis point q most opposite p, about as near to c as p
        nr, nc = _shifted(br, dr, dc, 0.0), _shifted(bc, dr, dc, 0.0)
        vr, vc = nr - rr, nc - cc
        n2 = vr ** 2 + vc ** 2
        ok = _shifted(open_, dr, dc, False) & (n2 <= reach2) & (n2 > 0) & (clearance > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            k = np.where(ok, (vr * pr + vc * pc) / np.sqrt(n2 * (pr ** 2 + pc ** 2)), 1.0)
        better = k < cos
        cos = np.where(better, k, cos)
        qr, qc = np.where(better, nr, qr), np.where(better, nc, qc)
    sep2 = (qr - br) ** 2 + (qc - bc) ** 2
    cand = free & (cos <= OPPOSITE) & (sep2 >= 4.0)
    r, c = np.nonzero(cand)
    if not len(r):
        return np.zeros((0, 2), dtype=np.int64), np.zeros((0, 4), dtype=np.int64)
    p = np.stack([br[r, c], bc[r, c]], axis=1)
    q = np.stack([qr[r, c], qc[r, c]], axis=1)
    u = (q - p) / np.linalg.norm(q - p, axis=1, keepdims=True)
    v = np.stack([-u[:, 1], u[:, 0]], axis=1)  # along the passage
    here = clearance[r, c]
    ok = np.ones(len(r), dtype=bool)
    rises = np.zeros(len(r), dtype=bool)
    for sign in (1.0, -1.0):  # a local minimum along the passage: not above either next cell, below one
        step = _sample(clearance, open_, r + sign * v[:, 0], c + sign * v[:, 1], ok)
        ok &= step >= here
        rises |= step > here
    ok &= rises | (here <= NARROW)
    r, c, u, v, here, p, q = r[ok], c[ok], u[ok], v[ok], here[ok], p[ok], q[ok]
    wider = [_widest(certain, open_, r, c, sign * v, u, here) >= here + WIDEN for sign in (1.0, -1.0)]
    ok = (wider[0] & wider[1]) | ((wider[0] | wider[1]) & (here <= NARROW))  # a narrow passage's mouth too
    cells = np.stack([r, c], axis=1)[ok]
    ends = np.concatenate([p[ok], q[ok]], axis=1).astype(np.int64)
    return cells.astype(np.int64), ends


def _widest(clearance: np.ndarray, open_: np.ndarray, r: np.ndarray, c: np.ndarray, v: np.ndarray,
            u: np.ndarray, here: np.ndarray) -> np.ndarray:
    """The most ``clearance`` within ``REACH`` steps along ``v`` from each ``(r, c)`` (before an occupied cell or
    the grid's edge), looking across the passage (along ``u``) up to its half-width ``here`` plus one cell each
    way (at most ``REACH``), up to a wall; -inf when the first step is blocked."""
    live = np.ones(len(r), dtype=bool)
    widest = np.full(len(r), -np.inf)
    half = np.minimum(np.ceil(here).astype(np.int64) + 1, REACH)
    for k in range(1, REACH + 1):
        sr, sc = r + k * v[:, 0], c + k * v[:, 1]
        d = _sample(clearance, open_, sr, sc, live)
        live &= d > -np.inf
        widest = np.maximum(widest, d)
        for sign in (1.0, -1.0):
            side = live.copy()
            for j in range(1, int(half.max(initial=0)) + 1):
                side &= half >= j
                d = _sample(clearance, open_, sr + sign * j * u[:, 0], sc + sign * j * u[:, 1], side)
                side &= d > -np.inf
                widest = np.maximum(widest, d)
    return widest


def _sample(clearance: np.ndarray, open_: np.ndarray, fr: np.ndarray, fc: np.ndarray, live: np.ndarray
            ) -> np.ndarray:
    """Clearance at the cells nearest ``(fr, fc)`` where ``live``; -inf elsewhere, off the grid or occupied."""
    rows, cols = clearance.shape
    sr, sc = np.rint(fr).astype(np.int64), np.rint(fc).astype(np.int64)
    ok = live & (sr >= 0) & (sr < rows) & (sc >= 0) & (sc < cols)
    ok[ok] &= open_[sr[ok], sc[ok]]
    d = np.full(len(fr), -np.inf)
    d[ok] = clearance[sr[ok], sc[ok]]
    return d


def _lines(critical: np.ndarray, ends: np.ndarray, open_: np.ndarray) -> np.ndarray:
    """The critical lines' open cells: each critical point joined to its two basis points."""
    cuts = np.zeros(open_.shape, dtype=bool)
    for (r, c), (pr, pc, qr, qc) in zip(critical.tolist(), ends.tolist(), strict=True):
        for er, ec in ((pr, pc), (qr, qc)):
            n = max(abs(er - r), abs(ec - c), 1)
            for k in range(n + 1):
                cuts[round(r + k * (er - r) / n), round(c + k * (ec - c) / n)] = True
    return cuts & open_


def _spread(labels: np.ndarray, free: np.ndarray) -> None:
    """Give every unlabelled free cell 4-connected to a region a label (the highest it touches), in place."""
    todo = free & (labels == 0)
    while todo.any():
        near = np.zeros_like(labels)
        for dr, dc in _FOUR:
            near = np.maximum(near, _shifted(labels, dr, dc, 0))
        take = todo & (near > 0)
        if not take.any():
            return
        labels[take] = near[take]
        todo &= ~take


def region_tasks(grid: np.ndarray, regions: Regions) -> list[RegionTask]:
    """The tasks of a segmentation (module docstring, step 4), ordered by their regions' labels."""
    cols = grid.shape[1]
    flat = regions.labels.ravel()
    frontier = frontier_mask(grid).ravel() & (flat > 0)
    idx = np.flatnonzero(frontier)
    if not len(idx):
        return []
    entries = _entries(regions)
    cuts = regions.cuts.ravel()
    order = np.argsort(flat, kind="stable")
    bounds = np.searchsorted(flat[order], np.arange(regions.count + 2))
    tasks: list[RegionTask] = []
    for k in np.unique(flat[idx]).tolist():
        cells = idx[flat[idx] == k].astype(np.int64)
        region = np.sort(order[bounds[k]:bounds[k + 1]]).astype(np.int64)
        cells.flags.writeable = region.flags.writeable = False
        entry = entries.get(k)
        inside = region[~cuts[region]]  # off the critical lines: a cell no other region can take
        target = _target(cells, cols) if entry is None else _nearest(inside if len(inside) else region, entry, cols)
        tasks.append(RegionTask(cells=cells, target=target, region=region))
    return tasks


def _entries(regions: Regions) -> dict[int, Cell]:
    """Each region's entry critical point: of those whose line (or the cells next to it) touches the region, the
    one of least clearance, then least flat index."""
    labels, rows, cols = regions.labels, *regions.labels.shape
    ranked = sorted(regions.critical.tolist(), key=lambda rc: (float(regions.clearance[rc[0], rc[1]]),
                                                                rc[0] * cols + rc[1]))
    out: dict[int, Cell] = {}
    for r, c in ranked:
        window = labels[max(0, r - 1):min(rows, r + 2), max(0, c - 1):min(cols, c + 2)]
        for k in np.unique(window[window > 0]).tolist():
            out.setdefault(int(k), (int(r), int(c)))
    return out


def _nearest(region: np.ndarray, cell: Cell, cols: int) -> Cell:
    """The region's cell nearest ``cell`` (least flat index on ties)."""
    rr, cc = np.divmod(region, cols)
    k = int(np.argmin((rr - cell[0]) ** 2 + (cc - cell[1]) ** 2))
    return (int(rr[k]), int(cc[k]))


def holding(tasks: list[Cluster], cell: Cell, cols: int) -> int | None:
    """The index of the region task whose region holds ``cell`` (None when none does, or the tasks are not
    region tasks)."""
    index = cell[0] * cols + cell[1]
    for j, task in enumerate(tasks):
        region = getattr(task, "region", None)
        if region is not None:
            k = int(np.searchsorted(region, index))
            if k < len(region) and region[k] == index:
                return j
    return None


class RegionTasks:
    """One robot's region tasks, segmented at most once per belief: the last grid and its tasks are kept."""

    def __init__(self) -> None:
        self.grid: np.ndarray | None = None
        self.tasks: list[RegionTask] = []
        self.segmentations = 0  # how many times a grid was segmented
        self.cpu_ms = 0.0  # and the thread CPU it took (benchmarks/yan_regions.py prints it)

    def of(self, grid: np.ndarray) -> list[RegionTask]:
        """The region tasks of ``grid``."""
        if self.grid is None or self.grid.shape != grid.shape or not np.array_equal(self.grid, grid):
            t0 = time.thread_time()
            self.tasks = region_tasks(grid, segment(grid))
            self.grid = grid.copy()
            self.segmentations += 1
            self.cpu_ms += (time.thread_time() - t0) * 1000.0
        return self.tasks
