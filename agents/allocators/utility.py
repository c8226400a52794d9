"""Coordinated exploration by utility, Burgard, Moors, Stachniss and Schneider, IEEE T-RO 21(3), 2005
(section III, Table I; the method the MinPos paper compares against as "Burgard et al. [4]").

Every target (a frontier cluster's target cell) starts with utility ``U_t = 1``. While a robot is left
without a target, choose the pair ``(i, t) = argmax (U_t - beta * V_t^i)`` over the robots left and all
targets, assign it, and lower the utility of every target t' near t: ``U_t' <- U_t' - P(||t - t'||)`` with
Burgard's linear decrease ``P(d) = 1 - d / max_range`` for ``d < max_range``, else 0 (``max_range`` =
``sensor_range`` cells; ``d`` the Euclidean distance between target cells, so ``U_t`` itself drops by 1).
Targets are not removed: with more robots than targets a target can be given twice. ``V_t^i`` is the
wavefront cost normalised by the largest finite cost of the matrix, so that ``beta`` weighs a path across
the known map against one unit of utility. Each robot runs the sequence (all robots with known poses, in
id order) until its own assignment. Ties go to the lowest robot, then the lowest cluster index.
Unreachable targets are never chosen; a robot that reaches none is never assigned.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fleet_emu.agents.allocators.interface import Allocation, Allocator, Problem
from fleet_emu.agents.allocators.params import Param
from fleet_emu.core.messages import RadioMsg


def utility_choice(costs: np.ndarray, targets: np.ndarray, i: int, beta: float = 1.0,
                   sensor_range: float = 8.0) -> int | None:
    """Robot row ``i``'s target index under Burgard's Table I; ``targets`` is (m, 2) cells. None if it
    reaches no target."""
    m = costs.shape[1]
    if m == 0 or not np.isfinite(costs[i]).any():
        return None
    finite = np.isfinite(costs)
    top = costs[finite].max()
    cost = np.where(finite, costs / top if top > 0 else 0.0, np.inf)
    gap = np.linalg.norm(targets[:, None, :].astype(float) - targets[None, :, :], axis=2)
    drop = np.where(gap < sensor_range, 1.0 - gap / sensor_range, 0.0)
    utility = np.ones(m)
    left = finite.any(axis=1)
    while left.any():
        score = np.where(left[:, None] & finite, utility[None, :] - beta * cost, -np.inf)
        k, t = divmod(int(np.argmax(score)), m)  # row-major: lowest robot, then lowest target, on ties
        if k == i:
            return t
        utility -= drop[t]
        left[k] = False
    return None  # not reached: row i is finite, so it is assigned before ``left`` empties


class Utility(Allocator, plugin_name="utility"):
    """``beta``: weight of the normalised cost against utility; ``sensor_range``: max_range of P(d), cells
    (in a run, the scenario's sensor range)."""

    DESCRIPTION = "Burgard et al. 2005: utility minus path cost; a target taken lowers the utility of those near it"

    parameters = {"beta": Param(1.0, ge=0), "sensor_range": Param(8.0, gt=0)}
    scenario_fields = {"sensor_range": "sensor_cells"}
    beta: float
    sensor_range: float

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        if not problem.clusters:
            return Allocation.none()
        targets = np.array([c.target for c in problem.clusters], dtype=np.int64)
        t = utility_choice(problem.costs, targets, problem.index, self.beta, self.sensor_range)
        return Allocation.none() if t is None else Allocation.assigned(problem, t)
