"""The robot side of ``mhm`` (``agents/allocators/mhm/robot.py``) and its orders (``orders.py``): a robot obeys
the base's newest order inside its relays' reach, holds without a usable one, and hands the order's
routes to its relay. Grids are ASCII art: ``B`` is where the base station stands (a free cell)."""

from __future__ import annotations

import msgspec
import numpy as np
import pytest

from fleet_emu.agents.allocators import AllocStatus, Problem, make_allocator
from fleet_emu.agents.allocators.mhm.orders import MhmAck, MhmOrders
from fleet_emu.agents.allocators.mhm.robot import Mhm
from fleet_emu.agents.brain import Brain, BrainConfig
from fleet_emu.core.codec import Context
from fleet_emu.core.errors import ConfigError, DecodeError
from fleet_emu.core.grid import FREE, OCCUPIED, UNKNOWN, from_ascii
from fleet_emu.core.messages import Envelope, Observation, RadioMsg, open_envelope, seal
from fleet_emu.core.scenario import Scenario

# r0 near the base; the corridor runs east; with r_comm = 4 the safe area around the base ends at column 5.
ART = """
##############
#B.0.........#
#..1.........#
##############
"""
BASE_CELL = (1, 1)
TEAM = frozenset({"r0", "r1", "base"})


def _grid() -> tuple[np.ndarray, dict[str, tuple[int, int]]]:
    grid, robots = from_ascii(ART.replace("B", "."))
    return grid, robots


def _orders(tick: int = 3, goals: dict | None = None, roles: dict | None = None, relays: tuple = (BASE_CELL,),
            routes: dict | None = None) -> MhmOrders:
    return MhmOrders(plan_tick=tick, roles=roles or {"r0": "explorer", "r1": "explorer"},
                     goals={"r0": (1, 4)} if goals is None else goals,
                     routes={"r0": "base", "r1": "base"} if routes is None else routes, relays=relays)


def _msg(body: MhmOrders, origin: str = "base") -> RadioMsg:
    return RadioMsg(body, origin=origin, src=origin, tick=body.plan_tick)


def _alloc(**over: object) -> Mhm:
    a = make_allocator({"type": "mhm", "r_comm": 4.0, "sensor_range": 2.0, **over})
    assert isinstance(a, Mhm)
    a.reset(np.random.default_rng(0))
    return a


def _problem(me: str = "r0", at: tuple[int, int] | None = None) -> Problem:
    grid, robots = _grid()
    if at is not None:
        robots[me] = at
    return Problem(me=me, poses=robots, belief=grid, clusters=[])


def test_without_an_order_a_robot_holds() -> None:
    a = _alloc()
    got = a.allocate(_problem(), ())
    assert got.status is AllocStatus.HOLD and got.target is None and got.routes is None


def test_an_explorer_drives_to_its_goal_inside_the_safe_area() -> None:
    a = _alloc()
    got = a.allocate(_problem(), [_msg(_orders())])
    assert got.status is AllocStatus.GOAL and got.target == (1, 4)
    assert got.passable is not None and got.passable[1, 4] and not got.passable[1, 6]  # d < 4 from (1, 1)
    assert got.routes == {"r0": "base", "r1": "base"}  # new orders: their routes
    again = a.allocate(_problem(), ())
    assert again.status is AllocStatus.GOAL and again.routes is None  # the same orders: no new routes


def test_a_robot_with_orders_acks_them_to_the_base_and_one_without_sends_nothing() -> None:
    a = _alloc()
    assert a.allocate(_problem(), ()).outbox == ()
    got = a.allocate(_problem(), [_msg(_orders(tick=7))])
    assert [(m.dst, m.body) for m in got.outbox] == [("base", MhmAck(plan_tick=7, cell=(1, 3)))]


def test_a_goal_outside_the_safe_area_is_not_obeyed_and_an_older_order_is_ignored() -> None:
    a = _alloc()
    got = a.allocate(_problem(), [_msg(_orders(goals={"r0": (1, 8)}))])  # 7 cells from the only relay
    assert got.status is AllocStatus.HOLD
    a.allocate(_problem(), [_msg(_orders(tick=5, goals={"r0": (1, 4)}))])
    stale = a.allocate(_problem(), [_msg(_orders(tick=4, goals={"r0": (2, 2)}))])  # relayed late: older
    assert stale.status is AllocStatus.GOAL and stale.target == (1, 4)


