"""Correlated shadowing over real processes: the same seed gives the same field, so the same links, deliveries
and result, in the processes engine (netem its own process, over Zenoh) as in the memory engine."""

from __future__ import annotations

from pathlib import Path

import pytest

import fleet_emu as fe
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import deterministic, validate_result


@pytest.mark.slow  # shadowing: memory engine by default
def test_a_shadowed_run_over_processes_gives_the_memory_engines_result(small_map: Path, tmp_path: Path) -> None:
    s = fe.Scenario().override(map=str(small_map), robots=3, allocator="minpos", comm="wall", comm_range=2.0,
                               threshold=-6.0, loss=0.1, seed=5, max_ticks=60, shadowing_db=6.0, shadowing_m=1.0)
    over_zenoh = fe.run(s, tmp_path / "p")
    in_memory = Fleet(s).run()
    assert deterministic(in_memory.data) == deterministic(over_zenoh.data)
    assert in_memory.curve == over_zenoh.curve
    pred = over_zenoh["radio"]["prediction"]
    assert pred["pair_ticks"] == 3 * (over_zenoh["ticks"] + 1)  # three pairs at every tick's links, the last too
    assert pred["false_links"] + pred["missed_links"] > 0  # the field changed links eq. 4 alone calls otherwise
    assert over_zenoh["scenario"]["radio"]["shadowing_db"] == 6.0
    validate_result(over_zenoh.data)  # the schema knows radio.prediction and the two settings
    plain = Fleet(s.override(shadowing_db=0.0)).run()
    assert "prediction" not in plain["radio"]
    assert plain["radio"]["dropped_signal"] != in_memory["radio"]["dropped_signal"]  # the field changed the links
