"""The real-time keys of result.json: folded by the monitor from the world's clock and the robots' timing
summaries (and so recomputed from a recording); a lockstep run, which publishes neither, has none of them."""

from __future__ import annotations

import msgspec

from fleet_emu.core.keys import Keys
from fleet_emu.core.messages import Command, RobotTiming, WorldClock, WorldState
from fleet_emu.recording.monitor import Monitor
from fleet_emu.recording.result import fold_keys

ROBOTS = ("r0", "r1")
SCENARIO = {"seed": 0, "map": "m", "allocator": {"type": "greedy"}, "robots": 2, "radio": {"loss": 0.0, "comm": "full"}}
K = Keys("run")


def _state(tick: int) -> WorldState:
    return WorldState(src="world", tick=tick, seq=tick, poses={"r0": (1, 1), "r1": (1, 2)}, live=ROBOTS,
                      coverage=0.5, path_length={"r0": 0, "r1": 0})


def _timing(robot: str, decisions: int) -> RobotTiming:
    ms = {"p50": 120.0, "p90": 150.0, "p99": 180.0, "max": 200.0, "mean": 125.0}
    return RobotTiming(src=robot, tick=40, seq=9, decisions=decisions, plan_steps=30, waits=2, decision_ms=ms,
                       allocator_ms=ms)


def test_a_lockstep_run_has_no_real_time_keys() -> None:
    m = Monitor(ROBOTS)
    m.feed(K.state, _state(0).encode())
    m.feed(K.cmd("r0"), Command(src="r0", tick=0, seq=1, move=(0, 1), status="ASSIGNED", decision_ms=2.0).encode())
    res = fold_keys(m, SCENARIO, "run", 0.99)
    assert "realtime" not in res and "realtime_hz" not in res
    assert res["decision_ms"]["mean"] == 2.0


def test_a_real_time_run_reports_late_commands_overruns_and_decision_times_per_robot() -> None:
    m = Monitor(ROBOTS)
    m.feed(K.state, _state(40).encode())
    m.feed(K.clock, WorldClock(src="world", tick=40, seq=3, hz=10.0, elapsed=4.0, overruns=1,
                                late={"r0": 5, "r1": 0}, late_steps={"r0": 3, "r1": 0},
                                missed={"r0": 2, "r1": 0}).encode())
    m.feed(K.clock, WorldClock(src="world", tick=39, seq=2, hz=10.0, elapsed=3.9, overruns=0,
                                late={"r0": 4, "r1": 0}, late_steps={"r0": 1, "r1": 0},
                                missed={"r0": 2, "r1": 0}).encode())  # an older one
    m.feed(K.timing("r0"), _timing("r0", 7).encode())
    m.feed(K.cmd("r0"), Command(src="r0", tick=40, seq=4, move=(0, 1), status="STALE").encode())  # no decision
    m.feed(K.cmd("r0"), Command(src="r0", tick=38, seq=5, move=(0, 1), status="ASSIGNED", decision_ms=9.0).encode())
    res = fold_keys(m, SCENARIO, "run", 0.99)
    assert res["realtime_hz"] == 10.0
    rt = res["realtime"]
    assert rt["world_overruns"] == 1 and rt["late_commands"] == 5 and rt["ticks_per_second"] == 10.0
    assert rt["t90_s"] is None and rt["t99_s"] is None  # coverage 0.5 reached neither
    assert rt["robots"]["r0"] == {"late_commands": 5, "late_steps": 3, "missed_ticks": 2, "decisions": 7,
                                  "plan_steps": 30, "waits": 2, "decision_ms": _timing("r0", 7).decision_ms,
                                  "allocator_ms": _timing("r0", 7).allocator_ms}
    assert rt["robots"]["r1"]["decisions"] is None  # its summary never came (it failed, say)
    assert res["decision_ms"]["mean"] == 9.0  # the step along the last plan is not a decision


def test_a_spoofed_clock_is_never_folded() -> None:
    m = Monitor(ROBOTS)
    m.feed(K.clock, WorldClock(src="r0", tick=1, seq=1, hz=10.0, elapsed=0.1, overruns=0, late={}, late_steps={},
                               missed={}).encode())
    assert m.clock is None and m.malformed == 1


def test_the_wall_seconds_to_90_and_99_percent_come_from_the_clock_of_that_tick() -> None:
    m = Monitor(ROBOTS)
    for tick, cov in ((3, 0.5), (4, 0.95), (5, 0.97), (6, 0.995)):
        m.feed(K.state, msgspec.structs.replace(_state(tick), coverage=cov).encode())
        # the world ran slower than asked: tick k at 0.25 k s, not 0.1 k s
        m.feed(K.clock, WorldClock(src="world", tick=tick, seq=tick, hz=10.0, elapsed=0.25 * tick, overruns=tick,
                                    late={}, late_steps={}, missed={}).encode())
    rt = fold_keys(m, SCENARIO, "run", 0.99)["realtime"]
    assert (m.t90, m.t99) == (4, 6)
    assert (rt["t90_s"], rt["t99_s"]) == (1.0, 1.5)
