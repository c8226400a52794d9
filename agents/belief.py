"""A robot's belief grid: its own scans and teammates' map deltas, and what it newly learned to share."""

from __future__ import annotations

import numpy as np

from fleet_emu.core.grid import UNKNOWN


class Belief:
    """An int8 occupancy grid that starts unknown; ``take_news`` returns cells learned since the last call."""

    def __init__(self, shape: tuple[int, int]) -> None:
        self.grid = np.full(shape, UNKNOWN, dtype=np.int8)
        self._news = np.zeros(shape[0] * shape[1], dtype=np.bool_)

    @property
    def shape(self) -> tuple[int, int]:
        return self.grid.shape  # type: ignore[return-value]

    def merge(self, cells: np.ndarray, values: np.ndarray) -> int:
        """Write known values into the grid (later observations win); returns how many cells were unknown."""
        flat = self.grid.reshape(-1)
        known = values != UNKNOWN
        cells, values = cells[known], values[known]
        new = flat[cells] == UNKNOWN
        changed = flat[cells] != values
        flat[cells] = values
        self._news[cells[changed]] = True
        return int(new.sum())

    def take_news(self) -> tuple[np.ndarray, np.ndarray]:
        """Flat indices and values of every cell learned or changed since the last call."""
        idx = np.flatnonzero(self._news)
        self._news[idx] = False
        return idx.astype(np.int32), self.grid.reshape(-1)[idx].copy()

    def known(self) -> tuple[np.ndarray, np.ndarray]:
        """Every known cell (for a full-map sync to a teammate heard again after a silence)."""
        flat = self.grid.reshape(-1)
        idx = np.flatnonzero(flat != UNKNOWN)
        return idx.astype(np.int32), flat[idx].copy()
