"""The robots' fork server: robots forked from it (its children, each its own session and log), the same result
as robots started afresh, and no process left whichever process dies first."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from fleet_emu.launch.result import deterministic
from tests.integration.conftest import (
    ENDLESS,
    ROOT,
    all_pids,
    children_of,
    fleet,
    is_fork_server,
    pid_alive,
    result,
    wait_for,
)


def _stat(pid: int) -> list[str]:
    """``/proc/PID/stat`` after the command: state, ppid, pgrp, session, ..."""
    return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()


def _start(out: Path, robots: int = 3) -> subprocess.Popen[str]:
    """A run that lasts minutes (``ENDLESS``)."""
    return subprocess.Popen(
        [sys.executable, "-m", "fleet_emu.launch", "run", *ENDLESS.args(robots=robots), "--out", str(out),
         "--quiet", "--comm", "ideal"],
        cwd=ROOT, stderr=subprocess.PIPE, text=True)


def _server_and_robots(launcher: int, robots: int) -> tuple[int, list[int]]:
    """Wait until the fork server has forked every robot and the run has ticked."""
    found: list[tuple[int, list[int]]] = []

    def ready() -> bool:
        found[:] = [(p, children_of(p)) for p in children_of(launcher) if is_fork_server(p)]
        return len(found) == 1 and len(found[0][1]) == robots

    wait_for(ready, 120)
    return found[0]


def _nothing_left(pids: list[int]) -> None:
    wait_for(lambda: not any(pid_alive(p) for p in pids), 15)


def test_robots_are_forked_each_in_its_own_session_with_its_own_log(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = _start(out)
    server, robots = _server_and_robots(proc.pid, 3)
    wait_for(lambda: (out / "run.mcap").exists() and (out / "run.mcap").stat().st_size > 20000, 90)
    assert int(_stat(server)[2]) == server  # the server: its own process group
    for pid in robots:
        _, ppid, pgrp, session = _stat(pid)[:4]
        assert int(ppid) == server and int(pgrp) == pid and int(session) == pid
        name = Path(f"/proc/{pid}/comm").read_text().strip()
        assert name.startswith("fleet r")
        assert os.readlink(f"/proc/{pid}/fd/0") == os.devnull
        assert os.readlink(f"/proc/{pid}/fd/2") == str(out / f"{name.split()[1]}.log")
        assert {int(fd) for fd in os.listdir(f"/proc/{pid}/fd")} >= {0, 1, 2}
        pipes = [os.readlink(f"/proc/{pid}/fd/{fd}") for fd in os.listdir(f"/proc/{pid}/fd")]
        assert not any(p.startswith("pipe:") for p in pipes)  # none of the server's protocol pipes
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err[-2000:]
    res = result(out)
    assert res["pids"]["fork_server"] == server and sorted(res["pids"]["agents"]) == sorted(robots)
    _nothing_left([server, *robots, *all_pids(res)])


def test_a_killed_fork_server_fails_its_robots_and_leaves_nothing(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = _start(out, robots=2)
    server, robots = _server_and_robots(proc.pid, 2)
    wait_for(lambda: (out / "run.mcap").exists() and (out / "run.mcap").stat().st_size > 20000, 90)
    os.kill(server, signal.SIGKILL)
    _nothing_left(robots)  # the robots go with it, at once
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 1, err[-2000:]
    assert "Traceback" not in err
    res = result(out)
    assert res["failed"] == ["r0", "r1"]
    _nothing_left(all_pids(res))


def test_a_killed_robot_is_reported_and_the_launcher_leaves_nothing(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = _start(out, robots=2)
    server, robots = _server_and_robots(proc.pid, 2)
    wait_for(lambda: (out / "run.mcap").exists() and (out / "run.mcap").stat().st_size > 20000, 90)
    victim = next(p for p in robots if Path(f"/proc/{p}/comm").read_text().strip() == "fleet r1")
    os.kill(victim, signal.SIGKILL)
    wait_for(lambda: not pid_alive(victim), 10)
    time.sleep(2.0)
    assert pid_alive(server) and proc.poll() is None  # the run goes on without it
    proc.kill()  # and the launcher dies: the server sees its input end and ends the robot left
    proc.wait(10)
    _nothing_left([server, *robots])


def test_forked_robots_give_the_same_result_as_fresh_ones(small_map: Path, tmp_path: Path) -> None:
    runs = {}
    for flag in ("--fork-server", "--no-fork-server"):
        out = tmp_path / flag
        fleet("run", "--map", str(small_map), "--robots", "3", "--max-ticks", "60", "--seed", "3", "--quiet",
              "--out", str(out), flag)
        runs[flag] = result(out)
    forked, fresh = runs["--fork-server"], runs["--no-fork-server"]
    assert "fork_server" in forked["pids"] and "fork_server" not in fresh["pids"]
    assert deterministic(forked) == deterministic(fresh)
    for res in runs.values():
        _nothing_left(all_pids(res))
