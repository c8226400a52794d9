"""Trade-based allocation, Yan, Jouandeau and Ali Cherif 2011 (ICINCO), section 4.

A robot *not in a task* runs one round of the protocol; a robot in a task explores it and does not take part.

1. **Role allocation** (Algorithm 1). Every tick while not in a task, the robot broadcasts its number
   (``TradeNumber``; ``r3`` is 3). After ``time_max`` ticks of listening it decides: if it heard a number
   smaller than its own it is a *buyer* of the robot with the smallest number heard, otherwise the *seller*.
2. **Task allocation** (section 4.2). Tasks are frontier clusters, named by their target cell, or with
   ``tasks = "regions"`` the paper's own, regions of the map cut at critical points (:mod:`agents.regions`),
   named by their entry point: a region task lasts while the region holding that cell has a frontier cell,
   however far from the entry (``_track``), and a teammate's claim takes the region holding its cell. Each robot picks
   the task of least wavefront cost (eq. 2) that its task list does not show as taken by a teammate. A buyer
   sends the purchase message ``{r, m, c}`` (eq. 3, ``TradePurchase``) to its seller and waits for the answer.
   The seller, with its own pick, collects purchases for ``bid_period`` ticks, then runs Algorithm 2: per task,
   the request of lower cost wins (ties to the lower robot number; requests within ``task_radius`` cells count
   as the same task). It broadcasts the round's task-allocation messages ``{r, m}`` (eq. 4) as one
   ``TradeAllocation`` whose ``src`` is the seller. "The seller robot itself is also the object of task
   allocation": a seller whose pick went to a buyer takes its best task not awarded in the round.
3. **Completion.** A task is done when the belief holds no frontier cell within ``task_radius`` cells of it;
   the robot broadcasts ``TradeDone`` and starts a new round. Each robot keeps a task list (tasks awarded in
   any ``TradeAllocation`` it heard, by robot) and drops an entry on ``TradeDone``, when the robot holding it is
   awarded another task, or after ``claim_ttl`` ticks.

Robustness under loss (our addition; the paper does not say how a robot recovers). Every wait is bounded:

- a buyer whose allocation does not come within ``award_timeout`` ticks (its purchase or the allocation was
  lost, or the seller went silent) counts a failed round and elects again; a silent seller no longer
  broadcasts its number, so the next election picks another;
- a buyer who hears its seller's allocation without its own name (outbid, or its purchase lost) also counts a
  failed round and elects again, the awarded tasks now in its task list; a robot that receives a purchase
  while not selling (it was a buyer too, or its bidding period is over) answers with an empty allocation;
- after ``retries`` failed rounds in a row, the robot allocates itself its own pick at the next decision (as
  a seller that heard nobody would) and broadcasts that allocation;
- a task held for ``task_timeout`` ticks is given up (broadcast as done).

A teammate in the way (our addition; section 4.3 leaves local obstacle avoidance to the vector field histogram
and never has a robot leave a task before it is complete). A robot in a task whose every step toward it is
held by a teammate for ``blocked_after`` ticks without coming nearer (two robots head-on in a one-cell door;
:mod:`.blocking`) gives the task up as at ``task_timeout``: it broadcasts it as done, so that the teammate can
take it, and the next round's pick ranks only the tasks it can step toward now (MinPos's open clusters), all
of them when it can step toward none. ``blocked_after = 0`` keeps the task until it is done or timed out.

So a robot with a reachable frontier is in a task at most ``(retries + 1) * (time_max + award_timeout) +
time_max`` ticks after it becomes free. With no reachable frontier it returns NO_FRONTIER but still takes part
(it can sell to others). Ticks are the time unit. The paper gives no value for its timeMax or bidding period
(its robots ran in continuous time): the defaults are the least that let robots that became free in the same
tick, or one tick apart, meet in one round, as one tick is a message's latency here.

Between tasks (``explore_in_round``, default true). The paper does not stop a robot while it trades: Algorithm
1 and section 4.2 only say what a robot not in a task broadcasts, listens for and decides, section 4.3's motion
planning says how a task is carried out, and Fig. 1 shows a robot that "has completed the exploration of room 0"
already "moving to next room". Its tasks are whole regions (rooms, corridors), so a round is short beside a task;
ours are frontier clusters, done as soon as the robot has sensed them, so a round of ``time_max + bid_period``
ticks comes every dozen ticks or so, and a robot standing still through it (``explore_in_round = false``, the
first version) spent about a quarter of its ticks WAITING. So, during a round, the robot heads for the task it
trades for: the one it bid for or picked as seller once it has one (while that frontier is there), else its
current pick (the least-cost task not taken, the one it would bid for now), and its status is ASSIGNED. The
rules of the round are untouched (same messages, same decisions from the same belief and position); only the
position, and with it the costs, moves on meanwhile, and the award may send the robot elsewhere.
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Sequence
from typing import Any

import numpy as np

from fleet_emu.agents.allocators.blocking import BLOCKED_AFTER, Blockage, open_costs
from fleet_emu.agents.allocators.interface import Allocation, Allocator, AllocStatus, Problem, robot_order
from fleet_emu.agents.allocators.params import Param
from fleet_emu.agents.allocators.tasks import TASKS, use_tasks
from fleet_emu.agents.regions import RegionTasks, holding
from fleet_emu.core.codec import Context, Payload
from fleet_emu.core.errors import DecodeError
from fleet_emu.core.grid import Cell
from fleet_emu.core.messages import RadioMsg, check_cell, check_robot_cells

# --- the protocol's messages (section 4), sealed in radio envelopes by the brain -----------------------------


class TradeNumber(Payload, kw_only=True, frozen=True):
    """Role allocation (Algorithm 1): a robot not in a task broadcasts its number every tick."""

    KIND = "trade_num"
    number: int

    def validate(self, ctx: Context | None) -> None:
        if self.number < 0:
            raise DecodeError("trade_num: negative robot number")


class TradePurchase(Payload, kw_only=True, frozen=True):
    """A buyer's purchase message ``pums_r = {r, m, c}`` (eq. 3) to the seller: ``r`` is the sender, ``m`` the
    task (a frontier cluster's target cell), ``c`` its wavefront cost (eq. 2)."""

    KIND = "trade_buy"
    task: Cell
    cost: float

    def validate(self, ctx: Context | None) -> None:
        check_cell(self.task, ctx.shape if ctx else None, "trade_buy")
        if not (0.0 <= self.cost < 1e9):
            raise DecodeError("trade_buy: cost out of range")


class TradeAllocation(Payload, kw_only=True, frozen=True):
    """A seller's task-allocation messages ``tams = {r, m}`` (eq. 4) of one round, as one broadcast: the sender
    is the seller, ``awards`` maps each robot allocated a task to that task's cell."""

    KIND = "trade_alloc"
    awards: dict[str, Cell]

    def validate(self, ctx: Context | None) -> None:
        check_robot_cells(self.awards, ctx, "trade_alloc")


class TradeDone(Payload, kw_only=True, frozen=True):
    """A completed (or abandoned) task, broadcast so that teammates update their task lists (section 4.2)."""

    KIND = "trade_done"
    task: Cell

    def validate(self, ctx: Context | None) -> None:
        check_cell(self.task, ctx.shape if ctx else None, "trade_done")


class Phase(enum.Enum):
    ELECT = "elect"  # Algorithm 1: broadcasting and listening for numbers
    SELL = "sell"  # collecting purchases for the bidding period
    BUY = "buy"  # purchase sent, waiting for the seller's allocation
    TASK = "task"  # exploring an allocated task


@dataclasses.dataclass
class _State:
    me: str = ""
    tick: int = -1
    phase: Phase = Phase.ELECT
    since: int = 0  # tick the phase began
    heard: dict[str, int] = dataclasses.field(default_factory=dict)  # numbers heard this election
    seller: str = ""
    pick: tuple[Cell, float] | None = None  # own request (task, cost) this round
    purchases: dict[str, tuple[Cell, float]] = dataclasses.field(default_factory=dict)
    task: Cell | None = None
    started: bool = False  # the task has been explored for at least a tick
    claims: dict[str, tuple[Cell, int]] = dataclasses.field(default_factory=dict)  # robot -> (task, tick)
    failures: int = 0
    block: Blockage = dataclasses.field(default_factory=Blockage)  # a teammate in the way of the task
    avoid: bool = False  # the last task was given up for a teammate in the way: pick among open clusters


def near(a: Cell, b: Cell, radius: int) -> bool:
    """Chebyshev distance at most ``radius``: two cells name the same task."""
    return max(abs(a[0] - b[0]), abs(a[1] - b[1])) <= radius


def greedy_table(requests: dict[str, tuple[Cell, float]], radius: int) -> dict[str, Cell]:
    """Algorithm 2: per task the request of lower cost stays in the allocation table (ties: lower number)."""
    table: list[tuple[str, Cell, float]] = []
    for robot in sorted(requests, key=robot_order):
        task, cost = requests[robot]
        same = next((k for k, (_, t, _) in enumerate(table) if near(t, task, radius)), None)
        if same is None:
            table.append((robot, task, cost))
        elif cost < table[same][2]:
            table[same] = (robot, task, cost)
    return {robot: task for robot, task, _ in table}


class Trade(Allocator, plugin_name="trade"):
    """Yan et al. 2011: role allocation by robot numbers, purchases, a greedy seller (module docstring)."""

    DESCRIPTION = "Yan et al. 2011: robots trade frontier tasks over the radio, buyers bidding to a seller"

    parameters = {"time_max": Param(2, ge=0), "bid_period": Param(2, ge=0), "award_timeout": Param(5, ge=1),
                  "retries": Param(1, ge=0), "task_radius": Param(3, ge=0), "claim_ttl": Param(100, ge=0),
                  "task_timeout": Param(300, ge=1), "explore_in_round": Param(True),
                  "blocked_after": Param(BLOCKED_AFTER, ge=0), "tasks": TASKS}  # ticks, but task_radius
    time_max: int
    bid_period: int
    award_timeout: int
    retries: int
    task_radius: int
    claim_ttl: int
    task_timeout: int
    explore_in_round: bool
    blocked_after: int
    tasks: str

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        self.s = _State()
        self.regions = RegionTasks()

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self.s = _State()

    # --- one tick -------------------------------------------------------------------------------------

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        use_tasks(problem, self.tasks, self.regions)  # tasks = "regions": Yan's regions for the clusters
        s = self.s
        if problem.me != s.me or problem.tick < s.tick:  # another robot, or time went back: start afresh
            self.s = s = _State(me=problem.me, tick=problem.tick, since=problem.tick)
        s.tick = problem.tick
        out: list[RadioMsg] = []
        self._receive(problem, inbox, out)
        s.claims = {r: c for r, c in s.claims.items() if problem.tick - c[1] <= self.claim_ttl}

        if s.phase is Phase.TASK:
            alloc = self._explore(problem, out)
            if alloc is not None:
                return alloc
        if s.phase is Phase.ELECT and problem.tick - s.since >= self.time_max:
            self._decide(problem, out)
        if s.phase is Phase.SELL and problem.tick - s.since >= self.bid_period:
            self._close_sale(problem, out)
        if s.phase is Phase.BUY and problem.tick - s.since >= self.award_timeout:
            s.failures += 1  # no allocation in time: purchase or allocation lost, or the seller is silent
            self._enter(Phase.ELECT, problem.tick)
        if s.phase is Phase.TASK:  # allocated a task this tick
            alloc = self._explore(problem, out)
            if alloc is not None:
                return alloc
        out.append(RadioMsg(TradeNumber(number=self._number(s.me)), dst="*"))  # Alg. 1 line 2
        pick = self._pick(problem)
        if pick is None:
            return Allocation.none(tuple(out))
        if self.explore_in_round:  # on toward the task it trades for (module docstring, "Between tasks")
            j = self._track(problem, s.pick[0]) if s.pick is not None else None
            return Allocation.assigned(problem, self._index(problem, pick[0]) if j is None else j, tuple(out))
        return Allocation(AllocStatus.WAITING, outbox=tuple(out))

    def _explore(self, problem: Problem, out: list[RadioMsg]) -> Allocation | None:
        """ASSIGNED to the allocated task's cluster; None (back to role allocation) when the task is done,
        was given up after ``task_timeout`` ticks, or vanished before the robot could start it."""
        s = self.s
        if s.task is None:  # not reached: a robot enters TASK only through _take, which sets the task
            self._enter(Phase.ELECT, problem.tick)
            return None
        j = self._track(problem, s.task)
        s.avoid = j is not None and s.block.held(problem, j, self.blocked_after)  # a teammate in the way
        if j is not None and problem.tick - s.since < self.task_timeout and not s.avoid:
            s.failures, s.started = 0, True
            return Allocation.assigned(problem, j, tuple(out))
        if not s.started:  # the task's frontier vanished while we traded: a wasted round
            s.failures += 1
        out.append(RadioMsg(TradeDone(task=s.task), dst="*"))  # done (or given up): tell the team
        s.claims.pop(s.me, None)
        self._enter(Phase.ELECT, problem.tick)
        return None

    # --- protocol steps -------------------------------------------------------------------------------

    def _receive(self, problem: Problem, inbox: Sequence[RadioMsg], out: list[RadioMsg]) -> None:
        s = self.s
        for msg in inbox:
            sender, body = msg.origin, msg.body
            if sender == s.me:
                continue
            if isinstance(body, TradeNumber):
                if s.phase is Phase.ELECT and msg.tick >= s.since:  # sent during this election
                    s.heard[sender] = body.number
            elif isinstance(body, TradePurchase) and msg.dst == s.me:
                if s.phase is Phase.SELL:
                    s.purchases[sender] = (body.task, body.cost)
                else:  # not selling (any more): an empty allocation sends the buyer back to role allocation
                    out.append(RadioMsg(TradeAllocation(awards={}), dst=sender))
            elif isinstance(body, TradeAllocation):
                for robot, task in body.awards.items():
                    if robot != s.me:
                        s.claims[robot] = (task, problem.tick)
                if s.phase is Phase.BUY and sender == s.seller and msg.tick >= s.since:  # answers our purchase
                    if s.me in body.awards:
                        self._take(body.awards[s.me], problem.tick)
                    else:  # outbid, or our purchase was lost: a new round, the awarded tasks now known
                        s.failures += 1
                        self._enter(Phase.ELECT, problem.tick)
            elif isinstance(body, TradeDone):
                held = s.claims.get(sender)
                if held is not None and near(held[0], body.task, self.task_radius):
                    del s.claims[sender]

    def _decide(self, problem: Problem, out: list[RadioMsg]) -> None:
        """End of Algorithm 1: seller if no smaller number was heard, else buyer of the smallest heard."""
        s = self.s
        pick = self._pick(problem)
        mine = self._number(s.me)
        smaller = {r: n for r, n in s.heard.items() if n < mine}
        if s.failures > self.retries:  # fallback: allocate ourselves our own pick, and say so
            if pick is None:
                self._enter(Phase.ELECT, problem.tick)
                return
            out.append(RadioMsg(TradeAllocation(awards={s.me: pick[0]}), dst="*"))
            self._take(pick[0], problem.tick)
        elif smaller:
            s.seller = min(smaller, key=lambda r: (smaller[r], robot_order(r)))
            if pick is None:  # nothing to buy: listen again
                self._enter(Phase.ELECT, problem.tick)
                return
            out.append(RadioMsg(TradePurchase(task=pick[0], cost=float(pick[1])), dst=s.seller))
            s.pick = pick
            self._enter(Phase.BUY, problem.tick)
        else:
            s.pick = pick
            self._enter(Phase.SELL, problem.tick)

    def _close_sale(self, problem: Problem, out: list[RadioMsg]) -> None:
        """End of the bidding period: Algorithm 2 over the purchases and the seller's own pick."""
        s = self.s
        requests = dict(s.purchases)
        pick = self._pick(problem)  # the seller's pick, on its newest belief
        if pick is not None:
            requests[s.me] = pick
        awards = greedy_table(requests, self.task_radius)
        if pick is not None and s.me not in awards:  # outbid on its own pick: its best task left over
            other = self._pick(problem, exclude=list(awards.values()))
            if other is not None:
                awards[s.me] = other[0]
        if awards:
            out.append(RadioMsg(TradeAllocation(awards=awards), dst="*"))
        for robot, task in awards.items():
            if robot != s.me:
                s.claims[robot] = (task, problem.tick)
        if s.me in awards:
            self._take(awards[s.me], problem.tick)
        else:
            self._enter(Phase.ELECT, problem.tick)

    # --- helpers --------------------------------------------------------------------------------------

    def _enter(self, phase: Phase, tick: int) -> None:
        s = self.s
        s.phase, s.since = phase, tick
        if phase is Phase.ELECT:
            s.heard, s.purchases, s.pick, s.seller, s.task = {}, {}, None, "", None
        elif phase is Phase.SELL:
            s.purchases = {}

    def _take(self, task: Cell, tick: int) -> None:
        self._enter(Phase.TASK, tick)
        self.s.task, self.s.started, self.s.avoid = task, False, False
        self.s.block.clear()
        self.s.claims[self.s.me] = (task, tick)

    def _pick(self, problem: Problem, exclude: Sequence[Cell] = ()) -> tuple[Cell, float] | None:
        """The reachable task of least wavefront cost (eq. 2) not taken by a teammate nor in ``exclude``;
        if every reachable task is taken, the least-cost one anyway (a free robot never idles)."""
        if not problem.clusters:
            return None
        costs = open_costs(problem) if self.s.avoid else problem.costs[problem.index]
        reach = np.flatnonzero(np.isfinite(costs))
        if not len(reach):
            return None
        taken = [t for r, (t, _) in self.s.claims.items() if r != self.s.me] + list(exclude)
        free = [int(j) for j in reach if not any(self._names(problem, int(j), t) for t in taken)]
        pool = free or [int(j) for j in reach if problem.clusters[j].target not in exclude] or [int(j) for j in reach]
        j = min(pool, key=lambda k: (costs[k], k))
        return problem.clusters[j].target, float(costs[j])

    def _names(self, problem: Problem, j: int, cell: Cell) -> bool:
        """Task ``j`` is the one named by ``cell``: its target is within ``task_radius`` of it, or (a region
        task) its region holds it."""
        if near(problem.clusters[j].target, cell, self.task_radius):
            return True
        return self.tasks == "regions" and holding(problem.clusters[j:j + 1], cell, problem.belief.shape[1]) == 0

    def _track(self, problem: Problem, task: Cell) -> int | None:
        """The reachable cluster with a frontier cell nearest the task (within ``task_radius``), or None
        when the task's frontier is gone: the task is done. A region task is tracked by its region, which
        holds its entry point while it has a frontier cell (else by an entry within ``task_radius``)."""
        me = problem.poses[problem.me]
        cols = problem.belief.shape[1]
        if self.tasks == "regions":
            j = holding(problem.clusters, task, cols)
            if j is None:
                j = next((k for k, c in enumerate(problem.clusters) if near(c.target, task, self.task_radius)), None)
            return j if j is not None and problem.wavefronts[j][me] >= 0 else None
        best: tuple[int, int] | None = None
        for j, cluster in enumerate(problem.clusters):
            rows, cs = np.divmod(cluster.cells, cols)
            d = int(np.maximum(np.abs(rows - task[0]), np.abs(cs - task[1])).min())
            if d <= self.task_radius and problem.wavefronts[j][me] >= 0 and (best is None or d < best[0]):
                best = (d, j)
        return None if best is None else best[1]

    @staticmethod
    def _index(problem: Problem, target: Cell) -> int:
        """The cluster whose target is ``target`` (one of ``problem.clusters``, as ``_pick`` returns it)."""
        return next(j for j, c in enumerate(problem.clusters) if c.target == target)

    @staticmethod
    def _number(robot: str) -> int:
        return robot_order(robot)[0]
