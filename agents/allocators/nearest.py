"""Nearest frontier: Yamauchi's multi-robot frontier exploration, MinPos paper section 3.1, Algorithm 1.

Each robot goes to the frontier cluster of least wavefront cost from its own cell, with no regard for its
teammates: ``j = argmin_j C_ij`` (O(m)). Ties go to the lowest cluster index.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fleet_emu.agents.allocators.interface import Allocation, Allocator, Problem
from fleet_emu.core.messages import RadioMsg


class Nearest(Allocator, plugin_name="nearest"):
    DESCRIPTION = "each robot goes to its nearest frontier, whatever its teammates do (Bautin et al. 2012, Alg. 1)"

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        if not problem.clusters:
            return Allocation.none()
        me = problem.poses[problem.me]
        costs = np.array([wf[me] if wf[me] >= 0 else np.inf for wf in problem.wavefronts])
        if not np.isfinite(costs).any():
            return Allocation.none()
        return Allocation.assigned(problem, int(np.argmin(costs)))
