from __future__ import annotations

import json
from pathlib import Path

import pytest

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.rng import derive_seed, generator
from fleet_emu.core.scenario import Scenario

DEFAULT = Path(__file__).resolve().parents[2] / "launch" / "scenarios" / "default.toml"


def test_default_scenario_matches_design() -> None:
    s = Scenario.load(DEFAULT)
    assert (s.map, s.robots, s.allocator["type"], s.radio.loss, s.radio.comm) == ("office", 4, "minpos", 0.1, "wall")
    assert Scenario.from_dict(s.to_dict()) == s


@pytest.mark.parametrize("flags, match", [
    ({"robots": 0}, "robots"), ({"loss": 1.5}, "loss"), ({"loss": -0.1}, "loss"),
    ({"sensor_range": -1.0}, "^sensor_range "), ({"comm_range": 0.0}, "^comm_range "),
    ({"target_coverage": 0.0}, "^target_coverage "), ({"max_ticks": 0}, "^max_ticks "),
    ({"robots": "four"}, "robots"), ({"robots": True}, "robots"), ({"loss": "high"}, "loss"),
    ({"sensor_range": "4"}, "^sensor_range "), ({"seed": 1.5}, "seed"), ({"sensor_range": float("inf")}, "sensor"),
    ({"comm_range": float("nan")}, "^comm_range "), ({"cell_size": float("inf")}, "^cell_size "),
    ({"comm": "telepathy"}, "comm"), ({"start": (1, "a")}, "start"), ({"robots": 257}, "robots"),
])
def test_bad_values_fail_with_one_line(flags: dict, match: str) -> None:
    with pytest.raises(ConfigError, match=match) as exc:
        Scenario().override(**flags)
    assert "\n" not in str(exc.value)


def test_overrides_and_toml_errors(tmp_path: Path) -> None:
    s = Scenario().override(robots=3, loss=0.3, allocator="nearest", seed=None)
    assert (s.robots, s.radio.loss, s.allocator, s.seed) == (3, 0.3, {"type": "nearest"}, 0)
    bad = tmp_path / "bad.toml"
    bad.write_text("robots = [")
    with pytest.raises(ConfigError, match="not valid TOML"):
        Scenario.load(bad)
    with pytest.raises(ConfigError, match="not found"):
        Scenario.load(tmp_path / "missing.toml")
    unknown = tmp_path / "unknown.toml"
    unknown.write_text("[fleet]\nrobotz = 3\n")
    with pytest.raises(ConfigError, match="robotz"):
        Scenario.load(unknown)


def test_seeds() -> None:
    assert derive_seed(1, "r0") == derive_seed(1, "r0") != derive_seed(1, "r1")
    assert generator(5, "netem").random() == generator(5, "netem").random()


def test_scenario_json_round_trips_and_rejects_what_it_does_not_know(tmp_path: Path) -> None:
    s = Scenario().override(robots=3, comm="disk", start=(4, 5), allocator="greedy", seed=9)
    path = tmp_path / "scenario.json"
    path.write_text(json.dumps(s.to_dict()))
    assert Scenario.load(path) == s
    path.write_text(json.dumps(dict(s.to_dict(), robotz=3)))
    with pytest.raises(ConfigError, match="robotz"):
        Scenario.load(path)
    path.write_text(json.dumps(dict(s.to_dict(), radio={"loss": 0.1, "power": 3})))
    with pytest.raises(ConfigError, match="power"):
        Scenario.load(path)
    with pytest.raises(ConfigError, match="section"):
        bad = tmp_path / "top.toml"
        bad.write_text('map = "office"\n')
        Scenario.load(bad)


def test_a_base_station_from_toml_flags_and_json_and_absent_by_default(tmp_path: Path) -> None:
    assert "base" not in Scenario().to_dict() and not Scenario().has_base  # runs without one are unchanged
    toml = tmp_path / "b.toml"
    toml.write_text("[fleet]\nrobots = 2\nbase = [3, 4]\n")
    s = Scenario.load(toml)
    assert s.base == (3, 4) and s.has_base and s.to_dict()["base"] == [3, 4]
    assert Scenario.from_dict(json.loads(json.dumps(s.to_dict()))) == s
    toml.write_text("base = true\n")
    assert Scenario.load(toml).base is True
    assert Scenario().override(base=True).to_dict()["base"] is True
    assert Scenario().override(base=[1, 2]).base == (1, 2)


