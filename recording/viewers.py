"""The live server's viewers as the kernel sees them: each accepted connection of the server's port in this
process, how many bytes it still has queued and how many it has had acknowledged. The ``foxglove-sdk`` server
bounds each client's queue in messages (dropping the oldest) but has no way to drop one client, and its stop
waits for every client's socket to take what was sent: a viewer that stops reading would hold the run for as long
as it stays connected. :class:`ViewerWatch` drops such a viewer (a ``shutdown`` of its socket, which ends the
SDK's send to it at once), during the run and at the server's stop, and logs it.

A viewer is *stalled* when bytes wait in its socket and none of them was acknowledged for :data:`STALL_S`
seconds, or for :data:`MIN_STALL_S` while the server published :data:`STALL_BYTES` (the SDK queues a copy of
every message for each viewer: the bytes bound what a stalled viewer holds, whatever the run's rate). A slow
viewer that reads at all is kept: the SDK drops its oldest messages instead.

A dropped viewer is told once: one line each (never again while its connection lingers), and the SDK's own
lines about it (one ``Broken pipe`` per message still queued for it, the reset that ends it) are left out. Once
the SDK has closed its connection, the memory its queue held is handed back to the OS (``malloc_trim``)."""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import fcntl
import logging
import os
import re
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator

log = logging.getLogger(__name__)

STALL_S = 5.0  # seconds without an acknowledged byte, bytes waiting, before a viewer is dropped
MIN_STALL_S = 0.5  # ... or at least this long, while the server published STALL_BYTES
STALL_BYTES = 2 << 20
CHECK_S = 0.25  # seconds between two looks at the viewers
#: The SDK's loggers that name a client (``Error sending message to client HOST:PORT: ...``).
SDK_LOGGERS = ("foxglove.websocket.connected_client.poller", "foxglove.websocket.connected_client",
               "foxglove.websocket.server", "foxglove.websocket")
_CLIENT = re.compile(r"client (?:\[([0-9A-Fa-f:.]+)\]|([0-9.]+)):(\d+)")  # [IPv6]:PORT or IPv4:PORT
_SIOCOUTQ = 0x5411  # bytes in a socket's send queue, not yet acknowledged (Linux's TIOCOUTQ)
_BYTES_ACKED = 120  # offset of tcpi_bytes_acked (u64) in Linux's struct tcp_info


@dataclasses.dataclass(frozen=True)
class Viewer:
    """One connection as the kernel sees it: who, bytes waiting to be acknowledged, bytes acknowledged so far
    (None where the kernel does not say)."""

    peer: str
    queued: int
    acked: int | None


def _peer(sock: socket.socket, port: int) -> str | None:
    """``HOST:PORT`` of the client of an accepted connection of ``port``; None for any other socket."""
    if sock.family not in (socket.AF_INET, socket.AF_INET6) or sock.type != socket.SOCK_STREAM:
        return None
    if sock.getsockname()[1] != port:
        return None
    peer = sock.getpeername()  # the listening socket has none: OSError
    return f"{peer[0]}:{peer[1]}"


@contextlib.contextmanager
def connections(port: int) -> Iterator[dict[str, socket.socket]]:
    """This process's accepted TCP connections of ``port``, by client (duplicates of their descriptors: a
    ``shutdown`` acts on the connection, closing them does not)."""
    found: dict[str, socket.socket] = {}
    try:
        for name in os.listdir("/proc/self/fd"):
            try:
                if not os.readlink(f"/proc/self/fd/{name}").startswith("socket:"):
                    continue
                fd = os.dup(int(name))
            except OSError:  # closed meanwhile
                continue
            try:
                sock = socket.socket(fileno=fd)
            except OSError:
                os.close(fd)
                continue
            try:
                peer = _peer(sock, port)
            except OSError:
                peer = None
            if peer is None:
                sock.close()
            else:
                found[peer] = sock
        yield found
    finally:
        for sock in found.values():
            sock.close()


def measure(peer: str, sock: socket.socket) -> Viewer:
    """How far behind the viewer on ``sock`` is."""
    queued = struct.unpack("i", fcntl.ioctl(sock.fileno(), _SIOCOUTQ, b"\0" * 4))[0]
    info = sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_INFO, 256)
    acked = struct.unpack_from("Q", info, _BYTES_ACKED)[0] if len(info) >= _BYTES_ACKED + 8 else None
    return Viewer(peer, queued, acked)


