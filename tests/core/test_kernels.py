"""The compiled kernels on grids drawn as ASCII art."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from fleet_emu.core.grid import OCCUPIED, distinct, flat, from_ascii, to_ascii, unflat
from fleet_emu.core.kernels import count_walls, label, visible_cells, wavefront


def test_ascii_round_trip() -> None:
    art = """
    #####
    #0.?#
    #..1#
    #####
    """
    grid, robots = from_ascii(art)
    assert robots == {"r0": (1, 1), "r1": (2, 3)}
    assert grid[1, 3] == -1 and grid[0, 0] == OCCUPIED
    assert to_ascii(grid, robots).splitlines()[1] == "#0.?#"
    assert unflat(grid.shape, flat(grid.shape, (2, 3))) == (2, 3)


def test_distinct_is_numpy_s_unique() -> None:
    rng = np.random.default_rng(0)
    for n in (0, 1, 2, 3, 50, 5000):
        for dtype in (np.int32, np.int64):
            a = rng.integers(0, max(2, n // 3), n).astype(dtype)
            got, want = distinct(a), np.unique(a)
            assert got.dtype == want.dtype and np.array_equal(got, want), (n, dtype)
            assert got is not a  # a copy, as np.unique's


def test_wavefront_goes_around_walls_and_stops() -> None:
    grid, _ = from_ascii("""
    .....
    .###.
    .#...
    .#.#.
    """)
    passable = grid == 0
    dist = wavefront(passable, np.array([flat(grid.shape, (2, 2))], np.int64), -1)
    assert dist[2, 2] == 0 and dist[0, 0] == 8 and dist[3, 0] == 11
    assert dist[1, 1] == -1  # a wall is never reached
    stop = flat(grid.shape, (0, 4))
    partial = wavefront(passable, np.array([flat(grid.shape, (2, 2))], np.int64), stop)
    assert partial[0, 4] == dist[0, 4] == 4
    assert partial[3, 0] == -1  # farther cells were not computed


def test_visible_cells_stop_at_walls_and_range() -> None:
    grid, robots = from_ascii("""
    .........
    ....#....
    ..0.#....
    ....#....
    .........
    """)
    occ = grid == OCCUPIED
    seen = set(visible_cells(occ, *robots["r0"], 6.0).tolist())
    assert flat(grid.shape, (2, 4)) in seen  # the wall itself is seen
    assert flat(grid.shape, (2, 6)) not in seen  # the cell behind it is not
    assert flat(grid.shape, (2, 0)) in seen
    near = set(visible_cells(occ, *robots["r0"], 1.0).tolist())
    assert near == {flat(grid.shape, c) for c in [(1, 2), (2, 1), (2, 2), (2, 3), (3, 2)]}


def test_count_walls_counts_runs() -> None:
    grid, _ = from_ascii("""
    ..##..#..
    """)
    occ = grid == OCCUPIED
    assert count_walls(occ, 0, 0, 0, 8) == 2  # a two-cell-thick wall counts once
    assert count_walls(occ, 0, 0, 0, 1) == 0


def _visible_unclamped(occ: np.ndarray, row: int, col: int, radius: float) -> set[int]:
    """The sensor as it was before the clamp: rays to the border of the square of half-side ceil(radius)."""
    from fleet_emu.core.kernels import _trace

    big = int(np.ceil(radius))
    mark = np.zeros(occ.size, dtype=np.bool_)
    out = np.empty((2 * big + 1) ** 2 + 1, dtype=np.int64)
    count = 0
    for k in range(-big, big + 1):
        for r1, c1 in ((row - big, col + k), (row + big, col + k), (row + k, col - big), (row + k, col + big)):
            count = _trace(occ, row, col, r1, c1, radius * radius, mark, out, count)
    return set(out[:count].tolist())


_ROOMS = """
.........
....#....
..0.#....
....#....
.........
"""


def test_visible_cells_are_unchanged_for_ranges_within_the_grid() -> None:
    grid, robots = from_ascii(_ROOMS)
    occ = grid == OCCUPIED
    limit = float(np.hypot(*occ.shape))
    for radius in (1.0, 2.5, 4.0, 7.3, limit):
        assert set(visible_cells(occ, *robots["r0"], radius).tolist()) == \
            _visible_unclamped(occ, *robots["r0"], radius), radius


def test_a_range_beyond_the_grid_is_clamped_to_it() -> None:
    grid, robots = from_ascii(_ROOMS)
    occ = grid == OCCUPIED
    at_limit = visible_cells(occ, *robots["r0"], float(np.hypot(*occ.shape)))
    for radius in (1e9, 1e300, np.inf):
        got = visible_cells(occ, *robots["r0"], radius)
        assert np.array_equal(got, at_limit), radius
    assert flat(grid.shape, (2, 6)) not in set(at_limit.tolist())  # walls still block
    open_hall = np.zeros((3, 4), dtype=np.bool_)
    assert visible_cells(open_hall, 0, 0, 1e9).tolist() == list(range(12))  # every cell, each once


def test_a_negative_or_nan_range_sees_nothing() -> None:
    occ = np.zeros((4, 4), dtype=np.bool_)
    for radius in (-1.0, -np.inf, np.nan):
        assert visible_cells(occ, 1, 1, radius).size == 0, radius


def test_count_walls_off_the_grid_is_open_space() -> None:
    occ = np.zeros((3, 3), dtype=np.bool_)
    occ[1, 1] = True
    assert count_walls(occ, -5, -5, 7, 7) == 1  # only the wall inside the grid, no read outside it
    assert count_walls(occ, -3, 0, -3, 50) == 0


_LAZY = """
import sys
import fleet_emu, fleet_emu.agents.allocators
from fleet_emu.cli import main
from fleet_emu.core import cluster_kernels as k
from fleet_emu.core.kernels import warm_up, wavefront
try:
    main(["run", "--map", "no-such-map", "--quiet"])
