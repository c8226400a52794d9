"""``result.json``'s ``allocator_params`` records every parameter the allocator ran with: the scenario's table,
the scenario fields the allocator reads, and every other parameter at its default, plugins' included."""

from __future__ import annotations

from typing import Any, ClassVar

from fleet_emu.agents.allocators import Param, allocator_class
from fleet_emu.agents.allocators.nearest import Nearest
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import validate_result
from fleet_emu.recording.monitor import allocator_params


class _WithDefaults(Nearest, plugin_name="test-params-with-defaults"):
    """A plugin-like allocator whose parameters are all defaulted."""

    parameters: ClassVar[dict[str, Param]] = {"crowd": Param(15.0, ge=0), "stale": Param(40, ge=1)}


def test_a_run_records_every_effective_parameter() -> None:
    scenario = Scenario().override(allocator="utility", robots=2, max_ticks=3)
    data = Fleet(scenario).run().data
    declared = allocator_class("utility").parameters
    expected: dict[str, Any] = {"type": "utility", **{p: spec.default for p, spec in declared.items()}}
    expected["sensor_range"] = scenario.sensor_cells  # a scenario field of utility's
    assert data["allocator_params"] == expected and set(declared) <= set(data["allocator_params"])
    validate_result(data)


def test_a_plugins_defaults_are_filled_in_and_a_given_value_wins() -> None:
    scenario = Scenario().override(allocator={"type": "test-params-with-defaults", "stale": 7})
    assert allocator_params(scenario.to_dict()) == {"type": "test-params-with-defaults", "crowd": 15.0, "stale": 7}


def test_an_allocator_that_cannot_load_keeps_the_table_as_given() -> None:
    d = Scenario().to_dict() | {"allocator": {"type": "not-installed-here", "x": 1}}
    assert allocator_params(d) == {"type": "not-installed-here", "x": 1}
