"""How MHM's explorers explore a set of node cells and reach hinge points, as plain functions.

Section III says only that a node cell "is explored using frontier exploration method with all the available
explorer robots", citing Yamauchi's frontier exploration [11], and that an explorer is never farther than
r_comm from its closest node. Choices, and why:

- Explorers move only inside the *safe area*: known-free cells within r_comm (``d < r_comm``) of a hinged
  node or the base station. Every path the base plans stays in it, so an explorer is in range of a relay at
  every step; a robot that does not hear a new order keeps to its last goal inside it.
- The frontiers of the cells being explored are the frontier clusters (the project's, MinPos section 4.1)
  whose cells lie in those cells' areas; distances are breadth-first over the safe area.
- The base plans for everyone, so it coordinates: explorers take clusters greedily by path distance, one
  explorer per cluster (ties: lower robot id, then lower cluster index); explorers left over go to their
  nearest reachable cluster. Each goal is the cluster cell nearest the explorer (down the cluster's
  wavefront), not its centre, which may be on the far side.
- An explorer keeps its goal while that cell is still a frontier cell (a cluster holds it) of the safe area
  the explorer can reach, as Yamauchi's robots navigate to their frontier until they reach it; only the
  others are assigned, over the clusters nobody keeps, and an explorer left without a cluster of its own goes
  to its nearest cluster, held or not (it would otherwise wait). Re-assigning every explorer at every tick let
  two of them trade goals back and forth as they moved (an explorer's goal flipping A, B, A within a few
  ticks, ten times per hundred robot-ticks on a small map), the limit cycle of any plan re-solved from
  scratch. Kept goals rely on the robot driving to a goal its own map does not know yet (``robot.py``).
- Hinge points are taken greedily the same way: the explorer nearest each position by path distance. While
  the chosen explorers drive there, an idle explorer standing on one's path makes way (:func:`make_way`):
  with many robots an explorer holding in a doorway shut a room to the robot sent to hinge in it (50 robots on
  the office: a quarter of the run was spent in such waits).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from fleet_emu.agents.allocators.interface import robot_order
from fleet_emu.agents.allocators.mhm.wavefront import cell_window, disk_window
from fleet_emu.agents.frontiers import Cluster, find_clusters
from fleet_emu.core.grid import FREE, MOVES, OCCUPIED, Cell
from fleet_emu.core.kernels import wavefront

# Every mask below is whole-grid, but only the window around the cells it is made of is written or read: the
# grid may be far larger than the area the robots work in (an open map of 1,200 x 1,200 cells).
Box = tuple[int, int, int, int]  # rows r0 <= r < r1, columns c0 <= c < c1


def bounds(mask: np.ndarray, cells: np.ndarray | None = None) -> Box:
    """The smallest box holding ``mask``'s cells and ``cells`` (k x 2), at least one cell."""
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask[rows[0]:rows[-1] + 1].any(axis=0)) if len(rows) else rows
    lo = [int(rows[0]), int(cols[0])] if len(rows) else [mask.shape[0], mask.shape[1]]
    hi = [int(rows[-1]) + 1, int(cols[-1]) + 1] if len(rows) else [0, 0]
    if cells is not None and len(cells):
        lo = [min(lo[0], int(cells[:, 0].min())), min(lo[1], int(cells[:, 1].min()))]
        hi = [max(hi[0], int(cells[:, 0].max()) + 1), max(hi[1], int(cells[:, 1].max()) + 1)]
    if hi[0] <= lo[0]:
        return (0, 0, 1, 1)
    return (lo[0], lo[1], hi[0], hi[1])


def boxed_wavefront(passable: np.ndarray, box: Box, sources: np.ndarray) -> np.ndarray:
    """:func:`~fleet_emu.core.kernels.wavefront` from ``sources`` (k x 2 cells, inside ``box``) over the
    ``passable`` cells inside ``box``, as the box's distance array: equal to the whole grid's wherever
    ``box`` holds every passable cell."""
    r0, c0, r1, c1 = box
    local = np.ascontiguousarray(passable[r0:r1, c0:c1])
    flat = (sources[:, 0] - r0) * (c1 - c0) + (sources[:, 1] - c0)
    return wavefront(local, flat.astype(np.int64), -1)


