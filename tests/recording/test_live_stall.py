"""A viewer that stops reading never holds a run: a raw socket (``tests/harness/stalled_viewer.py``) subscribes to
every live channel and never reads again. The live server drops it (and says so on stderr), its stop has a
deadline, and ``fleet run`` ends with its normal code, its ``result.json`` and recording whole, at the run's end
and on SIGTERM."""

from __future__ import annotations

import json
import logging
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from fleet_emu.recording.clock import RunClock
from fleet_emu.recording.foxglove import Derived
from fleet_emu.recording.live import LiveServer
from fleet_emu.recording.viewers import MIN_STALL_S, STALL_BYTES, STALL_S, Quiet, Viewer, stalled
from tests.harness.cli import ROOT, result
from tests.harness.stalled_viewer import stall

# a run whose grids are large enough to fill a stalled viewer's socket within seconds (8 beliefs of 0.05 m cells)
BIG = ("--map", "autolab", "--robots", "8", "--cell-size", "0.05", "--target-coverage", "1.0", "--live",
       "127.0.0.1:0", "--live-hz", "10", "--quiet")


def _log(text: str, tick: int, topic: str) -> Derived:
    obj = {"timestamp": {"sec": tick, "nsec": 0}, "level": 2, "message": text, "name": "t", "file": "", "line": 0}
    return Derived(topic, "foxglove.Log", json.dumps(obj).encode(), tick)


def test_a_stalled_viewer_is_dropped_only_after_it_stalls() -> None:
    seen: dict[str, tuple[int | None, float, int]] = {}
    assert stalled(0.0, seen, [Viewer("a", 100, 5), Viewer("b", 100, 5), Viewer("c", 0, 5)]) == []
    later = STALL_S + 0.1
    # a: nothing acknowledged since; b: read some; c: nothing waiting for it
    assert stalled(later, seen, [Viewer("a", 100, 5), Viewer("b", 100, 9), Viewer("c", 0, 5)]) == ["a"]
    assert stalled(later + STALL_S / 2, seen, [Viewer("b", 100, 9)]) == []  # b's clock started again
    assert set(seen) == {"b"}  # a and c are gone


def test_a_viewer_is_dropped_sooner_once_the_server_published_enough_for_it() -> None:
    """A stalled viewer holds a copy of every message published since it stalled: bytes, not only seconds."""
    seen: dict[str, tuple[int | None, float, int]] = {}
    assert stalled(0.0, seen, [Viewer("a", 100, 5), Viewer("b", 100, 5)], published=0) == []
    soon = MIN_STALL_S + 0.01
    assert stalled(soon, seen, [Viewer("a", 100, 5), Viewer("b", 100, 6)], published=STALL_BYTES) == ["a"]
    assert stalled(soon, seen, [Viewer("b", 100, 6)], published=2 * STALL_BYTES) == []  # b read: its clock restarted
    assert stalled(MIN_STALL_S / 2, {"c": (5, 0.0, 0)}, [Viewer("c", 100, 5)], published=10 * STALL_BYTES) == []


def test_the_sdks_lines_about_a_dropped_viewer_are_left_out() -> None:
    quiet = Quiet()
    quiet.dropped.add("127.0.0.1:5000")

    def passes(text: str) -> bool:
        return quiet.filter(logging.LogRecord("foxglove.websocket", logging.WARNING, "", 0, text, None, None))

    assert not passes("Error sending message to client 127.0.0.1:5000: IO error: Broken pipe (os error 32)")
    assert not passes("Error receiving from client 127.0.0.1:5000: WebSocket protocol error: Connection reset")
    assert passes("Error sending message to client [::1]:6000: IO error: Broken pipe (os error 32)")  # first: told
    assert not passes("Error sending message to client [::1]:6000: IO error: Broken pipe (os error 32)")  # once
    quiet.dropped.add("::1:7000")  # an IPv6 peer, as the viewers' sockets name it
    assert not passes("Error sending message to client [::1]:7000: IO error: Broken pipe (os error 32)")
    assert passes("Server listening on 127.0.0.1:5000")  # names no client