def test_an_explorer_drives_toward_a_goal_its_own_map_has_not_seen_but_not_through_a_known_wall() -> None:
    # The base's team map reaches (1, 4); this robot, at (1, 2), knows only columns 0-2 (a teammate saw the rest).
    a = _alloc()
    grid, robots = _grid()
    robots["r0"] = (1, 2)
    grid[:, 3:] = UNKNOWN
    blind = Problem(me="r0", poses=robots, belief=grid, clusters=[])
    got = a.allocate(blind, [_msg(_orders())])
    assert got.status is AllocStatus.GOAL and got.target == (1, 4)
    assert got.passable is not None and got.passable[1, 3] and not got.passable[1, 6]  # still d < r_comm
    grid[:, 3] = OCCUPIED  # it saw a wall across the corridor: no way to the goal it knows of
    walled = Problem(me="r0", poses=robots, belief=grid, clusters=[])
    assert a.allocate(walled, ()).status is AllocStatus.HOLD


def test_an_explorer_plans_around_a_node_standing_on_its_relay_cell() -> None:
    a = _alloc()
    node_cell = (1, 3)  # r1 hinged there: a relay of the orders, and it stands on it
    order = _orders(goals={"r0": (1, 4)}, roles={"r0": "explorer", "r1": "node"}, relays=(BASE_CELL, node_cell))
    grid, robots = _grid()
    robots |= {"r0": (1, 2), "r1": node_cell}
    got = a.allocate(Problem(me="r0", poses=robots, belief=grid, clusters=[]), [_msg(order)])
    assert got.status is AllocStatus.GOAL and got.passable is not None
    assert not got.passable[node_cell] and got.passable[2, 3]  # around it, not through it
    robots["r1"] = (2, 5)  # not yet on its cell: the cell is free to drive over
    got = a.allocate(Problem(me="r0", poses=robots, belief=grid, clusters=[]), ())
    assert got.passable is not None and got.passable[node_cell]


def test_a_node_holds_on_its_cell() -> None:
    a = _alloc()
    got = a.allocate(_problem(), [_msg(_orders(roles={"r0": "node", "r1": "explorer"}, goals={"r0": (1, 3)}))])
    assert got.status is AllocStatus.HOLD


def test_a_node_adopts_the_explorers_it_hears_in_range_as_children() -> None:
    a = _alloc()
    order = _orders(roles={"r0": "node", "r1": "explorer"}, goals={"r0": (1, 3)}, routes={"r0": "base", "r1": "base"})
    p = _problem()
    p.tick, p.heard = 5, {"r1": 4}  # r1 at (2, 3), one cell away, heard last tick
    assert a.allocate(p, [_msg(order)]).routes == {"r0": "base", "r1": "r0"}
    p.tick = 7  # r1 not heard for three ticks: the base's routes as they are
    assert a.allocate(p, ()).routes == {"r0": "base", "r1": "base"}


def test_orders_from_a_robot_are_not_obeyed() -> None:
    a = _alloc()
    assert a.allocate(_problem(), [_msg(_orders(), origin="r1")]).status is AllocStatus.HOLD


def test_outside_the_safe_area_it_drives_back_to_its_last_safe_cell() -> None:
    a = _alloc()
    a.allocate(_problem(at=(1, 3)), [_msg(_orders(goals={}))])  # (1, 3) safe: remembered
    # it stands at (1, 6), out of every relay's range (d < 4), next to the safe area of a relay at (1, 10)
    far = _orders(tick=9, goals={"r0": (1, 11)}, relays=(BASE_CELL, (1, 10)))
    got = a.allocate(_problem(at=(1, 6)), [_msg(far)])
    assert got.status is AllocStatus.GOAL and got.target == (1, 11)  # into the safe area, to its goal
    assert got.passable is not None and got.passable[1, 6] and got.passable[1, 7] and not got.passable[1, 5]
    lost = _orders(tick=10, goals={"r0": (1, 11)}, relays=(BASE_CELL,))
    back = a.allocate(_problem(at=(1, 6)), [_msg(lost)])
    assert back.status is AllocStatus.GOAL and back.target == (1, 4)  # the nearest safe cell (d < 4 from B)
    grid, robots = _grid()
    grid[1:3, 5] = 100  # a wall between it and the safe area: it knows no way in but back where it came from
    grid[1, 5] = 0
    walled = Problem(me="r0", poses=robots | {"r0": (1, 6)}, belief=grid, clusters=[])
    assert a.allocate(walled, ()).target == (1, 4)
    grid[1, 5] = 100
    shut = Problem(me="r0", poses=robots | {"r0": (1, 6)}, belief=grid, clusters=[])
    assert a.allocate(shut, ()).status is AllocStatus.HOLD  # no way at all: it holds


