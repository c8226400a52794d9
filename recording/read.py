"""Reading a recording back: :func:`load_recording` folds a ``run.mcap`` into a :class:`Run`.

The scenario comes from the MCAP's ``scenario`` metadata; :class:`.metrics.RunMetrics` folds the recorded msgpack
messages (the same monitor fold as the live run, so the recomputed ``result.json`` keys are equal). The file is
read front to back with the mcap package's stream reader, so a recording without summary or footer (the launcher
was killed) reads up to its last complete chunk: the recorder flushes one at least once a second.

The recorder writes the schema version into the ``scenario`` metadata (``schema_version``); a recording without it
is of the first layout (schema 1), and one from a newer schema than :data:`fleet_emu.core.version.SCHEMA_VERSION`
is refused before anything else of it is read.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
from mcap.records import Channel, Metadata
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader

from fleet_emu.core.errors import ReportError
from fleet_emu.core.version import SCHEMA_VERSION
from fleet_emu.recording.metrics import RunMetrics
from fleet_emu.recording.recorder import SCENARIO_METADATA

MAGIC = b"\x89MCAP0\r\n"


class Run:
    """One recording, read and folded.

    ``result`` holds the ``result.json`` keys as recomputed from the recording (but ``metrics.NOT_RECORDED``:
    the launcher's clock, the signal it got, whether its bus was authenticated);
    ``metrics`` what ``fleet report`` writes to ``metrics.json`` (``result`` plus the analysis groups and
    ``truncated``); ``fold`` the :class:`.metrics.RunMetrics` behind them (per-tick series, trajectories).
    """

    def __init__(self, path: Path, fold: RunMetrics, messages: int, truncated: bool, schema_version: int,
                 fleet_emu_version: str | None) -> None:
        self.path = path
        self.fold = fold
        self.messages = messages  # every message in the file (the Foxglove channels too)
        self.truncated = truncated  # the recording was cut (no summary): read up to its last complete chunk
        self.schema_version = schema_version
        self.fleet_emu_version = fleet_emu_version  # None for a first-round recording
        self.result = fold.result(str(path))
        self.result["recording"]["messages"] = messages
        self.metrics = self.result | fold.analysis(self.result) | {"truncated": truncated}

    @property
    def scenario(self) -> dict[str, Any]:
        return self.fold.scenario

    @property
    def name(self) -> str:
        return self.path.parent.name if self.path.name == "run.mcap" else self.path.stem

    @property
    def label(self) -> str:
        return f"{self.name} ({self.metrics['allocator']}, {self.metrics['robots']} robots)"

    def coverage_curve(self) -> tuple[np.ndarray, np.ndarray]:
        """Ticks (ascending) and the team's coverage at each, from the world's states (the last state of a tick)."""
        curve = sorted(dict(self.fold.monitor.coverage_curve).items())
        return np.array([t for t, _ in curve], dtype=int), np.array([c for _, c in curve], dtype=float)


def resolve(path: Path) -> Path:
    """RUN_DIR (holding run.mcap) or RUN.mcap -> the recording's path."""
    if path.is_dir():
        mcap = path / "run.mcap"
        if not mcap.is_file():
            raise ReportError(f"{path} holds no run.mcap")
        return mcap
    if not path.exists():
        raise ReportError(f"no such file or directory: {path}")
    if not path.is_file():
        raise ReportError(f"not a file: {path}")
    return path


def load_recording(path: str | Path) -> Run:
    """Read and fold one recording (RUN_DIR or RUN.mcap), a cut last chunk included; prints and writes nothing.

    Raises :class:`~fleet_emu.core.errors.ReportError` (one line) when the path is missing, not an MCAP file,
    not a fleet recording, or written by a newer fleet_emu.
    """
    mcap = resolve(Path(path))
    try:
        f = open(mcap, "rb")  # noqa: SIM115 (closed below)
    except OSError as exc:
        raise ReportError(f"cannot read {mcap}: {exc.strerror or exc}") from None
    with f:
        if f.read(len(MAGIC)) != MAGIC:
            raise ReportError(f"{mcap} is not an MCAP file")
        f.seek(0)
        return _read(f, mcap)


def recorded_scenario(path: str | Path) -> dict[str, Any]:
    """The scenario a recording (RUN_DIR or RUN.mcap) was made of, from its ``scenario`` metadata, without folding
    its messages (the layout of a run needs its robots, not its metrics). ReportError as :func:`load_recording`."""
    mcap = resolve(Path(path))
    try:
        with open(mcap, "rb") as f:
            if f.read(len(MAGIC)) != MAGIC:
                raise ReportError(f"{mcap} is not an MCAP file")
            f.seek(0)
            for rec in StreamReader(f, record_size_limit=max(mcap.stat().st_size, 1)).records:
                if isinstance(rec, Metadata) and rec.name == SCENARIO_METADATA:
                    _versions(rec.metadata, mcap)
                    scenario = json.loads(rec.metadata.get("scenario", "null"))
                    if not isinstance(scenario, dict):
                        raise ReportError(f"{mcap}: unreadable scenario metadata")
                    return scenario
    except OSError as exc:
        raise ReportError(f"cannot read {mcap}: {exc.strerror or exc}") from None
    except ReportError:
        raise
    except Exception:  # a cut file ends inside a record before the metadata
        pass
    raise ReportError(f"{mcap} has no '{SCENARIO_METADATA}' metadata: not a fleet recording")


def _read(f: BinaryIO, mcap: Path) -> Run:
    """Feed the file's msgpack messages to the fold, in file order (those before the scenario wait for it)."""
    channels: dict[int, Channel] = {}
    pending: list[tuple[str, bytes, int]] = []
    fold: RunMetrics | None = None
    versions: tuple[int, str | None] = (1, None)
    messages = 0
    truncated = False
    records = StreamReader(f, record_size_limit=max(mcap.stat().st_size, 1)).records
    while True:
        try:
            rec = next(records)
        except StopIteration:
            break
        except Exception:  # the file ends inside a record (a cut recording): keep what was read
            truncated = True
            break
        if isinstance(rec, McapMessage):
            messages += 1
            ch = channels.get(rec.channel_id)
            if ch is None or ch.message_encoding != "msgpack":
                continue
            if fold is None:
                pending.append((ch.topic, rec.data, rec.publish_time))
            else:
                fold.feed(ch.topic, rec.data, rec.publish_time)
        elif isinstance(rec, Channel):
            channels.setdefault(rec.id, rec)
        elif isinstance(rec, Metadata) and rec.name == SCENARIO_METADATA and fold is None:
            versions = _versions(rec.metadata, mcap)
            fold = _fold_for(rec.metadata, mcap)
            for item in pending:
                fold.feed(*item)
            pending.clear()
    if fold is None:
        if truncated and not messages:
            raise ReportError(f"{mcap} was cut before anything was flushed to it")
        raise ReportError(f"{mcap} has no '{SCENARIO_METADATA}' metadata: not a fleet recording")
    return Run(mcap, fold, messages, truncated, *versions)


def _versions(metadata: dict[str, str], mcap: Path) -> tuple[int, str | None]:
    """The schema and fleet_emu versions a recording was written with (1 and None for the first layout's);
    refuses a newer schema."""
    try:
        schema = int(metadata.get("schema_version", 1))
    except ValueError:
        raise ReportError(f"{mcap}: unreadable schema_version {metadata['schema_version']!r}") from None
    if schema > SCHEMA_VERSION:
        raise ReportError(f"{mcap} was written by a newer fleet_emu (schema {schema}; this one reads up to "
                          f"{SCHEMA_VERSION}): upgrade fleet_emu to read it")
    return schema, metadata.get("fleet_emu_version")


def _fold_for(metadata: dict[str, str], mcap: Path) -> RunMetrics:
    try:
        scenario = json.loads(metadata["scenario"])
        run_id = metadata.get("run_id", "")
        return RunMetrics(scenario, run_id, metadata.get("engine"))
    except (KeyError, ValueError, TypeError) as exc:
        raise ReportError(f"{mcap}: unreadable scenario metadata ({exc})") from None
