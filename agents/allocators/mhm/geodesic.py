"""Shortest paths for MHM's phase 2 that follow straight lines where the map allows (section III-D, steps 8-9).

Phase 2 takes "the exploration frontier closest to the base station" and "the number and positions of nodes
required to create a path to the frontier". Nodes are relays a radio range apart, so the number of nodes is set
by the length of the path they follow. A 4-connected breadth-first path (the grid's wavefront) measures the
Manhattan distance in open space: a frontier on a diagonal looks 1.41 times as far as it is, and a chain along
such a path needs 1.41 times the nodes, so a fleet reaches a diamond instead of a disc. Here instead:

- **Closest** is the octile distance (8-connected Dijkstra, diagonal steps of sqrt 2, no corner cut: a
  diagonal step needs both of its orthogonal cells free), within 8 % of the straight-line length in open space
  and a path length around walls.
- **The path** is that Dijkstra path pulled taut (*string pulling*, as in any-angle path planning): from each
  waypoint, the farthest later point of the path that a straight segment of known-free cells reaches, then
  that segment's cells. In open space this is the straight line from the base to the frontier.

Both run inside the box of the known-free cells (the grid may be far larger).
"""

from __future__ import annotations

import heapq

import numpy as np

from fleet_emu.agents.allocators.mhm.explore import bounds
from fleet_emu.core.grid import FREE, Cell
from fleet_emu.core.jit import njit


@njit(cache=True)
def _octile(free: np.ndarray, source: int) -> tuple[np.ndarray, np.ndarray]:
    """8-connected Dijkstra over ``free`` (2-D bool) from the flat index ``source``: distances (-1 unreached)
    and each cell's predecessor (-1 for the source and unreached cells)."""
    rows, cols = free.shape
    flat = free.ravel()
    dist = np.full(rows * cols, np.inf)
    prev = np.full(rows * cols, -1, dtype=np.int64)
    dist[source] = 0.0
    heap = [(0.0, source)]
    while heap:
        d, cur = heapq.heappop(heap)
        if d > dist[cur]:
            continue
        r = cur // cols
        c = cur - r * cols
        for dr in range(-1, 2):
            for dc in range(-1, 2):
                if dr == 0 and dc == 0:
                    continue
                nr, nc = r + dr, c + dc
                if nr < 0 or nr >= rows or nc < 0 or nc >= cols or not flat[nr * cols + nc]:
                    continue
                if dr != 0 and dc != 0 and not (flat[nr * cols + c] and flat[r * cols + nc]):
                    continue
                nd = d + (1.4142135623730951 if dr != 0 and dc != 0 else 1.0)
                nxt = nr * cols + nc
                if nd < dist[nxt] - 1e-9:
                    dist[nxt] = nd
                    prev[nxt] = cur
                    heapq.heappush(heap, (nd, nxt))
    for k in range(rows * cols):
        if dist[k] == np.inf:
            dist[k] = -1.0
    return dist.reshape(rows, cols), prev


class Geodesic:
    """Octile distances from ``base`` over the known-free cells of ``grid`` (module docstring)."""

    def __init__(self, grid: np.ndarray, base: Cell) -> None:
        free = grid == FREE
        free[base] = True
        self.free = free
        self.box = bounds(free, np.array([base]))
        r0, c0, r1, c1 = self.box
        local = np.ascontiguousarray(free[r0:r1, c0:c1])
        self._dist, self._prev = _octile(local, (base[0] - r0) * (c1 - c0) + (base[1] - c0))
        self.dist = np.full(grid.shape, -1.0)
        self.dist[r0:r1, c0:c1] = self._dist

    def path(self, goal: Cell) -> list[Cell]:
        """The octile shortest path from the base to ``goal``, base first."""
        r0, c0, _, c1 = self.box
        if self.dist[goal] < 0:
            raise ValueError(f"{goal} is not reachable from the base")
        width = c1 - c0
        k = (goal[0] - r0) * width + (goal[1] - c0)
        out = []
        while k >= 0:
            out.append((k // width + r0, k % width + c0))
            k = int(self._prev[k])
        return out[::-1]

    def taut(self, goal: Cell) -> list[Cell]:
        """:meth:`path` pulled taut (module docstring): the cells of its straight segments, base first."""
        return taut(self.path(goal), self.free)


def segment(a: Cell, b: Cell) -> list[Cell]:
    """The cells of the straight segment from ``a`` to ``b``, one per step of the longer axis, both ends in."""
    n = max(abs(b[0] - a[0]), abs(b[1] - a[1]))
    if n == 0:
        return [a]
    t = np.arange(n + 1) / n
    rows = np.rint(a[0] + t * (b[0] - a[0])).astype(int)
    cols = np.rint(a[1] + t * (b[1] - a[1])).astype(int)
    return list(zip(rows.tolist(), cols.tolist(), strict=True))


def _clear(a: Cell, b: Cell, free: np.ndarray) -> bool:
    cells = np.array(segment(a, b))
    return bool(free[cells[:, 0], cells[:, 1]].all())


def taut(path: list[Cell], free: np.ndarray) -> list[Cell]:
    """``path`` pulled taut over ``free`` cells: from each waypoint, the farthest later path point a clear
    straight segment reaches (scanning on while the next one is clear), then that segment's cells."""
    out = [path[0]]
    a = 0
    while a < len(path) - 1:
        j = a + 1
        while j + 1 < len(path) and _clear(path[a], path[j + 1], free):
            j += 1
        out.extend(segment(path[a], path[j])[1:])
        a = j
    return out
