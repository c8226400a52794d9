"""The base station's process shell: ``python -m fleet_emu.agents.base_node``.

The base is a fixed radio endpoint: netem computes its links from its cell like a robot's and delivers to it,
on ``radio/rx/base``, what robots broadcast. It is driven only by those rx bundles: it takes no part in the
world's lockstep barrier (it has no command to send), and a run's robots do the same with or without it
(netem draws the base's receptions from a generator of its own). Each bundle is stepped, in the order netem
sent them, through :class:`~fleet_emu.agents.base.BaseStation`.

In a run whose allocator plans at the base (``mhm``, ``Scenario.plans_at_base``) the base also sends: after
stepping the rx bundle of tick t it publishes its tx bundle of t on ``radio/tx/base`` (the planner's orders,
sent even when empty), and netem waits for it as for a robot's before it sends tick t, so the run stays
lockstep and deterministic. Other runs publish nothing there and are as before.

At the world's stop of tick T it waits (at most :data:`FINAL_GRACE` seconds) for the bundles up to T - 1, the
last netem sends, so that its map is the same in every engine; then it publishes its
:class:`~fleet_emu.core.messages.BaseReport` on ``ctl/report/base`` and exits. The launcher's stop (Ctrl-C)
ends it at once. A base process that dies fails the run like the world or netem (exit code 1).
"""

from __future__ import annotations

import asyncio
import resource
import time

import msgspec
import zenoh

from fleet_emu.agents.allocators.mhm.station import station_planner
from fleet_emu.agents.base import BaseStation
from fleet_emu.agents.outputs import base_report, base_tx
from fleet_emu.core.bus import Inbox, Publisher
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.grid import Cell, MapData
from fleet_emu.core.keys import BASE, Keys, robot_ids
from fleet_emu.core.messages import RxBundle, Stop
from fleet_emu.core.node import Declared, NodeShell, add_base_cell, node_main, undeclare
from fleet_emu.core.scenario import Scenario

FINAL_GRACE = 2.0  # seconds to wait, after the world's stop, for the last rx bundles


class BaseStationNode(NodeShell):
    role = BASE

    def __init__(self, scenario: Scenario, run: str, map_data: MapData, cell: Cell) -> None:
        """``cell``: the base's cell, resolved by the launcher (``world.build.base_cell``)."""
        super().__init__(Keys(run), BASE)
        if not scenario.has_base:
            raise ConfigError("a base station's process for a scenario without a base")
        self.station = BaseStation(cell, map_data.grid.shape, frozenset(robot_ids(scenario.robots)),
                                   planner=station_planner(scenario), on_drop=self.drop)
        self.sends = scenario.plans_at_base
        self.pub_tx: Publisher | None = None
        self.next_tick = 0

    def next_seq(self) -> int:
        return self.station.next_seq()

    async def run(self, session: zenoh.Session) -> None:
        keys = self.keys
        inbox = self.inbox()
        handles: list[Declared] = [inbox.subscribe(session, keys.rx(BASE)), inbox.subscribe(session, keys.stop)]
        pub_report = self.publisher(session, keys.report(BASE))
        handles.append(pub_report)
        if self.sends:
            self.pub_tx = self.publisher(session, keys.tx(BASE))
            handles.append(self.pub_tx)
        handles += self.declare_presence(session, inbox)
        try:
            stop = await self._until_stop(inbox)
            if stop.src == "world":
                await self._final(inbox, stop.tick)
            rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
            report = base_report(self.station, stop.tick, self.dropped, rss)
            pub_report.put(msgspec.structs.replace(report, foreign=self.foreign).encode())
            await asyncio.sleep(0.05)
        finally:
            undeclare(handles)

    async def _until_stop(self, inbox: Inbox) -> Stop:
        while True:
            stop = await self._next(inbox)
            if stop is not None:
                return stop

    async def _final(self, inbox: Inbox, last: int) -> None:
        """Step the bundles still to come, up to tick ``last - 1``, for at most FINAL_GRACE seconds."""
        deadline = time.monotonic() + FINAL_GRACE
        while self.next_tick < last and time.monotonic() < deadline:
            await self._next(inbox, timeout=max(0.0, deadline - time.monotonic()))

    async def _next(self, inbox: Inbox, timeout: float | None = None) -> Stop | None:
        """Handle one incoming item; the stop when it is one."""
        item = await inbox.get(timeout)
        if item is None:
            return None
        key, data, _ = item
        channel = self.keys.channel(key)
        if channel == "hello":
            self.answer_hello(key, data)
        elif channel == "stop":
            return self.decode(key, data, Stop)
        elif channel == "rx":
            b = self.decode(key, data, RxBundle)  # loosely: the station checks each envelope against the team
            if b is not None and b.dst == BASE and b.tick >= self.next_tick:  # one key, one publisher: in order
                out = self.station.step(b.tick, b.msgs)
                if self.pub_tx is not None:
                    self.pub_tx.put(base_tx(self.station, b.tick, out).encode())
                self.next_tick = b.tick + 1
            elif b is not None:
                self.drop(key, "rx bundle for another node or a past tick")
        return None


def main(argv: list[str] | None = None) -> None:
    """``python -m fleet_emu.agents.base_node --run RUN --connect ENDPOINT --scenario FILE.json
    --map-file MAP.npz --base-cell ROW,COL``."""
    node_main("base", lambda a: BaseStationNode(a.scenario, a.run, a.map_file, a.base_cell), argv,
              lambda p: add_base_cell(p, required=True), map_file=True)


if __name__ == "__main__":
    main()
