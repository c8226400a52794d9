"""Navigation by descending a wavefront's gradient (MinPos section 4.4)."""

from __future__ import annotations

import numpy as np

from fleet_emu.core.grid import MOVES, STAY, Cell


def next_move(dist: np.ndarray, cell: Cell, blocked: set[Cell] | frozenset[Cell] = frozenset()) -> Cell:
    """The 4-connected step to the neighbour of least wavefront distance below the robot's own.

    ``dist`` holds BFS distances (-1 unreached). Neighbours in ``blocked`` (teammates' cells) are skipped;
    ties go to the first move in :data:`core.grid.MOVES` order. Stays when at the frontier (distance 0),
    when unreached, or when no lower neighbour is free.
    """
    here = int(dist[cell])
    if here <= 0:
        return STAY
    rows, cols = dist.shape
    best, best_d = STAY, here
    for dr, dc in MOVES:
        r, c = cell[0] + dr, cell[1] + dc
        if 0 <= r < rows and 0 <= c < cols and (r, c) not in blocked:
            d = int(dist[r, c])
            if 0 <= d < best_d:
                best, best_d = (dr, dc), d
    return best