def stalled(now: float, seen: dict[str, tuple[int | None, float, int]], viewers: list[Viewer],
            published: int = 0) -> list[str]:
    """The viewers stalled at ``now`` (see the module), the server having published ``published`` bytes so far;
    ``seen`` (peer -> acked, since when, published then) is updated."""
    out: list[str] = []
    for v in viewers:
        last = seen.get(v.peer)
        if v.queued == 0 or last is None or (v.acked is not None and v.acked != last[0]):
            seen[v.peer] = (v.acked, now, published)  # nothing waits, or it progressed: the clock starts again
            continue
        waited = now - last[1]
        if waited >= STALL_S or (waited >= MIN_STALL_S and published - last[2] >= STALL_BYTES):
            out.append(v.peer)
    for peer in set(seen) - {v.peer for v in viewers}:
        del seen[peer]  # gone
    return out


class Quiet(logging.Filter):
    """Leaves out the SDK's lines about a viewer that was dropped (it was told once), and all but the first
    about any other (a viewer gone on its own makes one ``Broken pipe`` per message still queued for it)."""

    def __init__(self) -> None:
        super().__init__()
        self.dropped: set[str] = set()
        self.told: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        m = _CLIENT.search(record.getMessage())
        if m is None:
            return True
        peer = f"{m.group(1) or m.group(2)}:{m.group(3)}"  # as ``connections`` names it: HOST:PORT
        if peer in self.dropped or peer in self.told:
            return False
        self.told.add(peer)
        return True


def trim() -> None:
    """Hand the memory freed by the SDK back to the OS (glibc keeps it in its arenas otherwise); a no-op off
    glibc."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).malloc_trim(0)


def drop(port: int, peers: set[str] | None, why: str, skip: set[str] | None = None,
         mark: Callable[[str], None] | None = None) -> list[str]:
    """Shut down the connections of ``port`` to ``peers`` (None: every one but ``skip``, those dropped before),
    logging each; ``mark(peer)`` is called first (so the SDK's lines about it can be left out)."""
    gone: list[str] = []
    with connections(port) as conns:
        for peer, sock in conns.items():
            if (peers is not None and peer not in peers) or (skip is not None and peer in skip):
                continue
            try:
                v = measure(peer, sock)
                if mark is not None:
                    mark(peer)
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                continue
            gone.append(peer)
            log.warning("live: dropped the viewer at %s (%s; %d bytes unread)", peer, why, v.queued)
    return gone


class ViewerWatch:
    """A thread that looks at the viewers of ``port`` every :data:`CHECK_S` and drops the stalled ones;
    ``published()`` is the bytes the server has published so far."""

    def __init__(self, port: int, published: Callable[[], int] = lambda: 0) -> None:
        self.port = port
        self.published = published
        self.dropped: list[str] = []  # every viewer dropped, once each
        self.quiet = Quiet()
        for name in SDK_LOGGERS:
            logging.getLogger(name).addFilter(self.quiet)
        self._lingering: set[str] = set()  # dropped, their connection not yet closed by the SDK
        self._stop = threading.Event()
        self._seen: dict[str, tuple[int | None, float, int]] = {}
        self._thread = threading.Thread(target=self._run, name="live-viewers", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(CHECK_S):
            try:
                self.check(time.monotonic())
            except Exception:  # a look that fails changes nothing; the next one tries again
                log.debug("live: cannot look at the viewers", exc_info=True)

    def check(self, now: float) -> None:
        """One look: drop the viewers stalled (see the module), each once."""
        with connections(self.port) as conns:
            viewers = []
            for peer, sock in conns.items():
                if peer not in self._lingering:
                    with contextlib.suppress(OSError):
                        viewers.append(measure(peer, sock))
            closed = self._lingering - set(conns)
        if closed:  # the SDK let go of their connections, and of their queues with them
            self._lingering -= closed
            trim()
        late = stalled(now, self._seen, viewers, self.published())
        if late:
            self._drop(set(late), f"nothing read for {now - min(self._seen[p][1] for p in late):.1f} s")

    def drop_all(self, why: str) -> None:
        """Drop every viewer still connected (but those dropped already)."""
        self._drop(None, why)

    def _drop(self, peers: set[str] | None, why: str) -> None:
        gone = drop(self.port, peers, why, skip=self._lingering, mark=self.quiet.dropped.add)
        self._lingering |= set(gone)
        self.dropped += gone

    def close(self) -> None:
        """Stop looking (the SDK's lines stay filtered until :meth:`release`: its last come as the server stops)."""
        self._stop.set()
        self._thread.join()

    def release(self) -> None:
        """Let the SDK's lines through again (the server has stopped)."""
        for name in SDK_LOGGERS:
            logging.getLogger(name).removeFilter(self.quiet)
