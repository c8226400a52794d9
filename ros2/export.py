"""``fleet export ros2 RUN_DIR [--out BAG]``: a recording as a rosbag2 — MCAP storage, CDR messages, with its
``metadata.yaml`` — of the live bridge's topics (:mod:`.fold`), written with ``rosbags``' rosbag2 writer, so
``ros2 bag info/play`` and rosbags read it. Every message's bag time and header stamp is its tick on the run's
clock (the recording's ``start_ns`` and ``tick_s``); the latched topics are offered transient local."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Literal

import numpy as np
from mcap.records import Channel, Metadata
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader

from fleet_emu.core.codec import decode
from fleet_emu.core.errors import ConfigError, DecodeError, ReportError
from fleet_emu.core.grid import MapData
from fleet_emu.core.messages import Message
from fleet_emu.recording.clock import RunClock
from fleet_emu.recording.read import resolve
from fleet_emu.recording.recorder import SCENARIO_METADATA
from fleet_emu.ros2.fold import Out, Ros2Fold
from fleet_emu.ros2.types import cdr, typestore

BAG_VERSION: Literal[9] = 9  # rosbag2's metadata version of Jazzy


def recorded(mcap: Path) -> tuple[dict[str, str], Iterator[Message]]:
    """The recording's ``scenario`` metadata and its bus messages (decoded, in file order; a cut last chunk
    ends them). Reads the metadata first: the recorder writes it before any message."""
    f = open(mcap, "rb")  # noqa: SIM115 (closed by the generator)
    records = StreamReader(f, record_size_limit=max(mcap.stat().st_size, 1)).records
    channels: dict[int, Channel] = {}
    first: list[McapMessage] = []
    meta: dict[str, str] | None = None
    for rec in _safe(records):
        if isinstance(rec, Metadata) and rec.name == SCENARIO_METADATA:
            meta = dict(rec.metadata)
            break
        if isinstance(rec, Channel):
            channels[rec.id] = rec
        elif isinstance(rec, McapMessage):
            first.append(rec)
    if meta is None:
        f.close()
        raise ReportError(f"{mcap} has no '{SCENARIO_METADATA}' metadata: not a fleet recording")

    def messages() -> Iterator[Message]:
        with f:
            for rec in [*first, *_safe(records)]:
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


def _safe(records: Iterator[Any]) -> Iterator[Any]:
    """The records up to the end, or up to where a cut file ends inside one."""
    while True:
        try:
            yield next(records)
        except StopIteration:
            return
        except Exception:
            return


def fold_for(meta: dict[str, str], run_dir: Path) -> Ros2Fold:
    """The fold of a recording: its scenario and clock, and the true map from the run's ``map.npz``."""
    try:
        scenario = json.loads(meta["scenario"])
        clock = RunClock(int(meta.get("start_ns", 0)), float(meta.get("tick_s", 1.0)))
    except (KeyError, ValueError, TypeError) as exc:
        raise ReportError(f"unreadable scenario metadata ({exc})") from None
    npz = run_dir / "map.npz"
    truth: np.ndarray | None = MapData.load(npz).grid if npz.is_file() else None
    return Ros2Fold(scenario, truth, clock=clock)


def export(run: Path, out: Path | None = None) -> tuple[Path, dict[str, int]]:
    """Write the rosbag2 of recording ``run`` (RUN_DIR or RUN.mcap) to ``out`` (default ``<run dir>/ros2``),
    which must not exist; its path and the messages per topic."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.writer import WriterError

    mcap = resolve(run)
    out = out if out is not None else mcap.parent / "ros2"
    if out.exists():
        raise ConfigError(f"--out {out} exists: give a new directory for the bag")
    meta, messages = recorded(mcap)
    fold = fold_for(meta, mcap.parent)
    counts: dict[str, int] = {}
    try:
        writer = Writer(out, version=BAG_VERSION, storage_plugin=StoragePlugin.MCAP)
    except WriterError as exc:
        raise ConfigError(f"--out {out}: {exc}") from None
    connections: dict[str, Any] = {}
    with writer:
        def write(items: list[Out]) -> None:
            for o in items:
                conn = connections.get(o.topic)
                if conn is None:
                    conn = connections[o.topic] = writer.add_connection(
                        o.topic, o.typename, typestore=typestore(), offered_qos_profiles=_qos(o.latched))
                writer.write(conn, fold.clock.ns(o.tick), cdr(o.msg, o.typename))
                counts[o.topic] = counts.get(o.topic, 0) + 1

        for msg in messages:
            write(fold.feed(msg))
        write(fold.finish())
    return out, counts


def _qos(latched: bool) -> list[Any]:
    """The offered QoS a bag records for a topic (``ros2 bag play`` offers it again): reliable, keep last 1,
    transient local when ``latched``, else volatile."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    infinite = QosTime(0x7FFFFFFF, 0xFFFFFFFF)
    durability = QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE
    return [Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, durability, infinite, infinite,
                QosLiveliness.AUTOMATIC, infinite, False)]
