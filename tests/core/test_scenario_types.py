"""Every scenario value of the wrong type is one line: each key of each table of a scenario file, TOML or JSON,
given a list, a table, a string, a boolean or a float where it takes something else, is a FleetError (the
CLI's one line), never another exception."""

from __future__ import annotations

import contextlib
import json
from pathlib import Path
from typing import Any

import pytest

from fleet_emu.core.errors import FleetError
from fleet_emu.core.radio import radio_settings
from fleet_emu.core.scenario import Scenario
from tests.conftest import run_cli

WRONG: list[Any] = [["minpos"], {"x": 1}, "x", True, 1.5, [[1], 2], {}]
TOP = ["seed", "max_ticks", "tick_s", "target_coverage", "stall_ticks", "coverage_stall_ticks", "barrier_timeout",
       "belief_every", "relay", "relay_ttl", "base"]
TABLES: dict[str, list[str]] = {
    "map": ["name", "cell_size"], "fleet": ["robots", "sensor_range", "start", "base"],
    "radio": [s.name for s in radio_settings()], "allocator": ["type", "wavefront", "replan"],
    "hosts": ["count", "names", "robots"],
}


def _toml(value: Any) -> str:
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return json.dumps(value)


def _cases() -> list[tuple[str | None, str]]:
    return [(None, k) for k in TOP] + [(t, k) for t, keys in TABLES.items() for k in keys]


def _tables(table: str | None, key: str, value: Any) -> dict[str, Any]:
    if table is None:
        return {key: value}
    inner: dict[str, Any] = {"type": "minpos"} if table == "allocator" and key != "type" else {}
    if table == "hosts" and key != "count":
        inner["count"] = 1
    return {table: {**inner, key: value}}


@pytest.mark.parametrize(("table", "key"), _cases())
def test_a_value_of_the_wrong_type_is_a_config_error(tmp_path: Path, table: str | None, key: str) -> None:
    for i, value in enumerate(WRONG):
        tables = _tables(table, key, value)
        lines = [f"{k} = {_toml(v)}" for k, v in tables.items() if not isinstance(v, dict)]
        lines += [f"[{k}]\n" + "\n".join(f"{kk} = {_toml(vv)}" for kk, vv in v.items())
                  for k, v in tables.items() if isinstance(v, dict)]
        toml = tmp_path / f"s{i}.toml"
        toml.write_text("\n".join(lines) + "\n")
        with contextlib.suppress(FleetError):  # a ConfigError or MapError: one line; anything else fails the test
            Scenario.load(toml)
        flat = dict(tables)
        if table in ("map", "fleet"):
            flat = dict(tables[table])
            if "name" in flat:
                flat["map"] = flat.pop("name")
        js = tmp_path / f"s{i}.json"
        js.write_text(json.dumps(flat))
        with contextlib.suppress(FleetError):
            Scenario.load(js)


@pytest.mark.parametrize("value", ['["minpos"]', '{x = 1}'])
def test_an_allocator_type_that_is_not_a_name_is_one_line(tmp_path: Path, value: str) -> None:
    f = tmp_path / "s.toml"
    f.write_text(f"[allocator]\ntype = {value}\n")
    code, _, err = run_cli(["run", "--engine", "memory", "--scenario", str(f), "--no-record", "--out",
                            str(tmp_path / "run")])
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert "allocator must be a table with a 'type' name" in err
