"""The stall rule reads the robots' own beliefs, on the memory engine with drawn maps: a fleet whose robots keep
learning is no stall although the fleet's union of what it sensed stays flat past the window (robots out of
range re-exploring what a teammate saw), and a fleet pacing without learning anything ends as one."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

from fleet_emu.core.grid import STAY, Cell, MapData, from_ascii
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet
from tests.harness.stall import oscillating

ROWS, COLS = 30, 30  # a 30 x 30 room: its diameter is 29 + 29 = 58 cells
ROOM = "\n".join(["#" * (COLS + 2), *("#" + "." * COLS + "#" for _ in range(ROWS)), "#" * (COLS + 2)])
LEFT = (2, 5, 8, 11, 14)  # the columns a sensor of one cell sweeps the left half along
DOWN, UP, RIGHT = (1, 0), (-1, 0), (0, 1)


def _fleet() -> Fleet:
    """Two robots at the room's top-left corner that never hear each other (a 1 cm disk radio), sensors of one
    cell, the window at twice the diameter (no floor)."""
    grid, _ = from_ascii(ROOM)
    s = Scenario(robots=2, allocator={"type": "nearest"}, sensor_range=0.5, coverage_stall_ticks=1,
                 target_coverage=0.99).override(comm="disk", comm_range=0.01, loss=0.0)
    starts: list[Cell] = [(1, 2), (1, 1)]
    return Fleet(s, map_data=MapData("room", grid, 0.5, starts[0]), starts=starts)


def _sweep() -> Iterator[Cell]:
    """The moves from (1, 2) down and up the :data:`LEFT` columns, ending at the bottom of the last one."""
    for i, col in enumerate(LEFT):
        yield from [DOWN if i % 2 == 0 else UP] * (ROWS - 1)
        if col != LEFT[-1]:
            yield from [RIGHT] * (LEFT[i + 1] - col)


def _known(fleet: Fleet, robot: str) -> int:
    belief = fleet.brains[robot].belief
    assert belief is not None
    return belief.known_cells


def test_robots_re_exploring_what_a_teammate_saw_are_no_stall() -> None:
    fleet = _fleet()
    fleet.reset()
    assert fleet.world.diameter == 58 and fleet.world.stall_window == 116
    for move in [*_sweep(), RIGHT]:  # r0 sweeps the left half while r1 waits; r0 then steps aside
        fleet.step({"r0": move, "r1": STAY})
    flat, r1_before = fleet.world.coverage, _known(fleet, "r1")
    ticks = 0
    for move in [RIGHT, *_sweep()]:  # r1 sweeps it again: all of it new to r1, none of it to the fleet
        fleet.step({"r0": STAY, "r1": move})
        ticks += 1
        assert fleet.world.coverage == flat and not fleet.done
    assert ticks > fleet.world.stall_window  # the fleet's coverage stayed flat past the window
    assert _known(fleet, "r1") > r1_before + 200
    while not fleet.done:  # then the brains explore the right half
        fleet.step()
    assert fleet.reason == "coverage" and fleet.result()["reason"] == "coverage"


def test_a_fleet_pacing_between_two_cells_ends_as_a_stall() -> None:
    fleet = _fleet()
    fleet.reset()
    last, best = 0, (0, 0)
    pace = [(DOWN, RIGHT), (UP, (0, -1))]
    while not fleet.done:
        fleet.step(dict(zip(("r0", "r1"), pace[fleet.world.tick % 2], strict=True)))
        known = (_known(fleet, "r0"), _known(fleet, "r1"))
        if any(k > b for k, b in zip(known, best, strict=True)):
            last, best = fleet.world.tick, known
    assert fleet.reason == "stall"
    assert fleet.world.tick == last + fleet.world.stall_window


def test_a_fleet_oscillating_between_targets_ends_as_a_stall(small_map: Path) -> None:
    fleet = Fleet(oscillating(small_map))
    res = fleet.run()
    w = fleet.world
    assert res["reason"] == "stall" and res["coverage"] < 1.0 and w.stall_window == 2 * w.diameter == 54
    assert w._idle == 0 and all(n > 50 for n in w.path_length.values())  # they kept moving to the end
    assert res["ticks"] < 400
