"""One definition of bytes sent (every emission's encoded envelope, once): ``result.json``'s ``radio.bytes_sent``,
``metrics.json``'s per-robot bytes and rate, ``fleet report``'s rows and the sweep tables agree."""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from rich.console import Console

from fleet_emu.core.radio import bytes_per_robot_tick
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import run_memory
from fleet_emu.recording.read import load_recording
from fleet_emu.recording.tables import summary_table
from fleet_emu.sweep.report import sent_kb


@pytest.mark.parametrize("bandwidth", [0.0, 8.0])
def test_the_report_metrics_and_result_count_the_same_bytes(bandwidth: float, tmp_path: Path) -> None:
    scenario = Scenario().override(robots=3, comm="full", bandwidth=bandwidth, max_ticks=25)
    result = run_memory(scenario, tmp_path)
    run = load_recording(tmp_path)
    sent, robots, ticks = result["radio"]["bytes_sent"], result["robots"], result["ticks"]
    detail = run.metrics["radio_detail"]
    assert sent > 0 and sum(v["bytes_sent"] for v in detail["per_robot"].values()) == sent
    rate = bytes_per_robot_tick(sent, robots, ticks)
    assert rate is not None and detail["bytes_per_robot_per_tick"] == pytest.approx(rate, abs=0.01)
    assert sent_kb({"ticks": ticks, "robots": robots, "radio.bytes_sent": sent}) == pytest.approx(rate / 1e3)
    console = Console(file=io.StringIO(), width=200)
    console.print(summary_table(run.metrics))
    text = console.file.getvalue()  # type: ignore[attr-defined]
    assert f"{rate:.0f} per robot-tick" in text
    assert ("airtime" in text and "dropped at a full queue" in text) == (bandwidth > 0)
