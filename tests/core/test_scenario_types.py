"""Every scenario value of the wrong type is one line: each key of each table of a scenario file, TOML or JSON,
given a list, a table, a string, a boolean or a float where it takes something else, is a FleetError (the
CLI's one line) naming the key, never another exception and never a value silently taken. The few values of
:data:`WRONG` that are a key's right type are listed in :data:`ACCEPTED`, each with its reason."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from fleet_emu.core.errors import FleetError
from fleet_emu.core.radio import radio_settings
from fleet_emu.core.scenario import Scenario
from fleet_emu.core.scenario_checks import check_names
from tests.harness.cli import run_cli

WRONG: list[Any] = [["minpos"], {"x": 1}, "x", True, 1.5, [[1], 2], {}]
TOP = ["seed", "max_ticks", "tick_s", "target_coverage", "stall_ticks", "coverage_stall_ticks", "barrier_timeout",
       "belief_every", "relay", "relay_ttl", "base"]
TABLES: dict[str, list[str]] = {
    "map": ["name", "cell_size"], "fleet": ["robots", "sensor_range", "start", "base"],
    "radio": [s.name for s in radio_settings()], "allocator": ["type", "wavefront", "replan"],
    "hosts": ["count", "names", "robots"],
}
#: The values of WRONG that are the key's own type, so taken: a float where the key is a number of seconds,
#: metres, dB...; ``true`` for ``base``, which puts the base station on the fleet's start cell
#: (docs/guides/base-station.md). Every other (key, value) must be refused.
FLOATS = ["tick_s", "barrier_timeout", "cell_size", "sensor_range", "comm_range", "path_loss", "waf", "threshold",
          "bandwidth", "shadowing_db", "shadowing_m"]
ACCEPTED: dict[str, list[Any]] = {**{key: [1.5] for key in FLOATS}, "base": [True]}


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


def _refused(path: Path, named: str) -> str | None:
    """Load the file as ``fleet run --scenario`` does: the FleetError's line (checked to be one line naming
    ``named``), or None when the file is taken. A run's ``scenario.json`` has its allocator and map checked when
    the run starts rather than when it is read (the TOML a user wrote, at once): the same check (``check_names``)
    runs here after the load."""
    try:
        check_names(Scenario.load(path), ["allocator", "map"])
    except FleetError as exc:  # a ConfigError or MapError: one line; anything else fails the test
        line = str(exc)
        assert "\n" not in line and named in line.replace("-", "_"), (path.name, line)
        return line
    return None


@pytest.mark.parametrize(("table", "key"), _cases())
def test_a_value_of_the_wrong_type_is_a_config_error(tmp_path: Path, table: str | None, key: str) -> None:
    named = {"name": "map", "type": "allocator"}.get(key, key)  # how the line names the key
    for i, value in enumerate(WRONG):
        tables = _tables(table, key, value)
        lines = [f"{k} = {_toml(v)}" for k, v in tables.items() if not isinstance(v, dict)]
        lines += [f"[{k}]\n" + "\n".join(f"{kk} = {_toml(vv)}" for kk, vv in v.items())
                  for k, v in tables.items() if isinstance(v, dict)]
        toml = tmp_path / f"s{i}.toml"
        toml.write_text("\n".join(lines) + "\n")
        flat = dict(tables)
        if table in ("map", "fleet"):
            flat = dict(tables[table])
            if "name" in flat:
                flat["map"] = flat.pop("name")
        js = tmp_path / f"s{i}.json"
        js.write_text(json.dumps(flat))
        taken = any(value == v and type(value) is type(v) for v in ACCEPTED.get(key, []))
        for path in (toml, js):
            line = _refused(path, named)
            assert (line is None) == taken, (f"{path.suffix} {table}.{key} = {value!r}: "
                                             + (f"refused ({line}) though listed as accepted" if taken
                                                else "taken: a wrong type silently accepted"))


@pytest.mark.parametrize("value", ['["minpos"]', '{x = 1}'])
def test_an_allocator_type_that_is_not_a_name_is_one_line(tmp_path: Path, value: str) -> None:
    f = tmp_path / "s.toml"
    f.write_text(f"[allocator]\ntype = {value}\n")
    code, _, err = run_cli(["run", "--engine", "memory", "--scenario", str(f), "--no-record", "--out",
                            str(tmp_path / "run")])
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert "allocator must be a table with a 'type' name" in err
