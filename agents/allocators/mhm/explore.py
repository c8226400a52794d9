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
- Hinge points are taken greedily the same way: the explorer nearest each position by path distance.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from fleet_emu.agents.allocators.base import robot_order
from fleet_emu.agents.allocators.mhm.wavefront import cell_area, disk
from fleet_emu.agents.frontiers import Cluster, find_clusters
from fleet_emu.core.grid import FREE, MOVES, OCCUPIED, Cell
from fleet_emu.core.kernels import wavefront


def safe_area(grid: np.ndarray, relays: Iterable[Cell], r_comm: float) -> np.ndarray:
    """Known-free cells within r_comm of a relay (a hinged node or the base station), the relays included."""
    mask = np.zeros(grid.shape, dtype=bool)
    for p in relays:
        mask |= disk(grid.shape, p, r_comm)
    return mask & (grid == FREE)


def cells_area(grid: np.ndarray, centers: Iterable[Cell], r_comm: float) -> np.ndarray:
    """The union of the node cells (:func:`cell_area`) of nodes at ``centers``."""
    mask = np.zeros(grid.shape, dtype=bool)
    for p in centers:
        mask |= cell_area(grid, p, r_comm)
    return mask


def near_any(shape: tuple[int, int], centers: Iterable[Cell], radius: float) -> np.ndarray:
    """Cells within ``radius`` (``d <= radius``) of any of ``centers``."""
    mask = np.zeros(shape, dtype=bool)
    for p in centers:
        mask |= disk(shape, p, radius + 1e-6)
    return mask


def path_gaps(passable: np.ndarray, poses: Mapping[str, Cell], targets: Mapping[str, Cell]) -> dict[str, float]:
    """Each robot's path distance over ``passable`` cells to its target (``inf``: no path)."""
    cols = passable.shape[1]
    out: dict[str, float] = {}
    for goal in set(targets.values()):
        dist = wavefront(passable, np.array([goal[0] * cols + goal[1]], dtype=np.int64), -1)
        for r, g in targets.items():
            if g == goal:
                d = dist[poses[r]]
                out[r] = float(d) if d >= 0 else math.inf
    return out


def area_clusters(grid: np.ndarray, area: np.ndarray, cluster_max: int) -> list[Cluster]:
    """The frontier clusters made of frontier cells inside ``area``."""
    clipped = grid.copy()
    clipped[(grid == FREE) & ~area] = OCCUPIED  # a frontier outside the area stops being one
    return find_clusters(clipped, cluster_max)


def descend(dist: np.ndarray, cell: Cell) -> Cell:
    """Follow ``dist`` down from ``cell`` to a source (distance 0), first move in the project's order on ties."""
    rows, cols = dist.shape
    while dist[cell] > 0:
        r, c = cell
        cell = next((r + dr, c + dc) for dr, dc in MOVES
                    if 0 <= r + dr < rows and 0 <= c + dc < cols and 0 <= dist[r + dr, c + dc] < dist[r, c])
    return cell


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
                     explorers: Mapping[str, Cell]) -> dict[str, tuple[Cell, int]]:
    """Goals for the explorers over ``passable`` cells, with each one's path distance to it: one explorer per
    cluster, nearest pairs first, then the rest to their nearest cluster; an explorer that reaches no cluster
    gets none."""
    dists = [wavefront(passable, c.cells.astype(np.int64), -1) for c in clusters]
    taken, pairs = _greedy(dists, explorers)
    for _, _, j, r in pairs:  # sorted by distance: the first pair of a robot is its nearest cluster
        taken.setdefault(r, j)
    return {r: (descend(dists[j], explorers[r]), int(dists[j][explorers[r]]))
            for r, j in sorted(taken.items(), key=lambda kv: robot_order(kv[0]))}


def assign_positions(passable: np.ndarray, positions: Sequence[Cell], explorers: Mapping[str, Cell]
                     ) -> dict[str, Cell]:
    """An explorer for each hinge position it can reach over ``passable`` cells, nearest pairs first;
    positions no free explorer reaches are left out."""
    cols = passable.shape[1]
    dists = [wavefront(passable, np.array([p[0] * cols + p[1]], dtype=np.int64), -1) for p in positions]
    taken, _ = _greedy(dists, explorers)
    return {r: positions[j] for r, j in sorted(taken.items(), key=lambda kv: kv[1])}
