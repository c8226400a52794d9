"""Every registered allocator drives a fleet to the target under loss, on the memory engine: the same World,
Channel and Brain objects the node processes run (their transport is proved once per concern in
``tests/integration``: ``test_memory_engine.py`` for a protocol allocator over processes,
``test_engine_messages.py`` for the base's planner; MHM to its target in ``test_mhm.py``). Every message of each
run also survives the bus's encoding: it decodes to what re-encodes to the same bytes."""

from __future__ import annotations

from pathlib import Path

import pytest

import fleet_emu as fe
from fleet_emu.agents.allocators import allocator_names
from fleet_emu.core.codec import decode
from fleet_emu.core.messages import Message
from fleet_emu.core.scenario import BASE_PLANNERS
from fleet_emu.launch.memory import Fleet


@pytest.mark.parametrize("loss", [0.0, pytest.param(0.3, marks=pytest.mark.slow), 0.5])  # 0.3: between the two
@pytest.mark.parametrize("allocator", [a for a in allocator_names() if a not in BASE_PLANNERS])
# mhm needs a base station and stops where its robots cannot reach (step 18): tests/integration/test_mhm.py
def test_every_allocator_completes_under_loss(allocator: str, loss: float, small_map: Path) -> None:
    kinds: set[str] = set()

    def on_the_bus(key: str, msg: Message, _ns: int) -> None:
        data = msg.encode()
        assert decode(data).encode() == data, key
        kinds.add(key.split("/")[2])

    s = fe.Scenario().override(map=str(small_map), robots=4, allocator=allocator, loss=loss, seed=3, max_ticks=400)
    res = Fleet(s, tap=on_the_bus).run()
    assert res["allocator"] == allocator and res["failed"] == []
    assert res["completed"] is True and res["coverage"] >= 0.99, res["reason"]
    assert kinds >= {"world", "netem", "robot", "radio"}  # every node's messages went through the codec
    radio = res["radio"]
    if loss > 0:
        assert radio["dropped_loss"] > 0
        assert abs(radio["dropped_loss"] / (radio["delivered"] + radio["dropped_loss"]) - loss) < 0.15
    else:
        assert radio["dropped_loss"] == 0
