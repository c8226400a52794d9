"""Frontier detection, clustering, the wavefront from clusters, and gradient navigation, on drawn grids."""

from __future__ import annotations

import itertools

import numpy as np

from fleet_emu.agents.frontiers import find_clusters, frontier_mask
from fleet_emu.agents.navigation import STAY, next_move
from fleet_emu.core.grid import FREE, flat, from_ascii
from fleet_emu.core.kernels import wavefront


def test_frontier_cells_are_free_cells_next_to_unknown() -> None:
    grid, _ = from_ascii("""
    #####
    #...?
    #.#.?
    #...#
    """)
    mask = frontier_mask(grid)
    assert np.argwhere(mask).tolist() == [[1, 3], [2, 3]]


def test_clusters_are_contiguous_groups_split_to_the_sensing_size() -> None:
    grid, _ = from_ascii("""
    ??????????????
    ..............
    ..............
    #############?
    ............??
    """)
    clusters = find_clusters(grid, cluster_max=5)
    sizes = [c.size for c in clusters]
    # the top row (14 cells) splits into 5 + 5 + 4; the right pocket (cells at rows 2-4) is a separate group
    assert sum(sizes) == int(frontier_mask(grid).sum())
    assert max(sizes) <= 5 and len(clusters) == 4
    cols = grid.shape[1]
    for c in clusters:
        assert grid[c.target] == FREE and flat(grid.shape, c.target) in set(c.cells.tolist())
        rows = c.cells // cols
        assert rows.max() - rows.min() <= 2  # contiguous pieces, not scattered cells
    assert find_clusters(grid, 5)[0].cells.tolist() == clusters[0].cells.tolist()  # deterministic
    assert [int(c.cells[0]) for c in clusters] == sorted(int(c.cells[0]) for c in clusters)


def test_no_frontier_in_a_closed_known_room() -> None:
    grid, _ = from_ascii("""
    #####
    #...#
    #####
    """)
    assert find_clusters(grid, 8) == []


def test_wavefront_from_a_cluster_and_descent_reaches_it() -> None:
    grid, robots = from_ascii("""
    #########
    #0..#...?
    #.#.#.#.?
    #.#...#.?
    #########
    """)
    (cluster,) = find_clusters(grid, 8)
    dist = wavefront(grid == FREE, cluster.cells, -1)
    cell = robots["r0"]
    assert dist[cell] == 10  # around the wall: right 2, down 2, right 2, up 2, right 1, then to the column
    path = [cell]
    for _ in range(20):
        move = next_move(dist, cell)
        if move == STAY:
            break
        cell = (cell[0] + move[0], cell[1] + move[1])
        path.append(cell)
    assert dist[cell] == 0 and len(path) == 11
    assert all(dist[b] == dist[a] - 1 for a, b in itertools.pairwise(path))


def test_navigation_sidesteps_a_teammate_and_waits_when_boxed() -> None:
    grid, robots = from_ascii("""
    ?....
    .....
    ...0.
    """)
    (cluster,) = find_clusters(grid, 8)
    dist = wavefront(grid == FREE, cluster.cells, -1)
    me = robots["r0"]
    free_move = next_move(dist, me)
    assert free_move == (-1, 0)  # up, first in MOVES order among equal descents
    assert next_move(dist, me, {(1, 3)}) == (0, -1)  # the teammate above: go left instead
    assert next_move(dist, me, {(1, 3), (2, 2)}) == STAY


def test_the_one_wavefront_navigation_uses_steps_as_the_full_one() -> None:
    """``Problem.wavefront_to`` (the assigned cluster's wavefront, stopped at the robot) gives the same move as
    the full wavefront, from every free cell, toward every cluster, with and without a teammate in the way."""
    from fleet_emu.agents.allocators import Problem

    grid, _ = from_ascii("""
    ##########?
    #....#....?
    #.##.#.##.#
    #.#..?..#.#
    #.#.####..?
    #...#.....#
    ####?######
    """)
    clusters = find_clusters(grid, 3)
    assert len(clusters) >= 3
    full = Problem(me="r0", poses={"r0": (1, 1)}, belief=grid, clusters=clusters).wavefronts
    for cell in map(tuple, np.argwhere(grid == FREE).tolist()):
        for j in range(len(clusters)):
            one = Problem(me="r0", poses={"r0": cell}, belief=grid, clusters=clusters).wavefront_to(j, cell)
            assert one[cell] == full[j][cell]
            for blocked in (set(), {(cell[0] - 1, cell[1])}, {(cell[0], cell[1] + 1)}):
                assert next_move(one, cell, blocked) == next_move(full[j], cell, blocked)
