"""``fleet recover``'s rewrite of a cut recording, on every cut of a small one: the result opens with the plain
indexed reader and holds every message flushed before the cut; a recorder whose disk
fails keeps the error and raises nothing."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader

from fleet_emu.core.errors import ReportError
from fleet_emu.core.keys import Keys
from fleet_emu.core.messages import WorldState
from fleet_emu.recording.recorder import Recorder
from fleet_emu.recording.recover import is_whole, rewrite


def _state(tick: int) -> bytes:
    return WorldState(src="world", tick=tick, seq=tick, poses={}, live=(), coverage=0.5, path_length={}).encode()


def _recording(path: Path) -> list[tuple[int, int]]:
    """A recording of three flushed batches of ten states and one unflushed batch; (file size, messages) after
    each flush."""
    keys = Keys("cut")
    rec = Recorder(path, {"run_id": "cut", "scenario": {}})
    ends = []
    for batch in range(4):
        for tick in range(batch * 10, batch * 10 + 10):
            rec.record(keys.state, _state(tick))
        if batch < 3:
            rec.flush()
            ends.append((path.stat().st_size, rec.messages))
    rec._file.flush()  # the last batch's chunk is still open: the file ends without it, as a killed writer's
    return ends


def test_every_cut_is_rewritten_whole_with_its_flushed_messages(tmp_path: Path) -> None:
    src = tmp_path / "full.mcap"
    ends = _recording(src)
    data = src.read_bytes()
    assert not is_whole(src)
    cut, whole = tmp_path / "cut.mcap", tmp_path / "whole.mcap"
    for end, count in ends:
        for off in (end - 1, end, end + 1):
            cut.write_bytes(data[:off])
            rewrite(cut, whole)
            with open(whole, "rb") as f:
                reader = make_reader(f)
                summary = reader.get_summary()
                assert summary is not None
                got = [m.log_time for _, _, m in reader.iter_messages()]
            assert len(got) == summary.statistics.message_count, off
            if off >= end:  # everything flushed before the cut
                assert len(got) == count, off
            else:  # a cut inside the flush's tail (its chunk whole or not)
                assert len(got) in (count - 10, count), off
            assert sorted(got) == got and is_whole(whole)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cut.mcap", "full.mcap", "whole.mcap"]  # no temporary


def test_a_file_cut_before_its_header_or_not_mcap_is_one_line(tmp_path: Path) -> None:
    (tmp_path / "empty.mcap").write_bytes(b"\x89MCAP0\r\n")
    with pytest.raises(ReportError, match="cut before its header"):
        rewrite(tmp_path / "empty.mcap", tmp_path / "out.mcap")
    (tmp_path / "text.mcap").write_text("hello, world")
    with pytest.raises(ReportError, match="not an MCAP file"):
        rewrite(tmp_path / "text.mcap", tmp_path / "out.mcap")
    assert not (tmp_path / "out.mcap").exists() and len(list(tmp_path.iterdir())) == 2


def test_a_recorder_whose_disk_fails_keeps_the_error(tmp_path: Path) -> None:
    rec = Recorder(tmp_path / "run.mcap", {"run_id": "full"})

    class Full:
        def write(self, _: bytes) -> int:
            raise OSError(28, "No space left on device")

        def flush(self) -> None:
            raise OSError(28, "No space left on device")

        def close(self) -> None:
            pass

    rec._writer._Writer__stream = Full()  # type: ignore[attr-defined]  # the disk fills up under the writer
    rec.record(Keys("full").state, _state(1))
    rec.flush()
    assert rec.failed is not None and rec.failed.errno == 28 and rec.closed
    rec.record(Keys("full").state, _state(2))  # later calls do nothing
    assert rec.close() == rec.messages
