"""``fleet maps`` and ``fleet maps fetch``, maps and scenarios by name in ``fleet run``, ``fe.Scenario`` and the
studies, the bare-bitmap rule, ``fleet --version`` and ``fleet allocators``: the CLI called in this process, and
one subprocess over an HTTP mirror."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import fleet_emu as fe
from fleet_emu.core.errors import ConfigError, MapError
from fleet_emu.launch.cli import main
from fleet_emu.sweep.study import Study
from fleet_emu.world.maps import BUILTIN_MAPS
from fleet_emu.world.registry import registry
from tests.harness.map_mirror import build_mirror, files_in, serve

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """This test's user cache (XDG_CACHE_HOME) and its maps' folder; the test runs from an empty folder."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")
    return tmp_path / "xdg" / "fleet-emu" / "maps"


@pytest.fixture(scope="module")
def mirror(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_mirror(tmp_path_factory.mktemp("mirror"))


def fleet(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    """``fleet ARGS`` in this process: its exit code, stdout and stderr."""
    with pytest.raises(SystemExit) as exc:
        main(list(args))
    out, err = capsys.readouterr()
    return int(exc.value.code or 0), out, err


def refused(code: int, err: str, *words: str) -> None:
    assert code == 2 and err.count("\n") == 1 and err.startswith("fleet: error: "), err
    for w in words:
        assert w in err, (w, err)


def test_fleet_maps_lists_every_map_and_fetch_prints_source_and_licence(
        capsys: pytest.CaptureFixture[str], cache: Path, mirror: Path) -> None:
    code, out, _ = fleet(capsys, "maps")
    names = [ln.split()[0] for ln in out.splitlines() if ln.startswith("  ") and ln.strip() and ln[2] != " "]
    assert code == 0 and names == [*BUILTIN_MAPS, *registry()]
    assert f"  {'cave':18s} 16 x 16 m, rtv/Stage, GPL-2.0: `fleet maps fetch cave`" in out.splitlines()
    code, out, _ = fleet(capsys, "maps", "fetch", "cave", "turtlebot3_world", "--mirror", str(mirror))
    lines = out.splitlines()
    assert code == 0 and len(lines) == 2
    assert lines[0].startswith("cave: rtv/Stage@281ed731ed worlds/bitmaps/cave.png via ") and "GPL-2.0" in lines[0]
    assert "turtlebot3_navigation/maps/map.pgm, turtlebot3_navigation/maps/map.yaml" in lines[1]
    assert "licence Apache-2.0" in lines[1] and f"-> {cache / 'turtlebot3_world'} (sha256 checked)" in lines[1]
    code, out, _ = fleet(capsys, "maps")
    assert "16 x 16 m, rtv/Stage, GPL-2.0: fetched" in out and "`fleet maps fetch hospital_section`" in out
    code, out, _ = fleet(capsys, "maps", "fetch", "cave")  # intact in the cache: nothing downloaded
    assert code == 0 and out == (f"cave: rtv/Stage@281ed731ed worlds/bitmaps/cave.png already in {cache / 'cave'} "
                                 "(sha256 checked); licence GPL-2.0 (Stage's README.md and COPYING.txt)\n")


def test_fetch_errors_are_one_line_exit_2_and_leave_nothing(capsys: pytest.CaptureFixture[str], cache: Path,
                                                            tmp_path: Path) -> None:
    refused(*fleet(capsys, "maps", "fetch", "cave", "atlantis")[::2], "unknown map 'atlantis'", "`fleet maps`")
    refused(*fleet(capsys, "maps", "fetch")[::2], "needs map names or --all")
    refused(*fleet(capsys, "maps", "fetch", "cave", "--all")[::2], "needs map names or --all")
    (tmp_path / "bad" / "cave").mkdir(parents=True)
    (tmp_path / "bad" / "cave" / "cave.png").write_bytes(b"a cave, but not Stage's")
    refused(*fleet(capsys, "maps", "fetch", "cave", "--mirror", str(tmp_path / "bad"))[::2], "sha256",
            "nothing was kept")
    refused(*fleet(capsys, "maps", "fetch", "mbicp", "--mirror", str(tmp_path / "bad"))[::2], "no such file")
    assert files_in(tmp_path / "xdg") == []


def test_an_unfetched_map_is_one_line_naming_its_fetch_command(capsys: pytest.CaptureFixture[str], cache: Path,
                                                               tmp_path: Path) -> None:
    code, _, err = fleet(capsys, "run", "--map", "cave", "--engine", "memory", "--quiet", "--out", str(tmp_path / "r"))
    refused(code, err, "map cave is not fetched: run `fleet maps fetch cave`")
    assert not (tmp_path / "r").exists()
    with pytest.raises(MapError, match="fleet maps fetch autolab"):
        fe.Fleet(fe.Scenario(map="autolab")).reset()
    (tmp_path / "s.toml").write_text('[study]\nname = "s"\n[grid]\nmap = ["mbicp"]\n')
    with pytest.raises(ConfigError, match=r"^study s: map mbicp is not fetched: run `fleet maps fetch mbicp`"):
        Study.load(tmp_path / "s.toml").points()


def test_a_fetched_map_is_named_by_run_scenario_and_study(capsys: pytest.CaptureFixture[str], cache: Path,
                                                          mirror: Path, tmp_path: Path) -> None:
    fleet(capsys, "maps", "fetch", "cave", "hospital_section", "--mirror", str(mirror))
    code, _, err = fleet(capsys, "run", "--map", "cave", "--engine", "memory", "--robots", "2", "--max-ticks", "4",
                         "--quiet", "--out", str(tmp_path / "r"))
    assert code == 3, err  # ended by the tick limit
    assert json.loads((tmp_path / "r" / "result.json").read_text())["ticks"] == 4
    assert json.loads((tmp_path / "r" / "scenario.json").read_text())["map"] == "cave"
    fleet_ = fe.Fleet(fe.Scenario(map="hospital_section", robots=2, max_ticks=3))
    assert fleet_.run().ticks == 3 and fleet_.map.grid.shape == (35, 82)
    points = Study.load("bautin-fig5").points()  # from an empty folder: the map by name, from the cache
    assert len(points) == 4 * 10 * 60 and {p.scenario["map"] for p in points} == {"hospital_section"}


def test_a_bare_bitmap_needs_a_cell_size(capsys: pytest.CaptureFixture[str], cache: Path, tmp_path: Path) -> None:
    img = np.full((12, 16), 255, dtype=np.uint8)
    img[[0, -1], :] = img[:, [0, -1]] = 0
    Image.fromarray(img, mode="L").save(tmp_path / "plan.png")
    args = ["run", "--map", str(tmp_path / "plan.png"), "--engine", "memory", "--robots", "2", "--max-ticks", "3",
            "--sensor-range", "2", "--quiet"]
    refused(*fleet(capsys, *args, "--out", str(tmp_path / "a"))[::2], "without a scale", "--cell-size", "YAML")
    assert not (tmp_path / "a").exists()
    assert fleet(capsys, *args, "--cell-size", "0.5", "--out", str(tmp_path / "b"))[0] == 3  # one pixel per cell
    with pytest.raises(MapError, match="without a scale"):
        fe.Fleet(fe.Scenario(map=str(tmp_path / "plan.png"))).reset()
    drawn = fe.Fleet(fe.Scenario(map=str(tmp_path / "plan.png"), cell_size=0.25, robots=2))
    drawn.reset()
    assert drawn.map.grid.shape == (12, 16) and drawn.map.cell_size == 0.25
    given = fe.Scenario.from_dict({"map": "office", "cell_size": 0.5})
    assert given.cell_size_given and not fe.Scenario().cell_size_given and given == fe.Scenario(map="office")
    assert not fe.Scenario.load("default").cell_size_given and fe.Scenario.load("default").cell_size == 0.5
    assert '"cell_size": 0.5,' in json.dumps(fe.Scenario().to_dict())  # written as any cell size is


def test_shipped_scenarios_by_name_from_any_folder(capsys: pytest.CaptureFixture[str], cache: Path,
                                                   tmp_path: Path) -> None:
    assert fe.Scenario.load("default").name == "default"
    assert fe.Scenario.load("connectivity").allocator["type"] == "connectivity"
    code, _, err = fleet(capsys, "run", "--scenario", "connectivity", "--engine", "memory", "--max-ticks", "2",
                         "--quiet", "--out", str(tmp_path / "c"))
    assert code == 3, err
    assert json.loads((tmp_path / "c" / "scenario.json").read_text())["name"] == "connectivity"
    refused(*fleet(capsys, "run", "--scenario", "nosuch", "--quiet")[::2], "scenario file not found: nosuch",
            "shipped scenario: connectivity, default")
    (tmp_path / "elsewhere" / "default").write_text('name = "mine"\n')  # a file of that name wins
    assert fe.Scenario.load("default").name == "mine"


def test_version_and_allocators(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = fleet(capsys, "--version")
    assert code == 0 and out == f"fleet-emu {fe.__version__}\n"
    code, out, _ = fleet(capsys, "allocators")
    lines = {ln.split()[0]: ln for ln in out.splitlines()}
    assert lines["minpos"].startswith(f"{'minpos':14s} MinPos (Bautin et al. 2012): the frontier with the fewest")
    assert lines["minpos"].endswith("[built-in: wavefront='full' (one of full, stop, parallel), replan='tick' (one "
                                    "of tick, observed)]")
    for name in ("nearest", "greedy", "utility", "connectivity", "hungarian", "trade", "mhm"):
        assert "(no description)" not in lines[name] and len(lines[name].split(" [")[0]) > 40, lines[name]


def test_fetch_over_http_in_a_subprocess(tmp_path: Path, mirror: Path) -> None:
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "xdg")}
    with serve(mirror) as url:
        proc = subprocess.run([sys.executable, "-m", "fleet_emu.launch", "maps", "fetch", "hospital_section",
                               "--mirror", url], capture_output=True, text=True, timeout=120, cwd=tmp_path, env=env)
    assert proc.returncode == 0 and proc.stderr == "", proc.stderr
    assert proc.stdout.startswith(f"hospital_section: rtv/Stage@281ed731ed worlds/bitmaps/hospital_section.png via "
                                  f"{url} -> {tmp_path / 'xdg' / 'fleet-emu' / 'maps' / 'hospital_section'}")
    assert [p.name for p in files_in(tmp_path / "xdg")] == ["hospital_section.png"]


@pytest.mark.slow
def test_bautin_fig5_sweeps_after_fetching_its_map(tmp_path: Path, mirror: Path) -> None:
    """The study's first run, from a folder with nothing beside it: ``fleet maps fetch`` then ``fleet sweep``."""
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "xdg")}

    def fleet_(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "fleet_emu", *args], capture_output=True, text=True,
                              timeout=600, cwd=tmp_path, env=env)

    assert fleet_("maps", "fetch", "hospital_section", "--mirror", str(mirror)).returncode == 0
    proc = fleet_("sweep", "bautin-fig5", "--out", "fig5", "--limit", "1", "--jobs", "1")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "bautin-fig5: 2400 runs, 0 done, 1 to run" in proc.stderr
    with (tmp_path / "fig5" / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [(r["map"], r["allocator"], r["robots"], r["status"]) for r in rows] == [
        ("hospital_section", "nearest", "1", "ok")]


def test_a_listing_piped_into_a_reader_that_left_is_no_traceback() -> None:
    """``fleet allocators | head -1`` once head has left: every write meets a closed pipe; exit 0, quietly."""
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before the listing writes its first line
    try:
        proc = subprocess.run([sys.executable, "-m", "fleet_emu", "allocators"], stdout=write_end,
                              stderr=subprocess.PIPE, text=True, timeout=60)
    finally:
        os.close(write_end)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
