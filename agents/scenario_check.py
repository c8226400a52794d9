"""The allocator check of :mod:`fleet_emu.core.scenario_checks` (entry point ``allocator``): the scenario's
allocator exists and takes its parameters, as every robot will build it."""

from __future__ import annotations

from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.brain import allocator_config
from fleet_emu.core.scenario import Scenario


def check_allocator(scenario: Scenario) -> None:
    """ConfigError on an unknown allocator, a plugin that does not load, or a parameter it refuses."""
    make_allocator(allocator_config(scenario))
