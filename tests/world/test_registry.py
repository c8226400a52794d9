"""The map registry: its data, fetching into the cache (from a folder or an HTTP mirror; every file checked, nothing
kept of a failed fetch), and a fetched map read by name as a map_server YAML would read it."""

from __future__ import annotations

import dataclasses
import hashlib
import re
import socket
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from fleet_emu.core.errors import MapError
from fleet_emu.core.grid import FREE
from fleet_emu.world.fetch import fetch
from fleet_emu.world.maps import START_RADIUS, _ball, load_map, load_ros_yaml
from fleet_emu.world.registry import MapFile, RegistryMap, is_fetched, local_map, lookup, registry
from tests.harness.map_mirror import build_mirror, files_in, serve

NAMES = {"hospital_section", "hospital", "cave", "autolab", "mbicp", "uoa_robotics_lab", "frieburg", "889_05",
         "cave_filled", "SFU", "turtlebot3_world", "depot", "warehouse"}


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The user cache directory of this test (XDG_CACHE_HOME), and the maps' folder in it."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    return tmp_path / "xdg" / "fleet-emu" / "maps"


@pytest.fixture(scope="module")
def mirror(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_mirror(tmp_path_factory.mktemp("mirror"))


def one_line(exc: pytest.ExceptionInfo[MapError], *words: str) -> str:
    msg = str(exc.value)
    assert msg and "\n" not in msg, msg
    for w in words:
        assert w in msg, (w, msg)
    return msg


def test_every_map_is_pinned_with_its_checksums_licence_and_scale() -> None:
    assert set(registry()) >= NAMES
    for entry in registry().values():
        assert re.fullmatch(r"[0-9a-f]{40}", entry.commit), entry.name
        assert entry.licence.startswith(("GPL-2.0", "Apache-2.0")) and entry.description and entry.scale
        for f in entry.files:
            assert re.fullmatch(r"[0-9a-f]{64}", f.sha256), (entry.name, f.path)
            assert entry.url(f) == f"https://raw.githubusercontent.com/{entry.repo}/{entry.commit}/{f.path}"
        if entry.yaml is None:  # a bitmap: one file, square pixels at the world's width over the image's
            assert len(entry.files) == 1 and entry.files[0].name.endswith(".png")
            if entry.world_size is not None:
                assert entry.resolution == round(entry.world_size[0] / entry.pixels[0], 6), entry.name
        else:  # a ROS map: its YAML and its image
            assert sorted(f.name.rsplit(".", 1)[1] for f in entry.files) == ["pgm", "yaml"]
    hs = lookup("hospital_section")
    assert (hs.pixels, hs.world_size, hs.resolution) == ((1086, 443), (40.0, 18.0), 0.036832)
    with pytest.raises(MapError) as exc:
        lookup("atlantis")
    one_line(exc, "'atlantis'", "hospital_section", "`fleet maps`")


def test_a_folder_mirror_fills_the_cache_with_every_map_checked(mirror: Path, cache: Path) -> None:
    for entry in registry().values():
        done = fetch(entry, str(mirror))
        assert not done.cached and done.folder == cache / entry.name and is_fetched(entry.name)
        assert done.origins == tuple(str(mirror / entry.name / f.name) for f in entry.files)
        for f in entry.files:  # real copies, not links into the mirror
            kept = done.folder / f.name
            assert not kept.is_symlink() and hashlib.sha256(kept.read_bytes()).hexdigest() == f.sha256
        image = next(done.folder / f.name for f in entry.files if not f.name.endswith(".yaml"))
        with Image.open(image) as im:
            assert im.size == entry.pixels, entry.name
        if entry.yaml is not None:
            assert yaml.safe_load((done.folder / entry.yaml).read_text())["resolution"] == entry.resolution
    assert sorted(p.name for p in cache.iterdir()) == sorted(registry())  # no temporary folder left
    assert fetch(lookup("cave"), str(mirror)).cached  # already there, intact: nothing read again


def test_a_registry_map_is_read_as_its_map_server_yaml_would_be(mirror: Path, cache: Path, tmp_path: Path) -> None:
    """The Stage bitmap at the registry's resolution gives the grid a map_server YAML beside it gives (40 m over
    1086 px: 0.036832 m/px, default thresholds), walls max-pooled; a ROS map is read through its own YAML."""
    for name in ("hospital_section", "turtlebot3_world"):
        fetch(lookup(name), str(mirror))
    (tmp_path / "hospital_section.yaml").write_text(
        "image: hospital_section.png\nresolution: 0.036832\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    (tmp_path / "hospital_section.png").symlink_to(mirror / "hospital_section" / "hospital_section.png")
    for cell_size in (0.5, 0.25):
        by_name = load_map("hospital_section", cell_size, 0)
        by_yaml = load_ros_yaml(tmp_path / "hospital_section.yaml", cell_size)
        assert np.array_equal(by_name.grid, by_yaml.grid) and by_name.start == by_yaml.start
        assert by_name.name == "hospital_section" and by_name.cell_size == cell_size
        tb3 = load_map("turtlebot3_world", cell_size, 0)
        for md, size_m, free_m2 in ((by_name, (443 * 0.036832, 1086 * 0.036832), 600.0),
                                    (tb3, (384 * 0.05, 384 * 0.05), 19.0)):
            for n, metres in zip(md.grid.shape, size_m, strict=True):
                assert metres / cell_size <= n <= metres / cell_size + 3
            # max-pooling walls costs some free area, but most survives (more at the finer cell size)
            assert (md.grid == FREE).sum() * cell_size**2 >= (0.45 if cell_size == 0.5 else 0.7) * free_m2
    hospital = load_map("hospital_section", 0.5, 0)
    assert _ball(hospital.grid == FREE, hospital.start, START_RADIUS) >= 20 and (hospital.grid == FREE).sum() > 1000


def test_an_http_mirror_serves_a_two_file_map(mirror: Path, cache: Path) -> None:
    with serve(mirror) as url:
        done = fetch(lookup("turtlebot3_world"), url + "/")
    assert done.origins == (f"{url}/turtlebot3_world/map.pgm", f"{url}/turtlebot3_world/map.yaml")
    assert local_map("turtlebot3_world") == cache / "turtlebot3_world" / "map.yaml"
    assert load_map("turtlebot3_world", 0.5, 0).grid.shape == (39, 39)


def fake_map(tmp_path: Path, good: bytes, served: bytes) -> tuple[RegistryMap, Path]:
    """A two-file map whose second file the mirror serves as ``served`` where the registry expects ``good``."""
    sha = [hashlib.sha256(b"P5 first file").hexdigest(), hashlib.sha256(good).hexdigest()]
    entry = dataclasses.replace(lookup("depot"), name="fake", files=(
        MapFile("maps/fake.pgm", sha[0]), MapFile("maps/fake.yaml", sha[1])))
    (tmp_path / "mirror" / "fake").mkdir(parents=True)
    (tmp_path / "mirror" / "fake" / "fake.pgm").write_bytes(b"P5 first file")
    (tmp_path / "mirror" / "fake" / "fake.yaml").write_bytes(served)
    return entry, tmp_path / "mirror"


def test_a_checksum_mismatch_keeps_nothing(tmp_path: Path, cache: Path) -> None:
    entry, mirror = fake_map(tmp_path, b"image: fake.pgm\n", b"image: evil.pgm\n")
    with pytest.raises(MapError) as exc:
        fetch(entry, str(mirror))
    one_line(exc, "map fake", "fake.yaml", "sha256", "nothing was kept")
    assert files_in(cache.parent.parent) == [] and not cache.exists()  # the folders it made are gone too
    with serve(mirror) as url, pytest.raises(MapError) as exc:
        fetch(entry, url)
    one_line(exc, f"{url}/fake/fake.yaml", "sha256")
    assert files_in(cache.parent.parent) == []


def test_an_unreachable_source_keeps_nothing(tmp_path: Path, cache: Path) -> None:
    entry, mirror = fake_map(tmp_path, b"x", b"x")
    (mirror / "fake" / "fake.yaml").unlink()
    with pytest.raises(MapError) as exc:
        fetch(entry, str(mirror))
    one_line(exc, str(mirror / "fake" / "fake.yaml"), "no such file", "nothing was kept")
    with serve(mirror) as url, pytest.raises(MapError) as exc:
        fetch(entry, url)
    one_line(exc, "HTTP 404")
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(MapError) as exc:
        fetch(entry, f"http://127.0.0.1:{port}")
    one_line(exc, f"http://127.0.0.1:{port}/fake/fake.pgm", "refused")
    assert files_in(cache.parent.parent) == []


def test_an_unfetched_or_altered_map_names_the_command_that_fetches_it(tmp_path: Path, cache: Path) -> None:
    with pytest.raises(MapError) as exc:
        load_map("cave", 0.5, 0)
    one_line(exc, "map cave is not fetched", "`fleet maps fetch cave`", "rtv/Stage@281ed731ed", "GPL-2.0")
    (cache / "cave").mkdir(parents=True)
    (cache / "cave" / "cave.png").write_bytes(b"not the cave")
    assert not is_fetched("cave")
    with pytest.raises(MapError) as exc:
        local_map("cave")
    one_line(exc, "altered", "`fleet maps fetch cave`")
