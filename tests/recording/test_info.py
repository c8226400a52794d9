"""``fleet info RUN|MCAP``: a recording's summary, as ``mcap info`` prints one, checked against the run's own
``result.json`` and the mcap package's reading of every message."""

from __future__ import annotations

import collections
from pathlib import Path

from mcap.reader import make_reader

import fleet_emu as fe
from tests.harness.cli import run_cli


def _run(out: Path) -> dict:
    scenario = fe.Scenario().override(map="office", robots=2, seed=3, max_ticks=30, tick_s=0.5)
    return fe.run(scenario, engine="memory", out=out)


def test_info_prints_the_runs_channels_counts_duration_and_scenario(tmp_path: Path) -> None:
    result = _run(tmp_path / "run")
    code, out, err = run_cli(["info", str(tmp_path / "run")])
    assert code == 0 and err == "", err
    lines = out.splitlines()
    field = {ln.split(":", 1)[0]: ln.split(":", 1)[1].strip() for ln in lines if not ln.startswith("  ")}
    with open(tmp_path / "run" / "run.mcap", "rb") as f:
        counts = collections.Counter(ch.topic for _, ch, _ in make_reader(f).iter_messages())
    assert field["messages"] == f"{result['recording']['messages']} in {len(counts)} channels"
    assert field["run"] == f"{result['run_id']} (memory engine)"
    assert field["scenario"] == "default: office / minpos, 2 robots, seed 3, radio wall, loss 0.1"
    assert field["duration"] == f"{result['ticks'] * 0.5:.3f} s ({result['ticks']} ticks of 0.5 s, simulated time)"
    rows = {ln.split(")", 1)[1].split()[0]: int(ln.split(")", 1)[1].split()[1]) for ln in lines if ln.startswith("  (")}
    assert rows == dict(counts)
    assert "None" not in out


def test_a_cut_recording_is_read_up_to_its_last_record_and_said_so(tmp_path: Path) -> None:
    result = _run(tmp_path / "run")
    data = (tmp_path / "run" / "run.mcap").read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 3])  # past the first chunks, short of the last (and of the summary)
    code, out, _ = run_cli(["info", str(cut)])
    assert code == 0 and "no summary (cut)" in out.splitlines()[0]
    count = int(next(ln for ln in out.splitlines() if ln.startswith("messages:")).split()[1])
    assert 0 < count < result["recording"]["messages"]


def test_a_file_that_is_not_a_recording_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "x.mcap").write_text("hello")
    for path, line in ((tmp_path / "x.mcap", "is not an MCAP file"), (tmp_path / "none", "no such file")):
        code, _, err = run_cli(["info", str(path)])
        assert code == 2 and line in err and err.count("\n") == 1, err
