"""The first tick each cell of a grid was sensed: one fold over observations, kept for the whole team (the
Foxglove coverage grid, the report's final map) and for each robot (first-discovery credit and overlap in
:mod:`.metrics`)."""

from __future__ import annotations

import numpy as np

from fleet_emu.core.messages import Message, Observation


class FirstSeen:
    """Per cell of a ``shape`` grid (flat, row-major): ``tick``, the first tick it was sensed (-1 never), and
    ``value``, the value last sensed there (-1 never). Observations may come in any order of ticks. A fold
    (``core/fold.py``): :meth:`fold` takes the world's observations."""

    def __init__(self, shape: tuple[int, int]) -> None:
        self.shape = (int(shape[0]), int(shape[1]))
        size = self.shape[0] * self.shape[1]
        self.tick = np.full(size, -1, dtype=np.int32)
        self.value = np.full(size, -1, dtype=np.int8)

    def observe(self, tick: int, cells: np.ndarray, values: np.ndarray) -> None:
        """Cells (flat indices) sensed at ``tick`` with their values; an earlier tick replaces a later one."""
        cells = np.asarray(cells).astype(np.int64)
        first = self.tick[cells]
        self.tick[cells[(first < 0) | (first > tick)]] = tick
        self.value[cells] = values

    def fold(self, msg: Message) -> None:
        """One decoded message: an observation of this grid's shape is observed; anything else is not this
        fold's."""
        if isinstance(msg, Observation) and tuple(msg.shape) == self.shape:
            self.observe(msg.tick, msg.cells, msg.values)

    def grid(self, upto: int) -> np.ndarray:
        """A ``shape`` grid of the values of the cells first sensed at or before ``upto``, -1 elsewhere."""
        seen = (self.tick >= 0) & (self.tick <= upto)
        return np.where(seen, self.value, -1).astype(np.int8).reshape(self.shape)


def fold_team(coverage: FirstSeen | None, shape: tuple[int, int] | None, obs: Observation) -> FirstSeen:
    """The team's first-seen grid with the world's ``Observation`` ``obs`` folded in: made at ``shape`` (the
    true map's, when known) or else at the first observation's; an observation of another shape is left out."""
    if coverage is None:
        coverage = FirstSeen(shape or (int(obs.shape[0]), int(obs.shape[1])))
    coverage.fold(obs)
    return coverage
