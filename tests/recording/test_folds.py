"""Every fold keeps core/fold.py's signatures: ``feed(key, data, time_ns=None)`` for a bus sample, ``fold(msg)``
for a checked message; and a fold fed messages gives what its specialised entry points give."""

from __future__ import annotations

import inspect
from collections.abc import Callable

import numpy as np
import pytest

from fleet_emu.core.fold import MessageFold, SampleFold
from fleet_emu.core.messages import Envelope, Observation, RxBundle, TxBundle, WorldState
from fleet_emu.recording.first_seen import FirstSeen
from fleet_emu.recording.foxglove import FoxgloveFold
from fleet_emu.recording.foxglove_writer import FoxgloveWriter
from fleet_emu.recording.metrics import RunMetrics
from fleet_emu.recording.monitor import Monitor
from fleet_emu.recording.relaystats import RelayStats
from fleet_emu.ros2.fold import Ros2Fold

SAMPLE_FOLDS = (Monitor, RunMetrics, FoxgloveWriter)
MESSAGE_FOLDS = (Monitor, FoxgloveFold, Ros2Fold, RelayStats, FirstSeen)


def _positional(method: Callable[..., object]) -> list[inspect.Parameter]:
    params = list(inspect.signature(method).parameters.values())[1:]  # after self
    assert all(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in params), method
    return params


@pytest.mark.parametrize("cls", SAMPLE_FOLDS, ids=lambda c: c.__name__)
def test_every_feed_takes_a_key_its_bytes_and_a_time(cls: type) -> None:
    params = _positional(cls.feed)
    assert [p.name for p in params[:3]] == ["key", "data", "time_ns"], params
    assert all(p.default is p.empty for p in params[:2]), params
    assert params[2].default is None and all(p.default is not p.empty for p in params[2:]), params


@pytest.mark.parametrize("cls", MESSAGE_FOLDS, ids=lambda c: c.__name__)
def test_every_fold_takes_one_message(cls: type) -> None:
    params = _positional(cls.fold)
    assert len(params) == 1 and params[0].name == "msg" and params[0].default is params[0].empty, params


def test_the_protocols_recognise_the_folds() -> None:
    assert isinstance(Monitor(("r0",)), SampleFold) and isinstance(Monitor(("r0",)), MessageFold)
    assert isinstance(RelayStats(endpoints=2), MessageFold) and not isinstance(RelayStats(endpoints=2), SampleFold)
    assert isinstance(FirstSeen((2, 2)), MessageFold)


def test_relay_stats_folded_message_by_message_equals_its_bundle_entry_points() -> None:
    b = Envelope(src="r0", tick=2, seq=1, origin="r0", dst="*", ttl=0, payload_kind="pose", payload=b"x")
    msgs = [TxBundle(src="r0", tick=2, seq=1, msgs=(b,)), RxBundle(src="netem", tick=3, seq=1, dst="r1", msgs=(b,)),
            RxBundle(src="r0", tick=3, seq=2, dst="r1", msgs=(b,))]  # an rx bundle not from netem: not folded
    by_fold, by_hand = RelayStats(endpoints=2), RelayStats(endpoints=2)
    for m in msgs:
        by_fold.fold(m)
    by_hand.fold_tx(msgs[0])  # type: ignore[arg-type]
    by_hand.fold_rx(msgs[1])  # type: ignore[arg-type]
    assert by_fold.result() == by_hand.result() and by_fold.result()["pose"]["delivered"] == 1


def test_first_seen_folds_observations_of_its_shape_only() -> None:
    fs = FirstSeen((2, 2))
    obs = Observation(src="world", tick=4, seq=0, robot="r0", cell=(0, 0), shape=(2, 2), cell_size=1.0,
                      cells=np.array([0, 3]), values=np.array([0, 100], dtype=np.int8))
    fs.fold(obs)
    fs.fold(Observation(src="world", tick=1, seq=1, robot="r0", cell=(0, 0), shape=(3, 3), cell_size=1.0,
                        cells=np.array([1]), values=np.array([0], dtype=np.int8)))  # another grid's: left out
    fs.fold(WorldState(src="world", tick=5, seq=5, poses={}, live=(), coverage=0.0, path_length={}))
    assert fs.tick.tolist() == [4, -1, -1, 4] and fs.grid(4).tolist() == [[0, -1], [-1, 100]]
