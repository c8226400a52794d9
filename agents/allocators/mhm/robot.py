"""The ``mhm`` allocator: a robot that obeys the base station's MHM orders (Mukhija et al., section III-D;
the planning is the base's, ``planner.py``, run by ``station.py`` in the base process).

Each tick the robot keeps the newest :class:`~.orders.MhmOrders` it heard (by ``plan_tick``; copies relayed late
are older and ignored) and decides from it alone:

- A **node** holds: it stands on its node's cell, a relay (section III: "a node does not move"). Should it
  not yet be there (orders that moved on while it drove), it drives to that cell like an explorer.
- An **explorer** drives to its goal inside the relays' reach: the cells within r_comm of a relay cell of
  the orders (the base, the hinged nodes) that its own map does not know to be occupied, the cell it stands
  on included. Explorers stay in range of a relay at every step (section III). The base plans every goal and
  its way over its *team* map's safe area; the robot's map may not know that way yet (a room a teammate
  explored), so the robot drives over the cells it does not know as well, and re-plans each tick as it sees
  them (it sees a cell before it steps on it). Its way goes around the node robots standing on their relay
  cells, as the base's paths do: a node does not move, and a robot whose shortest way ran through one stepped
  aside and back, tick after tick. Driving over known-free cells only, a robot sent to a room it
  never saw stood still until the base sent another robot.
- **Without a usable order** (none heard yet, no goal, a goal outside the relays' reach, or no path to it
  inside that reach) the robot keeps its *last safe position*: the last cell it stood on that was
  in the safe area of the orders it had then. It holds there. Standing outside the safe area of its newest
  orders (its relay unhinged before it heard of it), it drives over its known-free cells to the nearest
  cell of that safe area, or, when it knows no way there, back to its last safe cell. It never drives out
  of range on an old plan. Choice: the paper's robots hear every order at once; over a lossy multi-hop
  radio they do not, and this is the conservative reading of "a robot is never farther than r_comm".
- Each tick it follows orders, it answers the base with an ``MhmAck`` (their plan tick, its cell), which the
  base waits for before it breaks a tree.
- The orders' ``routes`` go to the robot's relay (``Allocation.routes``, applied by the brain to the
  ``tree`` policy) when new orders arrive: forwarding decisions of the tick an order arrives use the routes
  before it. A node also takes as its children the explorers it heard last tick within r_comm (every tick):
  the base routes an explorer through the relay nearest the cell it last heard it at, which is stale once the
  explorer moves on; an explorer that left that relay's range for another's would otherwise be heard by
  nobody who forwards (its acks and beacons lost, its orders not forwarded to it) while still in range.

Parameters: ``r_comm`` and ``sensor_range`` in cells (in a run: the scenario's radio, ``Scenario.link_cells``,
and sensor), ``x_min`` eq. 1's X_min, ``hinges`` the cap on hinge points per Wavefront Expansion iteration
(0: none), ``method`` how the base grows the tree (``mhm``, or ``shm``: the Single Hinged Method the paper
compares MHM with, ``shm.py``), ``cluster_max`` frontier cells per cluster and ``patience`` ticks without
progress before a planner's wait ends. The base builds its planner from the same parameters (:func:`mhm_config`),
so robots and base agree on r_comm. The allocator draws no random numbers.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from fleet_emu.agents.allocators.interface import Allocation, Allocator, Problem
from fleet_emu.agents.allocators.mhm.explore import descend, reach_area, safe_area
from fleet_emu.agents.allocators.mhm.orders import MhmAck, MhmOrders
from fleet_emu.agents.allocators.mhm.planner import METHODS, MhmConfig
from fleet_emu.agents.allocators.params import Param
from fleet_emu.core.grid import FREE, Cell
from fleet_emu.core.kernels import wavefront
from fleet_emu.core.keys import BASE
from fleet_emu.core.messages import RadioMsg


def mhm_config(params: dict[str, Any]) -> MhmConfig:
    """The planner's configuration from the allocator's parameters (``Mhm.params()``)."""
    return MhmConfig(r_comm=float(params["r_comm"]), sensor_range=float(params["sensor_range"]),
                     x_min=int(params["x_min"]), hinges=int(params["hinges"]), method=str(params["method"]),
                     cluster_max=int(params["cluster_max"]), patience=int(params["patience"]))


def _reaches(passable: np.ndarray, goal: Cell, me: Cell) -> bool:
    dist = wavefront(passable, np.array([goal[0] * passable.shape[1] + goal[1]], dtype=np.int64), -1)
    return bool(dist[me] > 0)


class Mhm(Allocator, plugin_name="mhm"):
    """Obeys the base station's MHM orders (module docstring)."""

    DESCRIPTION = "Mukhija et al.: a base station plans; robots hold relay posts or explore in its reach (needs --base)"

    parameters = {
        "r_comm": Param(20.0, gt=0),
        "sensor_range": Param(8.0, gt=0),
        "x_min": Param(1, ge=1),
        "hinges": Param(0, ge=0),
        "method": Param("mhm", choices=METHODS),
        "cluster_max": Param(30, ge=1),
        "patience": Param(60, ge=1),
    }
    scenario_fields = {"r_comm": "link_cells", "sensor_range": "sensor_cells"}
    r_comm: float
    sensor_range: float
    x_min: int
    hinges: int
    method: str
    cluster_max: int
    patience: int

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        self.order: MhmOrders | None = None
        self.last_safe: Cell | None = None

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self.order = None
        self.last_safe = None

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        fresh = False
        for msg in inbox:
            body = msg.body
            if isinstance(body, MhmOrders) and msg.origin == BASE and (
                    self.order is None or body.plan_tick > self.order.plan_tick):
                self.order, fresh = body, True
        me = problem.poses[problem.me]
        order = self.order
        routes = dict(order.routes) if fresh and order is not None else None
        if order is not None and order.roles.get(problem.me) == "node":
            routes = self._adopt(problem, me, order)
        if order is None or problem.me not in order.roles:
            return self._keep(problem, me, None, routes)
        ack = (RadioMsg(MhmAck(plan_tick=order.plan_tick, cell=me), dst=BASE),)
        return dataclasses.replace(self._obey(problem, me, order, routes), outbox=ack)

    def _adopt(self, problem: Problem, me: Cell, order: MhmOrders) -> dict[str, str]:
        """A node's routes: the base's, with every explorer it heard last tick within r_comm as its child too
        (module docstring)."""
        routes = dict(order.routes)
        for r, cell in problem.poses.items():
            if (order.roles.get(r) == "explorer" and problem.heard.get(r, -1) >= problem.tick - 1
                    and routes.get(r) != problem.me and math.dist(cell, me) < self.r_comm):
                routes[r] = problem.me
        return routes

    def _obey(self, problem: Problem, me: Cell, order: MhmOrders, routes: dict[str, str] | None) -> Allocation:
        safe = safe_area(problem.belief, order.relays, self.r_comm)
        if safe[me]:
            self.last_safe = me
        goal = order.goals.get(problem.me)
        if goal is None or goal == me:
            return self._keep(problem, me, safe, routes)
        passable = reach_area(problem.belief, order.relays, self.r_comm)
        if not passable[goal]:
            return self._keep(problem, me, safe, routes)
        standing = {cell for r, cell in problem.poses.items() if r != problem.me}
        for cell in order.relays[1:]:  # a node does not move: the way goes around it (the base's is not a body)
            if cell in standing and cell != goal:
                passable[cell] = False
        passable[me] = True
        if not _reaches(passable, goal, me):
            return self._keep(problem, me, safe, routes)
        return Allocation.goal(goal, passable, routes)

    def _keep(self, problem: Problem, me: Cell, safe: np.ndarray | None, routes: dict[str, str] | None
              ) -> Allocation:
        """Hold the last safe position; standing outside the safe area, go into it (module docstring)."""
        if safe is None or safe[me]:
            return Allocation.hold(routes)
        passable = problem.belief == FREE
        passable[me] = True
        dist = wavefront(passable, np.flatnonzero(safe).astype(np.int64), -1)
        if dist[me] > 0:
            return Allocation.goal(descend(dist, me), passable, routes)
        back = self.last_safe
        if back is None or back == me or not _reaches(passable, back, me):
            return Allocation.hold(routes)
        return Allocation.goal(back, passable, routes)