def _at(dist: np.ndarray, box: Box, cell: Cell) -> int:
    """``dist`` (a box's) at the grid cell ``cell``; -1 outside the box."""
    r, c = cell[0] - box[0], cell[1] - box[1]
    return int(dist[r, c]) if 0 <= r < dist.shape[0] and 0 <= c < dist.shape[1] else -1


def _or_windows(shape: tuple[int, int], parts: Iterable[tuple[tuple[slice, slice], np.ndarray]]) -> np.ndarray:
    mask = np.zeros(shape, dtype=bool)
    for win, inside in parts:
        mask[win] |= inside
    return mask


def _relay_disks(grid: np.ndarray, relays: Iterable[Cell], r_comm: float, known_free: bool) -> np.ndarray:
    """The cells within r_comm of a relay that ``grid`` knows to be free (``known_free``) or does not know to be
    occupied, read only in the box around the relays' disks."""
    relays = list(relays)
    mask = _or_windows(grid.shape, (disk_window(grid.shape, p, r_comm) for p in relays))
    if relays:
        k = math.ceil(r_comm)
        rc = np.array(relays)
        r0, c0 = np.maximum(rc.min(axis=0) - k, 0)
        r1, c1 = rc.max(axis=0) + k + 1
        window = grid[r0:r1, c0:c1]
        mask[r0:r1, c0:c1] &= (window == FREE) if known_free else (window != OCCUPIED)
    return mask


def safe_area(grid: np.ndarray, relays: Iterable[Cell], r_comm: float) -> np.ndarray:
    """Known-free cells within r_comm of a relay (a hinged node or the base station), the relays included."""
    return _relay_disks(grid, relays, r_comm, known_free=True)


def reach_area(belief: np.ndarray, relays: Iterable[Cell], r_comm: float) -> np.ndarray:
    """The cells within r_comm of a relay that ``belief`` does not know to be occupied (unknown cells
    included), the relays too: where an explorer may drive toward a goal the base's map reaches but its own
    map does not know yet (``robot.py``)."""
    relays = list(relays)
    mask = _relay_disks(belief, relays, r_comm, known_free=False)
    for p in relays:
        mask[p] = True
    return mask


def cells_area(grid: np.ndarray, centers: Iterable[Cell], r_comm: float) -> np.ndarray:
    """The union of the node cells (:func:`~.wavefront.cell_area`) of nodes at ``centers``."""
    return _or_windows(grid.shape, (cell_window(grid, p, r_comm) for p in centers))


def near_any(shape: tuple[int, int], centers: Iterable[Cell], radius: float) -> np.ndarray:
    """Cells within ``radius`` (``d <= radius``) of any of ``centers``."""
    return _or_windows(shape, (disk_window(shape, p, radius + 1e-6) for p in centers))


def path_gaps(passable: np.ndarray, poses: Mapping[str, Cell], targets: Mapping[str, Cell]) -> dict[str, float]:
    """Each robot's path distance over ``passable`` cells to its target (``inf``: no path)."""
    out: dict[str, float] = {}
    if not targets:
        return out
    box = bounds(passable, np.array(list(targets.values())))
    for goal in set(targets.values()):
        dist = boxed_wavefront(passable, box, np.array([goal]))
        for r, g in targets.items():
            if g == goal:
                d = _at(dist, box, poses[r])
                out[r] = float(d) if d >= 0 else math.inf
    return out


