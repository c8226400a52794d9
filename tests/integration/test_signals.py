"""SIGINT and SIGTERM at any moment: a request the runner honours through its normal teardown, so that
``result.json`` and a readable ``run.mcap`` are always written, and no process is left behind."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.runner import RunOptions, run_fleet
from fleet_emu.launch.signals import Interrupts
from fleet_emu.recording.monitor import Monitor
from tests.harness.cli import ENDLESS, ROOT, result
from tests.harness.procs import all_pids, pid_alive


def _files_are_whole(out: Path, res: dict) -> None:
    assert result(out) == {**res, "scenario": res["scenario"]}  # on disk, whole, and what the call returned
    with open(out / "run.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    assert sum(summary.statistics.channel_message_counts.values()) == res["recording"]["messages"]
    deadline = time.monotonic() + 10
    while any(pid_alive(p) for p in all_pids(res)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(pid_alive(p) for p in all_pids(res))


def _scenario(small_map: Path, max_ticks: int) -> Scenario:
    return Scenario().override(map=str(small_map), robots=2, max_ticks=max_ticks, seed=1)


def test_a_signal_before_anything_started_still_writes_both_files(small_map: Path, tmp_path: Path) -> None:
    irq = Interrupts()
    irq._handle(signal.SIGTERM, None)
    res = run_fleet(_scenario(small_map, 50), RunOptions(out_dir=tmp_path / "run", interrupts=irq)).data
    assert res["reason"] == "interrupted" and res["signal"] == "SIGTERM" and res["ticks"] == 0
    assert res["pids"] == {}
    assert irq.exit_code == 143
    with open(tmp_path / "run" / "run.mcap", "rb") as f:
        assert make_reader(f).get_summary() is not None


@pytest.mark.slow  # signals over processes: the sigint trial by default
def test_two_signals_mid_run_skip_the_wait_but_keep_the_files(small_map: Path, tmp_path: Path) -> None:
    irq = Interrupts()

    def progress(m: Monitor) -> None:
        if m.tick >= 3 and irq.count == 0:
            irq._handle(signal.SIGINT, None)
            irq._handle(signal.SIGINT, None)

    out = tmp_path / "run"
    res = run_fleet(_scenario(small_map, 100000), RunOptions(out_dir=out, interrupts=irq, on_progress=progress)).data
    assert irq.hurry.is_set() and irq.exit_code == 130
    assert res["reason"] == "interrupted" and res["signal"] == "SIGINT" and 3 <= res["ticks"] < 100000
    _files_are_whole(out, res)


@pytest.mark.slow  # signals over processes: the sigint trial by default
def test_a_signal_during_teardown_keeps_the_run_as_it_ended(small_map: Path, tmp_path: Path) -> None:
    irq = Interrupts()

    def progress(m: Monitor) -> None:
        if m.stop is not None and irq.count == 0:  # the world has stopped: the launcher is tearing down
            irq._handle(signal.SIGTERM, None)

    out = tmp_path / "run"
    res = run_fleet(_scenario(small_map, 8), RunOptions(out_dir=out, interrupts=irq, on_progress=progress)).data
    assert irq.count == 1
    assert res["reason"] == "max_ticks" and res["ticks"] == 8 and res["signal"] == "SIGTERM"
    _files_are_whole(out, res)


@pytest.mark.slow  # signals over processes: the sigint trial by default
@pytest.mark.parametrize("sig, code, delay", [
    (signal.SIGINT, 130, 1.5),
    # SIGTERM mid-run exits 143 in test_security.py
    (signal.SIGTERM, 143, 4.0)])
def test_the_cli_exits_128_plus_the_signal_during_start_up(tmp_path: Path, sig: int, code: int,
                                                          delay: float) -> None:
    out = tmp_path / "run"
    # one robot on ENDLESS runs for minutes: the signal cannot come after a natural end
    proc = subprocess.Popen([sys.executable, "-m", "fleet_emu.launch", "run", *ENDLESS.args(robots=1), "--out",
                             str(out), "--quiet"], cwd=ROOT, stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err[-2000:]
    assert "Traceback" not in err
    assert err.strip().splitlines()[-1].startswith(f"fleet: interrupted by {signal.Signals(sig).name}")
    res = result(out)
    assert res["reason"] == "interrupted" and res["completed"] is False
    with open(out / "run.mcap", "rb") as f:
        assert make_reader(f).get_summary() is not None
    if res["pids"]:
        deadline = time.monotonic() + 10
        while any(pid_alive(p) for p in all_pids(res)) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not any(pid_alive(p) for p in all_pids(res))
