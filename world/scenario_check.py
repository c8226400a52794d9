"""The map check of :mod:`fleet_emu.core.scenario_checks` (entry point ``map``): the scenario names a map that
exists, without loading it (a registry map counts once listed; ``fleet run`` asks to fetch it if need be)."""

from __future__ import annotations

from pathlib import Path

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.scenario import Scenario
from fleet_emu.world.maps import BUILTIN_MAPS
from fleet_emu.world.registry import registry


def check_map(scenario: Scenario) -> None:
    """ConfigError unless the map is a built-in's or a registry map's name, or a file (``load_map``'s cases)."""
    name = scenario.map
    if name in BUILTIN_MAPS or name in registry():
        return
    path = Path(name).expanduser()
    if path.is_file():
        return
    if path.exists():
        raise ConfigError(f"map path is not a file: {name}")
    if "/" in name or "\\" in name or path.suffix:
        raise ConfigError(f"map file not found: {name}")
    raise ConfigError(f"unknown map {name!r} (built-in: {', '.join(BUILTIN_MAPS)}; registry: "
                      f"{', '.join(registry())} (`fleet maps`); or a PNG/PGM/YAML path)")
