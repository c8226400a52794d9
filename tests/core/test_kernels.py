"""The compiled kernels on grids drawn as ASCII art."""

from __future__ import annotations

import numpy as np

from fleet_emu.core.grid import OCCUPIED, flat, from_ascii, to_ascii, unflat
from fleet_emu.core.kernels import count_walls, visible_cells, wavefront


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
