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


def test_the_mukhija_studies_run_the_papers_setting() -> None:
    from fleet_emu.world.maps import load_map

    fig5 = Study.load("mukhija-fig5")
    assert fig5.grid["robots"] == [10, 12, 14] and fig5.grid["allocator"] == ["mhm", {"type": "mhm", "method": "shm"}]
    starts = fig5.grid["start"] + fig5.more["start"]  # the replicate: the base's cell, 5 first, then more
    assert len(starts) == len({tuple(s) for s in starts}) == 25 and all(64 <= c < 448 for s in starts for c in s)
    assert fig5.baseline == "mhm(method=shm)" and len(fig5.points()) == 3 * 2 * 5 * len(fig5.seeds)
    scenario = fig5.points()[0].scenario
    grid = load_map(scenario["map"], scenario["cell_size"], 0).grid  # the open map shipped beside the study
    assert grid.shape == (512, 512) and (grid[1:-1, 1:-1] == 0).all() and (grid[0] == 100).all()
    assert (scenario["radio"]["comm_range"], scenario["sensor_range"], scenario["cell_size"]) == (40.0, 15.0, 1.0)
    fig7 = Study.load("mukhija-fig7")
    assert fig7.grid == {"robots": [10, 20, 30, 40, 50]} and fig7.fleet["allocator"] == "mhm"
    assert fig7.fleet["comm_range"] / fig7.fleet["cell_size"] == 40.0
    assert fig7.fleet["sensor_range"] / fig7.fleet["cell_size"] == 15.0


def test_yan_maps_compares_on_five_registry_maps_at_no_loss() -> None:
    maps = Study.load("yan-maps")
    assert len(maps.grid["map"]) >= 5 and maps.fleet["loss"] == 0.0 and maps.fleet["map_sync"] is False
    assert maps.paper["beside"] == "map" and len(maps.points()) == 5 * 3 * 4 * 10


def test_a_shipped_study_is_found_by_name_beside_a_folder_of_that_name(tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """``fleet sweep benavides --out benavides`` run twice: the second call finds the study, not the results."""
    from fleet_emu.sweep.study import Study

    (tmp_path / "benavides").mkdir()
    monkeypatch.chdir(tmp_path)
    assert Study.load("benavides").name == "benavides"
