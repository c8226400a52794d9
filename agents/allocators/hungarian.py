"""Centralized optimal assignment (Kuhn's Hungarian method, 1955), the reference planner of Yan, Jouandeau and
Ali Cherif 2011 (section 5, Tables 1-2: "a centralized approach based on the Hungarian method ... in which the task
allocation is done by a central planner").

Tasks are the brain's frontier clusters, or with ``tasks = "regions"`` the regions of the map cut at critical
points that Yan et al. bid on (section 4.2, :mod:`agents.regions`): below, a cluster is then a region task.

The coordinator minimises the total wavefront cost ``sum_ij alpha_ij C_ij`` over one-to-one assignments
(``scipy.optimize.linear_sum_assignment``). With more robots than clusters the cluster columns are
replicated ``ceil(n/m)`` times, so every robot is assigned; an unreachable pair costs a large finite value
that outweighs any sum of real costs, so the assignment maximises the number of robots sent to a reachable
cluster first. Among optimal assignments scipy's deterministic choice stands (the paper states none).

Protocol (explicit, over the lossy radio): the coordinator is the lowest live robot id, a robot being live to
me if it is me, or I heard it within ``timeout`` ticks (``Problem.heard``; a robot with a known pose and no
entry there counts as live: no liveness was recorded). The coordinator assigns the live robots every tick
and every ``period`` ticks broadcasts an :class:`Assignment` of target cells. Any other robot
takes its target from the newest Assignment received from the robot it believes is coordinator: the
reachable cluster whose cells contain the cell, else the reachable cluster whose target is nearest
(Euclidean). With no such Assignment, or one older than ``timeout`` ticks, or none naming it, it falls back
to its nearest frontier (MinPos Algorithm 1): moving toward a frontier beats waiting for a message that may
never come. When the coordinator falls silent for ``timeout`` ticks, the next lowest live id takes over.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from fleet_emu.agents.allocators.base import Allocation, Allocator, Problem
from fleet_emu.agents.allocators.params import Param
from fleet_emu.agents.allocators.tasks import TASKS, use_tasks
from fleet_emu.agents.regions import RegionTasks
from fleet_emu.core.codec import Context, Payload
from fleet_emu.core.grid import Cell, flat
from fleet_emu.core.messages import RadioMsg, check_robot_cells


@dataclasses.dataclass(frozen=True)
class Assignment(Payload):
    """A coordinator's assignment for round ``round``: each robot's target cell (broadcast)."""

    KIND = "assign"
    round: int
    targets: dict[str, Cell]

    def validate(self, ctx: Context | None) -> None:
        check_robot_cells(self.targets, ctx, "assign")


def optimal_assignment(costs: np.ndarray) -> np.ndarray:
    """The cluster of each robot row minimising the total cost (columns replicated when rows outnumber
    them); -1 where a robot could only be given a cluster it cannot reach."""
    n, m = costs.shape
    out = np.full(n, -1, dtype=np.int64)
    if m == 0 or n == 0:
        return out
    finite = np.isfinite(costs)
    big = (float(costs[finite].max()) + 1.0) * (n + 1) if finite.any() else 1.0
    tiled = np.tile(np.where(finite, costs, big), (1, -(-n // m)))
    from scipy.optimize import linear_sum_assignment  # imported on use: ~40 MB that other agents need not load

    rows, cols = linear_sum_assignment(tiled)
    out[rows] = cols % m
    out[~finite[np.arange(n), np.maximum(out, 0)]] = -1
    return out


def total_cost(costs: np.ndarray, assignment: np.ndarray) -> float:
    """The summed cost of an assignment (row -> cluster)."""
    return float(sum(costs[i, j] for i, j in enumerate(assignment) if j >= 0))


class Hungarian(Allocator, plugin_name="hungarian"):
    """``timeout``: ticks of silence after which a robot (or an Assignment) counts as gone;
    ``period``: the coordinator broadcasts its assignment every ``period`` ticks."""

    DESCRIPTION = "a coordinator robot assigns frontiers by the Hungarian method, over the radio (Yan et al. 2011)"

    parameters = {"timeout": Param(10, ge=1), "period": Param(1, ge=1), "tasks": TASKS}
    timeout: int
    period: int
    tasks: str

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        self.received: dict[str, RadioMsg] = {}  # the newest Assignment from each robot
        self.regions = RegionTasks()

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self.received = {}

    def live(self, problem: Problem) -> list[str]:
        """The robots with a known pose that are live to the deciding one, in id order."""
        return [r for r in problem.robots
                if r == problem.me or r not in problem.heard or problem.tick - problem.heard[r] <= self.timeout]

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        use_tasks(problem, self.tasks, self.regions)  # tasks = "regions": Yan's regions for the clusters
        for msg in inbox:
            if isinstance(msg.body, Assignment) and msg.dst in ("*", problem.me):
                old = self.received.get(msg.origin)
                if old is None or (msg.tick, msg.seq) > (old.tick, old.seq):
                    self.received[msg.origin] = msg
        if not problem.clusters:
            return Allocation.none()
        live = self.live(problem)
        if live[0] == problem.me:
            return self._coordinate(problem, live)
        last = self.received.get(live[0])  # an Assignment's (allocate keeps only those)
        targets = last.body.targets if last is not None and isinstance(last.body, Assignment) else {}
        if last is not None and problem.tick - last.tick <= self.timeout and problem.me in targets:
            j = self._cluster_of(problem, targets[problem.me])
            if j is not None:
                return Allocation.assigned(problem, j)
        return self._nearest(problem)

    def _coordinate(self, problem: Problem, live: list[str]) -> Allocation:
        rows = [problem.robots.index(r) for r in live]
        plan = optimal_assignment(problem.costs[rows])
        targets = {r: problem.clusters[j].target for r, j in zip(live, plan, strict=True) if j >= 0}
        outbox: tuple[RadioMsg, ...] = ()
        if problem.tick % self.period == 0:
            outbox = (RadioMsg(Assignment(round=problem.tick, targets=targets)),)
        if plan[0] >= 0:  # live[0] is me
            return Allocation.assigned(problem, int(plan[0]), outbox)
        fallback = self._nearest(problem)
        return Allocation(fallback.status, fallback.cluster, fallback.target, outbox)

    @staticmethod
    def _own(problem: Problem) -> np.ndarray:
        """The deciding robot's row of C, from the wavefronts alone (a non-coordinator needs no more)."""
        me = problem.poses[problem.me]
        return np.array([wf[me] if wf[me] >= 0 else np.inf for wf in problem.wavefronts])

    def _cluster_of(self, problem: Problem, cell: Cell) -> int | None:
        """The reachable cluster holding ``cell``, else the one whose target is nearest to it."""
        reachable = np.flatnonzero(np.isfinite(self._own(problem)))
        if not len(reachable):
            return None
        index = flat(problem.belief.shape, cell)
        for j in reachable:
            cells = problem.clusters[j].cells
            k = np.searchsorted(cells, index)
            if k < len(cells) and cells[k] == index:
                return int(j)
        targets = np.array([problem.clusters[j].target for j in reachable], dtype=float)
        return int(reachable[np.argmin(((targets - np.asarray(cell, dtype=float)) ** 2).sum(axis=1))])

    def _nearest(self, problem: Problem) -> Allocation:
        own = self._own(problem)
        return Allocation.assigned(problem, int(np.argmin(own))) if np.isfinite(own).any() else Allocation.none()
