"""Yan's regions (``agents/regions.py``): the segmentation on drawn maps, the region tasks, trade keeping a region
task while its frontier moves away from the entry, and small fleets on regions (memory engine)."""

from __future__ import annotations

import numpy as np
import pytest

from fleet_emu.agents.allocators import Problem
from fleet_emu.agents.allocators.trade import Trade, TradeDone
from fleet_emu.agents.frontiers import find_clusters
from fleet_emu.agents.regions import RegionTasks, holding, region_tasks, segment
from fleet_emu.core.grid import FREE, from_ascii
from tests.harness.lockstep import run_fleet

TWO_ROOMS = """
#############
#.....#.....#
#.....#.....#
#...........#
#.....#.....#
#.....#.....#
#############
"""

# Three rooms off a three-cell corridor, each by a one-cell door.
CORRIDOR = """
###################
#.....#.....#.....#
#.....#.....#.....#
#.....#.....#.....#
#.....#.....#.....#
###.#####.#####.###
#.................#
#.................#
#.................#
###################
"""

# Rooms whose one-cell doors open onto a one-cell hallway: no door is narrower than the hallway.
HALLWAY = """
#############
#...#...#...#
#...#...#...#
#...#...#...#
##.###.###.##
#...........#
#############
"""

PLAIN = """
##############
#............#
#............#
#............#
##############
"""

# The right room seen through the door: its known part holds the only frontier.
SEEN = """
#################
#.....#..????????
#.....#..????????
#.0.........?????
#.....#..????????
#.....#..????????
#################
"""


def _free_labelled(grid: np.ndarray, labels: np.ndarray) -> bool:
    return bool((labels[grid == FREE] > 0).all())


def test_two_rooms_split_at_the_door() -> None:
    grid, _ = from_ascii(TWO_ROOMS)
    regions = segment(grid)
    assert regions.count == 2
    assert regions.labels[3, 2] != regions.labels[3, 10]
    assert (regions.labels[1:6, 1:6] == regions.labels[3, 2]).all()  # each room whole
    assert (regions.labels[1:6, 7:12] == regions.labels[3, 10]).all()
    assert any(abs(r - 3) + abs(c - 6) <= 1 for r, c in regions.critical.tolist())  # at the door
    assert _free_labelled(grid, regions.labels)


def test_a_corridor_with_rooms_off_it() -> None:
    grid, _ = from_ascii(CORRIDOR)
    labels = segment(grid).labels
    rooms = {int(labels[2, c]) for c in (3, 9, 15)}
    corridor = set(labels[6:9, 1:18].ravel().tolist())
    assert len(rooms) == 3 and len(corridor) == 1 and not rooms & corridor
    assert _free_labelled(grid, labels)


def test_doors_onto_a_hallway_as_narrow_as_them_split_the_rooms_off() -> None:
    grid, _ = from_ascii(HALLWAY)
    labels = segment(grid).labels
    rooms = {int(labels[2, c]) for c in (2, 6, 10)}
    assert len(rooms) == 3 and int(labels[5, 6]) not in rooms
    assert _free_labelled(grid, labels)


def test_a_corridor_of_even_width_is_one_region() -> None:
    grid, _ = from_ascii(PLAIN)
    regions = segment(grid)
    assert regions.count == 1 and len(regions.critical) == 0


def test_a_region_with_frontier_is_a_task_entered_at_its_door() -> None:
    grid, _ = from_ascii(SEEN)
    regions = segment(grid)
    tasks = region_tasks(grid, regions)
    assert len(tasks) == 1  # the left room is explored: no task
    (task,) = tasks
    cols = grid.shape[1]
    assert set(np.divmod(task.cells, cols)[1].tolist()) <= {7, 8, 9, 10, 11}  # its frontier cells, right side
    assert abs(task.target[0] - 3) + abs(task.target[1] - 6) <= 1  # the entry: the door
    assert holding(list(tasks), (3, 8), cols) == 0 and holding(list(tasks), (3, 2), cols) is None


def test_a_belief_is_segmented_once() -> None:
    grid, _ = from_ascii(SEEN)
    cache = RegionTasks()
    first = cache.of(grid)
    assert cache.of(grid.copy()) is first and cache.segmentations == 1
    grid[3, 12] = FREE
    cache.of(grid)
    assert cache.segmentations == 2


def _reveal(grid: np.ndarray, upto: int) -> np.ndarray:
    """SEEN with the right room known up to column ``upto`` (walls drawn where the room has them)."""
    out = grid.copy()
    out[1:6, 7:upto + 1] = FREE
    out[0, 7:upto + 1] = out[6, 7:upto + 1] = 100
    return out


def test_trade_keeps_a_region_while_its_frontier_moves_off_the_entry() -> None:
    """Frontier tasks end once no frontier is within ``task_radius`` of the task's cell; a region task lasts
    while its region has a frontier, however far from the door it has moved."""
    grid, robots = from_ascii(SEEN)
    far = _reveal(grid, 14)  # the frontier now at column 14, 8 cells from the door
    outcomes = {}
    for tasks in ("frontiers", "regions"):
        trade = Trade(tasks=tasks, task_radius=3)
        trade.reset(np.random.default_rng(0))
        tick = 0
        while trade.s.phase.name != "TASK" and tick < 20:
            trade.allocate(Problem(me="r0", poses=robots, belief=grid, clusters=find_clusters(grid, 6),
                                           tick=tick))
            tick += 1
        assert trade.s.phase.name == "TASK", tasks
        later = Problem(me="r0", poses=robots, belief=far, clusters=find_clusters(far, 6), tick=tick)
        alloc = trade.allocate(later)
        outcomes[tasks] = any(isinstance(m.body, TradeDone) for m in alloc.outbox)
    assert outcomes == {"frontiers": True, "regions": False}


@pytest.mark.parametrize("allocator", ["trade", "hungarian"])
def test_a_fleet_on_regions_explores_everything(allocator: str) -> None:
    trace = run_fleet(CORRIDOR.replace("#.....#.....#.....#\n###", "#.0...#.....#..1..#\n###", 1),
                      {"type": allocator, "tasks": "regions"}, sensor_range=3.0, max_ticks=400)
    assert trace.reason == "coverage", (trace.reason, trace.coverage)
    assert trace.result["allocator_params"]["tasks"] == "regions"
