"""The first-seen fold, and that the Foxglove coverage grid and the report's metrics share it."""

from __future__ import annotations

import numpy as np

from fleet_emu.core.grid import from_ascii
from fleet_emu.core.messages import Observation, WorldState
from fleet_emu.recording.first_seen import FirstSeen
from fleet_emu.recording.foxglove import TOPIC_COVERAGE, FoxgloveFold, decode_grid
from fleet_emu.recording.metrics import RunMetrics

ART = """
#######
#.....#
#.#...#
#.....#
#######
"""


def test_earliest_tick_wins_whatever_the_order() -> None:
    fs = FirstSeen((2, 3))
    fs.observe(5, np.array([0, 1]), np.array([0, 100]))
    fs.observe(2, np.array([1, 2]), np.array([0, 0]))  # an earlier tick, fed later
    fs.observe(7, np.array([0, 2]), np.array([0, 0]))  # seen again later: the first ticks stay
    assert fs.tick.tolist() == [5, 2, 2, -1, -1, -1]
    assert fs.value.tolist() == [0, 0, 0, -1, -1, -1]  # the value last sensed
    assert fs.grid(1).tolist() == [[-1, -1, -1], [-1, -1, -1]]
    assert fs.grid(2).tolist() == [[-1, 0, 0], [-1, -1, -1]]
    assert fs.grid(9).tolist() == [[0, 0, 0], [-1, -1, -1]]
    assert fs.grid(9).dtype == np.int8


def test_foxglove_and_metrics_fold_the_same_observations_alike() -> None:
    truth, _ = from_ascii(ART)
    scenario = {"robots": 2, "cell_size": 0.5, "map": "art", "seed": 0, "allocator": {"type": "minpos"},
                "radio": {"loss": 0.0, "comm": "wall"}, "target_coverage": 0.99}
    fox = FoxgloveFold(scenario, truth, grid_every=1)
    met = RunMetrics(scenario, "t")
    seen = [("r0", 1, [8, 9, 15]), ("r1", 0, [26, 19, 9]), ("r0", 0, [10]), ("r1", 2, [8, 11])]
    for robot, tick, cells in seen:
        c = np.array(cells, np.int32)
        o = Observation(src="world", tick=tick, seq=0, robot=robot, cell=(1, 1), shape=truth.shape, cell_size=0.5,
                        cells=c, values=truth.ravel()[c].astype(np.int8))
        fox.fold(o)
        met.feed(f"fleet/t/world/obs/{robot}", o.encode())
    assert isinstance(fox.coverage, FirstSeen) and isinstance(met.team, FirstSeen)
    assert (fox.coverage.tick == met.team.tick).all() and (fox.coverage.value == met.team.value).all()
    per_robot = np.stack([met.first_seen[r].tick for r in ("r0", "r1")])
    earliest = np.where(per_robot >= 0, per_robot, np.iinfo(np.int32).max).min(axis=0)
    assert (met.team.tick == np.where(earliest == np.iinfo(np.int32).max, -1, earliest)).all()
    assert met.first_seen["r0"].tick[9] == 1 and met.first_seen["r1"].tick[9] == 0 and met.team.tick[9] == 0
    out = fox.fold(WorldState(src="world", tick=0, seq=0, poses={"r0": (1, 1), "r1": (3, 5)}, live=("r0", "r1"),
                              coverage=0.1, path_length={}))
    out += fox.finish()
    grids = [d for d in out if d.topic == TOPIC_COVERAGE]
    assert len(grids) == 1 and (decode_grid(grids[0].obj()) == met.team.grid(0)).all()
    assert (met.team.grid(0) >= 0).sum() == 4  # 26, 19, 9 (r1) and 10 (r0) at tick 0
