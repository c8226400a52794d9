"""The failure line names the real cause: a world frozen with a real SIGSTOP, a stop sent from outside the
launcher (by someone who read the run's nonce off an open router), a flood of another run's messages."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest
import zenoh

from fleet_emu.core.bus import client_config, router_config, router_locators
from fleet_emu.core.messages import Stop, WorldState
from fleet_emu.launch.causes import flood, froze, outside_stop, silent_world, state_timeout
from fleet_emu.recording.monitor import Monitor
from tests.harness.cli import ROOT, result, run_cli
from tests.harness.procs import fleet_processes


def _state(tick: int, done: bool = False) -> WorldState:
    return WorldState(src="world", tick=tick, seq=tick, poses={}, live=("r0",), coverage=0.5, path_length={},
                      done=done)


def test_the_causes_read_from_the_monitor() -> None:
    m = Monitor(("r0",))
    assert silent_world(m, 3.0, now_ns=10**12) is None  # before tick 0: the start-up has its own timeout
    m.feed("fleet/x/world/state", _state(7).encode(), time_ns=0)
    assert silent_world(m, 3.0, now_ns=2 * 10**9) is None
    assert silent_world(m, 3.0, now_ns=4 * 10**9) == "the world process stopped answering at tick 7 (no state " \
                                                      "for 3 s)"
    assert froze(m, 10.0) is None
    m.feed("fleet/x/world/state", _state(8, done=True).encode(), time_ns=20 * 10**9)
    assert silent_world(m, 3.0, now_ns=30 * 10**9) is None  # done: its stop is on the way
    assert froze(m, 10.0) == "the world process stopped answering at tick 7 (no state for 20 s)"
    assert froze(m, 30.0) is None and state_timeout(10.0) == 20.0
    assert flood([], 100) is None and flood(["r1"], 0) is None
    assert outside_stop(m) is None


def test_the_worlds_first_stop_is_the_runs_and_a_forged_one_is_kept_apart() -> None:
    def stop(tick: int, reason: str, src: str = "world") -> bytes:
        return Stop(src=src, tick=tick, seq=99, reason=reason).encode()

    m = Monitor(("r0",))
    m.feed("fleet/x/world/state", _state(7).encode())
    m.feed("fleet/x/ctl/stop", stop(7, "coverage"))  # the world is not done: not the world's
    assert m.stop is None and m.outside_stop is not None
    assert outside_stop(m) == ("a stop in the world's name that the world did not send ended the run at tick 7 "
                               "(reason 'coverage'; its last state was of tick 7, not done)")
    m.feed("fleet/x/world/state", _state(8, done=True).encode())
    m.feed("fleet/x/ctl/stop", stop(8, "done"))
    m.feed("fleet/x/ctl/stop", stop(8, "no_robots"))  # a second stop never replaces the first
    assert m.stop is not None and m.stop.reason == "done"
    ok = Monitor(("r0",))
    ok.feed("fleet/x/ctl/stop", stop(0, "interrupted", "launcher"))
    ok.feed("fleet/x/ctl/stop", stop(3, "interrupted"))  # the world's answer to the launcher's stop
    assert ok.stop is not None and ok.stop.reason == "interrupted"
    assert "r1 failed while the bus carried 100 message(s) of another run" in (flood(["r1"], 100) or "")


def test_a_world_stop_ahead_of_its_state_waits_for_it() -> None:
    """The world's stop and its last state travel on different keys and may arrive in either order: a stop of a
    tick whose state has not come is judged when that state comes (the world's own, done: the run's stop; a
    state not done: a forged one), and one whose state never comes is named as not the world's."""
    def stop(tick: int, reason: str) -> bytes:
        return Stop(src="world", tick=tick, seq=99, reason=reason).encode()

    real = Monitor(("r0",))
    real.feed("fleet/x/world/state", _state(14).encode())
    real.feed("fleet/x/ctl/stop", stop(15, "max_ticks"))
    assert real.stop is None and real.outside_stop is None and outside_stop(real) is None
    real.feed("fleet/x/world/state", WorldState(src="world", tick=15, seq=15, poses={}, live=("r0",), coverage=0.5,
                                                path_length={}, done=True, reason="max_ticks").encode())
    assert real.stop is not None and real.stop.reason == "max_ticks" and real.pending_stop is None
    forged = Monitor(("r0",))
    forged.feed("fleet/x/world/state", _state(14).encode())
    forged.feed("fleet/x/ctl/stop", stop(15, "coverage"))
    forged.feed("fleet/x/world/state", _state(15).encode())
    assert forged.stop is None and forged.outside_stop is not None and forged.pending_stop is None
    never = Monitor(("r0",))
    never.feed("fleet/x/world/state", _state(14).encode())
    never.feed("fleet/x/ctl/stop", stop(900, "coverage"))
    assert outside_stop(never) is None and (outside_stop(never, pending=True) or "").startswith(
        "a stop in the world's name that the world did not send ended the run at tick 900")


