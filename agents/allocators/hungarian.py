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

When the coordinator re-solves (``replan``). Yan et al. describe their reference only as "a centralized
approach based on the Hungarian method (Kuhn, 1955) in which the task allocation is done by a central planner"
(section 5); they do not say when it re-plans. Their tasks have a life, though (section 4.2): a robot "in task"
carries it out, only "the idle robot" enters task allocation, and "the robot which has completed a task"
takes part again. ``"commit"`` (default) gives the central planner that same life, so that the comparison with
trade is one of allocation rules, not of commitment. The coordinator keeps each robot's task across ticks
(state of the allocator, cleared by ``reset``) until

- the robot *reaches* it: it stands on the task's cell;
- the task stops being a frontier: no cluster holds the cell any more (it has been *observed*, as ``minpos``'s
  ``replan="observed"`` says: its unknown neighbours were sensed, by any robot whose map reached the
  coordinator);
- the robot *cannot reach* it: the coordinator's belief has no path from the robot to it, or the robot has made
  no progress toward it for ``patience`` ticks (its cost to the task has not dropped below the least seen since
  the task was given or its target cell last moved). A robot so released is not given the same cluster again
  in that tick when it can reach another;
- or the robot is no longer live.

Clusters are formed afresh every tick, so a kept task is the cluster holding its cell now, and that cluster's
target is the cell kept next. Only the robots without a task are assigned, by the Hungarian method over the
clusters nobody holds; a robot left without a reachable one (fewer free clusters than robots, or none it can
reach) is assigned over every cluster, sharing a held one. A robot that takes over as coordinator starts from
the newest Assignment it heard from another robot, whose tasks are then kept or released by the same rules; one
that stops being coordinator forgets its tasks. ``"tick"`` re-solves the whole assignment at every tick (the
first version): at loss 0, as the robots move, the optimal assignment sends robots between two frontiers back
and forth, tick after tick (``benchmarks/flips.py``: 25, 26 and 13 target flips per 100 robot-ticks with 2, 3
and 4 robots on the office, 507, 372 and 249 ticks to 99 %).

Why progress, and not ``minpos``'s blocked step, says the robot cannot reach its task: the coordinator sees a
teammate at the cell its last beacon announced it would move to (``agents/brain.py``, ``Teammate.expected``).
Two teammates meeting head-on each announce the other's cell, so on the coordinator's view they have passed
each other every other tick; released on a blocked step so judged, such a pair swapped tasks every two or
three ticks (3 robots on the office, seed 1: 637 flips in 1851 robot-ticks). The paper gives no time for giving
up a task; ``patience`` defaults to ``timeout``'s 10 ticks, the one wait this planner already has. Measured on
the office (full radio, loss 0, 10 seeds; 2, 3 and 4 robots), 2 ticks brings the flips back (14-15 per 100
robot-ticks; 725, 449 and 379 ticks to 99 %); 5, 10 and 30 keep them under 1 (410, 304, 228 ticks; 362, 273,
210; 407, 299, 220).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from fleet_emu.agents.allocators.interface import Allocation, Allocator, Problem, robot_order
from fleet_emu.agents.allocators.params import Param
from fleet_emu.agents.allocators.tasks import TASKS, use_tasks
from fleet_emu.agents.regions import RegionTasks
from fleet_emu.core.codec import Context, Payload
from fleet_emu.core.grid import Cell, flat
from fleet_emu.core.messages import RadioMsg, check_robot_cells

REPLANS = ("commit", "tick")


@dataclasses.dataclass(frozen=True)
class Held:
    """A robot's task as the coordinator keeps it (``replan="commit"``): the task's cell, the least cost from
    the robot to it so far, and the tick that cost was first seen (its last progress)."""

    cell: Cell
    best: float
    since: int