def area_clusters(grid: np.ndarray, area: np.ndarray, cluster_max: int) -> list[Cluster]:
    """The frontier clusters made of frontier cells inside ``area``."""
    if not area.any():
        return []
    r0, c0, r1, c1 = bounds(area)  # the area and its 4-neighbours: frontiers are the same as on the whole grid
    r0, c0, r1, c1 = max(0, r0 - 1), max(0, c0 - 1), min(grid.shape[0], r1 + 1), min(grid.shape[1], c1 + 1)
    clipped = grid[r0:r1, c0:c1].copy()
    clipped[(clipped == FREE) & ~area[r0:r1, c0:c1]] = OCCUPIED  # a frontier outside the area stops being one
    width, cols = c1 - c0, grid.shape[1]
    out = []
    for c in find_clusters(clipped, cluster_max):  # a box's raster order is the grid's: the same clusters
        rows, cs = np.divmod(c.cells, width)
        out.append(Cluster(cells=(rows + r0) * cols + cs + c0, target=(c.target[0] + r0, c.target[1] + c0)))
    return out


def _path(dist: np.ndarray, cell: Cell) -> list[Cell]:
    """The cells down ``dist`` from ``cell`` to its source, both included: first move in the project's order on ties."""
    rows, cols = dist.shape
    out = [cell]
    while dist[cell] > 0:
        r, c = cell
        cell = next((r + dr, c + dc) for dr, dc in MOVES
                    if 0 <= r + dr < rows and 0 <= c + dc < cols and 0 <= dist[r + dr, c + dc] < dist[r, c])
        out.append(cell)
    return out


def descend(dist: np.ndarray, cell: Cell) -> Cell:
    """Follow ``dist`` down from ``cell`` to a source (distance 0), first move in the project's order on ties."""
    return _path(dist, cell)[-1]


def _greedy(dists: Sequence[np.ndarray], robots: Mapping[str, Cell]) -> tuple[dict[str, int], list[tuple]]:
    """One robot per source, nearest pairs first; the reachable pairs too."""
    pairs = sorted((int(wf[cell]), robot_order(r), j, r) for j, wf in enumerate(dists)
                   for r, cell in robots.items() if wf[cell] >= 0)
    taken: dict[str, int] = {}
    used: set[int] = set()
    for _, _, j, r in pairs:
        if r not in taken and j not in used:
            taken[r] = j
            used.add(j)
    return taken, pairs


def assign_explorers(grid: np.ndarray, passable: np.ndarray, clusters: Sequence[Cluster],
                     explorers: Mapping[str, Cell], held: Mapping[str, Cell] | None = None
                     ) -> dict[str, tuple[Cell, int]]:
    """Goals for the explorers over ``passable`` cells, with each one's path distance to it. An explorer whose
    goal in ``held`` (the previous goals) a cluster still holds, and that it reaches, keeps it; the others take
    one cluster each among the rest, nearest pairs first, then any left over its nearest cluster (held or not,
    as before any was kept: an explorer never waits for lack of a cluster of its own); an explorer that reaches
    no cluster gets none."""
    cols = passable.shape[1]
    sources = [np.column_stack(np.divmod(c.cells, cols)) for c in clusters]
    box = bounds(passable, np.concatenate(sources) if sources else None)
    dists = [boxed_wavefront(passable, box, s) for s in sources]
    local = _inside(explorers, box)
    kept = _kept(clusters, dists, local, {r: g for r, g in (held or {}).items() if passable[g]}, box, cols)
    free = {r: c for r, c in local.items() if r not in kept}
    open_ = [i for i in range(len(dists)) if i not in {j for j, _ in kept.values()}]
    taken, _ = _greedy([dists[i] for i in open_], free)
    taken = {r: open_[k] for r, k in taken.items()}
    _, pairs = _greedy(dists, free)
    for _, _, j, r in pairs:  # sorted by distance: the first pair of a robot is its nearest cluster, held or not
        taken.setdefault(r, j)
    goals = {r: (_shift(descend(dists[j], local[r]), box), int(dists[j][local[r]])) for r, j in taken.items()}
    goals |= {r: (goal, int(dists[j][local[r]])) for r, (j, goal) in kept.items()}
    return dict(sorted(goals.items(), key=lambda kv: robot_order(kv[0])))


