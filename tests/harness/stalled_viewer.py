"""A viewer that stops reading: a raw socket that completes the WebSocket handshake of a live run's Foxglove
server, reads the channels it advertises, subscribes to every one and then never reads again (its receive
buffer kept small, so the server's send to it stalls at once). Nothing here parses more than the handshake and
the advertisements: it is the least a client can do to be sent everything."""

from __future__ import annotations

import base64
import json
import os
import socket
import struct
import time
from urllib.parse import urlparse


def _frame(text: str) -> bytes:
    """One masked text frame (a client's frames are masked)."""
    data = text.encode()
    mask = os.urandom(4)
    n = len(data)
    head = bytes([0x81]) + (bytes([0x80 | n]) if n < 126 else bytes([0x80 | 126]) + struct.pack(">H", n))
    return head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(data))


class _Reader:
    """The server's frames off a socket, for as long as the viewer still reads."""

    def __init__(self, sock: socket.socket, rest: bytes) -> None:
        self.sock, self.buf = sock, rest

    def _need(self, n: int) -> bytes:
        while len(self.buf) < n:
            chunk = self.sock.recv(65536)
            if not chunk:
                raise ConnectionError("the server closed the connection")
            self.buf += chunk
        out, self.buf = self.buf[:n], self.buf[n:]
        return out

    def frame(self) -> tuple[int, bytes]:
        b0, b1 = self._need(2)
        n = b1 & 0x7F
        if n == 126:
            n = struct.unpack(">H", self._need(2))[0]
        elif n == 127:
            n = struct.unpack(">Q", self._need(8))[0]
        return b0 & 0x0F, self._need(n)


def stall(url: str, channels: int, timeout: float = 60.0) -> socket.socket:
    """Connect to ``url``, wait until at least ``channels`` channels are advertised, subscribe to all of them and
    return the socket, which the caller keeps open and never reads (close it to let the viewer go)."""
    parts = urlparse(url)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.settimeout(timeout)
    sock.connect((parts.hostname or "127.0.0.1", parts.port or 80))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall((f"GET / HTTP/1.1\r\nHost: {parts.netloc}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                  f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
                  "Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n").encode())
    head = b""
    while b"\r\n\r\n" not in head:
        chunk = sock.recv(4096)
        if not chunk:
            raise ConnectionError("the server closed the connection during the handshake")
        head += chunk
    status, _, rest = head.partition(b"\r\n\r\n")
    if b" 101 " not in status.split(b"\r\n")[0]:
        raise ConnectionError(f"no WebSocket upgrade: {status.splitlines()[0]!r}")
    reader, ids = _Reader(sock, rest), set[int]()
    deadline = time.monotonic() + timeout
    while len(ids) < channels:
        if time.monotonic() > deadline:
            raise TimeoutError(f"only {len(ids)} of {channels} channels advertised")
        op, payload = reader.frame()
        if op == 1:
            msg = json.loads(payload)
            if msg.get("op") == "advertise":
                ids |= {c["id"] for c in msg["channels"]}
    subs = [{"id": i + 1, "channelId": c} for i, c in enumerate(sorted(ids))]
    sock.sendall(_frame(json.dumps({"op": "subscribe", "subscriptions": subs})))
    return sock
