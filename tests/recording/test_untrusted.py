"""Recordings are untrusted input: the scenario a recording carries is checked as a scenario file's is before
anything is sized from it, and a cut or inconsistent recording is refused, saying how much of it reads, unless
the user asks for that much (``--partial``, ``partial=True``). The adversary's own inputs: a few hundred bytes
of MCAP saying ``robots = 100000000`` (run under a 3 GB address-space limit: refused in one line, not a
MemoryError), metadata that is a list, and a real recording cut in half."""

from __future__ import annotations

import json
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from fleet_emu.core.errors import ReportError
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import run_memory
from fleet_emu.recording import load_recording
from fleet_emu.recording.recover import rewrite
from tests.harness.cli import ROOT, run_cli
from tests.harness.files import crafted

ADDRESS_SPACE = 3 << 30  # bytes: far more than fleet needs to refuse a file, far less than 100 million robots


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished run (memory engine) of several chunks: its run.mcap and result.json."""
    out = tmp_path_factory.mktemp("untrusted") / "run"
    run_memory(Scenario().override(map="office", robots=3, seed=1, max_ticks=200), out, run_id="whole")
    return out


@pytest.fixture
def half(finished: Path, tmp_path: Path) -> Path:
    """A copy of the finished run whose run.mcap is cut in half (its result.json kept)."""
    copy = tmp_path / "half"
    shutil.copytree(finished, copy)
    data = (finished / "run.mcap").read_bytes()
    (copy / "run.mcap").write_bytes(data[: len(data) // 2])
    return copy


def _limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))


@pytest.mark.parametrize("command", [["report", "--no-plots"], ["export", "ros2"]])
def test_a_recording_that_claims_a_hundred_million_robots_is_one_line(command: list[str], tmp_path: Path) -> None:
    mcap = crafted(tmp_path / "big.mcap", {"robots": 100_000_000, "cell_size": 1.0, "map": "office"})
    assert mcap.stat().st_size < 512  # the adversary's few hundred bytes
    if command[0] == "export":
        pytest.importorskip("rosbags")
        command = [*command, str(mcap), "--out", str(tmp_path / "bag")]
    else:
        command = [command[0], str(mcap), *command[1:]]
    proc = subprocess.run([sys.executable, "-m", "fleet_emu", *command], cwd=ROOT, capture_output=True, text=True,
                          timeout=120, preexec_fn=_limited)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr
    assert "robots must be from 1 to 256 (got 100000000)" in proc.stderr and str(mcap) in proc.stderr
    assert not (tmp_path / "bag").exists()


@pytest.mark.parametrize("scenario", [[1, 2, 3], "robots", {"robots": 2, "radio": [1]}, {"robots": "2"},
                                      {"robots": 2, "cell_size": float("nan")}, {"robots": 2, "name": "x" * 5000}])
def test_a_scenario_that_no_scenario_file_could_hold_is_one_line(scenario: object, tmp_path: Path) -> None:
    mcap = crafted(tmp_path / "odd.mcap", scenario)
    with pytest.raises(ReportError, match=r"odd\.mcap"):
        load_recording(mcap)
    for command in (["report", str(mcap), "--no-plots"], ["report", str(mcap), "--layout", str(tmp_path / "l")]):
        code, _, err = run_cli(command)
        assert code == 2 and err.startswith("fleet: error: ") and err.count("\n") == 1, err
    assert not (tmp_path / "l").exists()


def test_a_scenario_nested_past_a_scenario_files_limit_is_one_line(tmp_path: Path) -> None:
    mcap = crafted(tmp_path / "deep.mcap", json.loads("[" * 100 + "]" * 100))
    with pytest.raises(ReportError, match="nests 100 levels"):
        load_recording(mcap)


def test_a_recording_cut_in_half_is_named_with_how_much_reads(half: Path, finished: Path) -> None:
    recorded = json.loads((finished / "result.json").read_text())["recording"]["messages"]
    before = sorted(p.name for p in half.iterdir())
    code, out, err = run_cli(["report", str(half), "--no-plots"])
    assert code == 2 and err.count("\n") == 1, err
    assert "run.mcap is cut:" in err and f"of the {recorded} its run recorded" in err and "--partial" in err
    size = (half / "run.mcap").stat().st_size
    assert f"of its {size} bytes" in err
    assert sorted(p.name for p in half.iterdir()) == before  # nothing rewritten, nothing written

    with pytest.raises(ReportError, match=r"is cut: \d+ messages read"):
        load_recording(half)
    run = load_recording(half, partial=True)
    assert run.truncated and 0 < run.messages < recorded

    code, out, err = run_cli(["report", str(half), "--no-plots", "--partial"])
    assert code == 0, err
    assert "partial:" in out and f"its run recorded {recorded} messages" in out
    metrics = json.loads((half / "metrics.json").read_text())
    assert metrics["truncated"] is True and metrics["recording"]["messages"] < recorded


def test_a_bare_cut_file_is_refused_without_partial(finished: Path, tmp_path: Path) -> None:
    data = (finished / "run.mcap").read_bytes()
    (tmp_path / "cut.mcap").write_bytes(data[: len(data) // 2])
    code, _, err = run_cli(["report", str(tmp_path / "cut.mcap"), "--no-plots"])
    assert code == 2 and "cut.mcap is cut:" in err and err.count("\n") == 1
    assert run_cli(["report", str(tmp_path / "cut.mcap"), "--no-plots", "--partial"])[0] == 0


def test_a_whole_recording_with_fewer_messages_than_its_result_is_inconsistent(half: Path) -> None:
    """A cut copy rewritten whole (an indexed MCAP every reader opens) still holds half the run."""
    rewrite(half / "run.mcap", half / "whole.mcap")
    (half / "whole.mcap").replace(half / "run.mcap")
    with pytest.raises(ReportError, match=r"inconsistent with its result\.json"):
        load_recording(half)
    code, _, err = run_cli(["report", str(half), "--no-plots"])
    assert code == 2 and "inconsistent with its result.json" in err and err.count("\n") == 1
    assert load_recording(half, partial=True).truncated


def test_a_whole_run_reads_as_before(finished: Path) -> None:
    run = load_recording(finished)
    assert not run.truncated and run.recorded == run.messages
    assert run.scenario == json.loads((finished / "result.json").read_text())["scenario"]