class Assignment(Payload, kw_only=True, frozen=True):
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
    ``period``: the coordinator broadcasts its assignment every ``period`` ticks;
    ``replan``: ``"commit"`` (a robot keeps its task until done) or ``"tick"``; ``patience``: with ``"commit"``,
    the ticks without progress after which a robot's task is given up (module docstring)."""

    DESCRIPTION = "a coordinator robot assigns frontiers by the Hungarian method, over the radio (Yan et al. 2011)"

    parameters = {"timeout": Param(10, ge=1), "period": Param(1, ge=1), "replan": Param("commit", choices=REPLANS),
                  "patience": Param(10, ge=1), "tasks": TASKS}
    timeout: int
    period: int
    replan: str
    patience: int
    tasks: str

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        self.received: dict[str, RadioMsg] = {}  # the newest Assignment from each robot
        self.held: dict[str, Held] = {}  # as coordinator with replan="commit": each robot's task
        self.leading = False  # whether this robot coordinated at its previous decision
        self.regions = RegionTasks()

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self.received = {}
        self.held = {}
        self.leading = False

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
            if not self.leading:
                self.held = self._takeover(problem)
            self.leading = True
            return self._coordinate(problem, live)
        self.leading, self.held = False, {}
        last = self.received.get(live[0])  # an Assignment's (allocate keeps only those)
        targets = last.body.targets if last is not None and isinstance(last.body, Assignment) else {}
        if last is not None and problem.tick - last.tick <= self.timeout and problem.me in targets:
            j = self._cluster_of(problem, targets[problem.me])
            if j is not None:
                return Allocation.assigned(problem, j)
        return self._nearest(problem)

    def _takeover(self, problem: Problem) -> dict[str, Held]:
        """With ``"commit"``: the tasks of the newest Assignment heard from another robot, however old (a new
        coordinator carries on its predecessor's plan; each task is then checked as any kept one), else none."""
        heard = [m for r, m in self.received.items() if r != problem.me]
        if self.replan != "commit" or not heard:
            return {}
        last = max(heard, key=lambda m: (m.tick, robot_order(m.origin)))
        targets = last.body.targets if isinstance(last.body, Assignment) else {}
        return {r: Held(cell, np.inf, problem.tick) for r, cell in targets.items()}

    def _coordinate(self, problem: Problem, live: list[str]) -> Allocation:
        if self.replan == "commit":
            plan = self._committed(problem, live)
        else:
            plan = optimal_assignment(problem.costs[[problem.robots.index(r) for r in live]])
        targets = {r: problem.clusters[j].target for r, j in zip(live, plan, strict=True) if j >= 0}
        outbox: tuple[RadioMsg, ...] = ()
        if problem.tick % self.period == 0:
            outbox = (RadioMsg(Assignment(round=problem.tick, targets=targets)),)
        if plan[0] >= 0:  # live[0] is me
            return Allocation.assigned(problem, int(plan[0]), outbox)
        fallback = self._nearest(problem)
        return Allocation(fallback.status, fallback.cluster, fallback.target, outbox)

    def _committed(self, problem: Problem, live: list[str]) -> np.ndarray:
        """``"commit"``: each live robot's kept task, the others assigned over the clusters nobody keeps (then,
        for those left without a reachable one, over every cluster); the tasks kept for the next tick."""
        costs = problem.costs[[problem.robots.index(r) for r in live]].copy()
        plan = np.full(len(live), -1, dtype=np.int64)
        held: dict[str, Held] = {}
        for k, r in enumerate(live):
            j, task = self._kept(problem, r, costs[k])
            if task is not None:
                plan[k], held[r] = j, task
            elif j >= 0 and np.isfinite(np.delete(costs[k], j)).any():
                costs[k, j] = np.inf  # given up for want of progress: not this robot's again at once
        free = np.flatnonzero(plan < 0)
        if len(free):
            taken = np.zeros(len(problem.clusters), dtype=bool)
            taken[plan[plan >= 0]] = True
            cols = np.flatnonzero(~taken)
            if len(cols):
                sub = optimal_assignment(costs[free][:, cols])
                plan[free] = np.where(sub >= 0, cols[np.maximum(sub, 0)], -1)
            left = free[plan[free] < 0]
            if len(left):
                plan[left] = optimal_assignment(costs[left])
            for i in map(int, free):
                if plan[i] >= 0:
                    held[live[i]] = Held(problem.clusters[plan[i]].target, float(costs[i, plan[i]]), problem.tick)
        self.held = held
        return plan

    def _kept(self, problem: Problem, robot: str, costs: np.ndarray) -> tuple[int, Held | None]:
        """The cluster of the robot's task and the task as kept; (-1, None) when it has none, has reached it,
        the task is no longer a frontier or the robot cannot reach it on the belief; (j, None) when it made
        no progress toward cluster j for ``patience`` ticks (module docstring)."""
        task = self.held.get(robot)
        if task is None or problem.poses[robot] == task.cell:
            return -1, None
        j = _holding(problem, task.cell)
        if j is None or not np.isfinite(costs[j]):
            return -1, None
        cost, target = float(costs[j]), problem.clusters[j].target
        if target != task.cell or cost < task.best:
            return j, Held(target, cost, problem.tick)
        if problem.tick - task.since >= self.patience:
            return j, None
        return j, task

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
        j = _holding(problem, cell)
        if j is not None and j in reachable:
            return j
        targets = np.array([problem.clusters[j].target for j in reachable], dtype=float)
        return int(reachable[np.argmin(((targets - np.asarray(cell, dtype=float)) ** 2).sum(axis=1))])

    def _nearest(self, problem: Problem) -> Allocation:
        own = self._own(problem)
        return Allocation.assigned(problem, int(np.argmin(own))) if np.isfinite(own).any() else Allocation.none()


def _holding(problem: Problem, cell: Cell) -> int | None:
    """The cluster whose cells hold ``cell`` (clusters are disjoint), None if none does or it is off the grid."""
    shape = problem.belief.shape
    if not (0 <= cell[0] < shape[0] and 0 <= cell[1] < shape[1]):
        return None
    index = flat(shape, cell)
    for j, cluster in enumerate(problem.clusters):
        k = int(np.searchsorted(cluster.cells, index))
        if k < cluster.size and cluster.cells[k] == index:
            return j
    return None
