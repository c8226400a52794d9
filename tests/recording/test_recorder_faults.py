"""What the fault trials found in the launcher's recording path: a message whose tick no MCAP log time can hold
crashed the recorder thread (no result.json, a run.mcap no reader opens), and the Foxglove writer folded
spoofed messages that the monitor had rejected."""

from __future__ import annotations

from pathlib import Path

import msgpack
from mcap.reader import make_reader

from fleet_emu.core.keys import Keys
from fleet_emu.core.messages import Command, Message, Stop, WorldState
from fleet_emu.recording.clock import RunClock
from fleet_emu.recording.foxglove_writer import FoxgloveWriter
from fleet_emu.recording.recorder import Recorder


def _state(tick: int) -> bytes:
    return WorldState(src="world", tick=tick, seq=tick, poses={}, live=(), coverage=0.5, path_length={}).encode()


def test_ticks_beyond_the_log_time_are_logged_at_the_latest_tick(tmp_path: Path) -> None:
    clock = RunClock(1_700_000_000 * 10**9, 0.1)
    rec = Recorder(tmp_path / "run.mcap", {"run_id": "huge"}, clock)
    keys = Keys("huge")
    max_tick = clock.max_tick
    rec.record(keys.state, _state(7))
    for tick in (max_tick + 1, 2**63, 2**64 - 1):  # each a valid msgpack uint; its log time overflows
        rec.record(keys.cmd("r0"), msgpack.packb({"kind": "cmd", "src": "r0", "tick": tick}))
        rec.add_channel_message("/viz/log", 0, "json", b"{}", tick)
    rec.record(keys.state, _state(max_tick))  # the largest tick a log time holds is kept
    rec.flush()
    assert rec.close() == 8
    with open(tmp_path / "run.mcap", "rb") as f:
        times = [m.log_time for _, _, m in make_reader(f).iter_messages(log_time_order=False)]
    assert times == [clock.ns(7)] * 7 + [clock.ns(max_tick)] and clock.ns(max_tick) <= 2**64 - 1


class _Fold:
    def __init__(self) -> None:
        self.got: list[Message] = []

    def fold(self, msg: Message) -> list:
        self.got.append(msg)
        return []


def test_the_foxglove_writer_ignores_spoofed_senders() -> None:
    keys = Keys("spoof")
    fold = _Fold()
    writer = FoxgloveWriter(recorder=None, fold=fold, keys=keys)  # type: ignore[arg-type]
    writer.feed(keys.cmd("r0"), Command(src="r1", tick=3, seq=1, move=(0, 1)).encode())
    writer.feed(keys.stop, Stop(src="outsider", tick=3, seq=1, reason="pwned").encode())
    writer.feed(keys.state, _state(5000)[:-1] + b"")  # whatever does not decode is not folded either
    ok = Command(src="r0", tick=3, seq=2, move=(0, 1))
    writer.feed(keys.cmd("r0"), ok.encode())
    assert fold.got == [ok] and not writer.failed
