"""``fleet info RUN|MCAP``: a recording's summary, as ``mcap info`` prints one: the file, its writer, the run and
its scenario, the message count, the start, end and duration (simulated time: a message's log time is the run's
start plus its tick), and every channel with its message count and encoding.

It reads the MCAP's summary section (statistics, channels: no message is decoded), or, for a recording without
one (the launcher was killed: ``fleet recover`` repairs it), every record up to the last complete one, and says
so. The scenario is the recording's ``scenario`` metadata, checked as :func:`~fleet_emu.recording.read.scenario_of`
checks it before anything is read from it.
"""

from __future__ import annotations

import dataclasses
import datetime
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from fleet_emu.core.errors import ReportError
from fleet_emu.core.radio import radio_label
from fleet_emu.recording.read import open_mcap, resolve, scenario_of
from fleet_emu.recording.recorder import SCENARIO_METADATA


@dataclasses.dataclass(frozen=True)
class ChannelInfo:
    """One channel: its id, topic, message encoding, schema name ("" for none) and message count."""

    id: int
    topic: str
    encoding: str
    schema: str
    messages: int


@dataclasses.dataclass(frozen=True)
class RecordingInfo:
    """What ``fleet info`` prints of one recording; ``cut``: it has no summary and was read record by record."""

    path: Path
    size: int
    library: str
    metadata: dict[str, str]
    scenario: dict[str, Any]
    messages: int
    start_ns: int
    end_ns: int
    channels: tuple[ChannelInfo, ...]
    cut: bool

    @property
    def duration_s(self) -> float:
        return (self.end_ns - self.start_ns) / 1e9 if self.messages else 0.0


def recording_info(path: str | Path) -> RecordingInfo:
    """The summary of the recording at ``path`` (RUN_DIR or RUN.mcap); ReportError (one line) when it is missing,
    not an MCAP file, or not a fleet recording."""
    mcap = resolve(Path(path))
    try:
        with open_mcap(mcap) as f:
            found = _from_summary(f) or _from_records(f, mcap.stat().st_size)
            size = mcap.stat().st_size
    except OSError as exc:
        raise ReportError(f"cannot read {mcap}: {exc.strerror or exc}") from None
    library, metadata, counts, channels, span, cut = found
    if SCENARIO_METADATA not in metadata:
        raise ReportError(f"{mcap} has no '{SCENARIO_METADATA}' metadata: not a fleet recording")
    meta = metadata[SCENARIO_METADATA]
    scenario = scenario_of(meta, mcap)
    rows = tuple(ChannelInfo(cid, ch.topic, ch.message_encoding, schema, counts.get(cid, 0))
                 for cid, (ch, schema) in sorted(channels.items()))
    return RecordingInfo(mcap, size, library, dict(meta), scenario, sum(counts.values()), span[0], span[1], rows, cut)


_Found = tuple[str, dict[str, dict[str, str]], dict[int, int], dict[int, tuple[Channel, str]], tuple[int, int], bool]


def _from_summary(f: Any) -> _Found | None:
    """From the summary section; None when the file has none (or it does not read)."""
    try:
        reader = make_reader(f)
        summary = reader.get_summary()
        if summary is None or summary.statistics is None:
            return None
        stats = summary.statistics
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        library = reader.get_header().library
    except (McapError, ValueError, EOFError, KeyError):
        return None
    channels = {cid: (ch, _schema_name(summary.schemas.get(ch.schema_id))) for cid, ch in summary.channels.items()}
    span = (stats.message_start_time, stats.message_end_time)
    return library, metadata, dict(stats.channel_message_counts), channels, span, False


def _from_records(f: Any, size: int) -> _Found:
    """Every record up to the last complete one, for a file without a summary."""
    f.seek(0)
    library, metadata = "", {}
    counts: dict[int, int] = {}
    channels: dict[int, tuple[Channel, str]] = {}
    schemas: dict[int, str] = {}
    first, last = 0, 0
    try:
        for rec in StreamReader(f, record_size_limit=max(size, 1)).records:
            if isinstance(rec, Schema):
                schemas[rec.id] = rec.name
            elif isinstance(rec, Channel):
                channels[rec.id] = (rec, schemas.get(rec.schema_id, ""))
            elif isinstance(rec, Message):
                counts[rec.channel_id] = counts.get(rec.channel_id, 0) + 1
                first = rec.log_time if not first else min(first, rec.log_time)
                last = max(last, rec.log_time)
            elif isinstance(rec, Metadata):
                metadata[rec.name] = dict(rec.metadata)
            elif isinstance(rec, Header):
                library = rec.library
    except Exception:  # a cut file ends inside a record: what came before it is the answer
        pass
    return library, metadata, counts, channels, (first, last), True


def _schema_name(schema: Schema | None) -> str:
    return schema.name if schema is not None else ""


def info_lines(info: RecordingInfo) -> list[str]:
    """The lines ``fleet info`` prints."""
    s, meta = info.scenario, info.metadata
    alloc = s.get("allocator", {}).get("type", "?") if isinstance(s.get("allocator"), dict) else "?"
    radio = s.get("radio") or {}
    tick_s = float(meta.get("tick_s", s.get("tick_s", 1.0)))
    version = meta.get("fleet_emu_version", "")
    lines = [
        f"recording: {info.path} ({_size(info.size)})" + ("; no summary (cut): read up to its last record" if info.cut
                                                          else ""),
        f"library:   {info.library or '-'}" + (f" {version}" if version else "")
        + f" (message schema {meta.get('schema_version', 1)})",
        f"run:       {meta.get('run_id', '-')} ({meta.get('engine', '?')} engine)",
        f"scenario:  {s.get('name')}: {s.get('map')} / {alloc}, {s.get('robots')} robots, seed {s.get('seed')}, "
        f"radio {radio_label(str(radio.get('comm', '?')), float(radio.get('loss', 0.0)))}",
        f"messages:  {info.messages} in {len(info.channels)} channels",
        f"start:     {_when(info.start_ns)}",
        f"end:       {_when(info.end_ns)}",
        f"duration:  {info.duration_s:.3f} s ({info.duration_s / tick_s:g} ticks of {tick_s:g} s, simulated time)",
        "channels:",
    ]
    width = max((len(c.topic) for c in info.channels), default=0)
    digits = len(str(max((c.messages for c in info.channels), default=0)))
    ids = len(str(max((c.id for c in info.channels), default=0)))
    for c in info.channels:
        kind = f"{c.schema} [{c.encoding}]" if c.schema else f"[{c.encoding}]"
        lines.append(f"  ({c.id:>{ids}}) {c.topic:<{width}}  {c.messages:>{digits}} msgs  {kind}")
    return lines


def _size(n: int) -> str:
    return f"{n / 1e6:.2f} MB" if n >= 100_000 else f"{n} bytes"


def _when(ns: int) -> str:
    if not ns:
        return "-"
    stamp = datetime.datetime.fromtimestamp(ns / 1e9, tz=datetime.UTC)
    return f"{stamp.isoformat(timespec='milliseconds').replace('+00:00', 'Z')} ({ns} ns)"
