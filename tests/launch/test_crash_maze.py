"""A crashed robot in the maze with one-cell corridors (``--map maze --cell-size 2.0``), on the memory engine: one
robot crashes at tick 30 (``[[faults]]``), and over ten seeds the others reach the target coverage in every run
where what is left to sense can still be reached around its body; in every other run ``result.json`` names the
crashed robot as the body that blocks (``blocked_by``), and the map confirms it: with that body as a wall, the
survivors cannot reach the target. Before robots sensed bodies, such a run stood behind the body until the
belief-stall window ended it (docs/guides/faults.md has the table)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fleet_emu.core.grid import FREE, flat
from fleet_emu.core.kernels import wavefront
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet, fleet_map
from tests.harness.cli import run_cli

SEEDS = range(10)
CRASH_TICK = 30


def crash_scenario(seed: int, robot: int) -> Scenario:
    """4 robots in the 2 m maze; ``robot`` crashes at tick 30."""
    return Scenario().override(map="maze", cell_size=2.0, seed=seed,
                               faults=[{"robot": robot, "tick": CRASH_TICK, "kind": "crash"}])


def reachable_around(scenario: Scenario, body: tuple[int, int], survivors: list[tuple[int, int]]) -> float:
    """The share of the free cells reachable from the start that the survivors can still reach (and so sense)
    with the failed robot's body as a wall: the most coverage they can get without sensing past it."""
    grid = fleet_map(scenario).grid
    free = grid == FREE
    start = fleet_map(scenario).start
    total = wavefront(free, np.array([flat(grid.shape, start)], np.int64), -1) >= 0
    walled = free.copy()
    walled[body] = False
    reach = wavefront(walled, np.array([flat(grid.shape, c) for c in survivors], np.int64), -1) >= 0
    return float((reach & total).sum() / (total & free).sum())


def test_survivors_reach_the_target_around_a_crashed_body_or_name_it() -> None:
    """Robot ``seed mod 4`` crashes, over ten seeds."""
    check_runs([(seed, seed % 4) for seed in SEEDS])


@pytest.mark.slow
def test_any_one_robot_crashing_in_any_seed() -> None:
    """Each of the four robots in turn, over the ten seeds (40 runs)."""
    check_runs([(seed, robot) for seed in SEEDS for robot in range(4)])


def check_runs(runs: list[tuple[int, int]]) -> None:
    """Each (seed, robot) run: the target reached, or the crashed robot named as the body that blocks, and the
    true map agreeing that the survivors could not reach the target around it."""
    rows = []
    for seed, robot in runs:
        s = crash_scenario(seed, robot)
        fleet = Fleet(s)
        r = fleet.run()
        crashed = f"r{robot}"
        assert r["faults"] == [{"robot": crashed, "tick": CRASH_TICK, "kind": "crash"}]
        assert r["failed"] == [crashed]
        poses = fleet.world.poses
        blocked = r.data.get("blocked_by")
        rows.append((seed, crashed, r["ticks"], r["completed"], r["reason"], blocked))
        if blocked is None:
            assert r["reason"] == "coverage" and r["completed"], rows[-1]
        else:
            assert list(blocked) == [crashed] and blocked[crashed]["cell"] == list(poses[crashed]), rows[-1]
            assert not r["completed"] and r["reason"] in ("stall", "max_ticks")
            survivors = [poses[x] for x in fleet.world.live]
            assert reachable_around(s, poses[crashed], survivors) < s.target_coverage, rows[-1]
    assert any(row[5] is None for row in rows)  # the seeds hold both kinds of run
    assert any(row[5] is not None for row in rows)


def test_fleet_run_crash_flag_exits_3_naming_the_body(tmp_path: Path) -> None:
    """``fleet run --crash ROBOT@TICK``: a run its crash walls in exits 3 (not a failed robot's 1) with a line
    naming the body; a flag not of that form, or naming a robot the fleet does not have, is one line, exit 2."""
    out = tmp_path / "run"
    base = ["run", "--engine", "memory", "--map", "maze", "--cell-size", "2.0", "--no-record", "--quiet"]
    code, _, err = run_cli([*base, "--seed", "6", "--crash", "1@30", "--out", str(out)])
    assert code == 3, err
    assert "r1's body at cell (13, 1) cut the other robots off from 15 cell(s) still to sense" in err
    for bad, says in (("r1", "--crash must be ROBOT@TICK"), ("r9@30", "--crash[0]: robot r9 is not one of")):
        code, _, err = run_cli([*base, "--crash", bad, "--out", str(tmp_path / "bad")])
        assert code == 2 and says in err and len(err.strip().splitlines()) == 1, err


def test_the_parallel_env_truncates_a_crashed_robot_as_it_leaves() -> None:
    """``Fleet.step`` (PettingZoo's ParallelEnv): the crashed robot's last step truncates it, and it is gone from
    ``agents`` and the observations after."""
    fleet = Fleet(crash_scenario(1, 1).override(faults=[{"robot": 1, "tick": 3}]))
    fleet.reset()
    for tick in (1, 2, 3):
        obs, _, _, trunc, _ = fleet.step()
        assert trunc["r1"] is (tick == 3) and ("r1" in obs) is (tick < 3)
    assert "r1" not in fleet.agents and fleet.possible_agents == ["r0", "r1", "r2", "r3"]
