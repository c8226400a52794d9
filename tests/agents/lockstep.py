"""A small fleet stepped in lockstep without Zenoh: the real :class:`World`, :class:`Channel` and
:class:`Brain` objects, wired in the order their nodes use (world/node.py, netem/node.py, agents/node.py).

Tick t: the world's readings and poses of t; netem computes the links on the poses of t and delivers what is
due at t (sent at t - latency); every live robot steps on its observation and rx bundle; netem schedules the
tx bundles of t on the links of t; the world applies the moves and advances. Bundles go through their codec,
as on the bus.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.brain import Brain, BrainConfig
from fleet_emu.core.grid import Cell, MapData, from_ascii
from fleet_emu.core.messages import Observation, RxBundle, decode
from fleet_emu.core.radio import RadioConfig, link_matrix
from fleet_emu.core.rng import generator
from fleet_emu.netem.channel import Channel
from fleet_emu.world.sim import World, WorldConfig


@dataclasses.dataclass
class Trace:
    """What a lockstep run did: the true poses of every tick, each robot's target per tick, and the end."""

    ticks: int
    reason: str | None
    coverage: float
    poses: list[dict[str, Cell]]
    targets: list[dict[str, Cell | None]]

    def visited(self, robot: str) -> list[Cell]:
        return [p[robot] for p in self.poses]


class DrawnWorld(World):
    """The world with every robot on the cell its digit marks in the drawing, instead of around the start."""

    def __init__(self, map_data: MapData, cells: dict[str, Cell], config: WorldConfig, rng: Any) -> None:
        super().__init__(map_data, list(cells), config, rng)
        self.drawn = list(cells.values())

    def start_cells(self) -> list[Cell]:
        return self.drawn


def run_fleet(art: str, allocator: dict[str, Any], *, sensor_range: float = 3.0,
              max_ticks: int = 300, seed: int = 0, radio: RadioConfig | None = None,
              cluster_max: int = 6, cell_size: float = 0.5) -> Trace:
    """Explore the drawn map (``#`` wall, ``.`` free, ``0``-``9`` a robot's start cell) until full coverage,
    the tick limit or a stall. ``radio``: ideal (every pair linked, no loss) with the usual 1-tick latency by
    default."""
    grid, marks = from_ascii(art)
    radio = radio or RadioConfig(comm="ideal", loss=0.0)
    ids = list(marks)
    world = DrawnWorld(MapData("drawn", grid, cell_size, marks["r0"]), marks,
                       WorldConfig(sensor_range=sensor_range, target_coverage=1.0, max_ticks=max_ticks),
                       generator(seed, "world"))
    channel = Channel(radio.applied_loss, generator(seed, "netem"), radio.latency)
    team = frozenset(ids)
    brains = {r: Brain(r, make_allocator(dict(allocator)), generator(seed, r), BrainConfig(cluster_max=cluster_max),
                       team=team) for r in ids}
    occupied = grid > 0
    readings = world.reset()
    poses, targets = [dict(world.poses)], []
    while not world.done:
        t = world.tick
        live = tuple(r for r in ids if r in world.live)
        _, link = link_matrix(occupied, [world.poses[r] for r in live], cell_size, radio)
        arriving = channel.deliver(t)
        moves, bundles, chosen = {}, {}, {}
        for r in live:
            rd = readings[r]
            obs = Observation(src="world", tick=t, seq=0, robot=r, cell=rd.cell, shape=world.shape,
                              cell_size=cell_size, cells=rd.cells, values=rd.values)
            rx = decode(RxBundle(src="netem", tick=t, seq=0, dst=r, msgs=tuple(arriving.get(r, ()))).encode())
            cmd, out = brains[r].step(obs, rx.msgs)
            moves[r], bundles[r], chosen[r] = cmd.move, out, cmd.target
        channel.transmit(t, live, link, bundles)
        readings = world.step(moves)
        poses.append(dict(world.poses))
        targets.append(chosen)
    return Trace(ticks=world.tick, reason=world.reason, coverage=world.coverage, poses=poses, targets=targets)
