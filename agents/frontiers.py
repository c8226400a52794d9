"""Frontier identification and clustering (MinPos section 4.1).

A frontier cell is a known-free cell 4-adjacent to an unknown one. Contiguous frontier cells (8-connected,
``core.kernels.label``) are grouped, and a group larger than what one sensing covers (``cluster_max``
cells) is split into consecutive pieces along a breadth-first walk of the group, so that each piece is
contiguous. Each cluster's ``target`` is its cell nearest the cluster's mean. Cluster order is by smallest
flat index, so every robot holding the same belief finds the same clusters in the same order.

:func:`find_clusters` is the definition, over the whole grid; a robot's brain keeps the same clusters up to
date around what changed each tick (:class:`agents.clusters.FrontierClusters`, tested equal to it).
"""

from __future__ import annotations

import dataclasses
from collections import deque

import numpy as np

from fleet_emu.core.grid import FREE, UNKNOWN, Cell
from fleet_emu.core.kernels import label


@dataclasses.dataclass(frozen=True, eq=False)
class Cluster:
    """A group of frontier cells: flat indices (ascending) and the target cell robots navigate toward."""

    cells: np.ndarray
    target: Cell

    @property
    def size(self) -> int:
        return len(self.cells)


def frontier_mask(grid: np.ndarray) -> np.ndarray:
    """Free cells with an unknown 4-neighbour."""
    unknown = grid == UNKNOWN
    near = np.zeros_like(unknown)
    near[1:, :] |= unknown[:-1, :]
    near[:-1, :] |= unknown[1:, :]
    near[:, 1:] |= unknown[:, :-1]
    near[:, :-1] |= unknown[:, 1:]
    return (grid == FREE) & near


def find_clusters(grid: np.ndarray, cluster_max: int) -> list[Cluster]:
    """The frontier clusters of a belief grid, each at most ``cluster_max`` cells."""
    mask = frontier_mask(grid)
    labels, n = label(mask, eight=True)
    if n == 0:
        return []
    cols = grid.shape[1]
    flat_labels = labels.ravel()
    idx = np.flatnonzero(flat_labels)
    order = np.argsort(flat_labels[idx], kind="stable")
    groups = np.split(idx[order], np.cumsum(np.bincount(flat_labels[idx])[1:])[:-1])
    pieces: list[np.ndarray] = []
    for group in groups:
        if len(group) <= cluster_max:
            pieces.append(group)
        else:
            walk = _bfs_order(group, cols)
            pieces.extend(np.sort(walk[k:k + cluster_max]) for k in range(0, len(walk), cluster_max))
    pieces.sort(key=lambda p: int(p[0]))
    return [Cluster(cells=p.astype(np.int64), target=_target(p, cols)) for p in pieces]


def _bfs_order(group: np.ndarray, cols: int) -> np.ndarray:
    """The group's cells in breadth-first order (8-connected) from its smallest flat index."""
    members = set(group.tolist())
    start = int(group.min())
    seen = {start}
    queue = deque([start])
    out: list[int] = []
    while queue:
        cur = queue.popleft()
        out.append(cur)
        r, c = divmod(cur, cols)
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                nxt = (r + dr) * cols + (c + dc)
                if (dr or dc) and 0 <= c + dc < cols and nxt in members and nxt not in seen:
                    seen.add(nxt)
                    queue.append(nxt)
    return np.array(out, dtype=np.int64)


def _target(cells: np.ndarray, cols: int) -> Cell:
    """The cluster's cell nearest its mean (lowest flat index on ties)."""
    rows, cs = np.divmod(cells, cols)
    d2 = (rows - rows.mean()) ** 2 + (cs - cs.mean()) ** 2
    k = int(np.argmin(d2))
    return (int(rows[k]), int(cs[k]))
