"""The base station over real Zenoh sessions and real processes: its own process,
``base_connected_fraction`` and its team map in result.json, the same in every engine; torn down on every
exit path; and the access control around its keys, tried with real sessions against a real router."""

from __future__ import annotations

import dataclasses
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import zenoh

import fleet_emu as fe
from fleet_emu.core.access import Credential, read_dictionary
from fleet_emu.core.bus import client_config, router_locators
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import deterministic
from fleet_emu.launch.router_config import router_config_text
from tests.harness.cli import ENDLESS, ROOT, result, run_cli
from tests.harness.faults import RunSpec, kill_trial, sigint_trial
from tests.harness.procs import all_pids, fleet_processes, pid_alive, wait_for

RUN = "basesec"


def _scenario(small_map: Path) -> fe.Scenario:
    """Three robots on the two-room map with a disk radio of 2 m (4 cells): they drift out of the base's reach."""
    return fe.Scenario().override(map=str(small_map), robots=3, allocator="minpos", comm="disk", comm_range=2.0,
                                  loss=0.2, seed=4, max_ticks=120, base=True)


def test_a_base_run_over_processes_gives_the_memory_engines_result(small_map: Path, tmp_path: Path) -> None:
    s = _scenario(small_map)
    over_zenoh = fe.run(s, tmp_path / "p")
    in_process = fe.run(s, in_process=True)
    in_memory = Fleet(s).run()
    frac = over_zenoh["base_connected_fraction"]
    assert set(frac) == {"overall", "all_ticks", "per_robot"} and set(frac["per_robot"]) == {"r0", "r1", "r2"}
    assert min(frac["per_robot"].values()) < 1.0 and 0.0 < frac["overall"] < 1.0  # some robot lost the base
    base = over_zenoh["base"]
    assert base["cell"] is not None and base["known_cells"] > 0 and 0 < base["known_fraction"] < 1
    assert base["ticks"] == over_zenoh["ticks"]  # it heard netem every tick, the last one included
    assert deterministic(in_memory.data) == deterministic(over_zenoh.data) == deterministic(in_process.data)
    assert in_memory.curve == over_zenoh.curve
    pids = over_zenoh["pids"]
    assert pids["base"] not in (pids["world"], pids["netem"], *pids["robots"])  # its own OS process
    assert not [p for p in all_pids(over_zenoh.data) if pid_alive(p)]
    assert (tmp_path / "p" / "base.log").exists()
    code, out, err = run_cli(["report", str(tmp_path / "p"), "--no-plots"])
    assert code == 0 and "matches result.json" in out + err  # recomputed from the recording
    assert "base connected" in out
    without = fe.run(s.override(base=False), engine="memory")  # the robots do as they did without a base
    assert "base_connected_fraction" not in without.data and "base" not in without["scenario"]
    assert (without["ticks"], without["path_length"], without["coverage"]) == \
        (over_zenoh["ticks"], over_zenoh["path_length"], over_zenoh["coverage"])


def test_fleet_run_base_flags(small_map: Path, tmp_path: Path) -> None:
    """``--base-cell``: refused off the map or on a wall, in one line; a free cell is the base's (on the memory
    engine: the flag's meaning does not depend on the engine; the base's process and its log are the test
    above's)."""
    common = ["run", "--map", str(small_map), "--robots", "2", "--comm", "disk", "--comm-range", "2", "--seed", "3",
              "--max-ticks", "80", "--quiet"]
    for cell, why in (("0,0", "base cell (0, 0) is not a free cell of the map"),
                      ("40,1", "base cell (40, 1) is off the map (12 x 24 cells)")):
        code, _, err = run_cli([*common, "--base-cell", cell, "--out", str(tmp_path / "bad")])
        assert code == 2 and err.strip().endswith(why) and err.count("\n") == 1
        assert not (tmp_path / "bad").exists()
    code, _, err = run_cli([*common, "--base-cell", "9,20", "--engine", "memory", "--out", str(tmp_path / "m")])
    assert code in (0, 3), err
    res = result(tmp_path / "m")
    assert res["scenario"]["base"] == [9, 20] and res["base"]["cell"] == [9, 20]
    code, out, err = run_cli(["report", str(tmp_path / "m"), "--no-plots"])
    assert code == 0 and "matches result.json" in out + err and "base connected" in out


