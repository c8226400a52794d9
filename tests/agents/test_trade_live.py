"""Trade live: a small fleet through ``World``, ``Channel`` and ``Brain`` (the memory engine, robots on the cells
drawn) with the real one-tick latency, robots moving during protocol rounds (``explore_in_round``) against the
first version that stood still through them."""

from __future__ import annotations

import pytest

from tests.harness.lockstep import run_fleet

# Three rooms off a corridor; the fleet starts in the left room.
TRUTH = """
##########################
#0.1.....#.......#.......#
#2.......#.......#.......#
#........#.......#.......#
#........................#
#........#.......#.......#
#........#.......#.......#
##########################
"""


def run_live(explore_in_round: bool, ticks: int = 300) -> tuple[int, dict[str, int]]:
    """Ticks to full coverage, and the idle robot-ticks by status as result.json counts them (a robot whose
    command was not NO_FRONTIER on the same cell the next tick)."""
    trace = run_fleet(TRUTH, {"type": "trade", "explore_in_round": explore_in_round}, sensor_range=3.0,
                      max_ticks=ticks, stall_ticks=ticks)
    assert trace.reason == "coverage", trace.reason
    return trace.ticks, dict(trace.result["idle_by_status"])


@pytest.fixture(scope="module")
def runs() -> dict[bool, tuple[int, dict[str, int]]]:
    return {explore: run_live(explore) for explore in (True, False)}


def test_robots_keep_exploring_during_rounds(runs: dict[bool, tuple[int, dict[str, int]]]) -> None:
    (moving_ticks, moving), (standing_ticks, standing) = runs[True], runs[False]
    assert standing.get("WAITING", 0) > 30  # the first version: every round spent standing still
    assert "WAITING" not in moving  # now: no robot-tick spent waiting on its cell
    assert sum(moving.values()) < sum(standing.values()) / 2  # what is left: steps blocked by a teammate
    assert moving_ticks < standing_ticks, (moving_ticks, standing_ticks)
