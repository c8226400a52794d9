"""Zenoh session helpers: router/client configs, reliable publishers, and the asyncio bridge.

zenoh-python has no async API: callbacks run on zenoh's threads, so :class:`Inbox` only copies the bytes
and hands them to the event loop with ``call_soon_threadsafe`` (docs/design/architecture.md, "Dependencies").
"""

from __future__ import annotations

import asyncio
import collections
import json
import os
import threading
from typing import Any

import zenoh

from fleet_emu.core.access import Credential
from fleet_emu.core.errors import ConfigError

# Zenoh's default lease. A killed process is still noticed at once (its TCP link closes); a frozen one is caught by
# the barrier timeout. A 1 s lease expired under load here (load average 8 on 2 cores) and failed healthy robots.
LEASE_MS = 10_000
NONCE_BYTES = 8

# Zenoh's shared-memory transport is off unless FLEET_ZENOH_SHM=1. On (Zenoh's default), every session makes a
# 16 MB pool and sends each message over 3 kB through it, so every receiver maps every sender's pool: netem and
# the router, which hear every robot, grew by about 8 MB per robot each. benchmarks/scale.py, 80 robots on a
# 512 x 512 maze (load 27-33 on 2 cores): PSS per agent 33 -> 13 MB, netem 719 -> 88 MB, launcher 759 -> 112 MB,
# and CPU per robot-tick 31.3 -> 17.5 ms with it off.


def shm_enabled() -> bool:
    """Whether the fleet's sessions use Zenoh's shared-memory transport (``FLEET_ZENOH_SHM=1``)."""
    return os.environ.get("FLEET_ZENOH_SHM") == "1"


def _common_config(mode: str) -> zenoh.Config:
    """The settings a router's and a client's configurations share (``mode``: ``router`` or ``client``)."""
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
    conf = _common_config("router")
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
    conf = _common_config("client")
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    if credential is not None:
        conf.insert_json5("transport/auth/usrpwd/user", json.dumps(credential.user))
        conf.insert_json5("transport/auth/usrpwd/password", json.dumps(credential.password))
        if credential.tls_ca is not None:
            conf.insert_json5("transport/link/tls/root_ca_certificate", json.dumps(credential.tls_ca))
    return conf


def open_client(endpoint: str, credential: Credential | None, timeout_s: float, *, example: str, refused: str = "",
                hint: str = "") -> zenoh.Session:
    """A client session to the router at ``endpoint`` (``--connect``) that stops trying after ``timeout_s``; a
    ConfigError of one line when ``endpoint`` is not a Zenoh endpoint (``example``: one that is) or no router
    answered in time (the line adds ``refused`` and then ``hint``: what the credentials may have to do with it)."""
    try:
        conf = client_config(endpoint, credential)
        ms = int(timeout_s * 1000)
        conf.insert_json5("connect/timeout_ms", f'{{"router": -1, "peer": -1, "client": {ms}}}')
    except zenoh.ZError:
        raise ConfigError(f"--connect {endpoint!r} is not a Zenoh endpoint (expected <protocol>/<address>, "
                          f"e.g. {example})") from None
    try:
        return zenoh.open(conf)
    except zenoh.ZError:
        raise ConfigError(f"--connect {endpoint}: no Zenoh router answered{refused} (gave up after "
                          f"{timeout_s:g} s){hint}") from None


def router_locators(session: zenoh.Session) -> list[str]:
    """The endpoints the router embedded in ``session`` listens on, from its admin space."""
    zid = str(session.info.zid())
    for reply in session.get(f"@/{zid}/router"):
        if reply.ok is not None:
            return list(json.loads(reply.ok.payload.to_bytes()).get("locators", []))
    return []


class Publisher:
    """A reliable, blocking publisher whose every put carries the run's nonce (when given) as its Zenoh
    attachment: a receiver of the run drops what carries another (docs/design/security.md, "Run nonce")."""

    def __init__(self, pub: zenoh.Publisher, nonce: bytes | None) -> None:
        self.pub = pub
        self.attachment = zenoh.ZBytes(nonce) if nonce is not None else None  # made once, put with every message

    def put(self, data: bytes) -> None:
        self.pub.put(data, attachment=self.attachment)

    def undeclare(self) -> None:
        self.pub.undeclare()


def publisher(session: zenoh.Session, key_expr: str, nonce: bytes | None = None) -> Publisher:
    """A reliable, blocking publisher: the only losses in the system are the ones netem decides. ``nonce``:
    the run's nonce, put on every message (none for the hosts' lobby, which is not a run's)."""
    return Publisher(session.declare_publisher(
        key_expr, congestion_control=zenoh.CongestionControl.BLOCK, reliability=zenoh.Reliability.RELIABLE
    ), nonce)


