"""netem's shell takes the world's state of exactly the tick it awaits: an old state that arrives late (a
replay, a copy) is dropped and counted, never used for the links and deliveries of a later tick."""

from __future__ import annotations

import asyncio

import numpy as np

from fleet_emu.core.bus import Inbox
from fleet_emu.core.grid import MapData
from fleet_emu.core.messages import WorldState
from fleet_emu.core.scenario import Scenario
from fleet_emu.netem.node import NetemNode


def _state(tick: int, coverage: float) -> WorldState:
    return WorldState(src="world", tick=tick, seq=tick + 1, poses={"r0": (1, 1)}, live=("r0",), coverage=coverage,
                      path_length={"r0": tick})


def test_an_old_state_arriving_before_the_awaited_one_is_dropped_not_used() -> None:
    node = NetemNode(Scenario().override(robots=1), "run", MapData("open", np.zeros((6, 6), np.int8), 0.5, (1, 1)))

    async def go() -> tuple[WorldState | None, WorldState | None]:
        inbox = Inbox()

        def put(st: WorldState) -> None:
            inbox.put_nowait((node.keys.state, st.encode(), True))

        put(_state(0, 0.1))
        first = await node._await_state(inbox, 0)
        put(_state(1, 0.2))  # the state of tick 1 comes while netem still waits for tick 0's bundles ...
        put(_state(0, 0.9))  # ... then an old one, of tick 0 again
        assert await node._next(inbox, 1.0) and await node._next(inbox, 1.0)
        return first, await node._await_state(inbox, 1)

    first, second = asyncio.run(go())
    assert first is not None and (first.tick, first.coverage) == (0, 0.1)
    assert second is not None and (second.tick, second.coverage) == (1, 0.2)
    assert node.dropped == 1 and node.states == {}