except SystemExit as exc:
    assert exc.code == 2, exc.code
assert "numba" not in sys.modules, "numba imported before any kernel ran"
warm_up()
assert all(f.signatures for f in (k.update_mask, k._touched_labels, k.relabel, k.target))
import numba, numpy as np
assert isinstance(k.relabel, numba.core.registry.CPUDispatcher) and wavefront.signatures
assert "scipy.linalg" not in sys.modules and "numpy.f2py" not in sys.modules
dot = numba.njit(lambda a, b: np.dot(a, b))
assert dot(np.ones(3), np.ones(3)) == 3.0
print("ok")
"""


def test_kernels_load_numba_on_first_use_and_warm_up_loads_them_all() -> None:
    """Importing the product (every allocator) and refusing bad input never imports numba; ``warm_up`` (the
    fork server's) then loads every kernel a robot uses per tick, the incremental clusters' too; a kernel imported
    before that forwards to its dispatcher; numba's BLAS check was skipped (no ``scipy.linalg``) and BLAS still
    works for a user's own ``np.dot``."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", _LAZY], capture_output=True, text=True)
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr[-2000:]


_CACHED = """
from fleet_emu.core.jit import njit

@njit(cache=True)
def plus_one(x):
    return x + 1

assert plus_one(1) == 2
print(sum(plus_one.stats.cache_hits.values()), sum(plus_one.stats.cache_misses.values()))
"""


def test_a_kernel_is_cached_in_the_kernel_cache_and_loaded_from_another_checkout(tmp_path: Path) -> None:
    """A ``cache=True`` kernel's machine code goes to ``FLEET_KERNEL_CACHE`` (not beside its source), keyed by the
    source: the same module in another folder (a new clone) loads it instead of compiling."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "FLEET_KERNEL_CACHE": str(tmp_path / "cache")}
    runs = []
    for clone in ("a", "b"):
        (tmp_path / clone).mkdir()
        (tmp_path / clone / "cached_kernel.py").write_text(_CACHED)
        out = subprocess.run([sys.executable, "-c", "import cached_kernel"], cwd=tmp_path / clone, env=env,
                             capture_output=True, text=True)
        assert out.returncode == 0, out.stderr[-2000:]
        runs.append(out.stdout.split())
    assert runs == [["0", "1"], ["1", "0"]]  # compiled once, then loaded (hits, misses)
    assert any(p.suffix == ".nbi" for p in (tmp_path / "cache").iterdir())
    assert not (tmp_path / "a" / "__pycache__").exists() or not any((tmp_path / "a" / "__pycache__").glob("*.nb*"))


def test_label_numbers_components_as_scipy_does() -> None:
    """The reference is scipy.ndimage.label (cross and full 3 x 3 structures): the same labels, dtype and count
    on random masks of every density and shape, empty and single-row ones included."""
    from scipy import ndimage

    rng = np.random.default_rng(0)
    cross, full = ndimage.generate_binary_structure(2, 1), np.ones((3, 3), dtype=bool)
    shapes = [(1, 1), (1, 9), (9, 1), *(tuple(rng.integers(2, 30, 2)) for _ in range(150))]
    for shape in shapes:
        mask = rng.random(shape) < rng.random()
        for eight, structure in ((False, cross), (True, full)):
            ours, n = label(mask, eight)
            theirs, m = ndimage.label(mask, structure=structure)
            assert n == m and ours.dtype == theirs.dtype and np.array_equal(ours, theirs), (shape, eight)
    diagonal = np.eye(4, dtype=bool)
    assert label(diagonal)[1] == 4 and label(diagonal, eight=True)[1] == 1
