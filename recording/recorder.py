"""The recorder: every sample on ``fleet/<run>/**`` into ``run.mcap``, one channel per key expression.

Messages keep their msgpack bytes (message encoding ``msgpack``, no schema). Log times follow the sim tick on the
run's clock (:class:`~fleet_emu.recording.clock.RunClock`: the run's UTC start plus tick x tick period), so
scrubbing a viewer's timeline moves through ticks; a raw sample's publish time is its wall-clock arrival, a derived
message's the log time.
The ``scenario`` metadata record holds what the launcher passes (``run_id``, the scenario as JSON) and the
versions it was written with: ``schema_version`` (:data:`fleet_emu.core.version.SCHEMA_VERSION`) and
``fleet_emu_version`` (:data:`fleet_emu.core.version.__version__`), and the clock's ``start_ns`` and ``tick_s``.
The writer closes a chunk and flushes at least once a second (and :data:`CHUNK_SIZE` bounds a chunk), so a
recording cut by a crash still reads up to the last flush and loses about a second at most; ``fleet recover``
makes such a file whole again (:mod:`.recover`). A write that fails (a full disk) stops the recording: the
error is kept in :attr:`Recorder.failed` for the launcher to end the run with, and nothing raises.
"""

from __future__ import annotations

import contextlib
import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer

from fleet_emu.core.codec import peek_tick
from fleet_emu.core.files import open_new
from fleet_emu.core.radio import RadioConfig
from fleet_emu.core.version import SCHEMA_VERSION, __version__
from fleet_emu.recording.clock import RunClock

FLUSH_SECONDS = 1.0
CHUNK_SIZE = 256 * 1024  # bytes of messages per chunk (before compression): a chunk is small
SCENARIO_METADATA = "scenario"


class Recorder:
    """Thread-safe MCAP writer; ``record`` may be called from any thread, ``close`` once at the end. The first
    write error (an OSError: a full disk) is kept in :attr:`failed` and ends the recording; later calls do
    nothing."""

    def __init__(self, path: Path, metadata: dict[str, Any], clock: RunClock | None = None) -> None:
        self.path = path
        self.clock = clock = clock or RunClock.now()
        self._file = open_new(path)  # a new file, never through a link planted there; closed in close()
        self.failed: OSError | None = None
        self._writer = Writer(self._file, compression=CompressionType.ZSTD, chunk_size=CHUNK_SIZE)
        self._writer.start(profile="", library="fleet-emu")
        versions = {"schema_version": str(SCHEMA_VERSION), "fleet_emu_version": __version__}
        record = {k: _text(v) for k, v in metadata.items()} | _radio(metadata) | versions | clock.metadata()
        self._writer.add_metadata(SCENARIO_METADATA, record)
        self._channels: dict[str, int] = {}
        self._lock = threading.Lock()
        self._last_flush = time.monotonic()
        self._last_tick = 0
        self.messages = 0
        self.closed = False

    def record(self, key: str, data: bytes, wall_ns: int | None = None) -> None:
        wall_ns = wall_ns if wall_ns is not None else time.time_ns()
        tick = peek_tick(data)
        with self._lock:
            if self.closed:
                return
            if tick is None or tick > self.clock.max_tick:  # no tick, or one no log time can hold (malformed, say):
                tick = self._last_tick  # logged at the latest tick
            self._last_tick = tick
            with self._fault():
                channel = self._channels.get(key)
                if channel is None:
                    channel = self._writer.register_channel(topic=key, message_encoding="msgpack", schema_id=0)
                    self._channels[key] = channel
                self._writer.add_message(channel_id=channel, log_time=self.clock.ns(tick), data=data,
                                         publish_time=wall_ns, sequence=self.messages)
                self.messages += 1
                self._maybe_flush()

    def add_channel_message(self, topic: str, schema_id: int, encoding: str, data: bytes, tick: int) -> None:
        """A derived message (e.g. a viewer channel with a schema) on its own topic."""
        with self._lock:
            if self.closed:
                return
            if not 0 <= tick <= self.clock.max_tick:  # derived from a message with a tick no log time can hold
                tick = self._last_tick
            with self._fault():
                channel = self._channels.get(topic)
                if channel is None:
                    channel = self._writer.register_channel(topic=topic, message_encoding=encoding, schema_id=schema_id)
                    self._channels[topic] = channel
                self._writer.add_message(channel_id=channel, log_time=self.clock.ns(tick), data=data,
                                         publish_time=self.clock.ns(tick), sequence=self.messages)
                self.messages += 1
                self._maybe_flush()

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        with self._lock, self._fault():
            return self._writer.register_schema(name=name, encoding=encoding, data=data)
        return 0  # the recording failed: nothing will be written on the schema's channels

    def _maybe_flush(self) -> None:
        now = time.monotonic()
        if now - self._last_flush >= FLUSH_SECONDS:
            self._writer.flush()
            self._last_flush = now

    def flush(self) -> None:
        with self._lock:
            if not self.closed:
                with self._fault():
                    self._writer.flush()
                    self._last_flush = time.monotonic()

    def close(self) -> int:
        """Finish the file (summary and index); returns the number of messages written."""
        with self._lock:
            if not self.closed:
                with self._fault():
                    self._writer.finish()
                    self.closed = True
                    self._file.close()
            return self.messages

    @contextlib.contextmanager
    def _fault(self) -> Iterator[None]:
        """Under the lock: an OSError of the block is kept in :attr:`failed` and closes the recording (the file
        as far as it got: ``fleet recover`` reads it)."""
        try:
            yield
        except OSError as exc:
            self.failed = self.failed or exc
            self.closed = True
            with contextlib.suppress(OSError, ValueError):
                self._file.close()


def _text(value: Any) -> str:
    return value if isinstance(value, str) else json.dumps(value)


def _radio(metadata: dict[str, Any]) -> dict[str, str]:
    """The radio model and the loss its channel applies (none on ``ideal``), stated beside the scenario."""
    radio = metadata.get("scenario", {}).get("radio") if isinstance(metadata.get("scenario"), dict) else None
    if not isinstance(radio, dict):
        return {}
    config = RadioConfig(comm=radio.get("comm", "wall"), loss=radio.get("loss", 0.0))
    return {"radio_model": config.comm, "loss_applied": repr(config.applied_loss)}
