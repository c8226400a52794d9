"""The run folder is the run's own: a folder holding a run is refused unless ``--overwrite`` (which removes all
of that run's files first), a folder another run is writing is refused naming that run's pid (a real second
``fleet run`` at once), and a run killed with SIGKILL is made whole by ``fleet recover`` (and ``fleet report``)
so that the plain ``mcap`` indexed reader opens it. The runs here are the memory engine's: the folder's rules
and the recorder are the same objects on every engine."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from mcap.reader import make_reader

from fleet_emu.launch.outdir import LOCK
from fleet_emu.launch.result import validate_result
from tests.harness.cli import ROOT, run_cli

#: A run that goes on until stopped: one short-sighted robot in the office, the stall rules and the tick limit
#: out of reach.
ENDLESS = ('name = "endless"\nmax_ticks = 1000000000\ntarget_coverage = 1.0\nstall_ticks = 1000000000\n'
           'coverage_stall_ticks = 1000000000\n[map]\nname = "office"\n[fleet]\nrobots = 1\nsensor_range = 1.0\n')


def _strays(folder: Path) -> list[str]:
    """Temporary files and lock files left in ``folder``."""
    return sorted(p.name for p in folder.iterdir() if ".tmp" in p.name or p.name == LOCK)


@pytest.fixture
def endless(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[str], Path]]:
    """A real `fleet run --engine memory` writing ``tmp_path/run`` until stopped, once it holds the folder and
    its recording has a flushed chunk; killed on the way out if the test did not end it."""
    scenario = tmp_path / "endless.toml"
    scenario.write_text(ENDLESS)
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "fleet_emu", "run", str(scenario), "--engine", "memory",
                             "--quiet", "--out", str(out)],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not ((out / LOCK).is_file() and (out / LOCK).read_text().strip() == str(proc.pid)
                   and (out / "run.mcap").is_file() and (out / "run.mcap").stat().st_size > 20_000):
            assert proc.poll() is None and time.monotonic() < deadline, f"the run did not start: {proc.stderr}"
            time.sleep(0.2)
        yield proc, out
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.communicate()


def test_a_folder_holding_a_run_is_refused_unless_overwrite(small_map: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = ["run", "--map", str(small_map), "--engine", "memory", "--quiet", "--max-ticks", "5", "--out", str(out)]
    run_cli(args, check=True)
    first = json.loads((out / "result.json").read_text())
    for name in ("r2.log", "coverage.png", "metrics.json"):  # what an earlier run and its report leave
        (out / name).write_text("earlier")
    (out / "notes.txt").write_text("mine")
    code, _, err = run_cli(args)
    assert code == 2 and err.count("\n") == 1 and "holds a run" in err and "--overwrite" in err, err
    assert json.loads((out / "result.json").read_text()) == first  # nothing touched
    code, _, err = run_cli([*args, "--seed", "3", "--overwrite"])
    assert code in (0, 3), err
    assert json.loads((out / "result.json").read_text())["seed"] == 3
    assert not any((out / n).exists() for n in ("r2.log", "coverage.png", "metrics.json"))
    assert (out / "notes.txt").read_text() == "mine"  # not a run's file: kept
    assert _strays(out) == []


@pytest.mark.slow  # two live fleets over processes
def test_a_second_run_into_a_live_folder_is_refused_naming_its_pid(
        endless: tuple[subprocess.Popen[str], Path], small_map: Path) -> None:
    proc, out = endless
    for extra in ([], ["--overwrite"]):  # the processes engine, and with --overwrite: refused all the same
        code, _, err = run_cli(["run", "--map", str(small_map), "--quiet", "--out", str(out), *extra])
        assert code == 2 and err.count("\n") == 1, err
        assert f"in use by another run (pid {proc.pid})" in err, err
    code, _, err = run_cli(["recover", str(out)])  # nor may a recovery touch a live run
    assert code == 2 and f"pid {proc.pid}" in err, err
    proc.send_signal(signal.SIGINT)
    assert proc.wait(60) == 130
    result = json.loads((out / "result.json").read_text())
    validate_result(result)
    assert result["reason"] == "interrupted" and result["seed"] == 0
    with open(out / "run.mcap", "rb") as f:  # the first run's recording, whole and its own
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        assert sum(1 for _ in reader.iter_messages()) == summary.statistics.message_count == \
            result["recording"]["messages"]
    assert _strays(out) == []


def test_a_killed_run_is_recovered_into_a_file_any_mcap_reader_opens(
        endless: tuple[subprocess.Popen[str], Path], tmp_path: Path) -> None:
    proc, out = endless
    size = (out / "run.mcap").stat().st_size
    while (out / "run.mcap").stat().st_size == size:  # one flush more, so that a chunk is cut mid-run
        time.sleep(0.1)
    proc.send_signal(signal.SIGKILL)
    proc.wait(30)
    assert not (out / "result.json").exists()
    with open(out / "run.mcap", "rb") as f, pytest.raises(Exception):  # noqa: B017 (whatever the reader raises)
        list(make_reader(f).iter_messages())
    spare = tmp_path / "spare"  # a second copy of the cut run, for `fleet report`
    spare.mkdir()
    shutil.copy(out / "run.mcap", spare / "run.mcap")

    code, said, err = run_cli(["recover", str(out)])
    assert code == 0 and not err, err
    assert "run.mcap.cut" in said and "reason crashed" in said
    assert (out / "run.mcap.cut").is_file()
    with open(out / "run.mcap", "rb") as f:  # the plain indexed API, as any reader
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        topics = [channel.topic for _, channel, _ in reader.iter_messages()]
    assert len(topics) == summary.statistics.message_count > 50
    result = json.loads((out / "result.json").read_text())
    validate_result(result)
    assert result["reason"] == "crashed" and not result["completed"] and result["ticks"] > 0
    assert result["recording"]["messages"] == len(topics)
    assert _strays(out) == []
    code, said, _ = run_cli(["recover", str(out)])  # idempotent
    assert code == 0 and "nothing to recover" in said

    code, said, err = run_cli(["report", str(spare), "--no-plots"])  # report recovers first
    assert code == 0, err
    assert "reason crashed" in said and (spare / "run.mcap.cut").is_file() and (spare / "metrics.json").is_file()
    assert json.loads((spare / "result.json").read_text())["ticks"] == result["ticks"]
    assert _strays(spare) == []


def test_recover_refuses_a_folder_without_a_recording(tmp_path: Path) -> None:
    code, _, err = run_cli(["recover", str(tmp_path)])
    assert code != 0 and err.count("\n") == 1 and "holds no run.mcap" in err, err
    assert os.listdir(tmp_path) == []