@pytest.mark.slow  # a fleet frozen over processes (12 s wall); causes by default
def test_a_frozen_world_is_named_with_its_tick(tmp_path: Path) -> None:
    """``kill -STOP`` of the world mid-run: the launcher ends the run within the state timeout (two of the
    scenario's ``barrier_timeout``, here 1 s) with one line naming the world and the tick it froze at. (The
    office, a run of hundreds of ticks: the two-room map's could end before the stop landed.)"""
    scenario = tmp_path / "frozen.toml"
    scenario.write_text('max_ticks = 100000\ntarget_coverage = 1.0\nbarrier_timeout = 1.0\n'
                        '[map]\nname = "office"\n[fleet]\nrobots = 2\n')
    ticks: list[int] = []
    with zenoh.open(router_config()) as router:
        endpoint = router_locators(router)[0]
        watch = router.declare_subscriber("fleet/frozen/world/state", lambda _: ticks.append(len(ticks)))
        proc = subprocess.Popen([sys.executable, "-m", "fleet_emu", "run", str(scenario), "--quiet", "--no-record",
                                 "--connect", endpoint, "--run-id", "frozen", "--out", str(tmp_path / "run")],
                                cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        world = None
        try:
            while len(ticks) < 5 and proc.poll() is None:
                threading.Event().wait(0.1)
            world = next(p for p in fleet_processes(proc.pid)  # forked by the fork server, named "fleet world"
                         if Path(f"/proc/{p}/comm").read_text().strip() == "fleet world")
            os.kill(world, signal.SIGSTOP)
            _, err = proc.communicate(timeout=120)
        finally:
            if world is not None:
                with contextlib.suppress(ProcessLookupError):  # the launcher killed it
                    os.kill(world, signal.SIGCONT)
            if proc.poll() is None:
                proc.kill()
        watch.undeclare()
    res = result(tmp_path / "run")
    assert proc.returncode == 1 and len(_errors(err)) == 1, err
    assert "the world process stopped answering at tick" in err and "(no state for 2 s)" in err
    assert res["reason"] == "error" and res["error"] in err and res["ticks"] >= 4


def _stop_from_outside(endpoint: str, done: threading.Event, src: str, reason: str) -> None:
    """Read the run's nonce off its first state on the open router, then put a stop in ``src``'s name."""
    got: list[zenoh.Sample] = []
    with zenoh.open(client_config(endpoint)) as s:
        watch = s.declare_subscriber("fleet/outside/world/state", got.append)
        while not got and not done.is_set():
            threading.Event().wait(0.05)
        if got:
            nonce = got[0].attachment
            s.put("fleet/outside/ctl/stop", Stop(src=src, tick=0, seq=1, reason=reason).encode(),
                  attachment=nonce.to_bytes() if nonce is not None else None)
        watch.undeclare()


@pytest.mark.parametrize(("src", "reason", "says"), [
    ("launcher", "interrupted", "a stop from outside this launcher ended the run"),
    ("world", "coverage", "a stop in the world's name that the world did not send ended the run at tick 0 "
                          "(reason 'coverage'"),
])
def test_a_stop_from_outside_is_named(small_map: Path, tmp_path: Path, src: str, reason: str, says: str) -> None:
    """The nonce binds a run to its traffic; it does not authenticate (on an open router anyone can read it off
    a message). A stop put in the launcher's or the world's name with it ends the run (the robots obey it), and
    the line says so: not robots that failed, not the run's own end."""
    done = threading.Event()
    with zenoh.open(router_config()) as router:
        endpoint = router_locators(router)[0]
        attacker = threading.Thread(target=_stop_from_outside, args=(endpoint, done, src, reason), daemon=True)
        attacker.start()
        code, _, err = run_cli(["run", "--map", str(small_map), "--robots", "2", "--max-ticks", "100000",
                                "--target-coverage", "1.0", "--quiet", "--no-record", "--in-process",
                                "--connect", endpoint, "--run-id", "outside", "--out", str(tmp_path / "run")])
        done.set()
        attacker.join(30)
    assert code == 1 and len(_errors(err)) == 1, err
    assert says in err
    res = result(tmp_path / "run")
    assert res["reason"] == "error" and says in res["error"]


def _errors(err: str) -> list[str]:
    """The lines on stderr but the warning that an open router's bus is not authenticated."""
    return [line for line in err.splitlines() if "is not authenticated" not in line]