def test_a_dropped_viewer_is_told_once_and_the_sdks_broken_pipes_are_not(caplog: pytest.LogCaptureFixture) -> None:
    """The adversary's stalled viewer, against the real SDK server: dropped once its socket is full and enough was
    published (the look at the viewers driven here with a clock of the test's, so nothing depends on timing),
    then never again, and one line says so: not one per message still queued for it."""
    caplog.set_level(logging.WARNING)
    server = LiveServer("127.0.0.1", 0, RunClock.now())
    server.viewers.close()  # the test looks at the viewers itself
    topics = [f"/viz/t{i}" for i in range(3)]
    server.publish([_log("x", 0, t) for t in topics])
    sock = stall(server.url, len(topics))
    try:
        big = "x" * 200_000
        for tick in range(1, 30):  # 17 MB: more than the sockets' buffers hold
            server.publish([_log(big, tick, t) for t in topics])
        t0 = time.monotonic()
        watch = server.viewers
        watch.check(t0)
        watch.check(t0 + MIN_STALL_S / 2)
        watch.check(t0 + MIN_STALL_S + 0.01)
        server.published_bytes += STALL_BYTES  # and enough since it stalled: dropped
        watch.check(t0 + MIN_STALL_S + 0.02)
        assert len(watch.dropped) == 1
        for tick in range(30, 40):  # the SDK meets the dropped socket once a message: Broken pipe
            server.publish([_log(big, tick, t) for t in topics])
        watch.check(t0 + 10 * STALL_S)  # long after: not dropped (nor told) again
        server.close()
    finally:
        sock.close()
    peer = watch.dropped[0]
    assert watch.dropped == [peer]
    assert caplog.text.count(f"dropped the viewer at {peer}") == 1
    sdk = [r.getMessage() for r in caplog.records if r.name.startswith("foxglove")]
    assert not [line for line in sdk if peer in line or "Broken pipe" in line], sdk[:3]


def test_the_servers_stop_drops_a_viewer_that_never_reads(caplog: pytest.LogCaptureFixture) -> None:
    server = LiveServer("127.0.0.1", 0, RunClock.now())
    topics = [f"/viz/t{i}" for i in range(3)]
    server.publish([_log("x", 0, t) for t in topics])
    sock = stall(server.url, len(topics))
    try:
        big = "x" * 200_000
        for tick in range(1, 60):  # 36 MB: far more than a socket's buffers hold
            server.publish([_log(big, tick, t) for t in topics])
        assert not server.failed
        closer = threading.Thread(target=server.close, daemon=True)
        closer.start()
        closer.join(30)
        assert not closer.is_alive(), "the server's stop waited on a viewer that never reads"
        assert len(server.viewers.dropped) == 1
        assert "dropped the viewer at 127.0.0.1:" in caplog.text
    finally:
        sock.close()


def _start(out: Path, ticks: int) -> tuple[subprocess.Popen[str], socket.socket]:
    proc = subprocess.Popen([sys.executable, "-m", "fleet_emu", "run", "--engine", "memory", *BIG, "--max-ticks",
                             str(ticks), "--out", str(out)], stderr=subprocess.PIPE, text=True, cwd=ROOT)
    assert proc.stderr is not None
    line = proc.stderr.readline()
    url = re.search(r"live: (ws://\S+)", line)
    assert url, line
    return proc, stall(url.group(1), 5)


def _whole(out: Path) -> dict:
    res = result(out)
    with (out / "run.mcap").open("rb") as f:
        reader = make_reader(f)
        assert reader.get_summary() is not None
        assert sum(1 for _ in reader.iter_messages()) > res["ticks"]
    return res


@pytest.mark.slow
def test_a_run_watched_by_a_stalled_viewer_ends_on_time(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc, sock = _start(out, 80)  # 8 s at 10 ticks a second
    try:
        try:
            code = proc.wait(60)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise AssertionError("fleet run held by a viewer that never reads") from None
        ended = time.time()
        err = proc.stderr.read() if proc.stderr else ""
    finally:
        sock.close()
    assert code == 3, err  # its normal code: the run stopped at --max-ticks
    assert ended - (out / "result.json").stat().st_mtime < 10
    assert "live: dropped the viewer at 127.0.0.1:" in err and "Traceback" not in err
    assert _whole(out)["ticks"] == 80


@pytest.mark.slow
def test_sigterm_ends_a_run_watched_by_a_stalled_viewer(tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc, sock = _start(out, 100_000)
    try:
        time.sleep(3)  # the viewer's socket is full by now
        proc.send_signal(signal.SIGTERM)
        sent = time.monotonic()
        try:
            code = proc.wait(30)
        except subprocess.TimeoutExpired:
            proc.kill()
            raise AssertionError("SIGTERM did not end a run held by a viewer that never reads") from None
        took = time.monotonic() - sent
    finally:
        sock.close()
    assert code == 143
    assert took < 5
    assert _whole(out)["ticks"] < 100_000
