"""Peers that misbehave on purpose, on loopback: what the product must give up on within its deadlines."""

from __future__ import annotations

import contextlib
import socket
import threading
from collections.abc import Iterator


@contextlib.contextmanager
def silent_peer(accepted: list[socket.socket] | None = None) -> Iterator[str]:
    """A loopback listener that accepts every connection (kept in ``accepted``) and never sends a byte: its
    ``tcp://`` address."""
    server = socket.create_server(("127.0.0.1", 0))
    accepted = [] if accepted is None else accepted
    stop = threading.Event()

    def accept() -> None:
        server.settimeout(0.2)
        while not stop.is_set():
            with contextlib.suppress(OSError):
                accepted.append(server.accept()[0])

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        thread.join()
        for conn in accepted:
            conn.close()
        server.close()
