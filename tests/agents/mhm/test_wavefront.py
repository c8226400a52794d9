"""MHM section III-A on drawn grids: cell areas, the Exploration Wavefront, bearing order, the r_comm filter
and eq. (1)."""

from __future__ import annotations

import math

import numpy as np

from fleet_emu.agents.allocators.mhm.wavefront import (
    bearing,
    bearing_order,
    cell_area,
    cell_boundary,
    disk,
    exploration_wavefront,
    filter_positions,
    hinge_positions,
    hinging_allowed,
)
from fleet_emu.core.grid import from_ascii

# With r_comm = 3 a cell's boundary (2 <= d < 3) is the border of the 5 x 5 square around its node. The base
# stands at (3, 3); the unknown is north-east, so the frontier cells are (1, 5), (2, 5) and (3, 6).
NE = """
########
#.....?#
#.....?#
#......#
#......#
#......#
########
"""
BASE = (3, 3)


def test_the_boundary_is_the_ring_just_within_r_comm() -> None:
    grid, _ = from_ascii(NE)
    ring = {tuple(map(int, p)) for p in cell_boundary(grid, BASE, 3.0)}
    square = {(r, c) for r in range(1, 6) for c in range(1, 6) if max(abs(r - 3), abs(c - 3)) == 2}
    assert ring == square
    assert disk(grid.shape, BASE, 3.0).sum() == 25  # offsets with dr^2 + dc^2 < 9: the 5 x 5 square


def test_a_wall_cuts_the_cell() -> None:
    long_wall = """
    .........
    ....#....
    ....#....
    ....#....
    ..0.#....
    ....#....
    ....#....
    ....#....
    ....#....
    """
    grid, robots = from_ascii(long_wall)
    area = cell_area(grid, robots["r0"], 4.0)
    assert area[4, 2] and area[4, 3] and not area[4, 4]
    assert not area[4, 5] and not area[2, 5]  # within 4 cells, but no way to them inside the disk
    short_wall = """
    .........
    .........
    ....#....
    ....#....
    ..0.#....
    ....#....
    .........
    """
    grid, robots = from_ascii(short_wall)
    area = cell_area(grid, robots["r0"], 4.0)
    assert area[4, 5] and area[2, 5]  # around the wall's end, inside the disk: part of the cell


def test_the_exploration_wavefront_and_its_bearing_order() -> None:
    grid, _ = from_ascii(NE)
    ew = exploration_wavefront(grid, [BASE], r_comm=3.0, sensor_range=1.0)
    assert [tuple(map(int, p)) for p in ew] == [(1, 4), (1, 5), (2, 5), (3, 5)]
    # bearings from the base, clockwise from north: 26.6, 45, 63.4 and 90 degrees
    assert [round(math.degrees(bearing(p, BASE)), 1) for p in [(1, 4), (1, 5), (2, 5), (3, 5)]] == [
        26.6, 45.0, 63.4, 90.0]
    assert bearing_order(ew[::-1], BASE) == [(1, 4), (1, 5), (2, 5), (3, 5)]
    # a larger sensor range reaches the frontier from more of the ring
    wide = {tuple(map(int, p)) for p in exploration_wavefront(grid, [BASE], 3.0, 2.0)}
    assert {(1, 3), (3, 5), (4, 5)} <= wide and (5, 1) not in wide


def test_no_frontier_no_wavefront() -> None:
    grid, _ = from_ascii(NE.replace("?", "."))
    assert exploration_wavefront(grid, [BASE], 3.0, 5.0).shape == (0, 2)
    assert hinge_positions(grid, [BASE], BASE, 3.0, 5.0) == []


def test_bearing_order_sweeps_clockwise_from_north() -> None:
    base = (5, 5)
    compass = {"N": (1, 5), "NE": (2, 8), "E": (5, 9), "SE": (8, 8), "S": (9, 5), "SW": (8, 2), "W": (5, 1),
               "NW": (2, 2)}
    order = bearing_order(list(compass.values())[::-1], base)
    assert [next(k for k, v in compass.items() if v == p) for p in order] == list(compass)
    assert bearing_order([(1, 5), (3, 5), (2, 5)], base) == [(3, 5), (2, 5), (1, 5)]  # one ray: nearer first


def test_the_r_comm_filter() -> None:
    line = [(0, 0), (0, 1), (0, 3), (0, 4), (0, 6)]
    assert filter_positions(line, 3.0) == [(0, 0), (0, 3), (0, 6)]  # at exactly r_comm a point stays
    assert filter_positions(line, 3.5) == [(0, 0), (0, 4)]
    # the filter follows B's order, not space
    assert filter_positions([(0, 1), (0, 0), (0, 4)], 3.5) == [(0, 1)]
    assert filter_positions([(0, 0), (0, 1), (0, 4)], 3.5) == [(0, 0), (0, 4)]
    assert filter_positions([], 3.0) == []


# A wide hall, fully unknown beyond r_comm = 5 of the base: the EW rings the base's cell, and bearing order
# plus the filter spread the hinge points around it.
HALL = "\n".join(["?" * 21] * 3 + ["???" + "." * 15 + "???"] * 15 + ["?" * 21] * 3)


def test_hinge_positions_spread_around_the_base() -> None:
    grid, _ = from_ascii(HALL)
    grid[~disk(grid.shape, (10, 10), 6.0) & (grid == 0)] = -1  # known only within 6 cells of the base
    pos = hinge_positions(grid, [(10, 10)], (10, 10), r_comm=5.0, sensor_range=3.0)
    assert len(pos) >= 4
    assert pos[0] == (6, 10)  # due north first: the nearest ring point on the ray
    assert all(math.dist(a, b) >= 5.0 for k, a in enumerate(pos) for b in pos[k + 1:])
    bearings = [bearing(p, (10, 10)) for p in pos]
    assert bearings == sorted(bearings)
    assert hinge_positions(grid, [(10, 10)], (10, 10), 5.0, 3.0, hinges=1) == [(6, 10)]
    assert (6, 10) not in hinge_positions(grid, [(10, 10)], (10, 10), 5.0, 3.0, taken=[(6, 10)])


def test_eq1_hinges_only_while_enough_explorers_remain() -> None:
    assert hinging_allowed(2, x_available=5, x_min=3)
    assert not hinging_allowed(3, x_available=5, x_min=3)
    assert hinging_allowed(0, x_available=1, x_min=1)
    assert not hinging_allowed(1, x_available=1, x_min=1)


def test_disk_is_clipped_at_the_edges() -> None:
    d = disk((4, 4), (0, 0), 2.0)
    assert d.sum() == 4 and d[1, 1] and not d[0, 2]
    assert np.array_equal(disk((9, 9), (4, 4), 3.0), disk((9, 9), (4, 4), 3.0).T)
