"""A run served live over the Foxglove WebSocket protocol, with the ``foxglove-sdk`` package's server and typed
schemas: the same topics as the recording's Foxglove channels (:mod:`~fleet_emu.recording.foxglove`), so one
layout shows both.

:class:`LiveServer` takes the fold's derived messages (JSON, as written into ``run.mcap``) and logs each as the
SDK's typed message (``foxglove.Grid``, ``foxglove.SceneUpdate``, ``foxglove.Log``: protobuf on the wire) or, for
``/viz/stats``, as JSON on a channel with its JSON schema. Logging never waits for a viewer: the SDK queues each
client's messages (at most :data:`BACKLOG`, dropping the oldest for a slow one), a viewer that stops reading is
dropped (:class:`~fleet_emu.recording.viewers.ViewerWatch`), and the server's stop has a deadline. The grids
are latched: a client that subscribes mid-run gets the latest of each with the run's next messages. The SDK
can only log to every subscriber of a channel, so the latest grids go to all of them again; they go once for
all the viewers that subscribed within :data:`RESEND_S` (twenty viewers arriving one by one would otherwise
send each grid twenty times to each of them).

Every channel of the run (:func:`~fleet_emu.recording.foxglove.live_topics`: the scene, the maps, each robot's
belief, the log, the stats) exists before the server starts: a client is advertised all of them in the one
advertisement it gets on connecting, and subscribes to them before the run logs anything. (A channel made
mid-run is advertised to the connected clients while they may still be connecting; the SDK then lost some of
their subscriptions, ``attempted to subscribe to unknown channel``, and the channel stayed dead for them.)
"""

from __future__ import annotations

import base64
import logging
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import foxglove
import foxglove.channels as fc
import foxglove.messages as fm
from foxglove.websocket import ChannelView, Client, ServerListener

from fleet_emu.recording.clock import RunClock
from fleet_emu.recording.foxglove import Derived
from fleet_emu.recording.stats import SCHEMA_STATS, STATS_SCHEMA
from fleet_emu.recording.viewers import ViewerWatch

log = logging.getLogger(__name__)

DEFAULT_HOST = "127.0.0.1"
BACKLOG = 4096  # messages queued per client before the oldest are dropped
RESEND_S = 1.0  # seconds between two sends of the latched grids to viewers that subscribed meanwhile
LINGER = 0.5  # seconds the server stays up after the run, for its last messages to reach the viewers
STOP_S = 2.0  # seconds the server's stop may take before every viewer still connected is dropped

# nested JSON fields -> the SDK's typed message of that field (a list field: each item's type)
_TYPES: dict[str, Any] = {
    "timestamp": fm.Timestamp, "lifetime": fm.Duration, "pose": fm.Pose, "position": fm.Vector3,
    "orientation": fm.Quaternion, "size": fm.Vector3, "cell_size": fm.Vector2, "color": fm.Color,
    "colors": fm.Color, "points": fm.Point3, "metadata": fm.KeyValuePair, "cubes": fm.CubePrimitive,
    "spheres": fm.SpherePrimitive, "cylinders": fm.CylinderPrimitive, "lines": fm.LinePrimitive,
    "texts": fm.TextPrimitive, "entities": fm.SceneEntity, "deletions": fm.SceneEntityDeletion,
    "fields": fm.PackedElementField,
}
# integer enums, by the message type that holds them
_ENUMS: dict[Any, tuple[str, Any]] = {
    fm.Log: ("level", fm.LogLevel), fm.LinePrimitive: ("type", fm.LinePrimitiveLineType),
    fm.SceneEntityDeletion: ("type", fm.SceneEntityDeletionType),
    fm.PackedElementField: ("type", fm.PackedElementFieldNumericType),
}
_TOP: dict[str, tuple[Any, Callable[..., Any]]] = {
    "foxglove.Grid": (fm.Grid, fc.GridChannel), "foxglove.SceneUpdate": (fm.SceneUpdate, fc.SceneUpdateChannel),
    "foxglove.Log": (fm.Log, fc.LogChannel),
}
_SKIP = frozenset({"arrows", "triangles", "models"})  # primitives the fold never draws (always empty)


def _enum(kind: Any, value: int) -> Any:
    return next(getattr(kind, n) for n in dir(kind) if n[:1].isupper() and getattr(kind, n).value == value)


def typed(cls: Any, obj: dict[str, Any]) -> Any:
    """The SDK's typed message ``cls`` of a JSON message of its schema (as the fold writes them)."""
    kwargs: dict[str, Any] = {}
    enum = _ENUMS.get(cls)
    for key, value in obj.items():
        if key in _SKIP:
            continue
        sub = _TYPES.get(key)
        if enum is not None and key == enum[0]:
            kwargs[key] = _enum(enum[1], int(value))
        elif key == "data" and cls is fm.Grid:
            kwargs[key] = base64.b64decode(value)
        elif sub is not None and isinstance(value, list):
            kwargs[key] = [typed(sub, v) for v in value]
        elif sub is not None and isinstance(value, dict):
            kwargs[key] = typed(sub, value)
        else:
            kwargs[key] = value
    return cls(**kwargs)


