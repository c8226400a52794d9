"""The ROS 2 fold on hand-made bus messages: frames and the grid's row order, goals only when they change,
paths and coverage every ``grid_every`` ticks, the radio links coloured by strength."""

from __future__ import annotations

import msgspec
import numpy as np
import pytest

pytest.importorskip("rosbags")

from fleet_emu.core.messages import BeliefSnapshot, Command, Links, WorldState
from fleet_emu.recording.clock import RunClock
from fleet_emu.ros2.fold import Ros2Fold
from fleet_emu.ros2.types import GRID, cdr, decode

SCENARIO = {"robots": 2, "cell_size": 0.5, "belief_every": 5, "radio": {"threshold": -90.0}}
TRUTH = np.array([[100, 0, 0], [0, 0, -1]], dtype=np.int8)  # 2 rows x 3 columns


def _state(t: int, poses: dict[str, tuple[int, int]]) -> WorldState:
    return WorldState(src="world", tick=t, seq=t, poses=poses, live=("r0", "r1"), coverage=0.5,
                      path_length={r: t for r in poses})


def _fold() -> Ros2Fold:
    return Ros2Fold(SCENARIO, TRUTH, grid_every=2, clock=RunClock(10**9, 0.5))


def test_frames_stamps_and_the_grid_rows() -> None:
    fold = _fold()
    out = {o.topic: o for o in fold.fold(_state(0, {"r0": (0, 0), "r1": (1, 2)}))}
    assert set(out) >= {"/clock", "/tf", "/map", "/r0/pose", "/r1/pose", "/r0/path"}
    pose = out["/r0/pose"].msg.pose.position
    assert (pose.x, pose.y) == (0.25, 0.75)  # row 0 is the top: y up
    grid = decode(cdr(out["/map"].msg, GRID), GRID)  # through CDR and back
    assert (grid.info.width, grid.info.height, grid.info.resolution) == (3, 2, 0.5)
    rows = np.asarray(grid.data).reshape(2, 3)
    assert rows[1, 0] == 100 and rows[0, 2] == -1  # the top row last: the grid's rows go up
    assert out["/map"].latched and not out["/r0/pose"].latched
    tf = out["/tf"].msg.transforms
    assert [t.child_frame_id for t in tf] == ["r0/base_link", "r1/base_link"] and tf[0].header.frame_id == "map"
    stamp = out["/clock"].msg.clock
    assert (stamp.sec, stamp.nanosec) == (1, 0)
    later = {o.topic: o for o in fold.fold(_state(3, {"r0": (0, 1), "r1": (1, 2)}))}
    assert "/map" not in later and "/r0/path" not in later  # the true map once; paths every 2 ticks
    assert (later["/clock"].msg.clock.sec, later["/clock"].msg.clock.nanosec) == (2, 500_000_000)
    (path,) = [o for o in fold.finish() if o.topic == "/r0/path"]
    assert [p.pose.position.x for p in path.msg.poses] == [0.25, 0.75]


def test_goals_only_when_they_change_and_beliefs_as_they_come() -> None:
    fold = _fold()
    cmd = {"src": "r0", "seq": 0, "move": (0, 0)}
    assert len(fold.fold(Command(tick=0, target=(1, 1), **cmd))) == 1
    assert fold.fold(Command(tick=1, target=(1, 1), **cmd)) == []
    (goal,) = fold.fold(Command(tick=2, target=(0, 2), **cmd))
    assert goal.topic == "/r0/goal" and goal.msg.pose.position.x == 1.25
    belief = np.full((2, 3), -1, dtype=np.int8)
    belief[0, 0] = 0
    (o,) = fold.fold(BeliefSnapshot(src="r1", tick=4, seq=0, grid=belief))
    assert o.topic == "/r1/map" and o.latched and np.asarray(o.msg.data).reshape(2, 3)[1, 0] == 0


def test_links_are_coloured_by_strength() -> None:
    fold = _fold()
    fold.fold(_state(0, {"r0": (0, 0), "r1": (1, 2)}))
    link = np.array([[False, True], [False, False]])
    lk = Links(src="netem", tick=0, seq=0, robots=("r0", "r1"), strength=np.array([[0.0, -80.0], [-200.0, 0.0]]),
               link=link, connected=True, sent=1, delivered=1, dropped_loss=0, dropped_signal=0, bytes_sent=10)
    (o,) = fold.fold(lk)
    (marker,) = o.msg.markers
    assert marker.type == 5 and len(marker.points) == 2 and marker.header.frame_id == "map"
    assert marker.colors[0].g == pytest.approx(0.5) and marker.colors[0].r == pytest.approx(0.5)  # 10 dB above
    lk2 = msgspec.structs.replace(lk, **{"link": np.zeros((2, 2), dtype=bool)})
    assert fold.fold(lk2)[0].msg.markers[0].points == []