def _kept(clusters: Sequence[Cluster], dists: Sequence[np.ndarray], local: Mapping[str, Cell],
          held: Mapping[str, Cell], box: Box, cols: int) -> dict[str, tuple[int, Cell]]:
    """The explorers that keep their goal: (cluster, goal) for each whose goal a cluster still holds, that
    reaches that cluster and does not stand on the goal already; one explorer per cluster (the lower robot id)."""
    kept: dict[str, tuple[int, Cell]] = {}
    for r in sorted(held, key=robot_order):
        goal = held[r]
        if r not in local or _shift(local[r], box) == goal:
            continue
        index = goal[0] * cols + goal[1]
        j = next((j for j, c in enumerate(clusters) if _holds(c.cells, index)), None)
        if j is not None and dists[j][local[r]] >= 0 and all(j != k for k, _ in kept.values()):
            kept[r] = (j, goal)
    return kept


def _holds(cells: np.ndarray, index: int) -> bool:
    """Whether the sorted flat indices ``cells`` hold ``index``."""
    k = int(np.searchsorted(cells, index))
    return k < len(cells) and int(cells[k]) == index


def _inside(robots: Mapping[str, Cell], box: Box) -> dict[str, Cell]:
    """The robots standing inside ``box``, at their cells in the box (the others reach nothing in it)."""
    return {r: (c[0] - box[0], c[1] - box[1]) for r, c in robots.items()
            if box[0] <= c[0] < box[2] and box[1] <= c[1] < box[3]}


def _shift(cell: Cell, box: Box) -> Cell:
    return (cell[0] + box[0], cell[1] + box[1])


def make_way(passable: np.ndarray, poses: Mapping[str, Cell], targets: Mapping[str, Cell],
             idle: Iterable[str]) -> dict[str, Cell]:
    """Goals that take the ``idle`` robots standing on the way of a robot driving to its target (``targets``,
    its path over ``passable`` cells) to the nearest passable cell on no such way and free of robots; an idle
    robot that knows no such cell gets none. Without it an explorer that holds in a doorway shuts a room to the
    robot sent to hinge inside it, until the wait's patience runs out."""
    if not targets:
        return {}
    box = bounds(passable, np.array(list(targets.values()) + [poses[r] for r in targets]))
    local = _inside(poses, box)
    way: set[Cell] = set()
    for r, goal in targets.items():
        dist = boxed_wavefront(passable, box, np.array([goal]))
        if r in local and dist[local[r]] > 0:
            way.update(_path(dist, local[r])[1:])
    taken = set(local.values()) | way
    out: dict[str, Cell] = {}
    for r in sorted((r for r in idle if r in local and local[r] in way), key=robot_order):
        dist = boxed_wavefront(passable, box, np.array([poses[r]]))
        free = np.argwhere(dist > 0)
        order = np.lexsort((free[:, 1], free[:, 0], dist[free[:, 0], free[:, 1]]))
        spot = next((tuple(int(v) for v in free[k]) for k in order if tuple(int(v) for v in free[k]) not in taken),
                    None)
        if spot is not None:
            taken.add(spot)  # type: ignore[arg-type]
            out[r] = _shift(spot, box)  # type: ignore[arg-type]
    return out


def assign_positions(passable: np.ndarray, positions: Sequence[Cell], explorers: Mapping[str, Cell]
                     ) -> dict[str, Cell]:
    """An explorer for each hinge position it can reach over ``passable`` cells, nearest pairs first;
    positions no free explorer reaches are left out."""
    box = bounds(passable, np.array(positions) if positions else None)
    dists = [boxed_wavefront(passable, box, np.array([p])) for p in positions]
    taken, _ = _greedy(dists, _inside(explorers, box))
    return {r: positions[j] for r, j in sorted(taken.items(), key=lambda kv: kv[1])}
