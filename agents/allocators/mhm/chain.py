"""MHM's phase 2 (Mukhija et al., section III-D, steps 8-10): the frontier closest to the base station and
the chain of nodes that reaches it.

Choices where the paper is silent, and why:

- "Closest to the base station" is the path distance over known-free cells, not the straight line: the
  chain is made of robots that drive there, and a frontier behind a wall is far for them. A frontier no
  known-free path reaches is out of reach (section III: "all the frontiers are out of reach"). Ties go to the
  lowest (row, col). The distance is the octile one (8-connected), and the hop path is its shortest path
  pulled taut into straight segments (``geodesic``): a 4-connected path would measure Manhattan distances,
  and a chain along it would need up to 1.41 times the nodes on a diagonal (the reach of a fleet a diamond
  instead of a disc). :func:`path_from_base` (one 4-connected shortest path read back down a wavefront) is
  the hop path the planner used before that.
- Nodes are placed greedily along that path: from the last node (the base first), the next node is the
  farthest point of the path such that every point of the path up to it is within r_comm of the last node.
  A robot driving along the path is then always in range of a node, and consecutive nodes are in range of
  each other. The last node stands on the frontier cell itself: the "node to be hinged just before the
  frontier" whose cell C_f the second phase expands.
- Step 10's test ``n_h < R_t`` counts every node of L_h, C_f included, and not the base station.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from fleet_emu.agents.allocators.mhm.geodesic import Geodesic
from fleet_emu.agents.frontiers import frontier_mask
from fleet_emu.core.grid import FREE, MOVES, Cell
from fleet_emu.core.kernels import wavefront


def base_distance(grid: np.ndarray, base: Cell) -> np.ndarray:
    """Breadth-first path distance from the base over known-free cells; -1 where no path reaches."""
    source = np.array([base[0] * grid.shape[1] + base[1]], dtype=np.int64)
    return wavefront(grid == FREE, source, -1)


def closest_frontier(grid: np.ndarray, base: Cell, dist: np.ndarray | None = None,
                     exclude: Iterable[Cell] = ()) -> Cell | None:
    """Step 8: the reachable frontier cell nearest the base station by path (``dist``: a path distance from
    the base, negative where unreached; by default :func:`base_distance`), ``exclude`` left out; None when
    there is none."""
    if dist is None:
        dist = base_distance(grid, base)
    cand = frontier_mask(grid) & (dist >= 0)
    for c in exclude:
        cand[c] = False
    if not cand.any():
        return None
    cells = np.argwhere(cand)
    d = dist[cand]
    k = int(np.lexsort((cells[:, 1], cells[:, 0], d))[0])
    return (int(cells[k, 0]), int(cells[k, 1]))


def path_from_base(dist: np.ndarray, goal: Cell) -> list[Cell]:
    """A shortest path from the base (distance 0) to ``goal``, read back down the wavefront ``dist``."""
    if dist[goal] < 0:
        raise ValueError(f"{goal} is not reachable from the base")
    path = [goal]
    rows, cols = dist.shape
    while dist[path[-1]] > 0:
        r, c = path[-1]
        for dr, dc in MOVES:
            n = (r + dr, c + dc)
            if 0 <= n[0] < rows and 0 <= n[1] < cols and dist[n] == dist[r, c] - 1:
                path.append(n)
                break
    return path[::-1]


def chain_positions(path: list[Cell], r_comm: float) -> list[Cell]:
    """Step 9's L_h: node positions along ``path`` (base first, frontier last), in hop order from the base,
    the base itself left out; the last one is the path's end."""
    nodes: list[Cell] = []
    last = path[0]
    k = 0
    while k < len(path) - 1:
        j = k
        while j + 1 < len(path) and math.dist(path[j + 1], last) < r_comm:
            j += 1
        if j == k:  # consecutive path cells are one apart: only r_comm <= 1 gets here
            raise ValueError("r_comm must exceed one cell")
        if j == len(path) - 1:
            break
        nodes.append(path[j])
        last, k = path[j], j
    nodes.append(path[-1])
    return nodes


def phase2_chain(grid: np.ndarray, base: Cell, r_comm: float,
                 exclude: Iterable[Cell] = ()) -> tuple[Cell, list[Cell]] | None:
    """Steps 8-9: the closest frontier (``exclude`` left out) and L_h, along the taut octile path; None when
    no frontier is reachable."""
    geo = Geodesic(grid, base)
    frontier = closest_frontier(grid, base, geo.dist, exclude)
    if frontier is None or frontier == base:
        return None
    return frontier, chain_positions(geo.taut(frontier), r_comm)
