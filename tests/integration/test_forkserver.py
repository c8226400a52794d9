"""The robots' fork server: robots forked from it (its children, each its own session and log), the same result
as robots started afresh, and no process left whichever process dies first."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from fleet_emu.launch.result import deterministic
from tests.harness.cli import ENDLESS, ROOT, result, run_cli
from tests.harness.procs import (
    all_pids,
    children_of,
    fleet_processes,
    is_fork_server,
    is_router,
    nothing_left,
    pid_alive,
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


def _name(pid: int) -> str:
    """A forked node's name, ``fleet NAME`` (``""`` once it is gone)."""
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return ""


def _server_and_robots(launcher: int, robots: int) -> tuple[int, list[int]]:
    """Wait until the fork server has forked every robot (and the world and netem) and the run has ticked."""
    found: list[tuple[int, list[int]]] = []

    def ready() -> bool:
        found[:] = [(p, [c for c in children_of(p) if _name(c).startswith("fleet r")])
                    for p in children_of(launcher) if is_fork_server(p)]
        return len(found) == 1 and len(found[0][1]) == robots

    wait_for(ready, 120)
    return found[0]


@pytest.mark.slow  # fork server teardown: a killed robot by default
def test_robots_are_forked_each_in_its_own_session_and_sigint_tears_the_fleet_down(tmp_path: Path) -> None:
    """Forked robots, world and netem: the server's children, each its own session and log (none a child of the
    launcher but the server and the router). SIGINT (Ctrl-C) then ends the run through its teardown: exit 130, an
    interrupted result.json, a recording that reads to its end, no process left."""
    out = tmp_path / "run"
    proc = _start(out)
    server, robots = _server_and_robots(proc.pid, 3)
    wait_for(lambda: (out / "run.mcap").exists() and (out / "run.mcap").stat().st_size > 20000, 90)
    assert len(fleet_processes(proc.pid)) == 5  # world, netem and the three robots
    assert sorted(_name(p) for p in children_of(server)) == ["fleet netem", "fleet r0", "fleet r1", "fleet r2",
                                                             "fleet world"]
    assert set(children_of(proc.pid)) == {server, *(p for p in children_of(proc.pid) if is_router(p))}
    assert int(_stat(server)[2]) == server  # the server: its own process group
    nodes = [p for p in children_of(server) if _name(p) in ("fleet world", "fleet netem")]
    for pid in [*robots, *nodes]:
        _, ppid, pgrp, session = _stat(pid)[:4]
        assert int(ppid) == server and int(pgrp) == pid and int(session) == pid
        name = _name(pid)
        assert name.startswith("fleet ")
        assert os.readlink(f"/proc/{pid}/fd/0") == os.devnull
        assert os.readlink(f"/proc/{pid}/fd/2") == str(out / f"{name.split()[1]}.log")
        assert {int(fd) for fd in os.listdir(f"/proc/{pid}/fd")} >= {0, 1, 2}
        pipes = [os.readlink(f"/proc/{pid}/fd/{fd}") for fd in os.listdir(f"/proc/{pid}/fd")]
        assert not any(p.startswith("pipe:") for p in pipes)  # none of the server's protocol pipes
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err[-2000:]
    assert "Traceback" not in err
    res = result(out)
    assert res["reason"] == "interrupted" and res["completed"] is False
    assert res["pids"]["fork_server"] == server and sorted(res["pids"]["robots"]) == sorted(robots)
    assert sorted(nodes) == sorted([res["pids"]["world"], res["pids"]["netem"]])
    with open(out / "run.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None and sum(summary.statistics.channel_message_counts.values()) == \
        res["recording"]["messages"] > 0
    nothing_left([server, *robots, *all_pids(res)], timeout=10)


@pytest.mark.slow  # fork server teardown: a killed robot by default
def test_a_killed_fork_server_fails_the_run_and_leaves_nothing(tmp_path: Path) -> None:
    """The server forked every node: killed, it takes the robots, the world and netem with it. The run ends as an
    error naming the world (exit 1, one line), its files written."""
    out = tmp_path / "run"
    proc = _start(out, robots=2)
    server, _ = _server_and_robots(proc.pid, 2)
    wait_for(lambda: (out / "run.mcap").exists() and (out / "run.mcap").stat().st_size > 20000, 90)
    nodes = children_of(server)
    os.kill(server, signal.SIGKILL)
    nothing_left(nodes)  # the robots, the world and netem go with it, at once
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 1, err[-2000:]
    assert "Traceback" not in err
    assert err.strip().splitlines()[-1].startswith("fleet: error: the world process exited with code -9"), err
    res = result(out)
    assert res["reason"] == "error" and res["error"].startswith("the world process exited")
    nothing_left(all_pids(res))


@pytest.mark.slow  # kill -9 over processes: the kill trial by default
def test_a_killed_robot_is_reported_and_a_killed_launcher_leaves_nothing(tmp_path: Path) -> None:
    """A robot killed: the run goes on without it. Then the launcher killed (no teardown of its own): every
    process it started goes too (the world, netem and the router see it die; the fork server sees its input
    end and ends the robot left)."""
    out = tmp_path / "run"
    proc = _start(out, robots=2)
    server, robots = _server_and_robots(proc.pid, 2)
    wait_for(lambda: (out / "run.mcap").exists() and (out / "run.mcap").stat().st_size > 20000, 90)
    started = fleet_processes(proc.pid) + children_of(proc.pid)  # the fork server and the router too
    assert len(fleet_processes(proc.pid)) == 4 and server in started
    victim = next(p for p in robots if Path(f"/proc/{p}/comm").read_text().strip() == "fleet r1")
    os.kill(victim, signal.SIGKILL)
    wait_for(lambda: not pid_alive(victim), 10)
    time.sleep(2.0)
    assert pid_alive(server) and proc.poll() is None  # the run goes on without it
    proc.kill()
    proc.wait(10)
    nothing_left([*started, *robots])


@pytest.mark.slow  # a second fleet; forked = fresh by seed on the memory engine
def test_fresh_robots_give_the_same_result_as_forked_ones(small_run: Path, tmp_path: Path) -> None:
    """The suite's plain run's scenario with every node started afresh (one robot: each fresh node is an
    interpreter of its own, a CPU second or more): the memory engine's result, as the forked run is (the
    suite's plain run, forked, against the memory engine: ``test_fleet_run.py``)."""
    forked = result(small_run)
    args = ["run", str(small_run / "scenario.json"), "--robots", "1", "--quiet", "--no-record"]
    run_cli([*args, "--out", str(tmp_path / "fresh"), "--no-fork-server"], check=True)
    run_cli([*args, "--out", str(tmp_path / "memory"), "--engine", "memory"], check=True)
    fresh = result(tmp_path / "fresh")
    assert "fork_server" in forked["pids"] and "fork_server" not in fresh["pids"]
    assert deterministic(fresh) == deterministic(result(tmp_path / "memory"))
    for res in (forked, fresh):
        nothing_left(all_pids(res))
