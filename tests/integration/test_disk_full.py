"""A full disk ends the run: a real 200 KiB tmpfs as ``--out`` (mounting needs root: the tests skip, saying so,
where it cannot be mounted). Every engine exits 1 within seconds with one line naming the folder and the error,
no traceback, no temporary file and no lock file left; a signal during that teardown changes the exit code,
never the line."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from fleet_emu.launch.outdir import LOCK, DiskFault
from tests.harness.cli import ROOT, run_cli
from tests.harness.files import tmpfs


@pytest.fixture
def tiny_disk(tmp_path: Path) -> Iterator[Path]:
    """A mounted 200 KiB tmpfs, unmounted after the test."""
    with tmpfs(tmp_path / "tiny", "200k") as mnt:
        yield mnt


def _strays(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if ".tmp" in p.name or p.name == LOCK)


def _one_line(err: str, out: Path) -> None:
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert f"cannot write the run's files in {out}" in err and "No space left on device" in err, err


def test_a_full_disk_ends_a_memory_run_with_one_line(tiny_disk: Path) -> None:
    out = tiny_disk / "run"
    code, _, err = run_cli(["run", "--engine", "memory", "--quiet", "--out", str(out)])
    assert code == 1
    _one_line(err, out)
    assert _strays(out) == []
    code, _, err = run_cli(["run", "--engine", "memory", "--quiet", "--no-record", "--out", str(tiny_disk / "x")])
    assert code == 1  # the disk is full: even result.json cannot be written; no temporary file is left
    _one_line(err, tiny_disk / "x")
    assert _strays(tiny_disk / "x") == []


@pytest.mark.slow  # a full disk over processes; memory engine by default
def test_a_full_disk_ends_a_run_over_processes(tiny_disk: Path) -> None:
    """The recorder thread of the launcher meets the full disk: the run ends, every process stopped."""
    out = tiny_disk / "run"
    proc = subprocess.run([sys.executable, "-m", "fleet_emu", "run", "--quiet", "--out", str(out)], cwd=ROOT,
                          capture_output=True, text=True, timeout=180)
    assert proc.returncode == 1, proc.stderr
    _one_line(proc.stderr, out)
    assert _strays(out) == []
    ours = subprocess.run(["pgrep", "-f", str(out)], capture_output=True, text=True).stdout.split()
    assert ours == [], "a process of the run outlived it"


def test_a_signal_during_the_teardown_changes_the_code_not_the_line(monkeypatch: pytest.MonkeyPatch,
                                                                   tmp_path: Path) -> None:
    """A disk fault whose teardown a SIGTERM (a real one, to this process) interrupts: 143, the same line."""
    from fleet_emu.launch import cli

    def faulty_run(args: object, interrupts: object) -> int:
        os.kill(os.getpid(), signal.SIGTERM)  # the handler turns it into a request, as during a teardown
        raise DiskFault(f"cannot write the run's files in {tmp_path}: No space left on device")

    monkeypatch.setattr(cli, "cmd_run", faulty_run)
    code, _, err = run_cli(["run", "--quiet", "--out", str(tmp_path)])
    assert code == 143
    _one_line(err, tmp_path)


def test_a_recording_fault_ends_the_wait_whatever_signal_came() -> None:
    """The launcher's wait returns the recording's fault first: a signal then cannot turn it into an interrupt."""
    import threading

    from fleet_emu.launch import watch
    from fleet_emu.recording.monitor import Monitor

    class Consumer:
        changed = threading.Event()
        fault = "cannot write the run's files in /x (run.mcap): No space left on device"

    requested = threading.Event()
    requested.set()
    assert watch.wait_for_end(Monitor(("r0",)), Consumer(), None, None, None,  # type: ignore[arg-type]
                              requested, lambda _: None) == Consumer.fault
