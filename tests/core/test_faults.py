"""Robot failures as scenario events (``[[faults]]``, core/faults.py): read from a scenario file, a dict, an
override or a study's grid, written back as they were read, and every bad entry refused in one line naming it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.faults import Fault, applied
from fleet_emu.core.scenario import Scenario
from fleet_emu.sweep.study import Study, param_label


def test_a_scenario_file_declares_faults_and_scenario_json_keeps_them(tmp_path: Path) -> None:
    f = tmp_path / "crash.toml"
    f.write_text('[fleet]\nrobots = 3\n\n[[faults]]\nrobot = "r1"\ntick = 30\nkind = "crash"\n\n'
                 '[[faults]]\nrobot = 2\ntick = 45\n')
    s = Scenario.load(f)
    assert s.faults == (Fault("r1", 30, "crash"), Fault("r2", 45, "crash"))
    assert s.to_dict()["faults"] == [{"robot": "r1", "tick": 30, "kind": "crash"},
                                     {"robot": "r2", "tick": 45, "kind": "crash"}]
    assert Scenario.from_dict(s.to_dict()) == s
    assert "faults" not in Scenario().to_dict()  # a run without faults keeps its scenario.json


@pytest.mark.parametrize(("faults", "message"), [
    ([{"robot": 4, "tick": 3}], r"^faults\[0\]: robot r4 is not one of the fleet's 4 \(r0 to r3\)$"),
    ([{"robot": "x1", "tick": 3}], r"^faults\[0\]: robot must be a robot's id"),
    ([{"robot": 1}], r"^faults\[0\] needs tick "),
    ([{"robot": 1, "tick": -1}], r"^faults\[0\]: tick must be a whole number >= 0 \(got -1\)$"),
    ([{"robot": 1, "tick": 2.5}], r"^faults\[0\]: tick must be a whole number"),
    ([{"robot": 1, "tick": 3, "kind": "hang"}], r"^faults\[0\]: kind must be one of crash \(got 'hang'\)$"),
    ([{"robot": 1, "tick": 3, "when": 2}], r"^faults\[0\]: unknown key\(s\) when \(known: robot, tick, kind\)$"),
    ([{"robot": 1, "tick": 3}, {"robot": "r1", "tick": 9}], r"^faults\[1\]: robot r1 already has a fault"),
    ([{"robot": 0, "tick": 2001}], r"^faults\[0\]: tick 2001 is past the tick limit 2000$"),
    ("r1@30", r"^faults must be a list of tables"),
    (["r1"], r"^faults\[0\] must be a table"),
])
def test_a_bad_fault_is_one_line_naming_the_entry(faults: Any, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as info:
        Scenario().override(faults=faults)
    assert "\n" not in str(info.value)


def test_a_bad_fault_in_a_file_names_the_file(tmp_path: Path) -> None:
    f = tmp_path / "bad.toml"
    f.write_text('[[faults]]\nrobot = "r9"\ntick = 3\n')
    with pytest.raises(ConfigError, match=rf"^scenario {f}: .*robot r9 is not one of the fleet's 4"):
        Scenario.load(f)


def test_the_faults_applied_are_those_of_a_tick_reached() -> None:
    faults = [{"robot": "r0", "tick": 0, "kind": "crash"}, {"robot": "r1", "tick": 30, "kind": "crash"}]
    assert applied(faults, 29) == faults[:1]
    assert applied(faults, 30) == faults


def test_a_study_grid_key_varies_the_faults(tmp_path: Path) -> None:
    f = tmp_path / "study.toml"
    f.write_text('[study]\nseeds = 2\n[grid]\nfaults = [[], [{robot = 0, tick = 30, kind = "crash"}]]\n'
                 '[fleet]\nmap = "maze"\ncell_size = 2.0\n')
    points = Study.load(f).points()
    assert [p.params["faults"] for p in points] == ["none", "none", "crash r0@30", "crash r0@30"]
    assert "faults" not in points[0].scenario
    assert points[2].scenario["faults"] == [{"robot": "r0", "tick": 30, "kind": "crash"}]
    assert param_label([{"robot": "r2", "tick": 5}]) == "crash r2@5"
    bad = tmp_path / "bad.toml"
    bad.write_text('[grid]\nfaults = [[{robot = 7, tick = 30}]]\n')
    with pytest.raises(ConfigError, match=r"robot r7 is not one of the fleet's 4"):
        Study.load(bad)


def test_a_crash_the_study_asked_for_is_no_failed_row(tmp_path: Path) -> None:
    """A study's row is failed for a robot that failed unasked, not for one its grid crashed; ``failed`` still
    lists it, and ``faults`` says it was asked for."""
    from fleet_emu.sweep.execute import run_point

    f = tmp_path / "study.toml"
    f.write_text('[study]\nseeds = 1\n[grid]\nfaults = [[{robot = 1, tick = 5, kind = "crash"}]]\n'
                 '[fleet]\nmap = "maze"\ncell_size = 2.0\nmax_ticks = 12\n')
    (point,) = Study.load(f).points()
    row = run_point(point)
    assert row["status"] == "ok" and row["error"] is None and "r1" in row["failed"], row
