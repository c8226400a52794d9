"""A bandwidth-limited radio over processes gives the memory engine's run (the suite's one processes run of the
shared medium): netem's queues, airtime and delay are the same pure code in both engines."""

from __future__ import annotations

from pathlib import Path

import fleet_emu as fe
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import deterministic


def test_memory_equals_processes_under_a_bandwidth_limit(small_map: Path) -> None:
    s = fe.Scenario().override(map=str(small_map), robots=3, allocator="trade", loss=0.2, seed=4, max_ticks=120,
                               bandwidth=4.0, jitter=1)  # 500 bytes a tick: queues, airtime and jitter all matter
    over_zenoh = fe.run(s)
    in_memory = Fleet(s).run()
    assert deterministic(in_memory.data) == deterministic(over_zenoh.data)
    assert in_memory.curve == over_zenoh.curve
    radio = over_zenoh["radio"]
    assert radio["queued_max_bytes"] > 0 and radio["delay_ticks"]["max"] > 2 and radio["dropped_loss"] > 0
