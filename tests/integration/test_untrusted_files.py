"""Files a run does not trust, tried as an adversary would: symbolic links planted in a shared ``--out`` folder
where a run's files go (its logs, its lock, its result) are refused in one line before anything is written,
their targets untouched, on every engine and for a sweep; and a FIFO given as a scenario, a policy or a study is
refused at once instead of blocking in ``open()`` (there, SIGINT and SIGTERM were caught and the open retried,
so only SIGKILL ended it): each command here runs as a user runs it, under a deadline, with SIGTERM sent if it
is still there."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from tests.harness.cli import ROOT, run_cli

#: The run files an adversary links to a victim file: the processes' logs, the lock, the result, the recording.
PLANTED = ("r0.log", "r1.log", "world.log", "netem.log", "router.log", "forkserver.log", ".fleet.lock",
           "result.json", "run.mcap")


def _plant(folder: Path, victim: Path, names: tuple[str, ...] = PLANTED) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for name in names:
        (folder / name).symlink_to(victim)


@pytest.mark.parametrize("engine", ["processes", "memory"])
def test_a_folder_with_links_where_run_files_go_is_refused_and_the_targets_kept(
        small_map: Path, tmp_path: Path, engine: str) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    out = tmp_path / "shared"
    _plant(out, victim)
    code, _, err = run_cli(["run", "--map", str(small_map), "--robots", "2", "--engine", engine, "--max-ticks", "20",
                            "--quiet", "--out", str(out)])
    assert code == 2 and err.count("\n") == 1 and "symbolic links" in err and "r0.log" in err, err
    assert victim.read_text() == "precious"
    assert sorted(p.name for p in out.iterdir()) == sorted(PLANTED)  # nothing written, no link replaced


def test_a_dangling_link_and_a_hard_linked_lock_are_refused(small_map: Path, tmp_path: Path) -> None:
    out = tmp_path / "shared"
    out.mkdir()
    (out / "world.log").symlink_to(tmp_path / "created-through-the-link")  # O_CREAT would make the target
    argv = ["run", "--map", str(small_map), "--robots", "2", "--engine", "memory", "--max-ticks", "20", "--quiet"]
    code, _, err = run_cli([*argv, "--out", str(out)])
    assert code == 2 and "world.log" in err and not (tmp_path / "created-through-the-link").exists(), err
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    hard = tmp_path / "hard"
    hard.mkdir()
    os.link(victim, hard / ".fleet.lock")  # the lock file is truncated to hold the pid: never a hard link
    code, _, err = run_cli([*argv, "--out", str(hard)])
    assert code == 2 and ".fleet.lock" in err and victim.read_text() == "precious", err


def test_a_sweep_folder_with_links_is_refused(tmp_path: Path) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    out = tmp_path / "sweep"
    _plant(out, victim, ("rows.jsonl", "results.csv", "study.toml", ".fleet.lock"))
    study = tmp_path / "s.toml"
    study.write_text('[study]\nname = "s"\n[grid]\nrobots = [2]\n[fleet]\nmap = "office"\nmax_ticks = 5\n')
    code, _, err = run_cli(["sweep", str(study), "--out", str(out), "--quiet"])
    assert code == 2 and err.count("\n") == 1 and "symbolic links" in err, err
    assert victim.read_text() == "precious"


def _under_deadline(argv: list[str], seconds: float = 60.0) -> tuple[int, str]:
    """``fleet ARGV`` as a user runs it; when it has not ended within ``seconds``, SIGTERM, then (10 s later)
    SIGKILL and a failure: the exit code and standard error of a command that ended by itself or on SIGTERM."""
    proc = subprocess.Popen([sys.executable, "-m", "fleet_emu", *argv], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, cwd=ROOT, start_new_session=True)
    try:
        _, err = proc.communicate(timeout=seconds)
        return proc.returncode, err
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGTERM)
        try:
            _, err = proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            raise AssertionError(f"fleet {' '.join(argv)} still waited 10 s after SIGTERM") from None
        raise AssertionError(f"fleet {' '.join(argv)} waited {seconds:g} s (ended by SIGTERM: {err[-300:]})") \
            from None


def test_a_fifo_as_a_scenario_a_policy_or_a_study_is_refused_at_once(small_map: Path, tmp_path: Path) -> None:
    fifos = {name: tmp_path / name for name in ("scenario.toml", "policy.npz", "study.toml")}
    for path in fifos.values():
        os.mkfifo(path)  # no writer ever comes: a blocking open would wait for ever
    cases = [(["run", "--scenario", str(fifos["scenario.toml"]), "--engine", "memory"], "cannot read scenario"),
             (["run", "--map", str(small_map), "--engine", "memory", "--allocator", "policy", "--param",
               f"path={fifos['policy.npz']}"], "cannot read the policy file"),
             (["sweep", str(fifos["study.toml"])], "cannot read study")]
    for i, (argv, says) in enumerate(cases):
        code, err = _under_deadline([*argv, "--out", str(tmp_path / f"out{i}")])
        assert code == 2 and err.count("\n") == 1 and says in err and "not a regular file (a FIFO)" in err, err
        assert not (tmp_path / f"out{i}").exists()
