"""``fleet report RUN --layout FILE``: the layout of the run it is written for, sized from its recording."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import run_memory
from fleet_emu.recording.read import recorded_scenario
from tests.harness.cli import run_cli


def _beliefs(path: Path) -> set[str]:
    return {t for t in json.loads(path.read_text())["content"]["items"][0]["content"]["items"][0]["content"]
            ["config"]["topics"] if t.startswith("/viz/belief/")}


@pytest.fixture(scope="module")
def run3(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("run3")
    run_memory(Scenario().override(robots=3, max_ticks=2), out)
    return out


def test_the_layout_has_the_runs_robots_and_robots_overrides(run3: Path, tmp_path: Path) -> None:
    assert recorded_scenario(run3)["robots"] == 3
    code, _, err = run_cli(["report", str(run3), "--no-plots", "--layout", str(tmp_path / "a.json")])
    assert code == 0, err
    assert _beliefs(tmp_path / "a.json") == {"/viz/belief/r0", "/viz/belief/r1", "/viz/belief/r2"}
    code, _, err = run_cli(["report", str(run3), "--no-plots", "--layout", str(tmp_path / "b.json"), "--robots", "5"])
    assert code == 0, err
    assert len(_beliefs(tmp_path / "b.json")) == 5


def test_a_file_that_is_no_recording_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "run.mcap").write_text("not mcap")
    code, _, err = run_cli(["report", str(tmp_path), "--layout", str(tmp_path / "c.json")])
    assert code == 2 and err.count("\n") == 1 and "not an MCAP file" in err
