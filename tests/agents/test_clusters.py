"""Incremental frontier clustering equals ``find_clusters`` on the whole grid: the same
clusters, in the same order, with the same cells and targets, after every belief update of many random
sequences on drawn and generated maps (numpy generators with fixed seeds)."""

from __future__ import annotations

import numpy as np
import pytest

from fleet_emu.agents.clusters import FrontierClusters
from fleet_emu.agents.frontiers import Cluster, find_clusters
from fleet_emu.core.grid import FREE, OCCUPIED, UNKNOWN, from_ascii
from fleet_emu.core.kernels import visible_cells
from fleet_emu.world.maps import load_map

VALUES = np.array([UNKNOWN, FREE, OCCUPIED], dtype=np.int8)


def as_lists(clusters: list[Cluster]) -> list[tuple[list[int], tuple[int, int]]]:
    return [(c.cells.tolist(), c.target) for c in clusters]


def same(fc: FrontierClusters, grid: np.ndarray, changed: np.ndarray) -> list[Cluster]:
    got = fc.update(grid, changed)
    want = find_clusters(grid, fc.cluster_max)
    assert as_lists(got) == as_lists(want)
    assert all(c.cells.dtype == np.int64 for c in got)
    return got


def write(grid: np.ndarray, cells: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Write values (later ones win, as ``Belief.merge``); the cells whose value changed."""
    flat = grid.reshape(-1)
    changed = cells[flat[cells] != values]
    flat[cells] = values
    return changed


def test_a_group_splits_and_two_groups_merge() -> None:
    truth, _ = from_ascii("""
    ..........
    ..........
    ####.#####
    ..........
    ??????????
    """)
    grid = np.full(truth.shape, UNKNOWN, dtype=np.int8)
    fc = FrontierClusters(grid.shape, cluster_max=4)

    def learn(cells: np.ndarray) -> list[Cluster]:
        return same(fc, grid, write(grid, cells, truth.reshape(-1)[cells]))

    # the top two rows known: one group of 10 frontier cells (row 1), split 4 + 4 + 2 along its walk
    assert [c.size for c in learn(np.arange(20))] == [4, 4, 2]
    # the wall row known but its door: the cell above the door stays a frontier, the rest of row 1 not
    assert [c.cells.tolist() for c in learn(np.array([20, 21, 22, 23, 25, 26, 27, 28, 29]))] == [[14]]
    # the bottom row's two ends (unknown below them): two more groups
    assert [c.cells.tolist() for c in learn(np.array([30, 31, 38, 39]))] == [[14], [30, 31], [38, 39]]
    assert [c.cells.tolist() for c in learn(np.array([24]))] == [[24], [30, 31], [38, 39]]
    # the rest of the bottom row: the two groups merge with the new cells into one of 10, split again
    merged = learn(np.arange(32, 38))
    assert [c.cells.tolist() for c in merged] == [[30, 31, 32, 33], [34, 35, 36, 37], [38, 39]]


def test_a_cluster_away_from_the_change_is_kept_as_it_was() -> None:
    grid, _ = from_ascii("""
    ..??#??..
    ..??#??..
    ....#....
    """)
    fc = FrontierClusters(grid.shape, cluster_max=8)
    before = same(fc, grid, np.arange(grid.size))
    after = same(fc, grid, write(grid, np.array([5]), np.array([FREE], dtype=np.int8)))
    assert after[0] is before[0] and after[1] is not before[1]
    assert fc.update(grid, np.zeros(0, dtype=np.int64)) is after  # nothing changed: the same list


@pytest.mark.parametrize("seed", [0, 1, *(pytest.param(s, marks=pytest.mark.slow) for s in range(2, 6))])  # more draws
@pytest.mark.parametrize("cluster_max", [2, 5, 16])
def test_random_updates_on_a_random_grid(seed: int, cluster_max: int) -> None:
    """Random cells set to random values (unknown again included), from a few cells to whole blocks."""
    rng = np.random.default_rng(seed)
    shape = (int(rng.integers(5, 30)), int(rng.integers(5, 30)))
    truth = np.where(rng.random(shape) < rng.uniform(0.05, 0.4), OCCUPIED, FREE).astype(np.int8)
    grid = np.full(shape, UNKNOWN, dtype=np.int8)
    fc = FrontierClusters(shape, cluster_max)
    for _ in range(150):
        if rng.random() < 0.3:  # a block, as a sensed disc or a map delta
            r, c = int(rng.integers(shape[0])), int(rng.integers(shape[1]))
            h, w = int(rng.integers(1, 12)), int(rng.integers(1, 12))
            rr, cc = np.mgrid[r:min(r + h, shape[0]), c:min(c + w, shape[1])]
            cells = (rr * shape[1] + cc).ravel()
        else:
            cells = rng.integers(0, grid.size, int(rng.integers(1, 30)))
        wrong = rng.random() < 0.2  # values from nowhere (unknown again among them), not the map's
        values = VALUES[rng.integers(0, 3, len(cells))] if wrong else truth.reshape(-1)[cells]
        changed = write(grid, cells, values)
        if rng.random() < 0.2:  # unchanged cells and repeats among the changed ones are harmless
            changed = np.concatenate([changed, changed, rng.integers(0, grid.size, 3)])
        same(fc, grid, changed)


@pytest.mark.parametrize(("name", "cell_size", "seed"), [("office", 0.5, 0), ("maze", 0.25, 1), ("hall", 0.5, 2),
                                                         ("grid", 0.5, 3)])
def test_robots_exploring_a_generated_map(name: str, cell_size: float, seed: int) -> None:
    """Sensed discs (``visible_cells``, as the world senses) along random walks of a few robots that now and then
    jump to a far cell (as a teammate's map delta reveals a far area): groups grow, merge and split."""
    truth = load_map(name, cell_size, seed)
    occupied = truth.grid > 0
    rng = np.random.default_rng(seed)
    free = np.flatnonzero(truth.grid.reshape(-1) == FREE)
    grid = np.full(truth.grid.shape, UNKNOWN, dtype=np.int8)
    fc = FrontierClusters(grid.shape, cluster_max=int(rng.integers(4, 20)))
    cols = grid.shape[1]
    robots = [divmod(int(c), cols) for c in rng.choice(free, 3)]
    largest = 0
    for _ in range(120):
        changed = []
        for k, (r, c) in enumerate(robots):
            seen = visible_cells(occupied, r, c, float(rng.uniform(2, 8)))
            changed.append(write(grid, seen, truth.grid.reshape(-1)[seen]))
            moves = [(r + dr, c + dc) for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1))
                     if 0 <= r + dr < grid.shape[0] and 0 <= c + dc < cols and not occupied[r + dr, c + dc]]
            if moves:
                robots[k] = moves[int(rng.integers(len(moves)))]
        if rng.random() < 0.1:  # a jump to a far cell (as a teammate's delta reveals a far area)
            robots[int(rng.integers(3))] = divmod(int(rng.choice(free)), cols)
        same(fc, grid, np.concatenate(changed))
        largest = max(largest, max((len(g) for g in fc.groups.values()), default=0))
    assert largest > fc.cluster_max  # large groups were split


def test_the_compiled_target_is_the_numpy_one_bit_for_bit() -> None:
    """``core.cluster_kernels.target`` against ``frontiers._target`` on random sorted pieces, large ones and
    ties (symmetric pieces) among them."""
    from fleet_emu.agents.frontiers import _target
    from fleet_emu.core.cluster_kernels import target

    rng = np.random.default_rng(7)
    cols = 512
    pieces = [np.unique(rng.integers(0, cols * cols, int(rng.integers(1, 5000)))) for _ in range(200)]
    pieces += [np.array([0, 2, 2 * cols, 2 * cols + 2], dtype=np.int64), np.array([5, 7], dtype=np.int64)]
    for p in pieces:
        assert tuple(int(v) for v in target(p.astype(np.int64), cols)) == _target(p, cols)
