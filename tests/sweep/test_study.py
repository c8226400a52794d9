"""Study files: the grid, seeds, [fleet], stable point ids, the shipped studies, and bad input."""

from __future__ import annotations

from pathlib import Path

import pytest

from fleet_emu.core.errors import ConfigError
from fleet_emu.sweep.study import Study, shipped


def test_the_grid_expands_with_seeds_innermost(study_dir: Path) -> None:
    study = Study.load(study_dir / "tiny.toml")
    points = study.points()
    assert len(points) == 2 * 2 * 2 and study.seeds == [0, 1]
    assert [p.params["seed"] for p in points[:4]] == [0, 1, 0, 1]
    first = points[0]
    assert first.params == {"allocator": "nearest", "robots": 2, "loss": 0.0, "comm": "ideal", "map": "rooms.png",
                            "seed": 0}
    s = first.scenario
    assert s["map"] == str(study_dir / "rooms.png") and s["sensor_range"] == 1.5 and s["start"] == [1, 1]
    assert s["radio"]["comm"] == "ideal" and s["allocator"] == {"type": "nearest"} and s["seed"] == 0
    assert len({p.id for p in points}) == len(points)
    assert [p.id for p in Study.load(study_dir / "tiny.toml").points()] == [p.id for p in points]  # stable


def test_allocator_tables_carry_parameters(study_dir: Path) -> None:
    study = Study.from_dict({"study": {"seeds": [4, 9]}, "grid": {
        "allocator": [{"type": "minpos", "wavefront": "stop"}, "greedy"], "map": ["office"]}})
    points = study.points()
    assert [p.params["allocator"] for p in points] == ["minpos(wavefront=stop)"] * 2 + ["greedy"] * 2
    assert points[0].scenario["allocator"] == {"type": "minpos", "wavefront": "stop"}
    assert [p.params["seed"] for p in points] == [4, 9, 4, 9]


@pytest.mark.parametrize(("raw", "message"), [
    ({"grid": {"robots": 3}}, "must be a non-empty list"),
    ({"study": {"engine": "warp"}}, "engine"),
    ({"study": {"seeds": 0}}, "seeds"),
    ({"grid": {"robots": [0]}}, "robots"),
    ({"grid": {"speed": [1]}}, "speed"),
    ({"fleet": {"loss": 2.0}}, "loss"),
    ({"study": {"colour": "red"}}, "colour"),
    ({"sweep": {}}, "sweep"),
])
def test_bad_studies_are_one_config_error(raw: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as err:
        Study.from_dict(raw)
    assert "\n" not in str(err.value)


def test_a_missing_map_says_where_to_get_it(tmp_path: Path) -> None:
    (tmp_path / "s.toml").write_text('[study]\nname = "s"\nmaps = "https://example.org/maps"\n'
                                     '[grid]\nmap = ["stage/no_such_map.yaml"]\n')
    with pytest.raises(ConfigError, match=r"map stage/no_such_map.yaml not found.*get it from https://example.org"):
        Study.load(tmp_path / "s.toml").points()


def test_the_shipped_studies_load() -> None:
    names = shipped()
    assert set(names) >= {"bautin-fig5", "benavides", "yan-loss"}
    fig5 = Study.load("bautin-fig5")
    assert fig5.grid == {"allocator": ["nearest", "greedy", "utility", "minpos"], "robots": list(range(1, 11))}
    assert len(fig5.seeds) == 60 and fig5.fleet["comm"] == "ideal" and fig5.fleet["target_coverage"] == 1.0
    ben = Study.load("benavides")
    assert (ben.fleet["robots"], ben.fleet["sensor_range"], ben.fleet["comm_range"], ben.fleet["comm"]) == \
        (2, 3.0, 6.0, "wall") and ben.fleet["target_coverage"] == 0.95
    assert ben.fleet["map"] == "hospital_section" and ben.replicates == ("start",) and len(ben.points()) == 20
    calibration = Study.load("benavides-calibration")  # the same setting, minpos alone, the threshold free
    assert {k: v for k, v in calibration.fleet.items() if k != "allocator"} == \
        {k: v for k, v in ben.fleet.items() if k != "threshold"} and calibration.grid["start"] == ben.grid["start"]
    yan = Study.load("yan-loss")
    assert yan.grid["loss"] == [0.0, 0.1, 0.3, 0.5] and yan.fleet["comm"] == "full"
    assert yan.grid["map_sync"] == [False, True] and yan.paper["beside"] == "map_sync"  # the paper's, then ours
    points = yan.points()
    assert len(points) == 3 * 3 * 4 * 2 * 10
    assert {p.scenario.get("map_sync", True) for p in points} == {False, True}
    regions = Study.load("yan-regions")
    assert regions.grid["allocator"][:2] == [{"type": "trade", "tasks": "regions"},
                                             {"type": "hungarian", "tasks": "regions"}]
    assert regions.grid["loss"] == yan.grid["loss"] and regions.fleet == yan.fleet | {"map_sync": False}
    assert len(regions.points()) == 4 * 3 * 4 * 10
