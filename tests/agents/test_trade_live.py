"""Trade live: a small fleet through ``World``, ``Channel`` and ``Brain`` with the real one-tick latency, robots
moving during protocol rounds (``explore_in_round``) against the first version that stood still through them."""

from __future__ import annotations

import numpy as np
import pytest

from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.brain import Brain, BrainConfig
from fleet_emu.core.grid import MapData, from_ascii
from fleet_emu.core.messages import Observation
from fleet_emu.netem.channel import Channel
from fleet_emu.world.sim import World, WorldConfig

# Three rooms off a corridor; the fleet starts in the left room.
TRUTH = """
##########################
#0.1.....#.......#.......#
#2.......#.......#.......#
#........#.......#.......#
#........................#
#........#.......#.......#
#........#.......#.......#
##########################
"""


def run_live(explore_in_round: bool, ticks: int = 300) -> tuple[int, dict[str, int]]:
    """Ticks to full coverage, idle robot-ticks as result.json counts them (a robot whose command was not
    NO_FRONTIER on the same cell the next tick), by that status."""
    grid, poses = from_ascii(TRUTH)
    robots = sorted(poses)
    world = World(MapData("rooms", grid, 0.5, poses["r0"]), robots,
                  WorldConfig(sensor_range=3.0, target_coverage=1.0, max_ticks=ticks, stall_ticks=ticks))
    channel = Channel(loss=0.0, rng=np.random.default_rng(0))
    brains = {r: Brain(r, make_allocator({"type": "trade", "explore_in_round": explore_in_round}),
                       np.random.default_rng(k), BrainConfig(cluster_max=6), team=frozenset(robots))
              for k, r in enumerate(robots)}
    readings = world.reset()
    idle: dict[str, int] = {}
    link = np.ones((len(robots), len(robots)), dtype=bool)
    while not world.done:
        t = world.tick
        inbox = channel.deliver(t)
        moves, bundles, status = {}, {}, {}
        for r in robots:
            rd = readings[r]
            obs = Observation(src="world", tick=t, seq=t, robot=r, cell=rd.cell, shape=world.shape, cell_size=0.5,
                              cells=rd.cells, values=rd.values)
            cmd, bundles[r] = brains[r].step(obs, inbox.get(r, []))
            moves[r] = cmd.move
            status[r] = cmd.status
        channel.transmit(t, tuple(robots), link, bundles)
        before = dict(world.poses)
        readings = world.step(moves)
        for r in robots:
            if world.poses[r] == before[r] and status[r] != "NO_FRONTIER":
                idle[status[r]] = idle.get(status[r], 0) + 1
    assert world.reason == "coverage", world.reason
    return world.tick, idle


@pytest.fixture(scope="module")
def runs() -> dict[bool, tuple[int, dict[str, int]]]:
    return {explore: run_live(explore) for explore in (True, False)}


def test_robots_keep_exploring_during_rounds(runs: dict[bool, tuple[int, dict[str, int]]]) -> None:
    (moving_ticks, moving), (standing_ticks, standing) = runs[True], runs[False]
    assert standing.get("WAITING", 0) > 30  # the first version: every round spent standing still
    assert "WAITING" not in moving  # now: no robot-tick spent waiting on its cell
    assert sum(moving.values()) < sum(standing.values()) / 2  # what is left: steps blocked by a teammate
    assert moving_ticks < standing_ticks, (moving_ticks, standing_ticks)
