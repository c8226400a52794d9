"""Decentralized greedy assignment, MinPos paper (Bautin et al. 2012) section 3.2, Algorithm 2.

Each robot computes the whole greedy assignment over the cost matrix C (every robot with a known pose) until
it finds its own pair: repeatedly take ``(k, j) = argmin C_kj`` over the robots and frontiers left, assign
R_k to F_j and remove both; "IF F = {} THEN F = F_init" (more robots than frontiers). Ties go to the lowest
robot (id order), then the lowest cluster index. O(n^2 m).

Unreachable pairs (``C_kj = inf``) are never chosen. When no robot left can reach any frontier left, the
frontiers left are as good as exhausted for them, so F is reset to F_init too (Algorithm 2 leaves the case
open); a robot that reaches no frontier at all is never assigned and stays out of everyone's sequence.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fleet_emu.agents.allocators.interface import Allocation, Allocator, Problem
from fleet_emu.core.messages import RadioMsg


def greedy_pairs(costs: np.ndarray, until: int | None = None) -> list[tuple[int, int]]:
    """Algorithm 2's sequence of (robot row, cluster) pairs, stopping after row ``until`` is assigned
    (or when every robot that reaches some frontier is assigned)."""
    m = costs.shape[1]
    pairs: list[tuple[int, int]] = []
    if m == 0:
        return pairs
    robots = np.isfinite(costs).any(axis=1)
    fronts = np.ones(m, dtype=bool)
    while robots.any():
        sub = np.where(robots[:, None] & fronts[None, :], costs, np.inf)
        if not np.isfinite(sub).any():
            fronts[:] = True  # what is left is unreachable for the robots left: F = F_init
            continue
        k, j = divmod(int(np.argmin(sub)), m)  # row-major: lowest robot, then lowest cluster, on ties
        pairs.append((k, j))
        if k == until:
            break
        robots[k] = False
        fronts[j] = False
        if not fronts.any():
            fronts[:] = True
    return pairs


def greedy_choice(costs: np.ndarray, i: int) -> int | None:
    """Robot row ``i``'s frontier under Algorithm 2; None if it reaches none."""
    if costs.shape[1] == 0 or not np.isfinite(costs[i]).any():
        return None
    k, j = greedy_pairs(costs, until=i)[-1]
    return j if k == i else None


class Greedy(Allocator, plugin_name="greedy"):
    DESCRIPTION = "greedy assignment: the closest robot-frontier pair first, then the next (Bautin et al. 2012, Alg. 2)"

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        if not problem.clusters:
            return Allocation.none()
        j = greedy_choice(problem.costs, problem.index)
        return Allocation.none() if j is None else Allocation.assigned(problem, j)
