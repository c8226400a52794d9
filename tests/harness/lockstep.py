"""A small fleet on a drawn map, run by the memory engine (:class:`fleet_emu.launch.memory.Fleet`: the real
:class:`World`, :class:`Channel` and :class:`Brain` objects in the order their nodes use) with every robot on the
cell its digit marks; this module only turns the drawing into a scenario and keeps the trace the tests read.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from fleet_emu.core.grid import Cell, MapData, from_ascii
from fleet_emu.core.messages import Command, Message, WorldState
from fleet_emu.core.radio import RadioConfig
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import Result


@dataclasses.dataclass
class Trace:
    """What a lockstep run did: the true poses of every tick, each robot's target per tick, the end, and the
    run's ``result.json`` (the memory engine's)."""

    ticks: int
    reason: str | None
    coverage: float
    poses: list[dict[str, Cell]]
    targets: list[dict[str, Cell | None]]
    result: Result

    def visited(self, robot: str) -> list[Cell]:
        return [p[robot] for p in self.poses]


def run_fleet(art: str, allocator: dict[str, Any], *, sensor_range: float = 3.0, max_ticks: int = 300,
              seed: int = 0, radio: RadioConfig | None = None, cell_size: float = 0.5,
              stall_ticks: int = 30, base: bool = False) -> Trace:
    """Explore the drawn map (``#`` wall, ``.`` free, ``0``-``9`` a robot's start cell) until full coverage,
    the tick limit or a stall. ``sensor_range`` in cells; ``radio``: ideal (every pair linked, no loss) with
    the usual 1-tick latency by default; ``base``: a base station at robot 0's start (a base planner's)."""
    grid, marks = from_ascii(art)
    scenario = Scenario(name="drawn", map="drawn", cell_size=cell_size, robots=len(marks),
                        sensor_range=sensor_range * cell_size, allocator=dict(allocator),
                        radio=radio or RadioConfig(comm="ideal", loss=0.0), seed=seed, max_ticks=max_ticks,
                        target_coverage=1.0, stall_ticks=stall_ticks, base=base)
    poses: list[dict[str, Cell]] = []
    targets: dict[int, dict[str, Cell | None]] = {}

    def tap(_key: str, msg: Message, _ns: int) -> None:
        if isinstance(msg, WorldState):
            poses.append(dict(msg.poses))
        elif isinstance(msg, Command):
            targets.setdefault(msg.tick, {})[msg.src] = msg.target

    fleet = Fleet(scenario, tap=tap, map_data=MapData("drawn", grid, cell_size, marks["r0"]), starts=marks)
    result = fleet.run()
    w = fleet.world
    return Trace(ticks=w.tick, reason=w.reason, coverage=w.coverage, poses=poses,
                 targets=[targets[t] for t in sorted(targets)], result=result)
