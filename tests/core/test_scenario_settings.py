"""Every scenario field is declared once (``core/fields.setting``): its flag, its key in a scenario file, its
``Scenario.override`` keyword, a study's grid key and its check all follow from that declaration, and an error
names the field as its user wrote it."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.fields import Setting
from fleet_emu.core.radio import radio_settings
from fleet_emu.core.scenario import Scenario, scenario_settings
from fleet_emu.core.setting_names import cli_spelling
from fleet_emu.sweep.study import Study

BOUNDED = [s for s in scenario_settings() if s.kind in (int, float) and math.isfinite(s.high)]


def _too_big(s: Setting) -> int | float:
    return int(s.high) + 1 if s.kind is int else s.high * 2


def _toml(s: Setting, value: object) -> str:
    line = f"{s.key or s.name} = {value!r}\n"
    return f"[{s.section}]\n{line}" if s.section else line


def test_every_field_is_declared_and_the_defaults_are_the_declarations() -> None:
    specs = scenario_settings()
    assert [s.name for s in specs] == list(Scenario.__dataclass_fields__)
    for s in specs:
        assert s.help, s.name
        if not s.table:
            assert getattr(Scenario(), s.name) == s.default, s.name


@pytest.mark.parametrize("spec", BOUNDED, ids=[s.name for s in BOUNDED])
def test_a_value_out_of_its_declared_range_is_one_line_naming_it_everywhere(spec: Setting, tmp_path: Path) -> None:
    value = _too_big(spec)
    expected = f"must be {spec.span()} (got {value!r})"
    with pytest.raises(ConfigError) as python:
        Scenario().override(**{spec.name: value})
    assert str(python.value) == f"{spec.name} {expected}"
    with cli_spelling(), pytest.raises(ConfigError) as cli:
        Scenario().override(**{spec.name: value})
    assert str(cli.value) == f"{spec.flag} {expected}"
    path = tmp_path / "s.toml"
    path.write_text(_toml(spec, value))
    with pytest.raises(ConfigError) as file:
        Scenario.load(path)
    assert str(file.value) == f"scenario {path}: {spec.file_key} {expected}"
    if spec.name == "seed":  # a study's seeds are its [study] seeds
        return
    with pytest.raises(ConfigError) as study:
        Study.from_dict({"grid": {spec.name: [spec.default, value]}})
    assert str(study.value) == f"study study: [grid] {spec.name} {expected}"


@pytest.mark.parametrize("spec", BOUNDED, ids=[s.name for s in BOUNDED])
def test_the_highest_declared_value_is_accepted_by_every_way_in(spec: Setting, tmp_path: Path) -> None:
    value = int(spec.high) if spec.kind is int else spec.high
    if spec.name == "cell_size":  # the sensor range must stay at least one cell
        value = 1.0
    assert getattr(Scenario().override(**{spec.name: value}), spec.name) == value
    path = tmp_path / "s.toml"
    path.write_text(_toml(spec, value))
    assert getattr(Scenario.load(path), spec.name) == value
    if spec.name == "seed":
        return
    (point,) = Study.from_dict({"grid": {spec.name: [value]}}).points()
    assert point.scenario[spec.name] == value


def test_the_result_schema_names_every_declared_field() -> None:
    """``result.json``'s schema restates the scenario's keys (their ranges for validation): a field declared is
    a key there too, and no other."""
    from fleet_emu.recording.result import result_schema

    scenario = result_schema()["$defs"]["scenario"]
    assert set(scenario["properties"]) == {s.name for s in scenario_settings()}
    assert set(scenario["properties"]["radio"]["properties"]) == {s.name for s in radio_settings()}


def _section(page: str, title: str) -> str:
    text = page.split(f"## {title}\n", 1)[1]
    return text.split("\n## ", 1)[0]


def test_the_scenarios_page_lists_every_declared_key_and_flag() -> None:
    """docs/guides/scenarios.md's "Every key" and "Every flag" tables are checked against the declarations: each
    field's key in its section, with its default, and each flag made from a field."""
    page = (Path(__file__).resolve().parents[2] / "docs" / "guides" / "scenarios.md").read_text()
    keys, flags = _section(page, "Every key"), _section(page, "Every flag")
    table = [row.split("|") for row in keys.splitlines() if row.startswith("| ")]
    for s in scenario_settings():
        section = f"[{s.section}]" if s.section else "top"
        if s.table and not s.key:  # a table of its own: its section's row ([radio], [hosts], [[faults]])
            rows = [row for row in table if section in row[1] or f"[[{s.name}]]" in row[1]]
        else:
            rows = [row for row in table if f"`{s.key or s.name}`" in row[2] and section in row[1]]
        assert rows, f"no row for {s.file_key} in Every key"
        if s.kind in (int, float) and not s.table:
            assert any(f"{s.default:g}" in row[-2] for row in rows), f"{s.name}: default {s.default}"
        if s.cli and not s.table:
            assert f"`{s.flag}" in flags or f", `{s.flag}`" in flags, f"{s.flag} is not in Every flag"
