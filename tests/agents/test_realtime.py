"""The robot's side of real-time mode: the plan a decision leaves, the steps along it while the next decision
runs, the observations merged in between, and the timing summary."""

from __future__ import annotations

import numpy as np

from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.brain import Brain, BrainConfig, Plan
from fleet_emu.agents.realtime import STALE, Timing, percentiles
from fleet_emu.core.grid import STAY, UNKNOWN, from_ascii
from fleet_emu.core.messages import Observation

CORRIDOR = """
###########
?.......0.?
###########
"""


def _obs(art: str, robot: str, tick: int, only: slice | None = None) -> Observation:
    grid, robots = from_ascii(art)
    cells = np.flatnonzero(grid.ravel() != UNKNOWN).astype(np.int32)
    if only is not None:
        cells = cells[only]
    return Observation(src="world", tick=tick, seq=0, robot=robot, cell=robots[robot], shape=grid.shape,
                       cell_size=0.5, cells=cells, values=grid.ravel()[cells].copy())


def _brain() -> Brain:
    return Brain("r0", make_allocator({"type": "nearest"}), np.random.default_rng(0), BrainConfig(),
                 team=frozenset({"r0"}))


def test_a_decision_leaves_a_plan_that_later_ticks_step_along() -> None:
    brain = _brain()
    cmd, _ = brain.step(_obs(CORRIDOR, "r0", 0), ())
    plan = brain.plan
    assert plan is not None and plan.status == "ASSIGNED" and plan.target == cmd.target
    assert cmd.move == (0, 1)  # the frontier on the right is nearer
    assert plan.step((1, 8)) == (0, 1)
    assert plan.step((1, 9)) == STAY  # at the frontier
    assert plan.step((1, 4)) == (0, 1)  # from a cell the robot reached since, still down the same wavefront


def test_no_plan_stays() -> None:
    assert Plan(None, None, "NO_FRONTIER").step((3, 3)) == STAY


def test_while_deciding_the_robot_steps_its_last_plan_or_waits_without_one() -> None:
    timing = Timing()
    waiting = timing.stale_command("r0", 3, 11, (1, 8), None)
    assert waiting.move == STAY and waiting.status == STALE and waiting.tick == 3
    dist = np.full((3, 11), -1, dtype=np.int32)
    dist[1, 1:10] = np.arange(8, -1, -1)  # the wavefront of the cell (1, 9)
    step = timing.stale_command("r0", 4, 12, (1, 5), Plan(dist, (1, 9), "ASSIGNED"))
    assert step.move == (0, 1) and step.target == (1, 9) and step.status == STALE
    assert (timing.waits, timing.plan_steps, timing.decisions) == (1, 1, 0)


def test_observations_absorbed_between_decisions_reach_the_belief() -> None:
    brain = _brain()
    brain.absorb(_obs(CORRIDOR, "r0", 0, only=slice(0, 5)))  # came while a decision ran
    assert brain.belief is not None
    seen = int((brain.belief.grid != UNKNOWN).sum())
    assert seen == 5
    brain.step(_obs(CORRIDOR, "r0", 1, only=slice(5, None)), ())
    grid, _ = from_ascii(CORRIDOR)
    assert int((brain.belief.grid != UNKNOWN).sum()) == int((grid != UNKNOWN).sum())


def test_decision_time_percentiles() -> None:
    timing = Timing()
    for ms in range(1, 101):
        timing.decided(float(ms))
    p = percentiles(timing.decision_ms)
    assert p["p50"] == 50.5 and p["p90"] == 90.1 and p["p99"] == 99.01 and p["max"] == 100.0 and p["mean"] == 50.5
    assert timing.decisions == 100
    assert percentiles([]) == {"p50": 0.0, "p90": 0.0, "p99": 0.0, "max": 0.0, "mean": 0.0}
