"""Nothing holds ``fleet maps fetch``: a server that trickles a byte now and then is cut off at the fetch's
total deadline (not only a silent one, at the per-read timeout), a FIFO in a mirror folder is refused at once,
and SIGINT or SIGTERM during a fetch leave nothing in the cache. The server is a real one on loopback."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from fleet_emu.core.errors import MapError
from fleet_emu.world import fetch as fetch_mod
from fleet_emu.world.registry import RegistryMap, lookup

ROOT = Path(__file__).resolve().parents[2]


@contextlib.contextmanager
def trickle(every: float = 0.2) -> Iterator[tuple[str, threading.Event]]:
    """An HTTP server on 127.0.0.1 that answers any request with a 1 MB body, sending one byte every ``every``
    seconds; its base URL and an event set once a request came."""
    listener = socket.create_server(("127.0.0.1", 0))
    listener.settimeout(0.2)
    done, asked = threading.Event(), threading.Event()

    def client(conn: socket.socket) -> None:
        with conn, contextlib.suppress(OSError):
            conn.recv(65536)
            asked.set()
            conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Length: 1048576\r\n\r\n")
            while not done.is_set():
                conn.sendall(b"x")
                done.wait(every)

    def accept() -> None:
        while not done.is_set():
            with contextlib.suppress(TimeoutError, OSError):
                conn, _ = listener.accept()
                threading.Thread(target=client, args=(conn,), daemon=True).start()

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{listener.getsockname()[1]}", asked
    finally:
        done.set()
        thread.join()
        listener.close()


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    return tmp_path / "xdg" / "fleet-emu" / "maps"


def _left(cache: Path) -> list[str]:
    return sorted(p.name for p in cache.rglob("*")) if cache.exists() else []


def test_a_trickling_mirror_is_cut_off_at_the_deadline(cache: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(fetch_mod, "DEADLINE", 2.0)
    monkeypatch.setattr(fetch_mod, "TIMEOUT", 30.0)  # a byte comes every 0.2 s: the per-read timeout never fires
    with trickle() as (url, _):
        start = time.monotonic()
        with pytest.raises(MapError, match="not whole within 2 s"):
            fetch_mod.fetch(lookup("cave"), url)
        took = time.monotonic() - start
    assert took < 10
    assert _left(cache) == []


def test_a_fifo_in_a_mirror_folder_is_refused_at_once(cache: Path, tmp_path: Path) -> None:
    entry = lookup("cave")
    folder = tmp_path / "mirror" / entry.name
    folder.mkdir(parents=True)
    os.mkfifo(folder / entry.files[0].name)  # opening it for reading would wait for a writer forever
    result: list[BaseException] = []
    worker = threading.Thread(target=lambda: _catch(result, entry, str(tmp_path / "mirror")), daemon=True)
    worker.start()
    worker.join(30)
    assert not worker.is_alive(), "the fetch waits on a FIFO"
    assert isinstance(result[0], MapError) and "is not a regular file" in str(result[0])
    assert _left(cache) == []


def _catch(out: list[BaseException], entry: RegistryMap, mirror: str) -> None:
    try:
        fetch_mod.fetch(entry, mirror)
    except BaseException as exc:  # the test looks at what it was
        out.append(exc)


def _background() -> None:
    """What a shell does to a background job: SIGINT ignored from the start."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@pytest.mark.parametrize(("sig", "code", "started"), [(signal.SIGTERM, 143, None), (signal.SIGINT, 130, None),
                                                      (signal.SIGINT, 130, _background)],
                         ids=["SIGTERM", "SIGINT", "SIGINT-in-a-background-job"])
def test_a_signal_during_a_fetch_leaves_nothing_in_the_cache(tmp_path: Path, sig: int, code: int,
                                                            started: Callable[[], None] | None) -> None:
    cache = tmp_path / "xdg" / "fleet-emu" / "maps"
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path / "xdg")}
    with trickle() as (url, asked):
        proc = subprocess.Popen([sys.executable, "-m", "fleet_emu", "maps", "fetch", "cave", "--mirror", url],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=tmp_path,
                                preexec_fn=started)
        assert asked.wait(60), "the fetch never asked"
        time.sleep(0.3)
        assert any(p.name.endswith(".part") for p in cache.iterdir())  # under way
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=30)
    assert proc.returncode == code, err
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert _left(cache.parent.parent) == [], _left(cache.parent.parent)
