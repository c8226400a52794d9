"""A run's world from its scenario, and where its base station stands: pure, no Zenoh and no files.

The launcher (its checks, the recording's Foxglove fold, the memory engine) and the world's node shell build
the world here. The base station's cell is the world's to say, since with ``base = true`` it is the start
cell the world places the fleet around, drawn from the world's own generator for a ``random`` start; so the
launcher resolves it here once and hands the cell to the processes that need it (netem and the base station,
``--base-cell ROW,COL``), which do not import ``world`` (the layering: world, netem and agents never import
one another).
"""

from __future__ import annotations

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.faults import crashes
from fleet_emu.core.grid import Cell, MapData
from fleet_emu.core.keys import robot_ids
from fleet_emu.core.rng import generator
from fleet_emu.core.scenario import Scenario
from fleet_emu.world.sim import World, WorldConfig


def build_world(scenario: Scenario, map_data: MapData, placement: tuple[Cell, ...] | None = None) -> World:
    """The world of a scenario on its map; ``placement``: explicit start cells, one per robot (the memory
    engine's :class:`~fleet_emu.launch.memory.Fleet` takes them)."""
    config = WorldConfig(
        sensor_range=scenario.sensor_cells,
        target_coverage=scenario.target_coverage,
        max_ticks=scenario.max_ticks,
        stall_ticks=scenario.stall_ticks,
        coverage_stall_ticks=scenario.coverage_stall_ticks,
        start=scenario.start,
        placement=placement,
        crashes=crashes(scenario.faults),
    )
    return World(map_data, robot_ids(scenario.robots), config, generator(scenario.seed, "world"))


def base_cell(scenario: Scenario, map_data: MapData, world: World | None = None) -> Cell | None:
    """The base station's cell (None without one): the scenario's ``base`` cell, or with ``base = true`` the
    start cell the world places the fleet around (``world``: one already placed or reset, whose start it takes;
    else a world is built and placed here, so that a ``random`` start is drawn as the world draws it). A cell off
    the map or not free is a one-line ConfigError. The base has no body: robots may drive over its cell."""
    if not scenario.has_base:
        return None
    if isinstance(scenario.base, tuple):
        cell = (int(scenario.base[0]), int(scenario.base[1]))
        rows, cols = map_data.grid.shape
        if not (0 <= cell[0] < rows and 0 <= cell[1] < cols):
            raise ConfigError(f"base cell {cell} is off the map ({rows} x {cols} cells)")
        if map_data.grid[cell] != 0:
            raise ConfigError(f"base cell {cell} is not a free cell of the map")
        return cell
    if world is None:
        world = build_world(scenario, map_data)
        world.place()
    return (int(world.start[0]), int(world.start[1]))
