"""The map check of :mod:`fleet_emu.core.scenario_checks` (entry point ``map``): the scenario names a map that
exists, without loading it (a registry map counts once listed; ``fleet run`` asks to fetch it if need be)."""

from __future__ import annotations

from pathlib import Path

from fleet_emu.core.scenario import Scenario
from fleet_emu.world.maps import BUILTIN_MAPS, missing_map
from fleet_emu.world.registry import registry


def check_map(scenario: Scenario) -> None:
    """MapError (as loading it would raise) unless the map is a built-in's or a registry map's name, or a file
    (``load_map``'s cases)."""
    name = scenario.map
    if name in BUILTIN_MAPS or name in registry() or Path(name).expanduser().is_file():
        return
    raise missing_map(name)
