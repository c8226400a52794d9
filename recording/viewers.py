"""The live server's viewers as the kernel sees them: each accepted connection of the server's port in this
process, how many bytes it still has queued and how many it has had acknowledged. The ``foxglove-sdk`` server
bounds each client's queue in messages (dropping the oldest) but has no way to drop one client, and its stop
waits for every client's socket to take what was sent: a viewer that stops reading would hold the run for as long
as it stays connected. :class:`ViewerWatch` drops such a viewer (a ``shutdown`` of its socket, which ends the
SDK's send to it at once), during the run and at the server's stop, and logs it.

A viewer is *stalled* when bytes wait in its socket and none of them was acknowledged for :data:`STALL_S`
seconds (a slow viewer that reads at all is kept: the SDK drops its oldest messages instead)."""

from __future__ import annotations

import contextlib
import dataclasses
import fcntl
import logging
import os
import socket
import struct
import threading
import time
from collections.abc import Iterator

log = logging.getLogger(__name__)

STALL_S = 5.0  # seconds without an acknowledged byte, bytes waiting, before a viewer is dropped
CHECK_S = 0.5  # seconds between two looks at the viewers
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


def stalled(now: float, seen: dict[str, tuple[int | None, float]], viewers: list[Viewer]) -> list[str]:
    """The viewers stalled for :data:`STALL_S` at ``now``; ``seen`` (peer -> acked, since when) is updated."""
    out: list[str] = []
    for v in viewers:
        last = seen.get(v.peer)
        if v.queued == 0 or last is None or (v.acked is not None and v.acked != last[0]):
            seen[v.peer] = (v.acked, now)  # nothing waits, or it progressed: the clock starts again
        elif now - last[1] >= STALL_S:
            out.append(v.peer)
    for peer in set(seen) - {v.peer for v in viewers}:
        del seen[peer]  # gone
    return out


def drop(port: int, peers: set[str] | None, why: str) -> list[str]:
    """Shut down the connections of ``port`` to ``peers`` (None: every one), logging each."""
    gone: list[str] = []
    with connections(port) as conns:
        for peer, sock in conns.items():
            try:
                v = measure(peer, sock)
                if peers is None or peer in peers:
                    sock.shutdown(socket.SHUT_RDWR)
                    gone.append(peer)
                    log.warning("live: dropped the viewer at %s (%s; %d bytes unread)", peer, why, v.queued)
            except OSError:
                continue
    return gone


class ViewerWatch:
    """A thread that looks at the viewers of ``port`` every :data:`CHECK_S` and drops the stalled ones."""

    def __init__(self, port: int) -> None:
        self.port = port
        self.dropped: list[str] = []
        self._stop = threading.Event()
        self._seen: dict[str, tuple[int | None, float]] = {}
        self._thread = threading.Thread(target=self._run, name="live-viewers", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(CHECK_S):
            try:
                self.check(time.monotonic())
            except Exception:  # a look that fails changes nothing; the next one tries again
                log.debug("live: cannot look at the viewers", exc_info=True)

    def check(self, now: float) -> None:
        """One look: drop the viewers stalled for :data:`STALL_S`."""
        with connections(self.port) as conns:
            viewers = []
            for peer, sock in conns.items():
                with contextlib.suppress(OSError):
                    viewers.append(measure(peer, sock))
        late = stalled(now, self._seen, viewers)
        if late:
            self.dropped += drop(self.port, set(late), f"nothing read for {STALL_S:g} s")

    def close(self) -> None:
        self._stop.set()
        self._thread.join()
