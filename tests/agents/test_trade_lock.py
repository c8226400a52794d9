"""A teammate in the way: the count of :mod:`agents.allocators.blocking` on drawn beliefs, and two trade robots
meeting head-on in a one-cell door on the memory engine, locked until ``task_timeout`` and beyond when a robot
keeps its task (``blocked_after = 0``), parted within a few ticks by default."""

from __future__ import annotations

from fleet_emu.agents.allocators import Problem
from fleet_emu.agents.allocators.blocking import BLOCKED_AFTER, Blockage, open_costs
from fleet_emu.agents.frontiers import find_clusters
from fleet_emu.core.grid import Cell, from_ascii
from tests.harness.lockstep import run_fleet

# A corridor two cells high toward one frontier (the unknown cell on the left); robots placed per test.
CORRIDOR = """
##########
?........#
#......###
##########
"""


def corridor(me: Cell, mate: Cell, tick: int = 10, heard: int = 9) -> Problem:
    """r1 at ``me`` deciding, r0 at ``mate`` heard at tick ``heard``."""
    grid, _ = from_ascii(CORRIDOR)
    return Problem(me="r1", poses={"r0": mate, "r1": me}, belief=grid, clusters=find_clusters(grid, 4), tick=tick,
                   heard={"r0": heard})


def test_a_teammate_on_the_only_step_counts_until_the_target_is_given_up() -> None:
    b = Blockage()
    ahead = corridor(me=(1, 8), mate=(1, 7))  # the corridor is one cell high at column 8: r0 holds the way
    assert [b.held(ahead, 0) for _ in range(BLOCKED_AFTER)] == [False] * (BLOCKED_AFTER - 1) + [True]
    b.clear()
    assert not any(b.held(ahead, 0, after=0) for _ in range(10))  # 0: never given up


def test_a_sidestep_and_back_is_no_progress_but_getting_past_is() -> None:
    b = Blockage()
    assert not b.held(corridor(me=(1, 6), mate=(1, 5)), 0)  # held at distance 5
    assert not b.held(corridor(me=(2, 6), mate=(1, 5)), 0)  # the brain's sidestep: open, nothing counted
    assert b.count == 1
    assert not b.held(corridor(me=(1, 6), mate=(1, 5)), 0)  # back, held again: the count goes on
    assert b.count == 2
    assert not b.held(corridor(me=(1, 5), mate=(2, 5)), 0)  # the teammate stepped aside: one cell nearer
    assert b.count == 0 and b.mark == -1


def test_a_teammate_not_heard_last_tick_is_not_in_the_way() -> None:
    b = Blockage()
    stale = corridor(me=(1, 8), mate=(1, 7), tick=10, heard=8)
    assert not any(b.held(stale, 0) for _ in range(2 * BLOCKED_AFTER)) and b.count == 0


def test_the_fresh_pick_ranks_only_clusters_the_robot_can_step_toward() -> None:
    grid, robots = from_ascii("""
    #########
    ?.01....?
    #########
    """)
    p = Problem(me="r1", poses=robots, belief=grid, clusters=find_clusters(grid, 4), tick=5)
    left = next(j for j, c in enumerate(p.clusters) if c.target[1] < 4)
    own = p.costs[p.index]
    assert own[left] < own[1 - left]  # the left frontier is the nearer, but r0 stands on the way to it
    costs = open_costs(p)
    assert costs[left] == float("inf") and costs[1 - left] == own[1 - left]


# Two rooms above a corridor, joined by a one-cell door at (4, 13). r0 starts at the bottom right, r1 at the top
# right; about tick 59 r0 stands west of the door heading for a task in the middle room below, r1 in the door
# heading for one in the top-left room, each stepping onto the other.
DOOR_MAP = """
##############################
#............#...............#
#............#..............1#
#............#...............#
#............................#
#............#...............#
#............#...............#
##############.###############
##############.###############
#............................#
#.......#..........#.........#
#.......#..........#......0..#
#.......#..........#.........#
##############################
"""
DOOR = (4, 13)


def at_the_door(poses: list[dict[str, Cell]]) -> int:
    """The longest run of ticks both robots spend within 2 cells (Chebyshev) of the door."""
    best = run = 0
    for p in poses:
        run = run + 1 if all(max(abs(r - DOOR[0]), abs(c - DOOR[1])) <= 2 for r, c in p.values()) else 0
        best = max(best, run)
    return best


def test_two_robots_head_on_in_a_door_part_within_a_few_ticks() -> None:
    kept = run_fleet(DOOR_MAP, {"type": "trade", "blocked_after": 0}, max_ticks=400, stall_ticks=400)
    assert kept.reason == "max_ticks"  # each kept its task: locked, past task_timeout (300), to the end
    assert at_the_door(kept.poses) >= 300
    parted = run_fleet(DOOR_MAP, {"type": "trade"}, max_ticks=400, stall_ticks=400)
    assert parted.reason == "coverage" and parted.ticks < 200
    assert at_the_door(parted.poses) < 5 * BLOCKED_AFTER  # one gave its task up, the other went through
