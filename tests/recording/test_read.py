"""``load_recording``: a real run read back as in a notebook, the schema version a recording carries, bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import Writer

import fleet_emu
from fleet_emu.core.errors import ReportError
from fleet_emu.core.messages import WorldState
from fleet_emu.core.version import SCHEMA_VERSION
from fleet_emu.recording import Run, load_recording
from fleet_emu.recording import recorder as recorder_module
from fleet_emu.recording.metrics import NOT_RECORDED
from fleet_emu.recording.recorder import Recorder
from tests.harness.cli import run_cli

TICK_NS = 100_000_000  # what the first round's recorder logged a tick as

SCENARIO = {"robots": 2, "cell_size": 0.5, "map": "art", "seed": 3, "allocator": {"type": "minpos"},
            "radio": {"loss": 0.1, "comm": "wall", "threshold": 0.0}, "target_coverage": 0.99, "belief_every": 0}
COVERAGE = (0.2, 0.5, 0.95)


def test_a_real_run_reads_back_as_its_result(small_run: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = sorted(p.name for p in small_run.iterdir())
    run = load_recording(small_run)
    assert capsys.readouterr() == ("", "")  # prints nothing
    assert sorted(p.name for p in small_run.iterdir()) == before  # writes nothing
    live = json.loads((small_run / "result.json").read_text())
    assert isinstance(run, Run) and not run.truncated
    assert set(run.result) == set(live) - set(NOT_RECORDED)  # the launcher's clock and signals are not on the bus
    for key, value in live.items():
        if key == "pids":  # the world sends no Ready; netem and every agent do
            assert run.result[key]["robots"] == value["robots"] and run.result[key]["netem"] == value["netem"]
        elif key not in NOT_RECORDED:
            assert run.result[key] == value, key
    for k, v in run.result.items():  # metrics.json says every key of the result alike; its groups add to radio's
        assert ({g: run.metrics[k][g] for g in v} if k in ("radio", "decision_ms") else run.metrics[k]) == v, k
    assert run.metrics["truncated"] is False and "share" in run.metrics and "share" not in run.result
    assert run.scenario == live["scenario"]
    ticks, coverage = run.coverage_curve()
    assert ticks.dtype.kind == "i" and (np.diff(ticks) > 0).all() and len(ticks) == len(coverage)
    assert ticks[0] == 0 and ticks[-1] == live["ticks"]
    assert coverage[-1] == pytest.approx(live["coverage"], abs=1e-6)
    assert (np.diff(coverage) >= 0).all()
    if live["t90"] is not None:
        assert ticks[np.argmax(coverage >= 0.9)] == live["t90"]
    assert run.schema_version == SCHEMA_VERSION and run.fleet_emu_version == fleet_emu.__version__


def _states(tick_ns: int = TICK_NS) -> list[tuple[str, bytes, int]]:
    out = []
    for t, cov in enumerate(COVERAGE):
        st = WorldState(src="world", tick=t, seq=t, poses={"r0": (1, 1), "r1": (1, 2)}, live=("r0", "r1"),
                        coverage=cov, path_length={"r0": t, "r1": 0})
        out.append(("fleet/old/world/state", st.encode(), 1_000_000_000 + t * tick_ns))
    return out


def _first_round_recording(path: Path) -> None:
    """What the first round's recorder wrote: the scenario metadata (no versions) and the bus."""
    with open(path, "wb") as f:
        w = Writer(f)
        w.start(profile="", library="fleet-emu")
        w.add_metadata("scenario", {"run_id": "old", "scenario": json.dumps(SCENARIO)})
        ch = w.register_channel(topic="fleet/old/world/state", message_encoding="msgpack", schema_id=0)
        for seq, (_, data, wall_ns) in enumerate(_states()):
            w.add_message(ch, seq * TICK_NS, data, wall_ns, sequence=seq)
        w.finish()


def test_a_recording_without_version_is_read_as_schema_1(tmp_path: Path) -> None:
    _first_round_recording(tmp_path / "old.mcap")
    run = load_recording(tmp_path / "old.mcap")
    assert run.schema_version == 1 and run.fleet_emu_version is None
    assert run.result["ticks"] == 2 and run.result["coverage"] == 0.95 and run.result["t90"] == 2
    assert run.coverage_curve()[1].tolist() == list(COVERAGE)


@pytest.fixture
def newer(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A recording written by the Recorder of a fleet_emu one schema ahead of this one."""
    monkeypatch.setattr(recorder_module, "SCHEMA_VERSION", SCHEMA_VERSION + 1)
    rec = Recorder(tmp_path / "run.mcap", {"run_id": "new", "scenario": SCENARIO})
    for key, data, wall_ns in _states():
        rec.record(key, data, wall_ns)
    rec.close()
    return tmp_path


def test_a_newer_schema_is_refused(newer: Path) -> None:
    with pytest.raises(ReportError) as exc:
        load_recording(newer)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(str(newer / "run.mcap"))
    assert msg.endswith(f"was written by a newer fleet_emu (schema {SCHEMA_VERSION + 1}; this one reads up to "
                        f"{SCHEMA_VERSION}): upgrade fleet_emu to read it")


def test_fleet_report_of_a_newer_schema_is_one_line_exit_2(newer: Path) -> None:
    code, _, err = run_cli(["report", str(newer)])
    assert code == 2
    assert err.startswith("fleet: error: ") and err.count("\n") == 1 and "newer fleet_emu" in err, err
    assert not (newer / "metrics.json").exists()


def test_the_current_schema_reads(tmp_path: Path) -> None:
    rec = Recorder(tmp_path / "run.mcap", {"run_id": "now", "scenario": SCENARIO})
    for key, data, wall_ns in _states():
        rec.record(key, data, wall_ns)
    rec.close()
    run = load_recording(tmp_path)
    assert run.schema_version == SCHEMA_VERSION and run.fleet_emu_version == fleet_emu.__version__
    assert run.result["run_id"] == "now" and run.result["recording"]["messages"] == len(COVERAGE)


@pytest.mark.parametrize("case", ["missing", "dir", "text", "no_scenario", "bad_version"])
def test_bad_input_is_one_line(case: str, tmp_path: Path) -> None:
    path = tmp_path / "a.mcap"
    if case == "missing":
        path = tmp_path / "nope"
    elif case == "dir":
        path = tmp_path
    elif case == "text":
        path.write_text("hello\n")
    else:
        with open(path, "wb") as f:
            w = Writer(f)
            w.start()
            if case == "bad_version":
                w.add_metadata("scenario", {"run_id": "x", "scenario": json.dumps(SCENARIO), "schema_version": "two"})
            ch = w.register_channel(topic="x", message_encoding="msgpack", schema_id=0)
            w.add_message(ch, 0, b"\x80", 0)
            w.finish()
    with pytest.raises(ReportError) as exc:
        load_recording(path)
    assert str(exc.value) and "\n" not in str(exc.value)
