"""The world simulation on drawn maps: start placement, sensing, motion conflicts, coverage and the end."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from fleet_emu.core.grid import FREE, OCCUPIED, flat, from_ascii, nearest_cells
from fleet_emu.world.maps import MapData
from fleet_emu.world.sim import STALL_DIAMETERS, StartAreaError, World, WorldConfig

ROOMS = """
###########
#....#....#
#.........#
#....#....#
###########
"""


def _world(art: str, robots: int, **cfg: object) -> World:
    grid, marks = from_ascii(art)
    start = marks.get("r0", (2, 2))
    md = MapData(name="test", grid=grid, cell_size=0.5, start=start)
    return World(md, [f"r{i}" for i in range(robots)], WorldConfig(**cfg))  # type: ignore[arg-type]


def test_start_placement_is_deterministic_and_around_the_start() -> None:
    w = _world(ROOMS, 3, sensor_range=2.0)
    w.reset()
    assert w.poses == {"r0": (2, 2), "r1": (1, 2), "r2": (2, 1)}  # BFS distance, then row-major
    assert len(set(w.poses.values())) == 3
    with pytest.raises(StartAreaError, match="26 robots do not fit the free area reachable from the start cell "
                                             r"\(2, 2\) of map 'test': it has 25 free cells"):
        _world(ROOMS, 26).reset()


def test_nearest_cells_is_the_wavefronts_order() -> None:
    """``nearest_cells`` (numpy, so that a launcher's check loads no kernel) against the compiled wavefront's BFS
    distances, ordered by distance then row-major: every count and radius, on random grids with cells that are
    passable but not free (unknown), from free and from unknown sources."""
    from fleet_emu.core.kernels import wavefront

    rng = np.random.default_rng(7)
    for trial in range(60):
        shape = (int(rng.integers(1, 30)), int(rng.integers(1, 30)))
        passable = rng.random(shape) > rng.uniform(0.0, 0.6)
        free = passable & (rng.random(shape) > 0.1)
        source = int(rng.integers(passable.size))
        passable.ravel()[source] = True
        dist = wavefront(passable, np.array([source], np.int64), -1).ravel()
        for n, radius in ((None, None), (1, None), (int(rng.integers(1, 40)), None), (None, int(rng.integers(0, 9))),
                          (int(rng.integers(1, 40)), int(rng.integers(0, 9)))):
            area = np.flatnonzero((dist >= 0) & free.ravel() & (dist <= (radius if radius is not None else dist.max())))
            want = area[np.lexsort((area, dist[area]))][:n]
            got = nearest_cells(passable, free, source, n, radius)
            assert got.tolist() == want.tolist(), (trial, n, radius)


_ROW = "#" + "." * 14 + "#"
OPEN = "\n".join(["#" * 16, *[_ROW] * 7, "#" + "." * 7 + "0" + "." * 6 + "#", *[_ROW] * 6, "#" * 16])
"""A 14 x 14 room, the start cell (``0``) in its middle."""


def test_the_start_area_grows_with_the_fleet_and_keeps_the_placement_of_smaller_fleets() -> None:
    """41 robots fill the diamond of 4 steps around the start (the old fixed start area); a fleet of 150 takes
    the nearest free cells beyond it, and its first 41 robots stand where the 41 did."""
    small, large = _world(OPEN, 41), _world(OPEN, 150)
    small.reset()
    large.reset()
    start = small.start
    steps = {r: abs(c[0] - start[0]) + abs(c[1] - start[1]) for r, c in large.poses.items()}
    assert max(abs(c[0] - start[0]) + abs(c[1] - start[1]) for c in small.poses.values()) == 4
    assert all(large.poses[r] == small.poses[r] for r in small.poses)
    assert len(set(large.poses.values())) == 150 and max(steps.values()) > 4
    placed = set(large.poses.values())
    free_left = [c for c in zip(*np.nonzero(large.grid == FREE), strict=True) if tuple(map(int, c)) not in placed]
    nearest_left = min(abs(int(c[0]) - start[0]) + abs(int(c[1]) - start[1]) for c in free_left)
    assert max(steps.values()) <= nearest_left  # nearest first: no free cell left nearer than a placed one
    with pytest.raises(StartAreaError, match=r"197 robots do not fit .* it has 196 free cells"):
        _world(OPEN, 197).reset()


def test_a_random_start_holds_a_large_fleet_within_a_grown_radius() -> None:
    """A random start for 60 robots (more than the 41 cells of a 4-step diamond) is a cell with the whole fleet
    within 5 steps (61 cells), the least radius whose diamond holds it."""
    w = _world(OPEN, 60, start="random")
    w.reset()
    start = w.start
    assert max(abs(c[0] - start[0]) + abs(c[1] - start[1]) for c in w.poses.values()) <= 5


def test_explicit_start_cells_place_each_robot_and_are_checked() -> None:
    w = _world(ROOMS, 3, placement=((1, 8), (3, 1), (2, 5)))
    w.reset()
    assert w.poses == {"r0": (1, 8), "r1": (3, 1), "r2": (2, 5)} and w.start == (1, 8)
    for cells, match in [(((1, 8), (3, 1)), "2 start cells given for 3 robots"),
                         (((1, 8), (1, 8), (2, 5)), "the same start cell"),
                         (((1, 8), (0, 0), (2, 5)), r"start cell \(0, 0\) is not a free cell")]:
        with pytest.raises(StartAreaError, match=match):
            _world(ROOMS, 3, placement=cells).reset()


def test_sensing_returns_true_values_and_stops_at_walls() -> None:
    w = _world(ROOMS, 1, sensor_range=4.0)
    rd = w.reset()["r0"]
    assert rd.cell == (2, 2)
    assert np.array_equal(rd.values, w.grid.ravel()[rd.cells])
    seen = set(rd.cells.tolist())
    assert flat(w.shape, (1, 5)) in seen  # the wall between the rooms is seen
    assert flat(w.shape, (1, 7)) not in seen  # the room behind it is not (from (2,2) the wall hides it)
    assert 0 < w.coverage < 1


def test_sensed_cells_count_walls_too_and_only_grow() -> None:
    """``sensed_cells`` (Mukhija et al. Fig. 7's "total visibility") counts every cell a sensor returned,
    occupied ones included, once, while ``coverage`` counts free reachable cells only."""
    w = _world(ROOMS, 1, sensor_range=4.0)
    assert w.sensed_cells == 0
    first = w.reset()["r0"]
    assert w.sensed_cells == len(first.cells) and (first.values == OCCUPIED).any()
    before = w.sensed_cells
    second = w.step({"r0": (0, 1)})["r0"]  # one step east: most cells seen again
    assert w.sensed_cells == len(set(first.cells.tolist()) | set(second.cells.tolist())) > before


def test_moves_respect_walls_and_other_robots() -> None:
    w = _world("""
    #######
    #0....#
    #######
    """, 2)
    w.reset()
    assert w.poses == {"r0": (1, 1), "r1": (1, 2)}
    w.step({"r0": (-1, 0), "r1": (0, -1)})  # into a wall; into r0's cell
    assert w.poses == {"r0": (1, 1), "r1": (1, 2)} and w.path_length == {"r0": 0, "r1": 0}
    w.step({"r0": (0, 1), "r1": (0, 1)})  # a line advances together (r0 follows r1 in the same tick)
    assert w.poses == {"r0": (1, 2), "r1": (1, 3)} and w.path_length == {"r0": 1, "r1": 1}
    w.step({"r0": (0, 1), "r1": (0, -1)})  # a swap never happens
    assert w.poses == {"r0": (1, 2), "r1": (1, 3)}
    assert w.tick == 3


def test_two_robots_into_one_cell_lowest_id_wins() -> None:
    w = _world("""
    #####
    #...#
    #.0.#
    #...#
    #####
    """, 3)
    w.reset()
    # r0 at (2,2); r1 at (1,2); r2 at (2,1). Both r1 and r2 aim at (1,1).
    w.step({"r2": (-1, 0), "r1": (0, -1)})  # the order commands arrived in does not matter
    assert w.poses["r1"] == (1, 1) and w.poses["r2"] == (2, 1)


def test_coverage_counts_reachable_free_cells_and_the_run_ends() -> None:
    art = """
    #########
    #0......#
    #########
    #.......#
    #########
    """
    w = _world(art, 1, sensor_range=1.0, max_ticks=100, target_coverage=1.0)
    w.reset()
    reachable = 7  # the lower corridor is walled off: it does not count
    for _ in range(6):
        w.step({"r0": (0, 1)})
    assert w.coverage == pytest.approx(1.0) and w.done and w.reason == "coverage"
    assert w._total == reachable
    assert (w.grid == FREE).sum() == 14 and (w.grid == OCCUPIED).any()


def test_tick_limit_stall_and_failure_end_the_run() -> None:
    w = _world(ROOMS, 1, sensor_range=1.0, max_ticks=3, stall_ticks=100)
    w.reset()
    for _ in range(3):
        w.step({"r0": (0, 1)})
    assert w.done and w.reason == "max_ticks"
    s = _world(ROOMS, 1, sensor_range=1.0, stall_ticks=4)
    s.reset()
    for _ in range(4):
        s.step({})
    assert s.done and s.reason == "stall"
    f = _world(ROOMS, 2, sensor_range=1.0)
    f.reset()
    f.fail("r1")
    assert f.live == ["r0"] and not f.done
    f.fail("r0")
    assert f.done and f.reason == "no_robots"


def test_the_stall_window_is_twice_the_maps_diameter_or_the_scenarios_floor() -> None:
    w = _world(ROOMS, 1, sensor_range=1.0)
    w.reset()
    assert w.diameter == 10  # (1, 1) to (3, 9) round the wall: 1 + 8 + 1 steps
    assert w.stall_window == 500  # the default floor, coverage_stall_ticks
    w = _world(ROOMS, 1, sensor_range=1.0, coverage_stall_ticks=6)
    w.reset()
    assert w.stall_window == STALL_DIAMETERS * 10 == 20


def _pacing(window: int, ticks: int, known: Callable[[int], dict[str, int]] | None = None
            ) -> tuple[World, list[tuple[int, float, bool, str | None]]]:
    """A robot stepping right and left for ``ticks`` ticks; ``known(t)``: its belief's known cells sent at t."""
    pace = [(0, 1), (0, -1)]
    w = _world(ROOMS, 1, sensor_range=1.0, coverage_stall_ticks=window, max_ticks=50)
    w.reset()
    out = [(0, w.coverage, w.done, w.reason)]
    for t in range(ticks):
        w.step({"r0": pace[t % 2]}, known(t) if known else None)
        out.append((w.tick, w.coverage, w.done, w.reason))
        if w.done:
            break
    return w, out


def test_a_robot_pacing_without_learning_stalls_after_the_window() -> None:
    """The belief rule ends a run whose robots keep moving but learn nothing new (the move rule cannot); a World
    stepped without the robots' counts reads what the fleet sensed instead."""
    w, trace = _pacing(window=6, ticks=50)
    grew = max(t for (t, c, _, _), (_, c0, _, _) in zip(trace[1:], trace, strict=False) if c > c0)
    assert grew == 1  # the first step sensed a new column; the pacing after it senses nothing
    tick, _, done, reason = trace[-1]
    assert (tick, done, reason) == (grew + w.stall_window, True, "stall") and w.stall_window == 20
    assert not any(d for _, _, d, _ in trace[:-1])
    w, trace = _pacing(window=6, ticks=50, known=lambda t: {"r0": 12})  # its belief never grows after tick 0
    assert trace[-1][0] == 1 + w.stall_window and trace[-1][2:] == (True, "stall")
    long = _pacing(window=1000, ticks=50)[1]  # with a window past the tick limit the moves keep the run going
    assert long[-1][2:] == (True, "max_ticks") and long[-1][0] == 50


def test_a_robot_whose_belief_grows_is_no_stall_though_the_fleet_senses_nothing_new() -> None:
    """Its teammates' maps reach it (its own belief grows) while nothing new is sensed: that is progress."""
    _, trace = _pacing(window=6, ticks=50, known=lambda t: {"r0": 12 + t})
    assert trace[-1][2:] == (True, "max_ticks") and trace[-1][0] == 50
    _, trace = _pacing(window=6, ticks=50, known=lambda t: {"r0": 12 + (t >= 10)})  # learns once more
    assert trace[-1][2:] == (True, "stall") and trace[-1][0] == 11 + 20  # the window counts from tick 11


def test_random_start_comes_from_the_generator_and_fits_the_fleet() -> None:
    grid, _ = from_ascii(ROOMS)
    md = MapData(name="test", grid=grid, cell_size=0.5, start=(2, 2))

    def start(seed: int) -> tuple[int, int]:
        w = World(md, ["r0", "r1", "r2"], WorldConfig(start="random"), np.random.default_rng(seed))
        w.reset()
        assert w.grid[w.start] == FREE and len(set(w.poses.values())) == 3
        return w.start

    draws = {start(s) for s in range(8)}
    assert start(3) == start(3) and len(draws) > 2  # the seed decides, and it does vary


def test_a_robot_lost_before_the_first_tick_neither_senses_nor_acts() -> None:
    w = _world(ROOMS, 2, sensor_range=2.0)
    readings = w.reset(failed={"r1"})
    assert list(readings) == ["r0"] and w.live == ["r0"]
    w.step({"r0": (0, -1), "r1": (0, 1)})
    assert w.poses["r1"] == (1, 2) and w.path_length["r1"] == 0  # its body stays where it was placed
