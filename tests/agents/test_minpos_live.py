"""MinPos's Fig. 6 (Bautin et al. 2012, section 4.3 and its discussion) run live: small fleets stepped through the
real World, Channel and Brain objects (:mod:`tests.harness.lockstep`), with the radio's 1-tick latency, instead of
the static snapshots of test_minpos.py."""

from __future__ import annotations

from fleet_emu.core.grid import Cell
from tests.harness.lockstep import Trace, run_fleet

# Fig. 6(a): two robots follow each other up a stem to a T. The left branch is the shorter, so both head
# for its frontier first; "as soon as the first one moves away from" the right frontier, the second is first
# toward it and goes there. Rooms at both ends keep each robot busy on its own side.
T_JUNCTION = """
##############################
#....#################.......#
#............................#
#....#######.##########......#
#....#######.##########......#
############.#################
############.#################
############.#################
############0#################
############1#################
##############################
"""
STEM = 12


def _sides(trace: Trace, robot: str) -> set[str]:
    """The sides of the T a robot went into (more than two cells past the stem)."""
    cols = [c for _, c in trace.visited(robot)]
    return {side for side, went in (("left", min(cols) < STEM - 2), ("right", max(cols) > STEM + 2)) if went}


def test_fig6a_live_robots_following_each_other_separate_at_the_t() -> None:
    trace = run_fleet(T_JUNCTION, {"type": "minpos"}, sensor_range=3.0)
    assert trace.reason == "coverage"
    # the leader takes the shorter branch, the follower turns the other way at the T, and neither comes
    # back through the junction to the other side (with beacons one tick old the follower took the leader,
    # one cell ahead, for level with it, kept following it, and the run took 53 ticks instead of 30)
    assert _sides(trace, "r0") == {"left"}, trace.visited("r0")
    assert _sides(trace, "r1") == {"right"}, trace.visited("r1")
    # "With the nearest frontier algorithm both robots would have continued exploring the area behind F1"
    nearest = run_fleet(T_JUNCTION, {"type": "nearest"}, sensor_range=3.0)
    assert _sides(nearest, "r1") == {"left", "right"}, nearest.visited("r1")
    assert trace.ticks < nearest.ticks


# Fig. 6(c), the limit case: R3 has R2 and R1 in front of it toward the three frontiers ahead, so it is third
# toward each and turns back toward F4, where it is second behind R0; a greedy assignment gives it a frontier
# ahead (there are more frontiers than robots in that direction).
FIG6C = """
##############################
##############....#...#...####
##############....#...#...####
##############....#...#...####
###############.###.###.######
###############.###.###.######
#..0......3.2.1.........######
#.############################
#.############################
#.############################
#.############################
#.....########################
#.....########################
#.....########################
##############################
"""
BACK, AHEAD = 3, 14  # the columns F4's side lies left of, and the frontiers ahead right of


def _r3_targets(allocator: str) -> list[Cell | None]:
    trace = run_fleet(FIG6C, {"type": allocator}, sensor_range=4.0)
    assert trace.reason == "coverage"
    return [t["r3"] for t in trace.targets[1:4]]  # from tick 1, when every robot has heard every beacon


def test_fig6c_live_third_robot_turns_back_where_greedy_goes_ahead() -> None:
    minpos = _r3_targets("minpos")
    assert all(t is not None and t[1] < BACK for t in minpos), minpos
    greedy = _r3_targets("greedy")
    assert all(t is not None and t[1] >= AHEAD for t in greedy), greedy