@pytest.mark.parametrize("base", ["yes", (1,), (1, 2, 3), (-1, 2), (1.5, 2), 1])
def test_a_bad_base_is_one_line(base: object) -> None:
    with pytest.raises(ConfigError, match="base must be true, false or a cell") as exc:
        Scenario().override(base=base)
    assert "\n" not in str(exc.value)


def test_a_base_cell_off_the_map_or_on_a_wall_is_one_line() -> None:
    from fleet_emu.core.grid import MapData, from_ascii
    from fleet_emu.world.build import base_cell

    grid, _ = from_ascii("""
        #####
        #...#
        #####
    """)
    md = MapData(grid=grid, name="t", cell_size=0.5, start=(1, 1))
    with pytest.raises(ConfigError, match=r"base cell \(0, 0\) is not a free cell"):
        base_cell(Scenario().override(robots=1, base=(0, 0)), md)
    with pytest.raises(ConfigError, match=r"base cell \(3, 1\) is off the map \(3 x 5 cells\)"):
        base_cell(Scenario().override(robots=1, base=(3, 1)), md)
    assert base_cell(Scenario().override(robots=1, base=(1, 3)), md) == (1, 3)
    assert base_cell(Scenario().override(robots=1, base=True), md) == (1, 1)  # the start cell
    assert base_cell(Scenario().override(robots=1), md) is None


def test_hosts_from_toml_json_and_the_flag_and_absent_by_default(tmp_path: Path) -> None:
    from fleet_emu.core.scenario import HostPlan

    assert "hosts" not in Scenario().to_dict() and Scenario().hosts is None  # runs on one machine are unchanged
    toml = tmp_path / "h.toml"
    toml.write_text('[fleet]\nrobots = 8\n[hosts]\nnames = ["host3", "host1"]\nrobots = [4, 2]\n')
    s = Scenario.load(toml)
    assert s.hosts == HostPlan(2, ("host3", "host1"), (4, 2))
    assert s.to_dict()["hosts"] == {"count": 2, "names": ["host3", "host1"], "robots": [4, 2]}
    assert Scenario.from_dict(json.loads(json.dumps(s.to_dict()))) == s
    toml.write_text("[hosts]\ncount = 2\n")
    assert Scenario.load(toml).to_dict()["hosts"] == {"count": 2}
    assert s.override(hosts=3).hosts == HostPlan(3)  # --hosts N replaces the table: round-robin over any N
    assert s.override(hosts=0).hosts is None and "hosts" not in s.override(hosts=0).to_dict()  # --hosts 0: all here
    toml.write_text("[hosts]\ncount = 0\n")
    assert Scenario.load(toml).hosts is None


@pytest.mark.parametrize("table, match", [
    ("count = 2\nrobotz = 1", r"unknown key\(s\) in \[hosts\]: robotz \(count, names, robots\)"),
    ("", r"\[hosts\] needs count = N or names"),
    ("count = 65", r"\[hosts\] count must be from 1 to 64 \(got 65\)"),
    ("count = \"2\"", r"\[hosts\] count must be a whole number"),
    ("count = 3\nnames = [\"host0\"]", r"\[hosts\] names lists 1 host\(s\) but count is 3"),
    ("names = [\"lab-a\"]", r"\[hosts\] names must be host0, host1, ... \(the hosts' logins; got 'lab-a'\)"),
    ("names = [\"host1\", \"host1\"]", r"\[hosts\] names lists a host twice"),
    ("count = 2\nrobots = [1]", r"\[hosts\] robots gives 1 number\(s\) for 2 host\(s\)"),
    ("count = 1\nrobots = [-1]", r"\[hosts\] robots \(each host's\) must be from 0 to 256"),
    ("count = 2\nrobots = [3, 2]", r"\[hosts\] robots puts 5 robots on hosts, more than the fleet's 4"),
    ("count = 1\nrobots = 3", r"\[hosts\] robots must be a list"),
])
def test_a_bad_hosts_table_is_one_line(table: str, match: str, tmp_path: Path) -> None:
    toml = tmp_path / "h.toml"
    toml.write_text(f"[fleet]\nrobots = 4\n[hosts]\n{table}\n")
    with pytest.raises(ConfigError, match=match) as exc:
        Scenario.load(toml)
    assert "\n" not in str(exc.value)
    with pytest.raises(ConfigError, match=r"^hosts must be in 0..64 \(got -1\)"):
        Scenario().override(hosts=-1)
