"""Robots' bodies in the world (world/sim.py): the sensor reports the cells that hold another robot, never as
map values (a body that moves on frees its cell); a crash fault takes a robot out at its tick, its body staying
where it stood; and a run that stalls behind a failed robot's body names it with the cells it holds off."""

from __future__ import annotations

import numpy as np

from fleet_emu.core.grid import FREE, STAY, flat, from_ascii
from fleet_emu.world.maps import MapData
from fleet_emu.world.sim import World, WorldConfig

CORRIDOR = """
###########
#0.1......#
###########
"""
RIGHT = (0, 1)


def _world(robots: int, **cfg: object) -> World:
    grid, marks = from_ascii(CORRIDOR)
    md = MapData(name="corridor", grid=grid, cell_size=0.5, start=marks["r0"])
    placement = tuple(marks[f"r{i}"] for i in range(robots))
    return World(md, [f"r{i}" for i in range(robots)], WorldConfig(placement=placement, **cfg))  # type: ignore[arg-type]


def test_the_sensor_reports_a_body_and_not_as_a_wall() -> None:
    w = _world(2, sensor_range=3.0)
    rd = w.reset()["r0"]
    shape = w.shape
    assert rd.bodies.tolist() == [flat(shape, (1, 3))]
    assert rd.values[rd.cells.tolist().index(flat(shape, (1, 3)))] == FREE  # the map's value, not the body
    assert rd.bodies.dtype == np.int32 and flat(shape, (1, 1)) not in rd.bodies.tolist()  # never its own
    rd = w.step({"r0": STAY, "r1": RIGHT})["r0"]
    assert rd.bodies.tolist() == [flat(shape, (1, 4))]  # it moved on: its old cell is free again
    rd = w.step({"r0": STAY, "r1": RIGHT})["r0"]
    assert rd.bodies.tolist() == []  # out of range


def test_a_crash_takes_the_robot_out_at_its_tick_and_its_body_stays() -> None:
    w = _world(2, sensor_range=3.0, crashes=(("r1", 2),))
    w.reset()
    w.step({"r0": STAY, "r1": RIGHT})
    assert w.live == ["r0", "r1"] and w.poses["r1"] == (1, 4)
    readings = w.step({"r0": RIGHT, "r1": RIGHT})  # tick 2: r1's command of tick 1 is the last it made
    assert w.tick == 2 and w.live == ["r0"] and set(readings) == {"r0"}
    assert w.poses["r1"] == (1, 5)
    assert readings["r0"].bodies.tolist() == [flat(w.shape, (1, 5))]
    for _ in range(4):
        w.step({"r0": RIGHT, "r1": RIGHT})  # a failed robot's moves are not applied
    assert w.poses == {"r0": (1, 4), "r1": (1, 5)}  # r0 cannot enter the failed robot's cell


def test_a_crash_at_tick_0_places_the_robot_without_it_sensing() -> None:
    w = _world(2, sensor_range=1.0, crashes=(("r1", 0),))
    readings = w.reset()
    assert set(readings) == {"r0"} and w.live == ["r0"] and w.poses["r1"] == (1, 3)


def test_a_stall_behind_a_failed_body_names_it_with_the_cells_it_holds_off() -> None:
    w = _world(2, sensor_range=1.0, stall_ticks=3, crashes=(("r1", 1),))
    w.reset()  # r1 senses (1, 2) and (1, 4) at tick 0, then crashes
    while not w.done:
        w.step({"r0": RIGHT})  # r0 walks up to the body and stays there
    assert w.reason == "stall" and w.poses["r0"] == (1, 2)
    assert w.blocked == {"r1": 5}  # (1, 5) to (1, 9): reachable from the start, never sensed, behind r1


def test_a_body_with_nothing_behind_it_blocks_nothing() -> None:
    w = _world(2, sensor_range=1.0, stall_ticks=3, crashes=(("r1", 1),))
    w.reset()
    w.step({"r0": RIGHT})
    assert w.live == ["r0"] and w.blocking() == {"r1": 5}
    w._sensed[1, 5:] = True  # what lies behind the body sensed already: nothing is held off
    assert w.blocking() == {}


def test_two_bodies_in_one_corridor_are_named_together() -> None:
    grid, marks = from_ascii("""
    ###########
    #0.12.....#
    ###########
    """)
    md = MapData(name="corridor", grid=grid, cell_size=0.5, start=marks["r0"])
    w = World(md, ["r0", "r1", "r2"], WorldConfig(placement=(marks["r0"], marks["r1"], marks["r2"]),
                                                  sensor_range=1.0, stall_ticks=3, crashes=(("r1", 1), ("r2", 1))))
    w.reset()
    while not w.done:
        w.step({"r0": STAY})
    assert w.blocked == {"r1": 4, "r2": 4}  # (1, 6) to (1, 9): neither body alone frees them
