"""A cut recording made whole: the pure part of ``fleet recover``.

A launcher killed mid-run (SIGKILL, a power cut) leaves a ``run.mcap`` with no summary, no index and no footer:
readers that seek (the mcap package's ``make_reader``, Foxglove's indexed open) refuse it. :func:`rewrite`
reads it front to back up to its last complete record and writes every schema, channel, metadata record and
message again into a new, indexed MCAP file; :func:`crashed_result` is the ``result.json`` of what the recording
holds, with ``reason`` ``crashed``. The folder's handling (lock, renames) is ``launch``'s.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mcap.records import Channel, Header, Metadata, Schema
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from fleet_emu.core.errors import ReportError
from fleet_emu.core.files import write_atomic
from fleet_emu.recording.read import Run, open_mcap
from fleet_emu.recording.recorder import CHUNK_SIZE
from fleet_emu.recording.result import Ending, Launcher, build_result


@dataclasses.dataclass(frozen=True)
class Rewritten:
    """What :func:`rewrite` carried over: the number of messages."""

    messages: int


def is_whole(path: Path) -> bool:
    """Whether ``path`` is an MCAP file an indexed reader opens: its footer and summary are there."""
    try:
        with open(path, "rb") as f:
            return make_reader(f).get_summary() is not None
    except Exception:  # OSError, McapError, and a variety of others on a file cut inside a record
        return False


def rewrite(src: Path, dst: Path) -> Rewritten:
    """Every complete record of the cut MCAP ``src`` written again, indexed, into ``dst`` (atomically);
    ReportError when ``src`` is not an MCAP file or holds nothing."""
    with open_mcap(src) as f:
        carried: list[Rewritten] = []
        try:
            write_atomic(dst, lambda tmp: carried.append(_copy(f, src.stat().st_size, tmp)))
        except ReportError as exc:
            raise ReportError(f"{src}: {exc}") from None
    return carried[0]


def _copy(f: Any, size: int, tmp: Path) -> Rewritten:
    """The records of the stream ``f`` into a new MCAP file ``tmp``; ids are renumbered as registered."""
    schemas: dict[int, int] = {0: 0}
    channels: dict[int, int] = {}
    messages = 0
    with open(tmp, "wb") as out:
        writer = Writer(out, compression=CompressionType.ZSTD, chunk_size=CHUNK_SIZE)
        started = False
        for rec in _records(f, size):
            if isinstance(rec, Header):
                writer.start(profile=rec.profile, library=rec.library)
                started = True
                continue
            if not started:
                raise ReportError("the recording has no MCAP header")
            if isinstance(rec, Schema) and rec.id not in schemas:
                schemas[rec.id] = writer.register_schema(rec.name, rec.encoding, rec.data)
            elif isinstance(rec, Channel) and rec.id not in channels and rec.schema_id in schemas:
                channels[rec.id] = writer.register_channel(rec.topic, rec.message_encoding, schemas[rec.schema_id],
                                                           rec.metadata)
            elif isinstance(rec, Metadata):
                writer.add_metadata(rec.name, rec.metadata)
            elif isinstance(rec, McapMessage) and rec.channel_id in channels:
                writer.add_message(channels[rec.channel_id], rec.log_time, rec.data, rec.publish_time,
                                   rec.sequence)
                messages += 1
        if not started:
            raise ReportError("the recording was cut before its header")
        writer.finish()
    return Rewritten(messages)


def _records(f: Any, size: int) -> Any:
    """The stream's records up to the first incomplete one (a cut file ends inside a record or a chunk)."""
    records = StreamReader(f, record_size_limit=max(size, 1)).records
    while True:
        try:
            yield next(records)
        except StopIteration:
            return
        except Exception:  # the file ends inside a record: what came before is kept
            return


def readable(path: Path) -> tuple[int, int, int]:
    """How much of the MCAP file ``path`` reads front to back: its messages, the bytes up to its last complete
    record, and its size."""
    messages = read = 0
    with open_mcap(path) as f:
        for rec in _records(f, path.stat().st_size):
            messages += isinstance(rec, McapMessage)
            read = f.tell()
    return messages, read, path.stat().st_size


def crashed_result(run: Run, wall_seconds: float) -> dict[str, Any]:
    """``result.json`` of a run whose launcher died (:func:`~fleet_emu.recording.result.build_result`): what the
    recording ``run`` holds, ``reason`` ``crashed``, not completed, no signal known, its ``pids`` only when every
    node's was recorded, ``wall_seconds`` as the recording's wall clock spans."""
    fold = run.fold
    pids = fold.recorded_pids()
    whole = None not in (pids["world"], pids["netem"], *pids["robots"])
    return build_result(fold.monitor, fold.scenario, fold.run_id, Ending(crashed=True), engine=fold.engine,
                        pids=pids if whole else {}, recording=str(run.path), messages=run.messages,
                        launcher=Launcher(wall_seconds, signal=None, authenticated=None))


def wall_span(path: Path) -> float:
    """Seconds between the first and the last message's publish time (the wall clock) in the recording."""
    first, last = None, 0
    with open_mcap(path) as f:
        for rec in _records(f, path.stat().st_size):
            if isinstance(rec, McapMessage):
                first = rec.publish_time if first is None else min(first, rec.publish_time)
                last = max(last, rec.publish_time)
    return (last - first) / 1e9 if first is not None else 0.0
