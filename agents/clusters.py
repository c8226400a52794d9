"""Incremental frontier clustering (MinPos section 4.1), exactly :func:`agents.frontiers.find_clusters`.

A robot's belief changes each tick only around its own observation and the map deltas it merged, so instead
of labelling the whole grid every tick (:func:`~fleet_emu.core.kernels.label` and a breadth-first walk per large group),
:class:`FrontierClusters` keeps the frontier mask, each frontier cell's group label and each group's pieces,
and on :meth:`update` with the cells whose value changed:

1. recomputes the frontier mask on those cells and their 4-neighbours (the only cells whose status they
   affect), giving the cells that joined or left the frontier;
2. takes apart every group that lost a cell or is 8-adjacent to a new frontier cell (a group touching
   nothing that changed is a maximal 8-connected set of unchanged frontier cells, so it stays a group);
3. labels the groups of those groups' remaining cells and the new frontier cells (merges and splits of groups
   fall out of this), and splits a group of more than ``cluster_max`` cells along the breadth-first walk from
   its smallest flat index, into sorted pieces, with each piece's target, as ``find_clusters`` does;
4. gives every piece, ordered by its smallest flat index.

The pieces of unchanged groups are the same :class:`Cluster` objects as before (their cells read-only).
``tests/agents/test_clusters.py`` checks the result against ``find_clusters`` on the whole grid over many random
sequences of belief updates.
"""

from __future__ import annotations

import numpy as np

from fleet_emu.agents.frontiers import Cluster
from fleet_emu.core.cluster_kernels import relabel, target, touched_labels, update_mask


class FrontierClusters:
    """The frontier clusters of one belief grid of ``shape``, kept up to date by :meth:`update`."""

    def __init__(self, shape: tuple[int, int], cluster_max: int) -> None:
        self.rows, self.cols = int(shape[0]), int(shape[1])
        self.cluster_max = int(cluster_max)
        n = self.rows * self.cols
        self.mask = np.zeros(n, dtype=np.bool_)
        self.labels = np.zeros(n, dtype=np.int32)
        self.groups: dict[int, np.ndarray] = {}  # label -> the group's cells
        self.pieces: dict[int, list[tuple[int, Cluster]]] = {}  # label -> (smallest cell, piece)
        self.next_label = 1
        self.clusters: list[Cluster] = []

    def update(self, grid: np.ndarray, changed: np.ndarray) -> list[Cluster]:
        """The clusters of ``grid`` (the belief, as it is now), given every cell whose value changed since the
        last call (flat indices; repeats and unchanged cells are harmless). The list is new only when a
        cluster changed; treat it as read-only."""
        flat = grid.reshape(-1)
        changed = np.ascontiguousarray(changed, dtype=np.int64)
        flips = update_mask(flat, self.rows, self.cols, self.mask, changed)
        if not len(flips):
            return self.clusters
        touched = touched_labels(self.labels, self.rows, self.cols, flips)
        old = [self.groups.pop(int(lab)) for lab in touched]
        for lab in touched:
            del self.pieces[int(lab)]
        seeds = np.concatenate([*old, flips]) if old else flips
        self.labels[seeds] = 0
        cells, bounds = relabel(self.mask, self.labels, self.rows, self.cols, seeds, self.next_label,
                                self.cluster_max)
        for k in range(len(bounds) - 1):
            lab = self.next_label + k
            group = cells[bounds[k]:bounds[k + 1]]
            self.groups[lab] = group
            self.pieces[lab] = self._split(group)
        self.next_label += len(bounds) - 1
        every = [p for pieces in self.pieces.values() for p in pieces]
        every.sort(key=lambda p: p[0])
        self.clusters = [c for _, c in every]
        return self.clusters

    def _split(self, group: np.ndarray) -> list[tuple[int, Cluster]]:
        """A group's pieces (``find_clusters``: whole when small, else consecutive runs of its walk)."""
        m, cols = self.cluster_max, self.cols  # a large ``group`` is the walk from its smallest cell
        pieces = [np.sort(group[k:k + m]) for k in range(0, len(group), m)]
        for p in pieces:
            p.flags.writeable = False  # kept from tick to tick: no allocator may write into it
        return [(int(p[0]), Cluster(cells=p, target=_cell(target(p, cols)))) for p in pieces]


def _cell(rc: tuple[int, int]) -> tuple[int, int]:
    return (int(rc[0]), int(rc[1]))