def _obs(cell: tuple[int, int], tick: int) -> Observation:
    grid, _ = _grid()
    cells = np.flatnonzero(grid >= FREE).astype(np.int64)
    return Observation(src="world", tick=tick, seq=1, robot="r0", cell=cell, shape=grid.shape, cell_size=0.5,
                       cells=cells, values=grid.reshape(-1)[cells].copy())


def _brain(**cfg: object) -> tuple[Brain, list[str]]:
    drops: list[str] = []
    brain = Brain("r0", _alloc(), np.random.default_rng(0), BrainConfig(**cfg), team=TEAM,  # type: ignore[arg-type]
                  on_drop=lambda key, why: drops.append(why))
    return brain, drops


def test_the_brain_steps_toward_the_goal_and_applies_the_routes() -> None:
    brain, drops = _brain(relay="tree", relay_ttl=3)
    env = seal(RadioMsg(_orders(routes={"r0": "base", "r1": "r0"}), ttl=3), "base", 3, 1)
    cmd, out = brain.step(_obs((1, 3), 4), [env])
    assert cmd.move == (0, 1) and cmd.status == "GOAL" and cmd.target == (1, 4) and drops == []
    assert brain.relay is not None and brain.relay.routes == {"r0": "base", "r1": "r0"}
    # routes apply from the next tick: the order that brought them went by on the routes r0 had (none)
    assert not any(e.origin == "base" for e in out)
    nxt = seal(RadioMsg(_orders(tick=4, routes={"r0": "base", "r1": "r0"}), ttl=3), "base", 4, 2)
    _, out = brain.step(_obs((1, 4), 5), [nxt])
    assert [e.seq for e in out if e.origin == "base" and e.src == "r0"] == [2]  # r0 has a child (r1): forwards


def test_a_malformed_order_is_counted_and_dropped() -> None:
    brain, drops = _brain()
    bad = seal(RadioMsg(_orders(roles={"r0": "pilot", "r1": "explorer"})), "base", 3, 1)
    cmd, _ = brain.step(_obs((1, 3), 4), [bad])
    assert cmd.status == "HOLD" and cmd.move == (0, 0) and len(drops) == 1 and "pilot" in drops[0]


@pytest.mark.parametrize("change", [
    {"roles": {"r7": "explorer"}}, {"roles": {"base": "node"}}, {"goals": {"r0": (9, 9)}},
    {"routes": {"r0": "r0"}}, {"routes": {"r0": "r9"}}, {"relays": ()}, {"relays": ((40, 1),)},
    {"plan_tick": -1}, {"goals": {"r1": (1, 2)}, "roles": {"r0": "node"}},
])
def test_orders_round_trip_and_bad_ones_do_not_decode(change: dict) -> None:
    ctx = Context(senders=TEAM, shape=(4, 14))
    good = _orders()
    env = seal(RadioMsg(good), "base", 3, 1)
    assert open_envelope(env, ctx).body == good
    bad = msgspec.structs.replace(good, **change)
    with pytest.raises(DecodeError, match="mhm"):
        open_envelope(seal(RadioMsg(bad), "base", 3, 2), ctx)


def test_an_envelope_from_the_base_is_refused_by_a_team_without_it() -> None:
    env: Envelope = seal(RadioMsg(_orders()), "base", 3, 1)
    with pytest.raises(DecodeError):
        env.validate(Context(senders=frozenset({"r0", "r1"}), shape=(4, 14)))


def test_mhm_needs_a_base_and_relays_on_the_tree_by_default() -> None:
    with pytest.raises(ConfigError, match="needs base=True"):
        Scenario().override(allocator="mhm")
    s = Scenario().override(allocator="mhm", base=True)
    assert s.plans_at_base and s.relay == "tree" and s.relay_ttl == 16 and s.stall_ticks == 200
    assert Scenario().override(allocator="mhm", base=True, stall_ticks=40).stall_ticks == 40
    assert Scenario().override(allocator="mhm", base=True, relay="flood", relay_ttl=5).relay_ttl == 5
    assert Scenario().relay == "none" and not Scenario().plans_at_base
    assert Scenario().override(comm="disk", comm_range=3.0).link_cells == pytest.approx(6.0)
    # wall: eq. 4 through max_walls = 4 walls of 3.1 dB, PL 2: 10 m * 10^(-12.4/20) = 2.40 m = 4.80 cells
    assert Scenario().link_cells == pytest.approx(4.7977, abs=1e-3)
