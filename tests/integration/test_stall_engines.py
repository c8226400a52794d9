"""The stall rule over processes: each robot's known cells cross the bus in its commands, and the world ends an
oscillating fleet's run at the tick the memory engine does, with the same result."""

from __future__ import annotations

from pathlib import Path

import pytest

import fleet_emu as fe
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import deterministic
from tests.harness.stall import oscillating


@pytest.mark.slow  # the stall rule over processes; memory engine by default
def test_a_belief_stall_over_processes_is_the_memory_engines(small_map: Path) -> None:
    s = oscillating(small_map)
    over_zenoh = fe.run(s)
    in_memory = Fleet(s).run()
    assert over_zenoh["reason"] == "stall" and over_zenoh["engine"] == "processes"
    assert deterministic(in_memory.data) == deterministic(over_zenoh.data)
