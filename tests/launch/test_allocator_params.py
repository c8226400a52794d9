"""``result.json``'s ``allocator_params`` records every parameter the allocator ran with: the scenario's table,
the scenario fields the allocator reads, and every other parameter at its default, plugins' included."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any, ClassVar

import pytest

from fleet_emu.agents.allocators import Allocator, Param, allocator_class
from fleet_emu.agents.allocators.nearest import Nearest
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import validate_result
from fleet_emu.recording.result import allocator_params


@pytest.fixture
def with_defaults() -> Iterator[str]:
    """A plugin-like allocator whose parameters are all defaulted, registered for the test only (another
    interpreter a later test starts would not know it)."""

    class _WithDefaults(Nearest):
        parameters: ClassVar[dict[str, Param]] = {"crowd": Param(15.0, ge=0), "stale": Param(40, ge=1)}

    _WithDefaults.register("test-params-with-defaults")
    try:
        yield "test-params-with-defaults"
    finally:
        del Allocator.registry["test-params-with-defaults"]


def test_a_run_records_every_effective_parameter() -> None:
    scenario = Scenario().override(allocator="utility", robots=2, max_ticks=3)
    data = Fleet(scenario).run().data
    declared = allocator_class("utility").parameters
    expected: dict[str, Any] = {"type": "utility", **{p: spec.default for p, spec in declared.items()}}
    expected["sensor_range"] = scenario.sensor_cells  # a scenario field of utility's
    assert data["allocator_params"] == expected and set(declared) <= set(data["allocator_params"])
    validate_result(data)


def test_a_plugins_defaults_are_filled_in_and_a_given_value_wins(with_defaults: str) -> None:
    scenario = Scenario().override(allocator={"type": with_defaults, "stale": 7})
    assert allocator_params(scenario.to_dict()) == {"type": with_defaults, "crowd": 15.0, "stale": 7}


def test_an_allocator_that_cannot_load_keeps_the_table_as_given() -> None:
    d = Scenario().to_dict() | {"allocator": {"type": "not-installed-here", "x": 1}}
    assert allocator_params(d) == {"type": "not-installed-here", "x": 1}
