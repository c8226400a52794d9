"""Zenoh session helpers: router/client configs, reliable publishers, and the asyncio bridge.

zenoh-python has no async API: callbacks run on zenoh's threads, so :class:`Inbox` only copies the bytes
and hands them to the event loop with ``call_soon_threadsafe`` (docs/design/architecture.md, "Dependencies").
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
from typing import Any

import zenoh

from fleet_emu.core.access import Credential

# Zenoh's default lease. A killed process is still noticed at once (its TCP link closes); a frozen one is caught by
# the barrier timeout. A 1 s lease expired under load here (load average 8 on 2 cores) and failed healthy robots.
LEASE_MS = 10_000

# Zenoh's shared-memory transport is off unless FLEET_ZENOH_SHM=1. On (Zenoh's default), every session makes a
# 16 MB pool and sends each message over 3 kB through it, so every receiver maps every sender's pool: netem and
# the router, which hear every robot, grew by about 8 MB per robot each. benchmarks/scale.py, 80 robots on a
# 512 x 512 maze (load 27-33 on 2 cores): PSS per agent 33 -> 13 MB, netem 719 -> 88 MB, launcher 759 -> 112 MB,
# and CPU per robot-tick 31.3 -> 17.5 ms with it off.


def shm_enabled() -> bool:
    """Whether the fleet's sessions use Zenoh's shared-memory transport (``FLEET_ZENOH_SHM=1``)."""
    return os.environ.get("FLEET_ZENOH_SHM") == "1"


def _base(mode: str) -> zenoh.Config:
    conf = zenoh.Config()
    conf.insert_json5("mode", json.dumps(mode))
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("transport/link/tx/lease", str(LEASE_MS))
    if not shm_enabled():
        conf.insert_json5("transport/shared_memory/enabled", "false")
    return conf


def router_config(listen: str | list[str] = "tcp/127.0.0.1:0", dictionary_file: str | None = None,
                  acl: dict[str, Any] | None = None, tls: tuple[str, str] | None = None) -> zenoh.Config:
    """An embedded loopback router (or one listening on ``listen``, an endpoint or several); port 0 lets the
    OS pick (read it back with :func:`router_locators`). With ``dictionary_file`` (``user:password`` lines) it
    refuses sessions without valid credentials, with ``acl`` (``fleet_emu.core.access.acl_config``) it filters
    what each user may put, and ``tls`` (its certificate and private key, PEM files) serves ``tls/`` and
    ``quic/`` endpoints."""
    conf = _base("router")
    conf.insert_json5("listen/endpoints", json.dumps([listen] if isinstance(listen, str) else listen))
    if tls is not None:
        conf.insert_json5("transport/link/tls/listen_certificate", json.dumps(tls[0]))
        conf.insert_json5("transport/link/tls/listen_private_key", json.dumps(tls[1]))
    conf.insert_json5("scouting/delay", "0")
    conf.insert_json5("adminspace/enabled", "true")
    if dictionary_file is not None:
        conf.insert_json5("transport/auth/usrpwd/dictionary_file", json.dumps(dictionary_file))
    if acl is not None:
        conf.insert_json5("access_control", json.dumps(acl))
    return conf


def client_config(endpoint: str, credential: Credential | None = None) -> zenoh.Config:
    """A client session to the router at ``endpoint`` (e.g. ``tcp/127.0.0.1:7447``), logged in as
    ``credential`` (and trusting its TLS CA) when given."""
    conf = _base("client")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    if credential is not None:
        conf.insert_json5("transport/auth/usrpwd/user", json.dumps(credential.user))
        conf.insert_json5("transport/auth/usrpwd/password", json.dumps(credential.password))
        if credential.tls_ca is not None:
            conf.insert_json5("transport/link/tls/root_ca_certificate", json.dumps(credential.tls_ca))
    return conf


def router_locators(session: zenoh.Session) -> list[str]:
    """The endpoints the router embedded in ``session`` listens on, from its admin space."""
    zid = str(session.info.zid())
    for reply in session.get(f"@/{zid}/router"):
        if reply.ok is not None:
            return list(json.loads(reply.ok.payload.to_bytes()).get("locators", []))
    return []


def publisher(session: zenoh.Session, key_expr: str) -> zenoh.Publisher:
    """A reliable, blocking publisher: the only losses in the system are the ones netem decides."""
    return session.declare_publisher(
        key_expr, congestion_control=zenoh.CongestionControl.BLOCK, reliability=zenoh.Reliability.RELIABLE
    )


class Inbox:
    """A queue of ``(key, payload, is_put)`` fed from zenoh callbacks into one asyncio loop."""

    def __init__(self, loop: asyncio.AbstractEventLoop | None = None) -> None:
        self.loop = loop or asyncio.get_running_loop()
        self.queue: asyncio.Queue[tuple[str, bytes, bool]] = asyncio.Queue()

    def callback(self, sample: zenoh.Sample) -> None:
        """The zenoh callback: copy the bytes out and return at once."""
        item = (str(sample.key_expr), sample.payload.to_bytes(), sample.kind == zenoh.SampleKind.PUT)
        with contextlib.suppress(RuntimeError):  # the loop closed during shutdown
            self.loop.call_soon_threadsafe(self.queue.put_nowait, item)

    def subscribe(self, session: zenoh.Session, key_expr: str) -> zenoh.Subscriber:
        return session.declare_subscriber(key_expr, self.callback)

    def watch_liveliness(self, session: zenoh.Session, key_expr: str) -> zenoh.Subscriber:
        """Liveliness changes under ``key_expr`` arrive as items with ``is_put`` False on deletion (tokens
        declared before this subscriber are announced too, so a later deletion is never missed)."""
        return session.liveliness().declare_subscriber(key_expr, self.callback, history=True)

    async def get(self, timeout: float | None = None) -> tuple[str, bytes, bool] | None:
        """The next item, or None after ``timeout`` seconds."""
        try:
            return await asyncio.wait_for(self.queue.get(), timeout)
        except TimeoutError:
            return None

