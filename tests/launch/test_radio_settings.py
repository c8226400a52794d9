"""Every radio setting, declared once in ``RadioConfig``, reaches every way of setting it: the ``fleet run`` flag,
``[radio]``, a study's ``[grid]`` and ``[fleet]`` (flat, or a ``radio`` table), ``Scenario.override``; bad
values are one line (exit 2 on the CLI). The cases are drawn from the declarations, so a field declared later
is tested by the same code. And ``override`` checks allocator tables, allocator names and maps."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any

import pytest

from fleet_emu.core.errors import ConfigError, FleetError, MapError
from fleet_emu.core.fields import Setting, setting, settings
from fleet_emu.core.radio import RadioConfig, radio_settings
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.cli import build_parser, scenario_from_args
from fleet_emu.sweep.study import Study
from tests.harness.cli import run_cli

SETTINGS = radio_settings()
IDS = [s.name for s in SETTINGS]


def good(s: Setting) -> Any:
    """A value the setting accepts, other than its default."""
    if s.choices:
        return next(c for c in s.choices if c != s.default)
    finite = [x for x in (s.low, s.high) if math.isfinite(x)]
    for v in (s.default * 2, s.default + 1, s.default - 1, sum(finite) / 2 if len(finite) == 2 else s.low + 1):
        v = int(v) if s.kind is int else float(v)
        if v != s.default and (s.low < v if s.low_open else s.low <= v) and v <= s.high:
            return v
    raise AssertionError(f"no good value for {s.name}")


def bad(s: Setting) -> Any:
    """A value the setting refuses."""
    if s.choices:
        return "telepathy"
    return s.high * 2 + 1 if math.isfinite(s.high) else s.low - 1


def test_every_field_is_declared_with_a_flag_and_a_range() -> None:
    assert [s.name for s in SETTINGS] == [f.name for f in dataclasses.fields(RadioConfig)]
    for s in SETTINGS:
        assert s.help and s.default == getattr(RadioConfig(), s.name)
        assert s.choices or (s.metavar and s.low <= s.default <= s.high), s.name
    for name, metavar in (("waf", "DB"), ("path_loss", "PL"), ("threshold", "DB"), ("latency", "TICKS"),
                          ("max_walls", "N")):
        assert next(s for s in SETTINGS if s.name == name).metavar == metavar


def test_an_undeclared_field_is_a_programming_error() -> None:
    @dataclasses.dataclass(frozen=True)
    class Half:
        a: float = setting(1.0, low=0.0, help="declared")
        b: int = 2

    with pytest.raises(TypeError, match=r"Half\.b has no setting"):
        settings(Half)


@pytest.mark.parametrize("s", SETTINGS, ids=IDS)
def test_a_setting_reaches_the_flag_the_table_override_and_a_study(s: Setting, tmp_path: Path) -> None:
    value = good(s)
    args = build_parser().parse_args(["run", s.flag, str(value)])
    assert getattr(scenario_from_args(args).radio, s.name) == value
    assert getattr(Scenario().override(**{s.name: value}).radio, s.name) == value
    assert getattr(Scenario().override(radio={s.name: value}).radio, s.name) == value
    toml = tmp_path / "s.toml"
    toml.write_text(f"[radio]\n{s.name} = {value!r}\n".replace("'", '"'))
    assert getattr(Scenario.load(toml).radio, s.name) == value
    for raw in ({"grid": {s.name: [s.default, value]}}, {"grid": {"radio": [{s.name: value}]}},
                {"fleet": {s.name: value}}, {"fleet": {"radio": {s.name: value}}}):
        points = Study.from_dict({**raw, "fleet": {"map": "office", **raw.get("fleet", {})}}).points()
        assert points[-1].scenario["radio"][s.name] == value, raw


@pytest.mark.parametrize("s", SETTINGS, ids=IDS)
def test_a_bad_value_is_one_line_everywhere(s: Setting, tmp_path: Path) -> None:
    value = bad(s)
    code, _, err = run_cli(["run", s.flag, str(value), "--engine", "memory", "--no-record"])
    assert code == 2 and err.count("\n") == 1 and s.flag in err, err
    for call in (lambda: Scenario().override(**{s.name: value}), lambda: Scenario().override(radio={s.name: value}),
                 lambda: Study.from_dict({"grid": {s.name: [s.default, value]}}),
                 lambda: Study.from_dict({"fleet": {"radio": {s.name: value}}})):
        with pytest.raises(ConfigError, match=s.name) as exc:  # from Python: the keyword, not the flag
            call()
        assert "\n" not in str(exc.value) and s.flag not in str(exc.value)
    study = tmp_path / "bad.toml"
    study.write_text(f"[grid]\nradio = [{{{s.name} = {value!r}}}]\n".replace("'", '"'))
    code, _, err = run_cli(["sweep", str(study), "--out", str(tmp_path / "out")])
    key = f"study {study}: [grid] radio.{s.name} "  # a file's value: the file and its key, not the flag
    assert code == 2 and err.count("\n") == 1 and key in err and not (tmp_path / "out").exists(), err


def test_in_a_study_the_grid_wins_over_fleet_and_a_flat_name_over_its_table() -> None:
    study = Study.from_dict({"grid": {"radio": [{"comm": "wall", "waf": 6.0}, {"comm": "disk"}], "map": ["office"]},
                             "fleet": {"waf": 2.0, "radio": {"waf": 1.0, "latency": 3}, "path_loss": 3.0}})
    points = study.points()
    radios = [p.scenario["radio"] for p in points]
    assert [(r["comm"], r["waf"], r["latency"], r["path_loss"]) for r in radios] == \
        [("wall", 6.0, 3, 3.0), ("disk", 2.0, 3, 3.0)]
    assert [p.params["radio"] for p in points] == ["comm=wall,waf=6.0", "comm=disk"]
    assert len({p.id for p in points}) == 2


@pytest.mark.parametrize(("raw", "match"), [
    ({"grid": {"radio": [3]}}, r"\[grid\] radio must be a table"),
    ({"fleet": {"radio": "wall"}}, r"\[fleet\] radio must be a table"),
    ({"fleet": {"radio": {"wafs": 6.0}}}, r"unknown key\(s\) in radio: wafs"),
    ({"grid": {"allocator": ["nearest", "nope"]}}, "unknown allocator 'nope'"),
])
def test_bad_radio_tables_in_a_study_are_one_line(raw: dict[str, Any], match: str) -> None:
    with pytest.raises(ConfigError, match=match) as exc:
        Study.from_dict(raw)
    assert "\n" not in str(exc.value)


def test_a_study_point_runs_with_its_radio_on_the_memory_engine(small_map: Path) -> None:
    import fleet_emu as fe

    study = Study.from_dict({"grid": {"waf": [9.0]}, "fleet": {
        "map": str(small_map), "robots": 2, "max_ticks": 15, "radio": {"comm": "wall", "max_walls": 2}}})
    (point,) = study.points()
    result = fe.Fleet(Scenario.from_dict(point.scenario)).run()
    assert result["scenario"]["radio"]["waf"] == 9.0 and result["scenario"]["radio"]["max_walls"] == 2
    assert result.ticks == 15


def test_override_takes_an_allocator_table_and_keeps_parameters_of_the_same_name() -> None:
    s = Scenario().override(allocator={"type": "minpos", "wavefront": "stop"})
    assert s.allocator == {"type": "minpos", "wavefront": "stop"}
    assert s.override(allocator="minpos").allocator == {"type": "minpos", "wavefront": "stop"}
    assert s.override(allocator="greedy").allocator == {"type": "greedy"}
    assert s.override(radio=RadioConfig(comm="disk")).radio == RadioConfig(comm="disk")
    assert s.override(radio={"comm": "disk"}, comm="full").radio.comm == "full"  # the name wins over the table


@pytest.mark.parametrize(("flags", "match"), [
    ({"allocator": "nope"}, "unknown allocator 'nope'"),
    ({"allocator": {"type": "nope"}}, "unknown allocator 'nope'"),
    ({"allocator": {"type": "minpos", "wavefront": "bogus"}}, "wavefront"),
    ({"allocator": {"type": "minpos", "colour": "red"}}, "colour"),
    ({"allocator": {"wavefront": "stop"}}, "allocator must be a name or a table with a 'type'"),
    ({"allocator": 3}, "allocator must be a name or a table"),
    ({"allocator": ["minpos"]}, "allocator must be a name or a table"),
    ({"map": "nomap"}, "unknown map 'nomap'"),
    ({"map": "maps/nowhere.png"}, "map file not found"),
    ({"radio": 3}, "radio must be a table"),
    ({"radio": {"wafs": 1.0}}, r"unknown key\(s\) in radio: wafs"),
])
def test_override_refuses_names_and_tables_when_the_scenario_is_built(flags: dict[str, Any], match: str) -> None:
    with pytest.raises(FleetError, match=match) as exc:  # a map: MapError, as loading it says; else ConfigError
        Scenario().override(**flags)
    assert "\n" not in str(exc.value) and isinstance(exc.value, MapError if "map" in flags else ConfigError)


def test_the_cli_refuses_an_unknown_allocator_or_map_in_one_line() -> None:
    for argv in (["--allocator", "nope"], ["--map", "nomap"]):
        code, _, err = run_cli(["run", *argv, "--engine", "memory", "--no-record"])
        assert code == 2 and err.startswith("fleet: error: unknown") and err.count("\n") == 1, err


@pytest.mark.parametrize(("toml", "match"), [
    ('[allocator]\ntype = "nope"\n', "unknown allocator 'nope'"),
    ('[allocator]\ntype = "minpos"\nwavefront = "bogus"\n', "wavefront"),
    ('[map]\nname = "nomap"\n', "unknown map 'nomap'"),
])
def test_a_scenario_file_with_an_unknown_allocator_or_map_is_refused_when_loaded(toml: str, match: str,
                                                                                  tmp_path: Path) -> None:
    path = tmp_path / "s.toml"
    path.write_text(toml)
    with pytest.raises(FleetError, match=match) as exc:
        Scenario.load(path)
    assert "\n" not in str(exc.value)
    code, _, err = run_cli(["run", str(path), "--engine", "memory", "--no-record"])
    assert code == 2 and match.split("'")[0] in err and err.count("\n") == 1, err
