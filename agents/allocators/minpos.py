"""MinPos, Bautin et al. 2012, section 4.3, Algorithm 3.

The position of robot i toward frontier j is ``P_ij = |{k != i : C_kj < C_ij}|``, the number of teammates
closer to it; the robot takes ``argmin_j P_ij``, and "in case of equality [chooses] the minimum cost among
min P_ij" (then the lowest cluster index). Frontiers the robot cannot reach are never chosen. O(nm).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from agents.allocators.base import Allocation, Allocator, Problem
from core.messages import RadioMsg


def positions(costs: np.ndarray, i: int) -> np.ndarray:
    """``P_ij`` for every frontier j of the cost matrix (robots x frontiers)."""
    closer = costs < costs[i][None, :]
    closer[i] = False
    return closer.sum(axis=0)


def minpos_choice(costs: np.ndarray, i: int) -> int | None:
    """Algorithm 3 on a cost matrix: the frontier of least position, then least cost; None if none reachable."""
    own = costs[i]
    reachable = np.isfinite(own)
    if not reachable.any():
        return None
    pos = positions(costs, i).astype(float)
    pos[~reachable] = np.inf
    best = pos.min()
    candidates = np.flatnonzero(pos == best)
    return int(candidates[np.argmin(own[candidates])])


class MinPos(Allocator, plugin_name="minpos"):
    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        if not problem.clusters:
            return Allocation.none()
        j = minpos_choice(problem.costs, problem.index)
        return Allocation.none() if j is None else Allocation.assigned(problem, j)
