"""``fleet export ros2 RUN_DIR [--out BAG]``: a recording as a rosbag2 — MCAP storage, CDR messages, with its
``metadata.yaml`` — of the live bridge's topics (:mod:`.fold`), written with ``rosbags``' rosbag2 writer, so
``ros2 bag info/play`` and rosbags read it. Every message's bag time and header stamp is its tick on the run's
clock (the recording's ``start_ns`` and ``tick_s``); the latched topics are offered transient local.

The recording is untrusted input: its scenario is checked as a scenario file's is before the fold is sized from
it (:func:`fleet_emu.recording.read.scenario_of`), and a cut or inconsistent recording is refused, saying how much
could be read, unless ``partial``. The bag is written whole or not at all: into a new hidden folder beside
``out`` (``.<name>.tmp<random>``), renamed to ``out`` once its ``metadata.yaml`` is written; any error, a full
disk or an interrupt removes the hidden folder, so ``out`` is either a bag rosbags opens or absent."""

from __future__ import annotations

import contextlib
import dataclasses
import errno
import os
import secrets
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO, Literal

import numpy as np
from mcap.records import Channel, Metadata
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader

from fleet_emu.core.codec import decode
from fleet_emu.core.errors import ConfigError, DecodeError, ReportError, RunError
from fleet_emu.core.grid import MapData
from fleet_emu.core.messages import Message
from fleet_emu.launch.signals import sigterm_unwinds
from fleet_emu.recording.clock import RunClock
from fleet_emu.recording.read import recorded_count, resolve, scenario_of
from fleet_emu.recording.recorder import SCENARIO_METADATA
from fleet_emu.ros2.fold import Out, Ros2Fold
from fleet_emu.ros2.types import cdr, typestore

BAG_VERSION: Literal[9] = 9  # rosbag2's metadata version of Jazzy


@dataclasses.dataclass
class Tally:
    """How much of a recording :func:`recorded` read: its messages, the bytes up to its last complete record, and
    whether it ended inside one (cut)."""

    messages: int = 0
    read_bytes: int = 0
    cut: bool = False


def recorded(f: BinaryIO, mcap: Path, tally: Tally) -> tuple[dict[str, str], Iterator[Message]]:
    """The ``scenario`` metadata and the bus messages (decoded, in file order; a cut last chunk ends them, and
    says so in ``tally``) of the recording ``mcap`` open as ``f``. Reads the metadata first: the recorder writes
    it before any message."""
    records = _safe(StreamReader(f, record_size_limit=max(mcap.stat().st_size, 1)).records, f, tally)
    channels: dict[int, Channel] = {}
    first: list[McapMessage] = []
    meta: dict[str, str] | None = None
    for rec in records:
        if isinstance(rec, Metadata) and rec.name == SCENARIO_METADATA:
            meta = dict(rec.metadata)
            break
        if isinstance(rec, Channel):
            channels[rec.id] = rec
        elif isinstance(rec, McapMessage):
            first.append(rec)
    if meta is None:
        raise ReportError(f"{mcap} has no '{SCENARIO_METADATA}' metadata: not a fleet recording")

    def messages() -> Iterator[Message]:
        for rec in [*first, *records]:
            if isinstance(rec, Channel):
                channels[rec.id] = rec
            elif isinstance(rec, McapMessage):
                ch = channels.get(rec.channel_id)
                if ch is not None and ch.message_encoding == "msgpack":
                    try:
                        yield decode(rec.data)
                    except DecodeError:
                        continue
    return meta, messages()


def _safe(records: Iterator[Any], f: Any, tally: Tally) -> Iterator[Any]:
    """The records up to the end, or up to where a cut file ends inside one (``tally`` counts them)."""
    while True:
        try:
            rec = next(records)
        except StopIteration:
            return
        except Exception:
            tally.cut = True
            return
        tally.read_bytes = f.tell()
        tally.messages += isinstance(rec, McapMessage)
        yield rec


def _scan(mcap: Path) -> Tally:
    """How much of ``mcap`` reads, record by record (nothing decoded)."""
    tally = Tally()
    with open(mcap, "rb") as f:
        for _ in _safe(StreamReader(f, record_size_limit=max(mcap.stat().st_size, 1)).records, f, tally):
            pass
    return tally


def fold_for(meta: dict[str, str], mcap: Path) -> Ros2Fold:
    """The fold of a recording: its scenario and clock, and the true map from the run's ``map.npz``."""
    scenario = scenario_of(meta, mcap)  # checked before the fold is sized from it
    run_dir = mcap.parent
    try:
        clock = RunClock(int(meta.get("start_ns", 0)), float(meta.get("tick_s", 1.0)))
    except (KeyError, ValueError, TypeError, OverflowError) as exc:
        raise ReportError(f"unreadable scenario metadata ({exc})") from None
    npz = run_dir / "map.npz"
    truth: np.ndarray | None = MapData.load(npz).grid if npz.is_file() else None
    return Ros2Fold(scenario, truth, clock=clock)


