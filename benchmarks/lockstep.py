"""The lockstep of one run, stepped directly in this process: the same ``World``, ``Channel`` and ``Brain``
objects the world, netem and agent processes drive, in the same order, without Zenoh.

A seed gives the same run as ``fleet run`` (``benchmarks/connectivity_table.py --check`` compares the two), at
a fraction of the cost, which is what a table of many long runs on a shared machine needs. Tick ``t``: the world's
readings of ``t``; netem's links of ``t`` on the true poses and the deliveries due at ``t``; every live robot's
brain decides; netem schedules the bundles; the world applies the moves.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.brain import Brain, allocator_config, brain_config
from fleet_emu.core.grid import MapData
from fleet_emu.core.keys import robot_ids
from fleet_emu.core.messages import Command, Observation
from fleet_emu.core.radio import connected, link_matrix
from fleet_emu.core.rng import generator
from fleet_emu.core.scenario import Scenario
from fleet_emu.netem.channel import Channel
from fleet_emu.world.maps import load_map
from fleet_emu.world.node import build_world


@dataclasses.dataclass
class Outcome:
    """What ``result.json`` would say of the run (the keys a table needs)."""

    ticks: int
    completed: bool
    coverage: float
    reason: str | None
    connected_fraction: float
    path_length: dict[str, int]


def simulate(scenario: Scenario, map_data: MapData | None = None,
             on_tick: Callable[[int, dict[str, Any], dict[str, Command]], None] | None = None) -> Outcome:
    """Run ``scenario`` to its end; ``on_tick(tick, world_poses, commands)`` sees every decision."""
    md = map_data if map_data is not None else load_map(scenario.map, scenario.cell_size, scenario.seed)
    world = build_world(scenario, md)
    robots = robot_ids(scenario.robots)
    team = frozenset(robots)
    brains = {r: Brain(r, make_allocator(allocator_config(scenario)), generator(scenario.seed, r),
                       brain_config(scenario), team=team) for r in robots}
    channel = Channel(scenario.radio.applied_loss, generator(scenario.seed, "netem"), scenario.radio.latency)
    occupied = md.grid > 0
    readings = world.reset()
    link_ticks = connected_ticks = 0
    while True:
        live = tuple(r for r in robots if r in world.live)
        _, link = link_matrix(occupied, [world.poses[r] for r in live], scenario.cell_size, scenario.radio)
        link_ticks += 1
        connected_ticks += int(connected(link))
        if world.done:
            break
        arriving = channel.deliver(world.tick)
        commands: dict[str, Command] = {}
        bundles = {}
        for r in live:
            rd = readings[r]
            obs = Observation(src="world", tick=world.tick, seq=0, robot=r, cell=rd.cell, shape=world.shape,
                              cell_size=scenario.cell_size, cells=rd.cells, values=rd.values)
            commands[r], bundles[r] = brains[r].step(obs, arriving.get(r, ()))
        if on_tick is not None:
            on_tick(world.tick, dict(world.poses), commands)
        channel.transmit(world.tick, live, link, bundles)
        readings = world.step({r: c.move for r, c in commands.items()})
    return Outcome(ticks=world.tick, completed=world.reason == "coverage", coverage=world.coverage,
                   reason=world.reason, connected_fraction=connected_ticks / link_ticks,
                   path_length=dict(world.path_length))
