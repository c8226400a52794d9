"""A robot's belief grid: its own scans and teammates' map deltas, and what it newly learned to share."""

from __future__ import annotations

import numpy as np

from fleet_emu.core.grid import UNKNOWN, distinct
from fleet_emu.core.kernels import known_grown, merge_parts


class Belief:
    """An int8 occupancy grid that starts unknown; ``take_news`` returns cells learned since the last call,
    ``take_changed`` the cells changed since its last call (for the incremental frontier clusters). Both are
    kept as the merges' changed cells, so that neither takes a pass over the whole grid. ``known_cells`` counts
    the cells known so far (the merges' unknown cells made known), sent with every command: the world's stall
    rule reads it."""

    def __init__(self, shape: tuple[int, int]) -> None:
        self.grid = np.full(shape, UNKNOWN, dtype=np.int8)
        self._news: list[np.ndarray] = []
        self._changed: list[np.ndarray] = []
        self._known: tuple[np.ndarray, np.ndarray] | None = None  # known()'s answer until a merge changes a cell
        self._known_idx: np.ndarray | None = None  # the known cells of known()'s last answer, ascending
        self._since: list[np.ndarray] = []  # the cells changed since, with their count in _since_n
        self._since_n = 0
        self.known_cells = 0

    @property
    def shape(self) -> tuple[int, int]:
        return self.grid.shape

    def merge(self, cells: np.ndarray, values: np.ndarray) -> int:
        """Write known values into the grid (later observations win); returns how many cells were unknown."""
        flat = self.grid.reshape(-1)
        known = values != UNKNOWN
        if not known.all():
            cells, values = cells[known], values[known]
        old = flat[cells]
        changed = cells[old != values]
        flat[cells] = values
        if len(changed):
            self._changed_too(changed)
        learned = int(np.count_nonzero(old == UNKNOWN))
        self.known_cells += learned
        return learned

    def merge_many(self, parts: list[tuple[np.ndarray, np.ndarray]]) -> int:
        """:meth:`merge` of each ``(cells, values)`` of ``parts`` in turn, in one compiled pass
        (:func:`~fleet_emu.core.kernels.merge_parts`; a robot merges every teammate's map delta each tick).
        The grid, the news, the changed cells (in the same order) and the count are
        those of the merges in turn."""
        if len(parts) <= 1:
            return sum(self.merge(c, v) for c, v in parts)
        cells = np.concatenate([c for c, _ in parts])
        values = np.concatenate([v for _, v in parts])
        bounds = np.zeros(len(parts) + 1, dtype=np.int64)
        np.cumsum([len(c) for c, _ in parts], out=bounds[1:])
        return self.merge_parts(cells, values, bounds)

    def merge_parts(self, cells: np.ndarray, values: np.ndarray, bounds: np.ndarray) -> int:
        """:meth:`merge_many` of the parts ``bounds[p]:bounds[p + 1]`` of ``cells`` and ``values`` (int64
        bounds from 0 to their length), already side by side."""
        if len(bounds) <= 2:
            return self.merge(cells, values)
        changed, unknowns = merge_parts(self.grid.reshape(-1), cells, values, bounds, UNKNOWN)
        if len(changed):
            self._changed_too(changed)
        self.known_cells += int(unknowns)
        return int(unknowns)

    def take_news(self) -> tuple[np.ndarray, np.ndarray]:
        """Flat indices (ascending) and values of every cell learned or changed since the last call."""
        idx = _union(self._news)
        self._news = []
        return idx.astype(np.int32), self.grid.reshape(-1)[idx]

    def take_changed(self) -> np.ndarray:
        """Flat indices of the cells changed since the last call (repeats possible)."""
        out = np.concatenate(self._changed) if self._changed else np.zeros(0, dtype=np.int64)
        self._changed = []
        return out

    def _changed_too(self, changed: np.ndarray) -> None:
        """A merge changed the cells ``changed``: news, changed cells, and known()'s answer to update."""
        self._known = None
        self._news.append(changed)
        self._changed.append(changed)
        self._since.append(changed)
        self._since_n += len(changed)
        if self._since_n > self.grid.size // 16:  # known() has not been asked for a while: a pass then
            self._known_idx, self._since, self._since_n = None, [], 0

    def known(self) -> tuple[np.ndarray, np.ndarray]:
        """Every known cell, flat indices ascending and their values (for a full-map sync to a teammate heard
        again after a silence), as read-only arrays. The answer is kept until a merge changes a cell, and then
        updated with the cells changed since rather than found by a pass over the grid (a merge never makes
        a cell unknown): at 100 robots a robot's first tick sends a whole map to most teammates, each after
        merging a teammate's delta."""
        if self._known is None:
            flat = self.grid.reshape(-1)
            idx = self._known_idx
            if idx is None or not self._since:
                idx = np.flatnonzero(flat != UNKNOWN) if idx is None else idx
                cells, values = idx.astype(np.int32), flat[idx]
            else:
                new = np.concatenate(self._since).astype(np.int64, copy=False)
                idx, cells, values = known_grown(idx, new, flat, UNKNOWN)
            self._known_idx, self._since, self._since_n = idx, [], 0
            cells.flags.writeable = values.flags.writeable = False
            self._known = cells, values
        return self._known


def _union(parts: list[np.ndarray]) -> np.ndarray:
    """The distinct indices of ``parts``, ascending."""
    if not parts:
        return np.zeros(0, dtype=np.int64)
    return distinct(np.concatenate(parts) if len(parts) > 1 else parts[0])