@pytest.mark.slow  # base over processes proven once by default (= memory)
def test_a_killed_base_fails_the_run_and_leaves_nothing_behind(small_map: Path, tmp_path: Path) -> None:
    out = tmp_path / "k"
    args = ["run", "--map", str(small_map), "--robots", "2", "--seed", "2", "--max-ticks", "100000",
            "--target-coverage", "1.0", "--sensor-range", "0.5", "--base", "--quiet", "--out", str(out),
            "--realtime", "5"]  # real time, 5 ticks a second: the run is still going when the base is killed
    proc = subprocess.Popen([sys.executable, "-m", "fleet_emu.launch", *args], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        def base_pid() -> int | None:  # forked by the fork server, named "fleet base"
            for pid in fleet_processes(proc.pid):
                try:
                    if Path(f"/proc/{pid}/comm").read_text().strip() == "fleet base":
                        return pid
                except OSError:
                    pass
            return None

        wait_for(lambda: base_pid() is not None, 120)
        time.sleep(4.0)  # into the run
        os.kill(base_pid(), signal.SIGKILL)  # type: ignore[arg-type]
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1 and "the base process exited with code -9" in err
    res = result(out)
    assert res["reason"] == "error" and "base" in res["pids"]
    assert res["base"]["known_cells"] is None  # it never reported
    time.sleep(0.5)
    assert not [p for p in all_pids(res) if pid_alive(p)]


@pytest.mark.slow  # signals over processes: the sigint trial by default
@pytest.mark.parametrize("i", [0, 1])
def test_sigint_at_a_random_moment_with_a_base_leaves_no_process(tmp_path: Path, i: int) -> None:
    """The fault trials' invariants (``tests/harness/faults.py``: no orphan among every descendant of the
    launcher, the base's process included; no death; result.json and run.mcap whole) with a base."""
    long_run = dataclasses.replace(ENDLESS, robots=2, seed=7, extra=(*ENDLESS.extra, "--base"))
    t = sigint_trial(long_run, tmp_path, np.random.default_rng([7, 10, i]), f"bsig{i}", window=5.0)
    assert t.failures == [], f"{t.label}: {t.failures} {t.notes}"
    assert t.exit_code == 130 and t.result["reason"] == "interrupted"
    assert "base" in t.result["pids"] or not t.result["pids"]  # nothing spawned when the signal came first


@pytest.mark.slow  # base over processes proven once by default (= memory)
def test_a_robot_killed_with_a_base_leaves_the_run_and_the_base_reports(small_map: Path, tmp_path: Path) -> None:
    spec = RunSpec(str(small_map), robots=3, max_ticks=50, target_coverage=1.0, seed=12,
                   extra=("--sensor-range", "1.0", "--base"))
    t = kill_trial(spec, tmp_path, np.random.default_rng([12, 11]), "bkill", window=30)
    assert t.failures == [], f"{t.label}: {t.failures} {t.notes}"
    res = t.result
    assert t.exit_code == 1 and len(res["failed"]) == 1
    assert res["base"]["ticks"] == res["ticks"] and res["base"]["known_cells"] > 0  # the base went on to the end
    frac = res["base_connected_fraction"]["per_robot"]
    assert set(frac) == {"r0", "r1", "r2"}  # the failed robot counted over the ticks it was live


@pytest.fixture
def router(tmp_path: Path):  # type: ignore[no-untyped-def]
    users = tmp_path / "users.txt"
    text = router_config_text(2, users, listen="tcp/127.0.0.1:0", run_id=RUN)
    conf = zenoh.Config.from_json5(text)
    conf.insert_json5("adminspace/enabled", "true")
    with zenoh.open(conf) as r:
        yield router_locators(r)[0], users


def _login(users: Path, user: str, endpoint: str) -> zenoh.Session:
    return zenoh.open(client_config(endpoint, Credential(user, read_dictionary(users.read_text())[user])))


def test_a_robot_cannot_put_on_the_bases_keys_nor_the_base_on_a_robots(router) -> None:  # type: ignore[no-untyped-def]
    endpoint, users = router
    got: list[str] = []
    with _login(users, "recorder", endpoint) as rec, _login(users, "r1", endpoint) as r1, \
            _login(users, "base", endpoint) as base:
        sub = rec.declare_subscriber(f"fleet/{RUN}/**", lambda s: got.append(f"{s.payload.to_bytes().decode()}"
                                                                             f" {str(s.key_expr).split('/', 2)[2]}"))
        time.sleep(0.5)
        for k in ("ctl/report/base", "ctl/ready/base", "radio/rx/base", "radio/tx/base"):
            r1.put(f"fleet/{RUN}/{k}", b"r1")
        for k in ("robot/r0/cmd", "radio/tx/r0", "ctl/report/r0", "ctl/ready/r1", "radio/rx/r0", "world/state",
                  "netem/links", "ctl/stop", "radio/tx/r1"):
            base.put(f"fleet/{RUN}/{k}", b"base")
        allowed = ["base ctl/report/base", "base ctl/ready/base", "base radio/tx/base", "r1 ctl/report/r1"]
        for a in allowed:
            who, k = a.split(" ")
            (base if who == "base" else r1).put(f"fleet/{RUN}/{k}", who.encode())
        wait_for(lambda: len(got) >= len(allowed), 10)
        time.sleep(0.5)
        sub.undeclare()
    assert sorted(got) == sorted(allowed)