def export(run: Path, out: Path | None = None, partial: bool = False) -> tuple[Path, dict[str, int]]:
    """Write the rosbag2 of recording ``run`` (RUN_DIR or RUN.mcap) to ``out`` (default ``<run dir>/ros2``),
    which must not exist, whole or not at all (see the module); its path and the messages per topic. A cut or
    inconsistent recording is a ReportError unless ``partial``; a write that fails (a read-only folder, a full
    disk) a RunError, one line each."""
    from fleet_emu.recording.recover import is_whole

    mcap = resolve(run)
    out = out if out is not None else mcap.parent / "ros2"
    if out.exists() or out.is_symlink():
        raise ConfigError(f"--out {out} exists: give a new directory for the bag")
    tally = Tally()
    try:
        f = open(mcap, "rb")  # noqa: SIM115 (closed below)
    except OSError as exc:
        raise ReportError(f"cannot read {mcap}: {exc.strerror or exc}") from None
    with f:
        meta, messages = recorded(f, mcap, tally)
        fold = fold_for(meta, mcap)
        if not partial and not is_whole(mcap):  # a cut recording is refused before anything is written
            _check(mcap, _scan(mcap), partial)
        with _staged(out) as bag:
            counts = _write(bag, fold, messages)
            _check(mcap, tally, partial)
    return out, counts


def _check(mcap: Path, tally: Tally, partial: bool) -> None:
    """ReportError, with how much was read, when the recording is cut or holds fewer messages than its
    ``result.json`` says were recorded (unless ``partial``)."""
    if partial:
        return
    size = mcap.stat().st_size
    if tally.cut:
        raise ReportError(f"{mcap} is cut: {tally.messages} messages read, {tally.read_bytes} of its {size} bytes; "
                          "pass --partial to export that much")
    expected = recorded_count(mcap)
    if expected is not None and expected != tally.messages:
        raise ReportError(f"{mcap} is inconsistent with its result.json: it holds {tally.messages} messages, the "
                          f"run recorded {expected}; pass --partial to export what it holds")


def _write(bag: Path, fold: Ros2Fold, messages: Iterator[Message]) -> dict[str, int]:
    """The fold of ``messages`` written as a rosbag2 at ``bag`` (a new path); the messages per topic."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    counts: dict[str, int] = {}
    connections: dict[str, Any] = {}
    with Writer(bag, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP) as writer:
        def write(items: list[Out]) -> None:
            for o in items:
                conn = connections.get(o.topic)
                if conn is None:
                    conn = connections[o.topic] = writer.add_connection(
                        o.topic, o.typename, typestore=typestore(), offered_qos_profiles=_qos(o.latched))
                writer.write(conn, fold.clock.ns(o.tick), cdr(o.msg, o.typename))
                counts[o.topic] = counts.get(o.topic, 0) + 1

        for msg in messages:
            write(fold.fold(msg))
        write(fold.finish())
    return counts


@contextlib.contextmanager
def _staged(out: Path) -> Iterator[Path]:
    """A path to write the bag at, in a new hidden folder beside ``out``; renamed to ``out`` when the block ends
    well, the hidden folder removed however it ends. SIGTERM during the block exits 143 (so it is cleaned
    up too); a failed write (read-only folder, full disk) is one line."""
    stage = out.with_name(f".{out.name}.tmp{secrets.token_hex(4)}")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)  # as the rosbag2 writer does for a bag's folder
        stage.mkdir(mode=0o700)  # new: never an existing folder or a symlink's target
    except OSError as exc:
        raise _write_error(out, exc) from None
    with sigterm_unwinds():  # SIGTERM exits 143 through the finally below
        try:
            bag = stage / out.name
            try:
                yield bag
                if out.exists() or out.is_symlink():
                    raise ConfigError(f"--out {out} appeared while the bag was written: give a new directory for it")
                os.rename(bag, out)
            except OSError as exc:
                raise _write_error(out, exc) from None
            except Exception as exc:  # the writer's own errors wrap the OSError that caused them
                cause = exc.__cause__ or exc.__context__
                if isinstance(cause, OSError) and not isinstance(exc, ReportError | ConfigError):
                    raise _write_error(out, cause) from None
                raise
        finally:
            shutil.rmtree(stage, ignore_errors=True)



def _write_error(out: Path, exc: OSError) -> RunError:
    why = "the disk is full" if exc.errno == errno.ENOSPC else exc.strerror or str(exc)
    return RunError(f"cannot write the bag {out}: {why}")


def _qos(latched: bool) -> list[Any]:
    """The offered QoS a bag records for a topic (``ros2 bag play`` offers it again): reliable, keep last 1,
    transient local when ``latched``, else volatile."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    infinite = QosTime(0x7FFFFFFF, 0xFFFFFFFF)
    durability = QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE
    return [Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, durability, infinite, infinite,
                QosLiveliness.AUTOMATIC, infinite, False)]
