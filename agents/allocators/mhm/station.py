"""The base station's side of ``mhm``: the :data:`~fleet_emu.agents.base.Planner` that runs the MHM planner
(section III-D, ``planner.py``) on what reached the base and broadcasts its orders (``orders.py``).

Each tick, after the base merged its rx bundle, :class:`MhmStation` steps :class:`~.planner.MhmPlanner` with
the base's view: its team map (the map deltas that reached it) and each robot's last heard cell (the ``cell``
of its last pose beacon, as old as the radio made it). Then it broadcasts one :class:`~.orders.MhmOrders`
(``dst = "*"``, hop limit the scenario's ``relay_ttl``), which netem delivers a tick later to the robots in
range, and the robots relay on: loss and hops delay the orders, or lose them.

Choices where the paper is silent, and why:

- *Start.* The paper's robots start in the base's range and the base knows where they are. Here the base
  knows a robot only once a beacon reached it, so the planner starts when every robot has been heard, or
  after ``patience`` ticks with the robots heard by then (a robot never heard gets no goal, holds, and is
  not in the plan). Until then the base sends nothing and the robots hold.
- *Poses.* The planner sees a robot at the cell of its newest beacon or ack that reached the base, not the
  cell a beacon says it moves to: a plan that waits for a robot to arrive then waits for a message sent from
  there. Each robot's newest ack also tells the planner which orders it follows (``View.follows``).
- *Orders every tick*, even unchanged: a robot that lost one hears the next; the message is small (a role
  and a goal per robot, the routes, the relay cells).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.allocators.mhm.orders import MhmAck, MhmOrders
from fleet_emu.agents.allocators.mhm.planner import MhmConfig, MhmPlanner, View
from fleet_emu.agents.allocators.mhm.robot import mhm_config
from fleet_emu.agents.base import BaseStation
from fleet_emu.agents.brain import allocator_config
from fleet_emu.core.grid import Cell
from fleet_emu.core.keys import BASE, robot_ids
from fleet_emu.core.messages import RadioMsg
from fleet_emu.core.rng import generator
from fleet_emu.core.scenario import Scenario


class MhmStation:
    """A base-station planner (``BaseStation(planner=MhmStation(...))``) for robots ``robots``."""

    def __init__(self, config: MhmConfig, robots: Sequence[str], rng: np.random.Generator, ttl: int) -> None:
        self.config = config
        self.robots = tuple(robots)
        self.rng = rng
        self.ttl = ttl
        self.planner: MhmPlanner | None = None
        self.acks: dict[str, tuple[int, int, Cell]] = {}  # robot -> (tick sent, plan tick followed, cell)
        self.first_tick: int | None = None

    def __call__(self, station: BaseStation) -> tuple[RadioMsg, ...]:
        for msg in station.mail:  # acks: the orders a robot follows, and where it stood then
            body = msg.body
            if isinstance(body, MhmAck) and msg.origin in self.robots:
                prev = self.acks.get(msg.origin)
                if prev is None or msg.tick > prev[0]:
                    self.acks[msg.origin] = (msg.tick, body.plan_tick, body.cell)
        poses = {}
        for r in self.robots:  # the newest of its beacon and its ack
            h, a = station.heard.get(r), self.acks.get(r)
            if a is not None and (h is None or a[0] > h.tick):
                poses[r] = a[2]
            elif h is not None:
                poses[r] = h.cell
        if self.first_tick is None:
            self.first_tick = station.tick
        if self.planner is None:
            waited = station.tick - self.first_tick
            if (len(poses) < len(self.robots) and waited < self.config.patience) or not poses:
                return ()
            self.planner = MhmPlanner(station.cell, sorted(poses), self.config, self.rng)
        p = self.planner
        follows = {r: a[1] for r, a in self.acks.items()}
        orders = p.step(View(station.tick, station.belief.grid, poses, follows))
        body = MhmOrders(
            plan_tick=station.tick,
            roles={r: o.role for r, o in orders.items()},
            goals={r: o.goal for r, o in orders.items() if o.goal is not None},
            routes=dict(sorted(p.routes().items())),
            relays=tuple(p.relays()),
            done=p.done)
        return (RadioMsg(body, dst="*", ttl=self.ttl),)


def station_planner(scenario: Scenario) -> MhmStation | None:
    """The base's planner of a run (None unless its allocator plans at the base): the scenario's ``mhm``
    parameters, as every robot builds them, and a generator of its own (eq. 3's draws)."""
    if not scenario.plans_at_base:
        return None
    params = make_allocator(allocator_config(scenario)).params()
    config = dataclasses.replace(mhm_config(params), latency=scenario.radio.latency)
    return MhmStation(config, robot_ids(scenario.robots), generator(scenario.seed, BASE, "mhm"), scenario.relay_ttl)
