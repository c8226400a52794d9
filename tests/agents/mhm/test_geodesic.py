"""MHM's phase 2 on open ground (section III-D, steps 8-9): the closest frontier by an octile path, the chain
along that path pulled taut, the final reach of a fleet against the disc a chain of n robots can reach; and the
planner's boxed helpers, which must equal their whole-grid definitions."""

from __future__ import annotations

import math
from itertools import pairwise

import numpy as np
import pytest

from fleet_emu.agents.allocators.mhm.chain import (
    base_distance,
    chain_positions,
    closest_frontier,
    path_from_base,
    phase2_chain,
)
from fleet_emu.agents.allocators.mhm.explore import area_clusters, cells_area, path_gaps
from fleet_emu.agents.allocators.mhm.geodesic import Geodesic
from fleet_emu.agents.allocators.mhm.planner import MhmConfig
from fleet_emu.agents.allocators.mhm.sim import sensed, simulate, worst
from fleet_emu.agents.frontiers import find_clusters
from fleet_emu.core.grid import FREE, OCCUPIED, UNKNOWN
from fleet_emu.core.kernels import visible_cells, wavefront

BASE = (5, 5)


def block(unknown: list[tuple[int, int]]) -> np.ndarray:
    """A known-free 41 x 41 block (rows and columns 5..45) in walls, with ``unknown`` cells."""
    grid = np.full((52, 52), OCCUPIED, dtype=np.int8)
    grid[5:46, 5:46] = FREE
    for c in unknown:
        grid[c] = UNKNOWN
    return grid


def test_the_chain_to_a_diagonal_frontier_is_the_straight_line() -> None:
    grid = block([(46, 45)])  # one frontier, at the far corner (45, 45): 56.6 cells away, 80 by 4-steps
    frontier, lh = phase2_chain(grid, BASE, 10.0)  # type: ignore[misc]
    assert frontier == (45, 45) and lh[-1] == frontier
    hops = [BASE, *lh]
    assert all(math.dist(a, b) < 10.0 for a, b in pairwise(hops))
    assert all(abs(r - c) <= 1 for r, c in lh)  # on the diagonal
    assert len(lh) == math.ceil(40 / 7)  # 7 diagonal steps (9.9 cells) per hop: 6 nodes
    manhattan = chain_positions(path_from_base(base_distance(grid, BASE), frontier), 10.0)
    assert len(manhattan) > len(lh)  # the 4-connected path needs more robots for the same frontier


def test_the_closest_frontier_is_by_octile_path() -> None:
    grid = block([(25, 46), (46, 35)])  # frontiers (25, 45) and (45, 35) ...
    grid[5:46, 25] = OCCUPIED  # ... behind a wall with a door at the top, (5, 25): no corner is cut there
    grid[5, 25] = FREE
    geo = Geodesic(grid, BASE)
    assert closest_frontier(grid, BASE, geo.dist) == (25, 45)
    assert abs(geo.dist[25, 45] - (22 + 19 * math.sqrt(2))) < 1e-6  # 21 steps through the door, then 19 + 1
    assert abs(geo.dist[45, 35] - (52 + 9 * math.sqrt(2))) < 1e-6
    assert all(grid[c] == FREE for c in geo.taut((25, 45)))  # the taut path keeps to known-free cells
    # open ground: a frontier 36.1 cells away on the diagonal, (30, 31), and one 40 away on the row, (5, 45)
    open_grid = block([(31, 31), (5, 46)])
    assert closest_frontier(open_grid, BASE, Geodesic(open_grid, BASE).dist) == (30, 31)
    assert closest_frontier(open_grid, BASE) == (5, 45)  # by 4-connected steps: 51 against 40


def test_boxed_helpers_equal_their_whole_grid_definitions() -> None:
    rng = np.random.default_rng(4)
    grid = rng.choice(np.array([FREE, OCCUPIED, UNKNOWN], dtype=np.int8), size=(120, 140), p=[0.7, 0.1, 0.2])
    centers = [(30, 40), (60, 50), (100, 130)]
    area = cells_area(grid, centers, 12.0)
    clipped = grid.copy()
    clipped[(grid == FREE) & ~area] = OCCUPIED
    whole = find_clusters(clipped, 8)
    boxed = area_clusters(grid, area, 8)
    assert len(whole) == len(boxed) > 3
    assert all(np.array_equal(a.cells, b.cells) and a.target == b.target for a, b in zip(whole, boxed, strict=True))
    passable = area.copy()
    poses = {f"r{k}": tuple(int(v) for v in c) for k, c in enumerate(np.argwhere(area)[::97])}
    goal = next(iter(poses.values()))
    dist = wavefront(passable, np.array([goal[0] * 140 + goal[1]]), -1)
    gaps = path_gaps(passable, poses, dict.fromkeys(poses, goal))
    assert gaps == {r: float(dist[c]) if dist[c] >= 0 else math.inf for r, c in poses.items()}
    occupied = grid == OCCUPIED
    for cell in [(0, 0), (60, 70), (119, 139), (3, 136)]:
        assert np.array_equal(sensed(occupied, cell, 9.0), visible_cells(occupied, cell[0], cell[1], 9.0))


@pytest.mark.slow  # a whole fleet run of the planner (5 CPU s)
def test_a_fleet_on_open_ground_reaches_the_disc_of_its_chain() -> None:
    grid = np.full((100, 100), FREE, dtype=np.int8)
    grid[[0, -1], :] = grid[:, [0, -1]] = OCCUPIED
    base = (50, 50)
    config = MhmConfig(r_comm=10.0, sensor_range=4.0, cluster_max=8, patience=40)
    out = simulate(grid, base, 4, config, keep_belief=True, max_ticks=5000)
    assert out.done and worst(out.connected) == 1.0
    assert out.planner.events[-1][1].startswith("stop: frontier")  # step 10: the closest frontier is too far
    disc = math.pi * (3 * 10.0 + 4.0) ** 2  # of a chain of 4 robots: pi ((n - 1) r_comm + r_sense)^2
    assert out.seen[-1] >= 0.9 * disc  # a chain along a 4-connected path reached 0.81 of it
    seen = np.argwhere(out.belief >= 0)  # type: ignore[operator]
    assert seen.min() > 5 and seen.max() < 94  # the map did not bound it
