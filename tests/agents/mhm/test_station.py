"""The base station's side of ``mhm`` (``agents/allocators/mhm/station.py``): it plans only once it has heard its
robots, and then broadcasts one order per tick, sealed as the base's, that a robot's context decodes."""

from __future__ import annotations

import numpy as np

from fleet_emu.agents.allocators.mhm.orders import MhmAck, MhmOrders
from fleet_emu.agents.allocators.mhm.planner import MhmConfig
from fleet_emu.agents.allocators.mhm.station import MhmStation, station_planner
from fleet_emu.agents.base import BaseStation
from fleet_emu.agents.protocol import MapDelta, PoseBeacon
from fleet_emu.core.codec import Context
from fleet_emu.core.grid import from_ascii
from fleet_emu.core.messages import RadioMsg, open_envelope, seal
from fleet_emu.core.scenario import Scenario

ROOM = """
##########
#0.......#
#1.......#
#........#
##########
"""


def _station(patience: int = 5) -> BaseStation:
    grid, _ = from_ascii(ROOM)
    planner = MhmStation(MhmConfig(r_comm=4.0, sensor_range=2.0, patience=patience), ["r0", "r1"],
                         np.random.default_rng(0), ttl=6)
    return BaseStation((2, 2), grid.shape, frozenset({"r0", "r1"}), planner=planner)


def _heard(robot: str, cell: tuple[int, int], tick: int, seq: int) -> list:
    grid, _ = from_ascii(ROOM)
    cells = np.flatnonzero(grid >= -1).astype(np.int64)
    return [seal(RadioMsg(PoseBeacon(cell=cell)), robot, tick, seq),
            seal(RadioMsg(MapDelta(cells=cells, values=grid.reshape(-1)[cells].copy())), robot, tick, seq + 1)]


def test_the_base_plans_once_it_heard_every_robot_and_sends_an_order_each_tick() -> None:
    st = _station()
    assert st.step(0, []) == ()  # nobody heard: no plan, nothing sent
    assert st.step(1, _heard("r0", (1, 1), 0, 1)) == ()  # r1 not yet
    out = st.step(2, _heard("r1", (2, 1), 1, 1))
    assert len(out) == 1 and out[0].origin == out[0].src == "base" and out[0].dst == "*" and out[0].ttl == 6
    ctx = Context(senders=frozenset({"r0", "r1", "base"}), shape=(5, 10))
    body = open_envelope(out[0], ctx).body
    assert isinstance(body, MhmOrders) and body.plan_tick == 2 and set(body.roles) == {"r0", "r1"}
    assert body.relays[0] == (2, 2) and set(body.routes) == {"r0", "r1"}
    nxt = st.step(3, [])
    assert len(nxt) == 1 and nxt[0].seq > out[0].seq  # every tick, from the base's one counter


def test_after_patience_it_plans_with_the_robots_it_heard() -> None:
    st = _station(patience=3)
    st.step(0, _heard("r0", (1, 1), 0, 1))
    assert st.step(1, []) == () and st.step(2, []) == ()
    out = st.step(3, [])
    body = open_envelope(out[0]).body
    assert isinstance(body, MhmOrders) and set(body.roles) == {"r0"}  # r1 never heard: not in the plan


def test_only_a_base_planner_scenario_gets_a_station_planner() -> None:
    assert station_planner(Scenario()) is None and station_planner(Scenario().override(base=True)) is None
    p = station_planner(Scenario().override(allocator="mhm", base=True, comm="disk", comm_range=3.0))
    assert p is not None and p.config.r_comm == 6.0 and p.config.latency == 1 and p.ttl == 16


def test_acks_reach_the_planner_as_poses_and_the_orders_followed() -> None:
    st = _station()
    st.step(0, _heard("r0", (1, 1), 0, 1) + _heard("r1", (2, 1), 0, 1))
    ack = seal(RadioMsg(MhmAck(plan_tick=0, cell=(1, 2)), dst="base"), "r0", 1, 3)
    st.step(2, [ack])
    planner = st.planner.planner  # type: ignore[union-attr]
    assert planner is not None and planner.view is not None
    assert planner.view.poses["r0"] == (1, 2) and planner.view.poses["r1"] == (2, 1)  # the ack is newer
    assert dict(planner.view.follows) == {"r0": 0}
