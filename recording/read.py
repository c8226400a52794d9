"""Reading a recording back: :func:`load_recording` folds a ``run.mcap`` into a :class:`Run`.

The scenario comes from the MCAP's ``scenario`` metadata; :class:`.metrics.RunMetrics` folds the recorded msgpack
messages (the same monitor fold as the live run, so the recomputed ``result.json`` keys are equal). The file is
read front to back with the mcap package's stream reader, so a recording without summary or footer (the launcher
was killed) reads up to its last complete chunk: the recorder flushes one at least once a second.

The recorder writes the schema version into the ``scenario`` metadata (``schema_version``); a recording without it
is of the first layout (schema 1), and one from a newer schema than :data:`fleet_emu.core.version.SCHEMA_VERSION`
is refused before anything else of it is read.

A recording is untrusted input. The scenario it carries is checked with a scenario file's limits
(:func:`scenario_of`: size, nesting, then :meth:`~fleet_emu.core.scenario.Scenario.from_dict`) before anything is
sized from it, so a few hundred bytes saying ``robots = 100000000`` are one line, not gigabytes. A recording cut
inside a record, or holding fewer messages than the ``result.json`` beside it says were recorded, is refused with
how much of it could be read, unless the caller asks for that much (``partial=True``, the CLI's ``--partial``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np
from mcap.records import Channel, Metadata
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader

from fleet_emu.core.errors import ConfigError, ReportError
from fleet_emu.core.limits import check_text
from fleet_emu.core.radio import radio_settings
from fleet_emu.core.scenario import Scenario
from fleet_emu.core.setting_names import file_spelling
from fleet_emu.core.version import SCHEMA_VERSION
from fleet_emu.recording.metrics import RunMetrics
from fleet_emu.recording.recorder import SCENARIO_METADATA

MAGIC = b"\x89MCAP0\r\n"
MAX_RESULT_BYTES = 64 << 20  # a result.json beside a recording larger than this is not read (256 robots: < 1 MB)


class Run:
    """One recording, read and folded.

    ``result`` holds the ``result.json`` keys as recomputed from the recording (but ``result.NOT_RECORDED``:
    the launcher's clock, the signal it got, whether its bus was authenticated);
    ``metrics`` what ``fleet report`` writes to ``metrics.json`` (``result`` plus the analysis groups and
    ``truncated``); ``fold`` the :class:`.metrics.RunMetrics` behind them (per-tick series, trajectories).
    """

    def __init__(self, path: Path, fold: RunMetrics, messages: int, truncated: bool, schema_version: int,
                 fleet_emu_version: str | None, read_bytes: int = 0) -> None:
        self.path = path
        self.fold = fold
        self.messages = messages  # every message in the file (the Foxglove channels too)
        self.cut = truncated  # it ends inside a record: read up to its last complete one
        self.recorded = recorded_count(path)  # what the result.json beside it says was recorded (None: no result)
        # the recording was cut (it ends inside a record), or holds fewer messages than its run recorded
        self.truncated = truncated or (self.recorded is not None and messages < self.recorded)
        self.read_bytes = read_bytes  # bytes up to the end of its last complete record
        self.schema_version = schema_version
        self.fleet_emu_version = fleet_emu_version  # None for a first-round recording
        self.result = fold.result(str(path), messages)
        self.metrics = self.result | fold.analysis(self.result) | {"truncated": self.truncated}

    @property
    def scenario(self) -> dict[str, Any]:
        return self.fold.scenario

    @property
    def extent(self) -> str:
        """How much of the file was read: its messages and bytes."""
        size = self.path.stat().st_size if self.path.exists() else 0
        return f"{self.messages} messages read, {self.read_bytes} of its {size} bytes"

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


def load_recording(path: str | Path, partial: bool = False) -> Run:
    """Read and fold one recording (RUN_DIR or RUN.mcap); prints and writes nothing.

    Raises :class:`~fleet_emu.core.errors.ReportError` (one line) when the path is missing, not an MCAP file,
    not a fleet recording, carries a scenario a scenario file could not hold, or was written by a newer
    fleet_emu; and, unless ``partial``, when it is cut (it ends inside a record: the launcher was killed, or the
    file was cut short) or holds fewer messages than its run's ``result.json`` says were recorded. With
    ``partial`` such a recording is read up to its last complete record (``Run.truncated``).
    """
    mcap = resolve(Path(path))
    with open_mcap(mcap) as f:
        run = _read(f, mcap)
    if not partial:
        complete(run)
    return run


def complete(run: Run) -> None:
    """ReportError, saying how much was read, when ``run`` is cut or holds fewer messages than its result says."""
    if run.cut:
        raise ReportError(f"{run.path} is cut: {run.extent}; pass --partial (partial=True) to read that much")
    if run.recorded is not None and run.recorded != run.messages:
        raise ReportError(f"{run.path} is inconsistent with its result.json: it holds {run.messages} messages, the "
                          f"run recorded {run.recorded}; pass --partial (partial=True) to read what it holds")


def recorded_count(mcap: Path) -> int | None:
    """The messages the ``result.json`` beside ``mcap`` (a run folder's ``run.mcap``) says its run recorded; None
    without one (or an unreadable one: a report does not judge the result, only the recording against it)."""
    result = mcap.parent / "result.json"
    try:
        if mcap.name != "run.mcap" or not result.is_file() or result.stat().st_size > MAX_RESULT_BYTES:
            return None
        messages = json.loads(result.read_text())["recording"]["messages"]
    except (OSError, ValueError, KeyError, TypeError, RecursionError):
        return None
    return messages if isinstance(messages, int) and not isinstance(messages, bool) else None


def scenario_of(metadata: dict[str, str], mcap: Path) -> dict[str, Any]:
    """The scenario a recording carries, checked as a scenario file is (its size and nesting, then every value
    with :meth:`Scenario.from_dict`) before anything is sized from it; the recorded keys as they are, any the
    folds read and the recording lacks at their defaults. ReportError (one line) otherwise."""
    where = f"{mcap}: its recorded scenario"
    text = metadata.get("scenario")
    if not isinstance(text, str):
        raise ReportError(f"{mcap}: unreadable scenario metadata (no scenario in it)")
    try:
        check_text(text, where)
        raw = json.loads(text)
        if not isinstance(raw, dict):
            raise ReportError(f"{where} is a JSON {type(raw).__name__}, not a table: unreadable scenario metadata")
        with file_spelling({s.name: f"radio.{s.name}" for s in radio_settings()}):  # named as the JSON keys
            return Scenario.from_dict(raw, where=where).to_dict() | raw
    except ConfigError as exc:
        text = str(exc)
        raise ReportError(text if text.startswith(where) else f"{where}: {text}") from None
    except (ValueError, RecursionError) as exc:
        raise ReportError(f"{mcap}: unreadable scenario metadata ({str(exc) or type(exc).__name__})") from None


def open_mcap(mcap: Path) -> BinaryIO:
    """``mcap`` open for reading at its start, once its first bytes are MCAP's magic; ReportError (one line) when
    it cannot be opened or is not an MCAP file. Every reader of a recording opens it so."""
    try:
        f = open(mcap, "rb")  # noqa: SIM115 (the caller closes it: ``with open_mcap(path) as f``)
    except OSError as exc:
        raise ReportError(f"cannot read {mcap}: {exc.strerror or exc}") from None
    try:
        if f.read(len(MAGIC)) != MAGIC:
            raise ReportError(f"{mcap} is not an MCAP file")
        f.seek(0)
    except BaseException:
        f.close()
        raise
    return f


def recorded_scenario(path: str | Path) -> dict[str, Any]:
    """The scenario a recording (RUN_DIR or RUN.mcap) was made of, from its ``scenario`` metadata, without folding
    its messages (the layout of a run needs its robots, not its metrics). ReportError as :func:`load_recording`."""
    mcap = resolve(Path(path))
    try:
        with open_mcap(mcap) as f:
            for rec in StreamReader(f, record_size_limit=max(mcap.stat().st_size, 1)).records:
                if isinstance(rec, Metadata) and rec.name == SCENARIO_METADATA:
                    _versions(rec.metadata, mcap)
                    return scenario_of(rec.metadata, mcap)
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
    messages = read_bytes = 0
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
        read_bytes = f.tell()
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
    return Run(mcap, fold, messages, truncated, *versions, read_bytes=read_bytes)


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
    scenario = scenario_of(metadata, mcap)  # checked before the fold sizes anything from it
    try:
        return RunMetrics(scenario, str(metadata.get("run_id", "")), metadata.get("engine"))
    except (KeyError, ValueError, TypeError, AttributeError) as exc:
        raise ReportError(f"{mcap}: unreadable scenario metadata ({exc})") from None
