"""The MHM planner's test fleet (its own simulator, :func:`fleet_emu.agents.allocators.mhm.sim.simulate`): an
office drawn in ASCII, the base station's cell, the planner's settings, a run, and its events by prefix."""

from __future__ import annotations

from fleet_emu.agents.allocators.mhm.planner import MhmConfig
from fleet_emu.agents.allocators.mhm.sim import SimResult, simulate
from fleet_emu.core.grid import from_ascii

# Two rooms off a hall, a long room along the bottom; every passage at least two cells wide, so that a node
# robot standing in one does not block it.
OFFICE = """
##############################################
#..........................#.................#
#..........................#.................#
#..........................#.................#
#.........########.........#.........#########
#.........#......#...................#.......#
#.........#......#...................#.......#
#.........#..........................#.......#
#.........#..........................#.......#
#.........#......#...................#.......#
#.........########.........#.........#.......#
#..........................#.................#
#..........................#.................#
#######....#################.........#########
#............................................#
#............................................#
#............................................#
##############################################
"""
BASE = (2, 2)


def run(art: str, robots: int, config: MhmConfig, seed: int = 0, max_ticks: int = 3000) -> SimResult:
    truth, _ = from_ascii(art)
    return simulate(truth, BASE, robots, config, seed, max_ticks)


CONFIG = MhmConfig(r_comm=10.0, sensor_range=4.0, x_min=1, cluster_max=8, patience=40)


def events(out: SimResult, prefix: str) -> list[tuple[int, str]]:
    return [(t, e) for t, e in out.planner.events if e.startswith(prefix)]
