"""``fleet run --realtime HZ`` end to end: real Zenoh sessions, real processes (and, for the slow robot, the
in-process engine, where an allocator registered by the test is found). Nothing here asserts a time: the
machine may be loaded, so the checks are on counts that hold at any speed."""

from __future__ import annotations

import signal
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

import pytest

from fleet_emu.agents.allocators import Allocation, Allocator, Param, Problem, make_allocator
from fleet_emu.core.messages import RadioMsg
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.runner import RunOptions, run_fleet
from fleet_emu.launch.signals import Interrupts
from fleet_emu.recording.monitor import Monitor
from tests.harness.cli import result, run_cli
from tests.harness.procs import all_pids, pid_alive

PERCENTILE_KEYS = {"p50", "p90", "p99", "max", "mean"}


def _scenario(small_map: Path, robots: int, max_ticks: int, **kw: object) -> Scenario:
    return Scenario().override(map=str(small_map), robots=robots, max_ticks=max_ticks, seed=1, **kw)


def test_a_real_time_run_writes_the_real_time_keys(small_map: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    _, _, err = run_cli(["run", "--map", str(small_map), "--robots", "3", "--realtime", "20", "--max-ticks", "400",
                         "--base", "--relay", "flood", "--relay-ttl", "1", "--out", str(out), "--quiet"], check=True)
    assert "Traceback" not in err
    res = result(out)  # the schema's real-time, base and relay keys together
    assert res["realtime_hz"] == 20.0 and res["failed"] == [] and res["reason"] in ("coverage", "max_ticks", "stall")
    assert res["engine"] == "processes" and res["authenticated"] is True
    assert res["base"]["ticks"] == res["ticks"] and set(res["relay"]["kinds"]) >= {"pose", "map"}
    rt = res["realtime"]
    assert set(rt["robots"]) == {"r0", "r1", "r2"}
    assert rt["world_overruns"] >= 0 and rt["ticks_per_second"] > 0
    for r, row in rt["robots"].items():
        assert row["decisions"] >= 1, r
        # at most one decision, and one step along the last plan (or a stay), per observation
        assert row["decisions"] <= res["ticks"] + 1 and row["plan_steps"] + row["waits"] <= res["ticks"] + 1, row
        assert row["late_commands"] >= 0 and row["late_steps"] >= 0 and row["missed_ticks"] >= 0
        assert set(row["decision_ms"]) == PERCENTILE_KEYS and set(row["allocator_ms"]) == PERCENTILE_KEYS
        assert row["decision_ms"]["p50"] <= row["decision_ms"]["p90"] <= row["decision_ms"]["max"]
    assert rt["late_commands"] == sum(row["late_commands"] for row in rt["robots"].values())
    assert sum(res["path_length"]) > 0  # the fleet moved


class _Slow(Allocator):
    """Nearest frontier, but robot ``robot`` sleeps ``sleep_ms`` in every decision (registered by the test
    below only, never a built-in)."""

    parameters = {"sleep_ms": Param(0.0, ge=0), "robot": Param("")}

    def __init__(self, **params: object) -> None:
        super().__init__(**params)
        self.nearest = make_allocator({"type": "nearest"})

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        if problem.me == self.robot:
            time.sleep(self.sleep_ms / 1000.0)
        return self.nearest.allocate(problem, inbox)


@pytest.fixture
def slow_allocator() -> Iterator[str]:
    _Slow.register("test_slow")
    try:
        yield "test_slow"
    finally:
        Allocator.registry.pop("test_slow", None)


@pytest.mark.slow  # real time over processes: its keys by default
def test_a_slow_robot_keeps_its_last_plan_and_its_decisions_come_late(tmp_path: Path, slow_allocator: str) -> None:
    sleep_ms = 300.0  # six ticks at 20 Hz
    base = Scenario().override(map="office", robots=2, max_ticks=60, seed=1, stall_ticks=1000,
                               coverage_stall_ticks=1000, target_coverage=1.0)  # far from done in 60 ticks
    scenario = Scenario.from_dict(base.to_dict() | {"allocator": {"type": slow_allocator, "sleep_ms": sleep_ms,
                                                                  "robot": "r0"}})
    res = run_fleet(scenario, RunOptions(out_dir=tmp_path / "run", in_process=True, record=False,
                                         realtime_hz=20.0)).data
    assert res["failed"] == [] and res["reason"] == "max_ticks" and res["ticks"] == 60  # the world kept ticking
    slow, fast = res["realtime"]["robots"]["r0"], res["realtime"]["robots"]["r1"]
    assert slow["decision_ms"]["p50"] >= sleep_ms and slow["allocator_ms"]["p50"] >= sleep_ms
    assert slow["late_commands"] >= 1  # a 300 ms decision ends after the 50 ms tick it was stamped for
    assert slow["plan_steps"] + slow["waits"] >= 1  # meanwhile it kept to its last plan (or stood, before one)
    # each slow decision spans at least 300 ms; the world went on ticking in that time
    assert res["ticks"] > 2 * slow["decisions"]
    assert fast["decisions"] > slow["decisions"]


@pytest.mark.slow  # signals over processes: the sigint trial by default
def test_ctrl_c_during_a_real_time_run_still_writes_the_result(small_map: Path, tmp_path: Path) -> None:
    irq = Interrupts()

    def progress(m: Monitor) -> None:
        if m.tick >= 5 and irq.count == 0:
            irq._handle(signal.SIGINT, None)

    out = tmp_path / "run"
    res = run_fleet(_scenario(small_map, 2, 100000, stall_ticks=100000, coverage_stall_ticks=100000,
                              target_coverage=1.0),
                    RunOptions(out_dir=out, interrupts=irq, on_progress=progress, realtime_hz=20.0)).data
    assert irq.exit_code == 130
    assert res["reason"] == "interrupted" and res["signal"] == "SIGINT" and 5 <= res["ticks"] < 100000
    assert result(out) == res and res["realtime_hz"] == 20.0
    deadline = time.monotonic() + 10
    while any(pid_alive(p) for p in all_pids(res)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(pid_alive(p) for p in all_pids(res))


@pytest.mark.parametrize("args, match", [
    (["--realtime", "0"], "argument --realtime: expected ticks per second, a number > 0 and <= 1000, got '0'"),
    (["--realtime", "-5"], "argument --realtime: expected ticks per second"),
    (["--realtime", "fast"], "argument --realtime: expected ticks per second"),
    (["--realtime", "nan"], "argument --realtime: expected ticks per second"),
    (["--realtime", "10", "--engine", "memory"], "--realtime needs the processes engine: --engine memory is "
                                                 "lockstep only"),
])
def test_bad_real_time_input_is_one_line_and_exit_2(args: list[str], match: str, tmp_path: Path) -> None:
    code, _, err = run_cli(["run", *args, "--out", str(tmp_path / "x"), "--quiet"])
    assert code == 2
    assert err.strip().splitlines() == [f"fleet: error: {match}"] or \
        (len(err.strip().splitlines()) == 1 and match in err), err
    assert not (tmp_path / "x").exists()
