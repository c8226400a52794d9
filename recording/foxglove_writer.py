"""The launcher's shell around :class:`~fleet_emu.recording.foxglove.FoxgloveFold`: it decodes the bus samples
the fold needs and writes the derived Foxglove messages into ``run.mcap`` through the recorder (when recording)
and to the live viewers (:class:`~fleet_emu.recording.live.LiveServer`, with ``fleet run --live``). A failure in
it never stops the run."""

from __future__ import annotations

import logging
from typing import Any

from fleet_emu.core.access import allowed_src
from fleet_emu.core.codec import DecodeError, decode
from fleet_emu.core.keys import Keys
from fleet_emu.core.messages import Message
from fleet_emu.recording.foxglove import Derived, FoxgloveFold, schema_text

log = logging.getLogger(__name__)

#: The channels the fold uses (``ParsedKey.channel``); the rest is not even decoded.
_FOLDED = frozenset({"obs", "state", "links", "cmd", "belief", "stop"})


class FoxgloveWriter:
    """The launcher's shell: decodes what the fold needs and writes its output through a recorder."""

    def __init__(self, recorder: Any, fold: FoxgloveFold, keys: Keys, live: Any = None) -> None:
        self.recorder = recorder  # None: live only
        self.live = live
        self.keys = keys
        self.fold = fold
        self.schema_ids: dict[str, int] = {}
        self.failed = False
        self.finished = False
        self.written = 0

    def feed(self, key: str, data: bytes, time_ns: int | None = None, msg: Message | None = None) -> None:
        """One bus sample (a ``SampleFold``, ``core/fold.py``; ``time_ns`` is not used: the derived messages
        carry the run's clock); ``msg`` is its decoded message when the caller has it already."""
        parsed = self.keys.parse(key)
        if self.failed or parsed is None or parsed.channel not in _FOLDED:
            return
        try:
            if msg is None:
                try:
                    msg = decode(data)
                except DecodeError:
                    return
                allowed = allowed_src(parsed)
                if allowed is not None and msg.src not in allowed:  # a spoofed sender (the monitor's rule)
                    return
            self._write(self.fold.fold(msg))
        except Exception:  # a viewer channel must never stop the run
            log.exception("foxglove channels disabled after an error")
            self.failed = True

    def finish(self) -> None:
        """The fold's last messages, once (a second call does nothing)."""
        if self.failed or self.finished:
            return
        self.finished = True
        try:
            self._write(self.fold.finish())
        except Exception:
            log.exception("foxglove channels: error at the end of the run")
            self.failed = True

    def _write(self, derived: list[Derived]) -> None:
        if self.live is not None:
            self.live.publish(derived)
        if self.recorder is None:
            return
        for d in derived:
            sid = self.schema_ids.get(d.schema)
            if sid is None:
                sid = self.recorder.register_schema(d.schema, "jsonschema", schema_text(d.schema))
                self.schema_ids[d.schema] = sid
            self.recorder.add_channel_message(d.topic, sid, "json", d.data, d.tick)
            self.written += 1
