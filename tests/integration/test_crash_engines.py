"""A crash fault over processes (``[[faults]]``): the launcher kills the robot's process when the world has taken
it out at its tick, the others go on, and the result is the memory engine's for the seed, field for field; the
exit code is the run's own (0 at the target), not a failed robot's 1, since the scenario asked for the crash."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import deterministic
from tests.harness.cli import run_cli

SCENARIO = """\
name = "crash"
seed = 1

[map]
name = "maze"
cell_size = 2.0

[[faults]]
robot = "r1"
tick = 30
kind = "crash"
"""


@pytest.mark.slow  # a crash over processes; memory engine by default
@pytest.mark.parametrize("engine", ["processes", "in-process"])
def test_a_crash_over_zenoh_is_the_memory_engines(tmp_path: Path, engine: str) -> None:
    """Over processes the robot is killed; in the launcher's process (``--in-process``) it sits out the run and,
    as a killed one, sends no report: the same result either way."""
    file = tmp_path / "crash.toml"
    file.write_text(SCENARIO)
    out = tmp_path / "run"
    flags = ["--in-process"] if engine == "in-process" else []
    code, _, err = run_cli(["run", "--scenario", str(file), "--out", str(out), "--quiet", "--no-record", *flags])
    result = json.loads((out / "result.json").read_text())
    assert code == 0, err
    assert result["engine"] == engine and result["faults"] == [{"robot": "r1", "tick": 30, "kind": "crash"}]
    assert result["failed"] == ["r1"] and result["completed"]
    assert "r1" not in result["robot_peak_rss_kb"]  # killed at tick 30 (left alone, it would report at the stop)
    in_memory = Fleet(Scenario.load(file)).run()
    assert deterministic(in_memory.data) == deterministic(result)
