"""``fleet export ros2``: the bag of a recording, read back with rosbags (the library's reader, not ours): its
message counts are the recording's, a decoded belief map is the robot's last snapshot, and its stamps are the
run's clock."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from mcap.reader import make_reader

from fleet_emu.core.codec import decode
from fleet_emu.core.messages import BeliefSnapshot, WorldState
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import run_memory
from tests.harness.cli import fleet


@pytest.fixture(scope="module")
def recorded(small_map: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ros2") / "run"
    run_memory(Scenario().override(map=str(small_map), robots=2, seed=4, max_ticks=60), out, run_id="bagged")
    return out


def _recording(run: Path) -> tuple[int, dict[str, list[BeliefSnapshot]], int]:
    """The world's states, each robot's belief snapshots, and the clock's start, read from run.mcap."""
    states, beliefs, start = 0, {}, 0
    with (run / "run.mcap").open("rb") as f:
        reader = make_reader(f)
        start = int(next(m for m in reader.iter_metadata() if m.name == "scenario").metadata["start_ns"])
        for _, channel, message in reader.iter_messages():
            if channel.message_encoding != "msgpack":
                continue
            msg = decode(message.data)
            if isinstance(msg, WorldState) and msg.src == "world":
                states += 1
            elif isinstance(msg, BeliefSnapshot):
                beliefs.setdefault(msg.src, []).append(msg)
    return states, beliefs, start


def test_the_bag_holds_the_recording(recorded: Path, tmp_path: Path) -> None:
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    bag = tmp_path / "bag"
    done = fleet("export", "ros2", str(recorded), "--out", str(bag))
    assert "messages on" in done.stdout
    assert (bag / "metadata.yaml").is_file()
    states, beliefs, start = _recording(recorded)
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert {c.msgtype for c in reader.connections if c.topic == "/r0/map"} == {"nav_msgs/msg/OccupancyGrid"}
        maps = [(t, store.deserialize_cdr(raw, c.msgtype)) for c, t, raw in reader.messages()
                if c.topic == "/r0/map"]
    assert states > 0 and counts["/clock"] == states and counts["/r1/pose"] == states
    assert counts["/r0/map"] == len(beliefs["r0"]) and counts["/map"] == 1
    last, (t, grid) = beliefs["r0"][-1], maps[-1]
    decoded = np.flipud(np.asarray(grid.data, dtype=np.int8).reshape(grid.info.height, grid.info.width))
    assert np.array_equal(decoded, last.grid)
    tick_ns = round(Scenario().tick_s * 1e9)
    assert t == start + last.tick * tick_ns
    assert grid.header.stamp.sec * 10**9 + grid.header.stamp.nanosec == t


@pytest.mark.slow  # a second export; the bag's content proven by default
def test_a_bag_is_not_written_over(recorded: Path, tmp_path: Path) -> None:
    (tmp_path / "taken").mkdir()
    done = fleet("export", "ros2", str(recorded), "--out", str(tmp_path / "taken"), check=False)
    assert done.returncode == 2 and done.stderr.count("\n") == 1 and "exists" in done.stderr
    done = fleet("export", "ros2", str(tmp_path / "nothing"), check=False)
    assert done.returncode != 0 and "Traceback" not in done.stderr
