"""The launcher's honest ends: the wait on a clean world exit, the CLI's exit codes and the summary's labels."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import pytest
from rich.table import Table

from fleet_emu.core.messages import Stop
from fleet_emu.core.radio import radio_label
from fleet_emu.launch import watch
from fleet_emu.launch.cli import exit_code
from fleet_emu.recording.monitor import Monitor
from fleet_emu.recording.tables import summary_table


class _Sup:
    """A supervisor whose world (and netem) already exited with code 0."""

    def __init__(self, dead: dict[str, int]) -> None:
        self._dead = dead

    def dead(self) -> dict[str, int]:
        return dict(self._dead)


class _Consumer:
    def __init__(self, backlog: list[int] | None = None) -> None:
        self.changed = threading.Event()
        self.pending = backlog or []
        self.fault: str | None = None  # the recording's write error (none here)

    def backlog(self) -> int:
        """The launcher's samples still to fold: one value per call, then none."""
        return self.pending.pop(0) if self.pending else 0


def _wait(monitor: Monitor, dead: dict[str, int]) -> str | None:
    return watch.wait_for_end(monitor, _Consumer(), _Sup(dead), None, None, threading.Event(), lambda _: None)  # type: ignore[arg-type]


def test_a_clean_world_exit_waits_for_its_stop(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(watch, "STOP_GRACE", 3.0)
    monitor = Monitor(("r0",))
    stop = Stop(src="world", tick=30, seq=1, reason="max_ticks")
    threading.Timer(0.5, lambda: setattr(monitor, "stop", stop)).start()  # the stop lands after the exit
    t0 = time.monotonic()
    assert _wait(monitor, {"world": 0, "netem": 0}) is None
    assert time.monotonic() - t0 < 2.5


def test_the_grace_after_a_clean_world_exit_counts_from_an_empty_backlog(monkeypatch: pytest.MonkeyPatch) -> None:
    """A large fleet's last messages can take the launcher longer than the grace to fold: the stop may be among
    them, so the grace starts once nothing is left to fold."""
    monkeypatch.setattr(watch, "STOP_GRACE", 0.5)
    t0 = time.monotonic()
    consumer = _Consumer(backlog=[5] * 6)  # the wait polls every 0.2 s: about 1.2 s of backlog
    error = watch.wait_for_end(Monitor(("r0",)), consumer, _Sup({"world": 0}), None, None,  # type: ignore[arg-type]
                         threading.Event(), lambda _: None)
    assert error is not None and "no stop reached the launcher" in error
    assert not consumer.pending  # every poll saw the backlog, and the grace began after it
    assert time.monotonic() - t0 >= 0.5 + 5 * 0.2


def test_a_clean_world_exit_without_a_stop_is_an_error_after_the_grace(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(watch, "STOP_GRACE", 0.5)
    t0 = time.monotonic()
    error = _wait(Monitor(("r0",)), {"world": 0})
    assert error == "the world process exited with code 0 but no stop reached the launcher within 0.5 s"
    assert time.monotonic() - t0 >= 0.5


def test_a_crashed_world_is_an_error_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(watch, "STOP_GRACE", 30.0)
    t0 = time.monotonic()
    assert _wait(Monitor(("r0",)), {"world": 0, "netem": -9}) == "the netem process exited with code -9 (see netem.log)"
    assert time.monotonic() - t0 < 5.0


def _result(**over: Any) -> dict[str, Any]:
    base = {"run_id": "x", "map": "office", "allocator": "minpos", "robots": 3, "seed": 0, "comm": "wall",
            "loss": 0.1, "completed": True, "reason": "coverage", "failed": [], "coverage": 0.99, "ticks": 50,
            "t90": 40, "t99": 50, "path_length": [1, 2, 3], "connected_fraction": 1.0,
            "radio": {"sent": 1, "delivered": 1, "dropped_loss": 0, "dropped_signal": 0, "bytes_sent": 10},
            "decision_ms": {"mean": 0.1, "p95": 0.2}, "ticks_per_second": 100.0, "wall_seconds": 1.0,
            "recording": {"path": None, "messages": 0}}
    return base | over


@pytest.mark.parametrize("over, code", [
    ({}, 0),
    ({"completed": False, "reason": "max_ticks"}, 3),
    ({"failed": ["r2"]}, 1),  # the others reached the target: still a failed robot
    ({"failed": ["r0", "r1", "r2"], "completed": False, "reason": "no_robots"}, 1),
])
def test_exit_codes(over: dict[str, Any], code: int, capsys: pytest.CaptureFixture[str]) -> None:
    assert exit_code(_result(**over), Path("runs/x")) == code
    err = capsys.readouterr().err
    if code == 1:
        assert err.startswith(f"fleet: error: robot(s) {', '.join(over['failed'])} of 3 failed")
        assert err.count("\n") == 1
    else:
        assert err == ""


def test_the_radio_label_shows_the_loss_applied() -> None:
    assert radio_label("ideal", 0.1) == "ideal, no loss"
    assert radio_label("wall", 0.1) == "wall, loss 0.1"
    assert radio_label("full", 0.0) == "full, no loss"


def _rows(table: Table) -> dict[str, str]:
    """The summary table's rows as {metric: value}."""
    metric, value = table.columns
    return dict(zip(metric.cells, value.cells, strict=True))  # type: ignore[arg-type]


def test_the_summary_names_the_failed_robots() -> None:
    rows = _rows(summary_table(_result(failed=["r1", "r2"], comm="ideal"), "o"))
    assert rows["failed robots"] == "r1, r2"
    assert rows["radio"] == "ideal, no loss"
    assert _rows(summary_table(_result(), "o"))["failed robots"] == "none"


def test_the_stop_is_put_again_until_every_node_exits() -> None:
    """A node that subscribed after the launcher's stop was put (one still starting when Ctrl-C came) takes a
    later put: ``wait_all`` calls ``again`` every :data:`AGAIN` seconds until the children are gone, and then
    no more."""
    import subprocess
    import sys

    from fleet_emu.launch.supervisor import AGAIN, Supervisor

    sup = Supervisor()
    child = subprocess.Popen([sys.executable, "-c", "import sys; sys.stdin.readline(); sys.stdin.readline()"],
                             stdin=subprocess.PIPE, text=True)
    sup.children["world"] = child
    puts: list[float] = []

    def again() -> None:  # the child "subscribes" late: it ends on the second put it reads
        puts.append(time.monotonic())
        assert child.stdin is not None
        child.stdin.write("stop\n")
        child.stdin.flush()

    assert sup.wait_all(30 * AGAIN, again=again)
    assert child.returncode == 0 and len(puts) >= 2
    n = len(puts)
    assert sup.wait_all(30 * AGAIN, again=again) and len(puts) == n  # nothing left to stop: no more puts
