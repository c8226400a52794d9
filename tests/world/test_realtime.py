"""The world's wall clock in real-time mode: the fixed schedule, overruns, and the command latch (late commands
applied at the next tick and counted, silent robots)."""

from __future__ import annotations

import pytest

from fleet_emu.world.realtime import CommandLatch, TickClock

UP, DOWN, STAY = (-1, 0), (1, 0), (0, 0)


def test_ticks_are_due_on_a_fixed_schedule_whatever_the_step_took() -> None:
    clock = TickClock(hz=10.0, t0=100.0)
    assert clock.deadline(0, now=100.001) == pytest.approx(100.1)
    assert clock.deadline(1, now=100.13) == pytest.approx(100.2)  # 30 ms of stepping did not push tick 2 back
    assert clock.deadline(2, now=100.2999) == pytest.approx(100.3)
    assert clock.overruns == 0


def test_an_overrun_is_counted_and_the_schedule_re_anchored_not_caught_up() -> None:
    clock = TickClock(hz=10.0, t0=0.0)
    assert clock.deadline(4, now=0.75) == pytest.approx(0.85)  # tick 5 was due at 0.5: a full period from now
    assert clock.overruns == 1
    assert clock.deadline(5, now=0.86) == pytest.approx(0.95)  # then the new schedule holds
    assert clock.overruns == 1


def test_the_last_command_received_is_applied_and_late_ones_are_counted() -> None:
    latch = CommandLatch(["r0", "r1", "r2"], now=0.0)
    assert latch.receive("r0", 7, UP, tick=7, now=1.0)  # on time
    assert latch.receive("r1", 6, DOWN, tick=7, now=1.0)  # decided on tick 6's observation: late
    assert latch.receive("r1", 7, STAY, tick=7, now=1.01) is True  # then on time: the last one received wins
    assert latch.receive("r2", 5, DOWN, tick=7, now=1.02)  # late, and the only one: applied now
    assert latch.receive("r0", 6, DOWN, tick=7, now=1.03, decided=False)  # a late step along the last plan
    assert latch.take(["r0", "r1", "r2"]) == {"r0": DOWN, "r1": STAY, "r2": DOWN}
    assert latch.late == {"r0": 0, "r1": 1, "r2": 1}
    assert latch.late_steps == {"r0": 1, "r1": 0, "r2": 0}
    assert latch.missed == {"r0": 0, "r1": 0, "r2": 0}


def test_a_robot_that_sent_nothing_stands_and_is_counted_missed() -> None:
    latch = CommandLatch(["r0", "r1"], now=0.0)
    latch.receive("r0", 0, UP, tick=0, now=0.01)
    assert latch.take(["r0", "r1"]) == {"r0": UP}
    assert latch.take(["r0", "r1"]) == {}  # nothing carried over to the next tick
    assert latch.missed == {"r0": 1, "r1": 2}


def test_a_command_for_a_tick_not_yet_published_is_refused() -> None:
    latch = CommandLatch(["r0"], now=0.0)
    assert latch.receive("r0", 8, UP, tick=7, now=0.5) is False
    assert latch.take(["r0"]) == {} and latch.late == {"r0": 0}


def test_silent_robots_are_those_not_heard_for_the_timeout() -> None:
    latch = CommandLatch(["r0", "r1"], now=0.0)
    latch.receive("r0", 0, UP, tick=0, now=9.0)
    assert latch.silent(["r0", "r1"], now=10.5, timeout=10.0) == ["r1"]
    assert latch.silent(["r0"], now=10.5, timeout=10.0) == []