def new_nonce() -> bytes:
    """A run's nonce: 8 bytes from the OS's entropy, never from the seed (it changes nothing a seed decides)."""
    return os.urandom(NONCE_BYTES)


def of_run(sample: zenoh.Sample, nonce: bytes) -> bool:
    """Whether ``sample`` carries the run's ``nonce`` as its attachment."""
    att = sample.attachment
    return att is not None and att.to_bytes() == nonce


class Inbox:
    """A queue of ``(key, payload, is_put)`` fed from zenoh callbacks into one asyncio loop. With ``nonce``, a
    message that does not carry it (another run's, a replayed recording's) is dropped in the callback and
    counted in :attr:`foreign`; liveliness changes carry no nonce and are all let through.

    The items go into a deque, and the loop is woken (``call_soon_threadsafe``: a write to its self-pipe, then
    an epoll wake-up and a read on the loop's side) once per burst, not once per item: a callback finding a
    wake-up already pending only appends. :meth:`get` takes an item already there without waiting. Netem and
    the world hear every robot each tick, a robot its observation and rx bundle."""

    def __init__(self, loop: asyncio.AbstractEventLoop | None = None, nonce: bytes | None = None) -> None:
        self.loop = loop or asyncio.get_running_loop()
        self.nonce = nonce
        self.foreign = 0
        self._items: collections.deque[tuple[str, bytes, bool]] = collections.deque()  # appends: thread-safe
        self._waiter: asyncio.Future[None] | None = None  # the pending get's, on the loop
        self._wake_pending = False  # a wake-up is scheduled on the loop and has not run yet
        self._lock = threading.Lock()  # zenoh calls back from several threads
        #: A key whose items are queued without waking the loop (None: every item wakes it), set by the loop: a
        #: robot waiting for its rx bundle has no use for its observation alone, which comes first. The loop
        #: clears it before it needs such an item, then finds any queued meanwhile (:meth:`get` takes an item
        #: already there without waiting; a callback appends its item before it reads this).
        self.quiet: str | None = None

    def callback(self, sample: zenoh.Sample) -> None:
        """The zenoh callback: drop a message of another run, else copy the bytes out and return at once."""
        if self.nonce is not None and not of_run(sample, self.nonce):
            with self._lock:
                self.foreign += 1
            return
        self._enqueue(sample)

    def _enqueue(self, sample: zenoh.Sample) -> None:
        self.put_nowait((str(sample.key_expr), sample.payload.to_bytes(), sample.kind == zenoh.SampleKind.PUT))

    def put_nowait(self, item: tuple[str, bytes, bool]) -> None:
        """Queue ``item`` (from any thread) and wake the loop unless its key is :attr:`quiet` or a wake-up is
        already pending: that one runs after this append, so it finds the item."""
        self._items.append(item)
        if item[0] == self.quiet:
            return
        with self._lock:
            if self._wake_pending:
                return
            self._wake_pending = True
        try:
            self.loop.call_soon_threadsafe(self._wake)
        except RuntimeError:  # the loop closed during shutdown
            with self._lock:
                self._wake_pending = False

    def _wake(self) -> None:
        """On the loop: let a later item schedule its own wake-up, then settle the pending get."""
        with self._lock:
            self._wake_pending = False
        waiter = self._waiter
        if waiter is not None and not waiter.done():
            waiter.set_result(None)

    def subscribe(self, session: zenoh.Session, key_expr: str) -> zenoh.Subscriber:
        return session.declare_subscriber(key_expr, self.callback)

    def watch_liveliness(self, session: zenoh.Session, key_expr: str) -> zenoh.Subscriber:
        """Liveliness changes under ``key_expr`` arrive as items with ``is_put`` False on deletion (tokens
        declared before this subscriber are announced too, so a later deletion is never missed)."""
        return session.liveliness().declare_subscriber(key_expr, self._enqueue, history=True)

    async def get(self, timeout: float | None = None) -> tuple[str, bytes, bool] | None:
        """The next item, or None after ``timeout`` seconds (one get at a time)."""
        deadline = None if timeout is None else self.loop.time() + timeout
        while not self._items:  # a wake-up may come for an item already taken: wait again
            waiter = self._waiter = self.loop.create_future()
            try:
                if deadline is None:
                    await waiter
                else:
                    await asyncio.wait_for(waiter, max(0.0, deadline - self.loop.time()))
            except TimeoutError:
                return self._items.popleft() if self._items else None
            finally:
                self._waiter = None
        return self._items.popleft()
