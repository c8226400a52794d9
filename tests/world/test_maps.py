"""Maps: the built-in generators, bitmap and ROS YAML loading, resampling, and the errors a user sees."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from scipy import ndimage

from fleet_emu.core.grid import FREE, OCCUPIED, from_ascii
from fleet_emu.world.maps import (
    BUILTIN_MAPS,
    START_RADIUS,
    MapData,
    MapError,
    _ball,
    diamond_sums,
    load_bitmap,
    load_map,
)

FOUR = ndimage.generate_binary_structure(2, 1)


def components(grid: np.ndarray) -> np.ndarray:
    return ndimage.label(grid == FREE, structure=FOUR)[0]


def check_map(md: MapData) -> None:
    """What every map guarantees: int8 0/100, walled in, start free and in the largest component."""
    g = md.grid
    assert g.dtype == np.int8 and g.ndim == 2
    assert set(np.unique(g).tolist()) <= {FREE, OCCUPIED}
    for edge in (g[0], g[-1], g[:, 0], g[:, -1]):
        assert (edge == OCCUPIED).all()
    labels = components(g)
    sizes = np.bincount(labels.ravel())[1:]
    assert g[md.start] == FREE
    assert sizes[labels[md.start] - 1] == sizes.max()


def write_png(path: Path, art: str) -> np.ndarray:
    grid, _ = from_ascii(art)
    Image.fromarray(np.where(grid == OCCUPIED, 0, 255).astype(np.uint8), mode="L").save(path)
    return grid


def write_yaml(path: Path, image: str, **kw: object) -> Path:
    lines = [f"image: {image}", "resolution: 0.5", "origin: [0.0, 0.0, 0.0]"]
    lines += [f"{k}: {v}" for k, v in kw.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


# ---------------------------------------------------------------------------------------------- built-ins


def test_builtin_names() -> None:
    assert list(BUILTIN_MAPS) == ["office", "maze", "grid", "hall"]
    assert all(desc and "\n" not in desc for desc in BUILTIN_MAPS.values())


@pytest.mark.parametrize("name", list(BUILTIN_MAPS))
@pytest.mark.parametrize("cell_size", [0.25, 0.5, 1.0])
def test_builtin_maps_are_sound(name: str, cell_size: float) -> None:
    md = load_map(name, cell_size, seed=3)
    assert md.name == name and md.cell_size == cell_size
    check_map(md)
    # the generators never leave free space disconnected
    assert components(md.grid).max() == 1
    # metres, not cells: the size scales with the cell size
    side = max(md.grid.shape) * cell_size
    assert 25 <= side <= 45
    # room for the fleet around the start (at coarse cells a 2 m corridor is only two cells wide)
    assert _ball(md.grid == FREE, md.start, START_RADIUS) >= (20 if cell_size <= 0.5 else 12)


@pytest.mark.parametrize("name", list(BUILTIN_MAPS))
def test_default_cell_size_gives_a_few_thousand_cells(name: str) -> None:
    md = load_map(name, 0.5, seed=0)
    assert 50 <= max(md.grid.shape) <= 100
    assert (md.grid == FREE).sum() > 1000


@pytest.mark.parametrize("name", list(BUILTIN_MAPS))
def test_same_seed_same_map(name: str) -> None:
    a, b = load_map(name, 0.5, 7), load_map(name, 0.5, 7)
    assert np.array_equal(a.grid, b.grid) and a.start == b.start


def test_seed_changes_maze_and_office_and_hall() -> None:
    for name in ("maze", "office", "hall"):
        grids = [load_map(name, 0.5, s).grid for s in range(4)]
        assert any(not np.array_equal(grids[0], g) for g in grids[1:]), name


def test_maze_is_perfect() -> None:
    """A spanning tree of 2 m rooms: no cycles, so passages = rooms - 1."""
    g = load_map("maze", 0.5, 11).grid
    p = 5  # 4 free cells (2 m) then a one-cell wall
    n = (g.shape[0] - 1) // p
    assert g.shape == (n * p + 1, n * p + 1)
    passages = sum(g[1 + i * p - 1 + p, 1 + j * p] == FREE for i in range(n - 1) for j in range(n))
    passages += sum(g[1 + i * p, 1 + j * p - 1 + p] == FREE for i in range(n) for j in range(n - 1))
    assert passages == n * n - 1


def test_office_start_is_in_the_corridor() -> None:
    md = load_map("office", 0.5, 0)
    r, c = md.start
    row, col = md.grid[r], md.grid[:, c]
    assert (row[1:-1] == FREE).mean() > 0.9 or (col[1:-1] == FREE).mean() > 0.9  # a through corridor


# ----------------------------------------------------------------------------------------------- bitmaps

ART = """
##########
#........#
#..##....#
#..##..#.#
#......#.#
##########
"""


def test_png_at_cell_size_round_trips(tmp_path: Path) -> None:
    grid = write_png(tmp_path / "a.png", ART)
    md = load_bitmap(tmp_path / "a.png", 0.5, resolution=0.5)
    assert np.array_equal(md.grid, grid)
    check_map(md)


def test_a_bare_bitmap_is_one_pixel_per_cell_whatever_its_size(tmp_path: Path) -> None:
    grid = write_png(tmp_path / "a.png", ART)
    md = load_map(str(tmp_path / "a.png"), 0.5, 0)
    assert np.array_equal(md.grid, grid) and md.name == str(tmp_path / "a.png")
    big = np.full((300, 260), 255, dtype=np.uint8)
    big[[0, -1], :] = big[:, [0, -1]] = 0
    Image.fromarray(big, mode="L").save(tmp_path / "big.pgm")
    assert load_map(str(tmp_path / "big.pgm"), 0.1, 0).grid.shape == (300, 260)


def test_a_bare_bitmap_without_a_cell_size_is_refused(tmp_path: Path) -> None:
    write_png(tmp_path / "a.png", ART)
    with pytest.raises(MapError) as exc:
        load_map(str(tmp_path / "a.png"), 0.5, 0, cell_size_given=False)
    assert_one_line(exc, "a.png", "without a scale", "--cell-size", "YAML")
    yaml_map = write_yaml(tmp_path / "a.yaml", "a.png")  # the same image with its scale: no cell size needed
    assert np.array_equal(load_map(str(yaml_map), 0.5, 0, cell_size_given=False).grid, from_ascii(ART)[0])
    assert load_map("office", 0.5, 0, cell_size_given=False).grid.size > 0


def test_open_edges_get_a_wall_border(tmp_path: Path) -> None:
    write_png(tmp_path / "open.png", "....\n.#..\n....")
    md = load_bitmap(tmp_path / "open.png", 1.0, resolution=1.0)
    assert md.grid.shape == (5, 6)
    check_map(md)
    assert (md.grid[1:-1, 1:-1] == from_ascii("....\n.#..\n....")[0]).all()


def test_downsampling_keeps_a_one_pixel_wall(tmp_path: Path) -> None:
    img = np.full((40, 40), 255, dtype=np.uint8)
    img[:, 21] = 0  # a wall one pixel thick, off the cell boundaries
    img[10, 3] = 0  # and a single obstacle pixel
    Image.fromarray(img, mode="L").save(tmp_path / "wall.png")
    md = load_bitmap(tmp_path / "wall.png", 0.2, resolution=0.05)  # 4 px per cell
    inner = md.grid[1:-1, 1:-1]  # the free image edge got a border
    assert inner.shape == (10, 10)
    assert (inner[:, 5] == OCCUPIED).all()
    assert inner[2, 0] == OCCUPIED
    assert (inner[:, 6:] == FREE).all() and (inner[:, 1:5] == FREE).all()


def test_non_integer_factor_covers_every_pixel(tmp_path: Path) -> None:
    img = np.full((25, 37), 255, dtype=np.uint8)
    img[-1, -1] = 0  # the last pixel must land in a cell
    Image.fromarray(img, mode="L").save(tmp_path / "odd.pgm")
    md = load_bitmap(tmp_path / "odd.pgm", 0.25, resolution=0.1)  # 2.5 px per cell
    assert md.grid.shape == (10 + 2, 15 + 2)
    assert md.grid[-2, -2] == OCCUPIED and md.grid[-2, -3] == FREE


def test_mostly_unknown_cells_are_occupied(tmp_path: Path) -> None:
    img = np.full((4, 8), 255, dtype=np.uint8)
    img[:, 4:] = 205  # map_server's unknown gray
    img[0:2, 0:4] = 205  # half the first cell unknown: still free
    Image.fromarray(img, mode="L").save(tmp_path / "u.png")
    g = load_bitmap(tmp_path / "u.png", 0.2, resolution=0.05).grid
    assert g[1, 1] == FREE and g[1, 2] == OCCUPIED


def test_rgba_transparent_is_free(tmp_path: Path) -> None:
    img = np.zeros((6, 6, 4), dtype=np.uint8)  # transparent black everywhere
    img[0, :] = img[-1, :] = img[:, 0] = img[:, -1] = (0, 0, 0, 255)  # opaque black walls
    Image.fromarray(img, mode="RGBA").save(tmp_path / "t.png")
    g = load_bitmap(tmp_path / "t.png", 0.5, resolution=0.5).grid
    assert g.shape == (6, 6) and (g[1:-1, 1:-1] == FREE).all() and (g[0] == OCCUPIED).all()


# ---------------------------------------------------------------------------------------------- ROS YAML


def gradient_pgm(path: Path) -> None:
    """Five columns of gray 0, 60, 128, 205, 255 between black walls, one pixel per 0.5 m cell."""
    img = np.zeros((5, 7), dtype=np.uint8)
    img[1:-1, 1:-1] = [0, 60, 128, 205, 255]
    Image.fromarray(img, mode="L").save(path)


def inner_row(md: MapData) -> list[str]:
    return ["." if v == FREE else "#" for v in md.grid[2, 1:-1]]


def test_ros_yaml_trinary_defaults(tmp_path: Path) -> None:
    gradient_pgm(tmp_path / "m.pgm")
    md = load_map(str(write_yaml(tmp_path / "m.yaml", "m.pgm", negate=0)), 0.5, 0)
    assert inner_row(md) == ["#", "#", "#", "#", "."]  # 128 and 205 are unknown -> occupied


def test_ros_yaml_negate(tmp_path: Path) -> None:
    gradient_pgm(tmp_path / "m.pgm")
    md = load_map(str(write_yaml(tmp_path / "m.yaml", "m.pgm", negate=1)), 0.5, 0)
    # the dark border became free, so a wall border was added
    assert md.grid.shape == (7, 9)
    check_map(md)
    # p = x / 255: 0 -> free; 60 (0.235) and 128 (0.5) unknown -> occupied; 205 and 255 occupied
    assert ["." if v == FREE else "#" for v in md.grid[3, 2:-2]] == [".", "#", "#", "#", "#"]


def test_ros_yaml_custom_thresholds(tmp_path: Path) -> None:
    gradient_pgm(tmp_path / "m.pgm")
    md = load_map(str(write_yaml(tmp_path / "m.yaml", "m.pgm", occupied_thresh=0.9, free_thresh=0.6)), 0.5, 0)
    # p = (255 - x) / 255: 1.0, 0.76, 0.5, 0.2, 0 -> occ, unknown, free, free, free
    assert inner_row(md) == ["#", "#", ".", ".", "."]


def test_ros_yaml_raw_mode(tmp_path: Path) -> None:
    img = np.zeros((3, 6), dtype=np.uint8)
    img[1, 1:-1] = [0, 50, 70, 255]
    img[[0, 2], :] = img[:, [0, -1]] = 100
    Image.fromarray(img, mode="L").save(tmp_path / "r.pgm")
    md = load_map(str(write_yaml(tmp_path / "r.yaml", "r.pgm", mode="raw")), 0.5, 0)
    assert ["." if v == FREE else "#" for v in md.grid[1, 1:-1]] == [".", ".", "#", "#"]


def test_ros_yaml_image_is_relative_to_the_yaml(tmp_path: Path) -> None:
    (tmp_path / "maps").mkdir()
    write_png(tmp_path / "maps" / "a.png", ART)
    y = write_yaml(tmp_path / "maps" / "a.yaml", "a.png")
    assert np.array_equal(load_map(str(y), 0.5, 0).grid, from_ascii(ART)[0])


# ------------------------------------------------------------------------------------------------ errors


def assert_one_line(exc: pytest.ExceptionInfo[MapError], *words: str) -> None:
    msg = str(exc.value)
    assert msg and "\n" not in msg
    for w in words:
        assert w in msg


def test_unknown_name() -> None:
    with pytest.raises(MapError) as exc:
        load_map("nowhere", 0.5, 0)
    assert str(exc.value).startswith("unknown map 'nowhere' (built-in: office, maze, grid, hall; registry: "
                                     "hospital_section, hospital, cave, ")
    assert_one_line(exc, "`fleet maps`", "or a PNG/PGM/YAML path")


def test_missing_file(tmp_path: Path) -> None:
    for p in (str(tmp_path / "none.png"), "no_such_map.yaml", "maps/thing"):
        with pytest.raises(MapError) as exc:
            load_map(p, 0.5, 0)
        assert_one_line(exc, "not found")


def test_garbage_png(tmp_path: Path) -> None:
    (tmp_path / "bad.png").write_bytes(np.random.default_rng(0).bytes(500))
    with pytest.raises(MapError) as exc:
        load_map(str(tmp_path / "bad.png"), 0.5, 0)
    assert_one_line(exc, "bad.png")


@pytest.mark.parametrize("text", [
    "resolution: 0.05\nnegate: 0\n",  # no image
    "image: [a, b\n  resolution: {\n",  # not YAML
    "just a string\n",
    "image: m.pgm\n",  # no resolution
    "image: m.pgm\nresolution: -1\n",
    "image: m.pgm\nresolution: 0.05\nmode: fancy\n",
    "image: m.pgm\nresolution: 0.05\noccupied_thresh: high\n",
    "image: missing.pgm\nresolution: 0.05\n",
])
def test_bad_yaml(tmp_path: Path, text: str) -> None:
    gradient_pgm(tmp_path / "m.pgm")
    (tmp_path / "m.yaml").write_text(text)
    with pytest.raises(MapError) as exc:
        load_map(str(tmp_path / "m.yaml"), 0.5, 0)
    assert_one_line(exc)


def test_binary_yaml_and_directory(tmp_path: Path) -> None:
    (tmp_path / "b.yaml").write_bytes(b"\xff\xfe\x00garbage\x00\n\x81")
    with pytest.raises(MapError) as exc:
        load_map(str(tmp_path / "b.yaml"), 0.5, 0)
    assert_one_line(exc)
    with pytest.raises(MapError) as exc:
        load_map(str(tmp_path), 0.5, 0)
    assert_one_line(exc)


def test_all_wall_image_and_bad_cell_size(tmp_path: Path) -> None:
    Image.fromarray(np.zeros((30, 30), dtype=np.uint8), mode="L").save(tmp_path / "black.png")
    with pytest.raises(MapError) as exc:
        load_map(str(tmp_path / "black.png"), 0.5, 0)
    assert_one_line(exc, "no free cell")
    with pytest.raises(MapError):
        load_map("office", 0.0, 0)


def test_diamond_sums_are_a_convolution_with_a_diamond() -> None:
    rng = np.random.default_rng(1)
    for shape, k in (((1, 1), 0), ((7, 3), 2), ((30, 41), START_RADIUS), ((5, 5), 9)):
        mask = rng.random(shape) < 0.6
        yy, xx = np.mgrid[-k:k + 1, -k:k + 1]
        want = ndimage.convolve(mask.astype(np.int32), (abs(yy) + abs(xx) <= k).astype(np.int32), mode="constant")
        assert np.array_equal(diamond_sums(mask, k), want)


def test_the_largest_component_is_the_labels_one_with_or_without_a_kernel() -> None:
    """``largest_component`` (a numpy search when one component holds most free cells) against the compiled
    labels' largest (lowest label on ties): random masks, sparse ones (many small components: the labels decide)
    and dense ones."""
    from fleet_emu.core import jit
    from fleet_emu.world.maps import _components, largest_component

    rng = np.random.default_rng(11)
    for density in (0.2, 0.45, 0.6, 0.8, 0.95):
        for _ in range(12):
            free = rng.random((int(rng.integers(1, 40)), int(rng.integers(1, 40)))) < density
            labels, best = _components(free)
            with pytest.MonkeyPatch.context() as mp:
                mp.setattr(jit, "_loaded", False)  # the search a launcher makes (this process has the kernels)
                got = largest_component(free)
            if best == 0:
                assert got is None
            else:
                assert got is not None and np.array_equal(got, labels == best)