def parse_live(text: str) -> tuple[str, int]:
    """``[HOST:]PORT`` -> (host, port); the host defaults to loopback. Raises ValueError on bad input."""
    host, _, port = text.rpartition(":")
    host = host.strip("[]") or DEFAULT_HOST
    if not port.isdigit() or not 0 <= int(port) <= 65535:
        raise ValueError(f"--live wants [HOST:]PORT with a port from 0 to 65535, not {text!r}")
    return host, int(port)


class LiveServer(ServerListener):
    """The run's Foxglove WebSocket server (its own SDK context, so nothing else logs into it); it is its own
    listener, to latch the grids."""

    def __init__(self, host: str, port: int, clock: RunClock, name: str = "fleet-emu",
                 topics: Sequence[tuple[str, str]] = ()) -> None:
        self.clock = clock
        self.context = foxglove.Context()
        self._channels: dict[str, Any] = {}
        for topic, schema in topics:  # advertised from the start: see the module's docstring
            self._channel(topic, schema)
        self._latest: dict[str, tuple[Any, int, int]] = {}  # latched topics (the grids): last message, time, bytes
        self._resend: set[str] = set()  # latched topics a viewer subscribed to since they were last sent
        self._resend_at = 0.0  # the monotonic time before which they are not sent again
        self._lock = threading.Lock()
        self.failed = False
        self.first_tick = 0.0  # the monotonic time before which the run's first tick must not come (launch/live.py)
        self.published = 0
        self.watched = False  # a viewer subscribed at some point
        self.server = foxglove.start_server(name=name, host=host, port=port, context=self.context,
                                            server_listener=self, message_backlog_size=BACKLOG)
        self.host = host
        self.published_bytes = 0  # what the viewers were sent, roughly (the JSON form): bounds a stalled one's queue
        self.viewers = ViewerWatch(self.server.port, lambda: self.published_bytes)

    @property
    def port(self) -> int:
        return self.server.port

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"

    def publish(self, derived: list[Derived]) -> None:
        """Log the fold's messages to every connected viewer; an error turns the live view off, never the run."""
        if self.failed:
            return
        try:
            self._send_latched()
            for d in derived:
                self._publish(d)
        except Exception:
            log.exception("live view disabled after an error")
            self.failed = True

    def _publish(self, d: Derived) -> None:
        t = self.clock.ns(d.tick)
        with self._lock:
            channel = self._channels.get(d.topic)
            if channel is None:
                channel = self._channel(d.topic, d.schema)
            if d.schema == SCHEMA_STATS:
                msg: Any = d.data
            else:
                msg = typed(_TOP[d.schema][0], d.obj())
            if d.schema == "foxglove.Grid":
                self._latest[d.topic] = (msg, t, len(d.data))
            channel.log(msg, log_time=t)
            self.published += 1
            self.published_bytes += len(d.data)

    def _send_latched(self) -> None:
        """The latest grid of each topic viewers subscribed to since the last send, once for them all (see the
        module); at most every :data:`RESEND_S`."""
        now = time.monotonic()
        if not self._resend or now < self._resend_at:
            return
        self._resend_at = now + RESEND_S
        with self._lock:
            for topic in list(self._resend):
                self._resend.discard(topic)
                latest = self._latest.get(topic)
                if latest is not None:
                    self._channels[topic].log(latest[0], log_time=latest[1])
                    self.published_bytes += latest[2]

    def _channel(self, topic: str, schema: str) -> Any:
        if schema == SCHEMA_STATS:
            channel: Any = foxglove.Channel(topic, schema=STATS_SCHEMA, message_encoding="json", context=self.context)
        else:
            channel = _TOP[schema][1](topic, context=self.context)
        self._channels[topic] = channel
        return channel

    # --- the SDK's ServerListener ------------------------------------------------------------------------

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        """A viewer subscribed: its topic's latest grid goes out with the run's next messages (see the module;
        nothing here waits on the run's thread)."""
        self.watched = True
        if channel.topic in self._latest:
            self._resend.add(channel.topic)

    def close(self) -> None:
        """Stop serving; a watched run first lingers a moment (stopping drops what is still queued). The SDK's
        stop waits for each viewer to take what it was sent: one that has not within :data:`STOP_S` is dropped,
        and a server that still does not stop is left to the process's exit (a run never waits on a viewer)."""
        if self.watched:
            time.sleep(LINGER)
        self.viewers.close()
        stopper = threading.Thread(target=self.server.stop, name="live-stop", daemon=True)
        stopper.start()
        stopper.join(STOP_S)
        if stopper.is_alive():
            self.viewers.drop_all(f"the server's stop waited {STOP_S:g} s for it")
            stopper.join(STOP_S)
        if stopper.is_alive():
            log.warning("live: the server did not stop within %g s; the run goes on without it", 2 * STOP_S)
        else:
            self.viewers.release()
