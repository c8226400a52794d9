"""The --live-hz cap: a pure function of the monotonic clock (patched here), never a timed test."""

from __future__ import annotations

import pytest

from fleet_emu.core import pace
from fleet_emu.core.pace import Pacer


def test_the_pacer_caps_ticks_per_second_and_does_not_burst_after_a_late_tick(monkeypatch: pytest.MonkeyPatch
                                                                               ) -> None:
    now = [100.0]
    monkeypatch.setattr(pace.time, "monotonic", lambda: now[0])
    p = Pacer(4.0)  # a tick every 0.25 s at most
    assert p.delay() == 0.0  # the first tick goes at once
    assert p.delay() == pytest.approx(0.25)
    now[0] += 0.1
    assert p.delay() == pytest.approx(0.4)  # planned 0.25 s after the previous one's planned time
    now[0] += 5.0  # a tick far late: the next ones are spaced from now, not squeezed to catch up
    assert p.delay() == 0.0
    assert p.delay() == pytest.approx(0.25)
    assert Pacer(None).delay() == 0.0 and Pacer(0.0).delay() == 0.0


def test_no_tick_before_first_with_or_without_a_cap(monkeypatch: pytest.MonkeyPatch) -> None:
    now = [100.0]
    monkeypatch.setattr(pace.time, "monotonic", lambda: now[0])
    free = Pacer(None, first=100.5)  # a live run's first tick half a second after its live: line
    assert free.delay() == pytest.approx(0.5)
    now[0] = 101.0
    assert free.delay() == 0.0 and free.delay() == 0.0  # then no cap
    now[0] = 100.0
    capped = Pacer(4.0, first=100.5)
    assert capped.delay() == pytest.approx(0.5) and capped.delay() == pytest.approx(0.75)
