"""The run's router in its own process: real Zenoh sessions through it, its authentication and access control,
its one-line failure, and that it never outlives the launcher."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import pytest
import zenoh

from fleet_emu.core.access import LAUNCHER, make_credentials
from fleet_emu.core.access import Credential as Login
from fleet_emu.core.bus import client_config
from fleet_emu.core.errors import RunError
from fleet_emu.core.keys import Keys
from fleet_emu.launch.router_process import router_process


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie not yet reaped by its parent has ended too
        return Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
    except OSError:
        return False


def _wait_gone(pid: int, timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while _alive(pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    return not _alive(pid)


def _roundtrip(endpoint: str, pub_login: Login | None, sub_login: Login | None, key: str) -> bytes | None:
    """Put on ``key`` as one user until the other, subscribed, receives it (None if it never does)."""
    with zenoh.open(client_config(endpoint, sub_login)) as sub_s, \
            zenoh.open(client_config(endpoint, pub_login)) as pub_s:
        sub = sub_s.declare_subscriber(key, zenoh.handlers.FifoChannel(64))
        for _ in range(40):
            pub_s.put(key, b"x")
            if (s := sub.handler.try_recv()) is not None:
                return s.payload.to_bytes()
            time.sleep(0.05)
        return None


def test_the_child_routes_with_the_run_s_logins_and_acl_and_ends_with_the_context(tmp_path: Path) -> None:
    keys = Keys("rp")
    nodes = ["world", "netem", "r0", "r1", LAUNCHER, "recorder"]
    creds = {n: Login(n, p) for n, p in make_credentials(nodes).items()}
    with router_process("rp", creds, ["tcp/127.0.0.1:0"], None, tmp_path) as router:
        pid = router.proc.pid
        assert router.exited() is None and router.endpoints[0].startswith("tcp/127.0.0.1:")
        assert _roundtrip(router.endpoints[0], creds["r0"], creds["recorder"], keys.cmd("r0")) == b"x"
        # r1 may not put on r0's keys: the router's access control drops it
        assert _roundtrip(router.endpoints[0], creds["r1"], creds["recorder"], keys.cmd("r0")) is None
        with pytest.raises(zenoh.ZError):  # and a session without a login is refused outright
            zenoh.open(client_config(router.endpoints[0], None)).close()
        # the users file lived only until the router had opened
        left = [p for p in Path(tempfile.gettempdir()).glob("fleet-router-*/*") if p.is_file()]
        assert not any(creds["r0"].password in p.read_text(errors="replace") for p in left)
    assert _wait_gone(pid, 5)


def test_a_router_that_cannot_listen_is_one_line(tmp_path: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(RunError) as exc, router_process("rp", None, [f"tcp/127.0.0.1:{port}"], None, tmp_path):
            pass
    message = str(exc.value)
    assert message.startswith("cannot open the embedded Zenoh router: ") and "\n" not in message
    assert len(message) > len("cannot open the embedded Zenoh router: ") + 5  # the child's own reason
    assert (tmp_path / "router.log").exists()


def test_the_router_never_outlives_a_killed_launcher(tmp_path: Path) -> None:
    """SIGKILL leaves the launcher no teardown: the child sees its standard input close and goes."""
    script = textwrap.dedent(f"""
        import sys, time
        from pathlib import Path
        from fleet_emu.launch.router_process import router_process
        with router_process("rp", None, ["tcp/127.0.0.1:0"], None, Path({str(tmp_path)!r})) as r:
            print(r.proc.pid, flush=True)
            time.sleep(600)
    """)
    launcher = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        assert launcher.stdout is not None
        child = int(launcher.stdout.readline())
        assert _alive(child)
        launcher.kill()
        launcher.wait(10)
        assert _wait_gone(child, 10)
    finally:
        if launcher.poll() is None:
            launcher.kill()


def test_sigterm_ends_the_child_cleanly(tmp_path: Path) -> None:
    with router_process("rp", None, ["tcp/127.0.0.1:0"], None, tmp_path) as router:
        os.kill(router.proc.pid, signal.SIGTERM)
        assert router.proc.wait(10) == 0
        assert router.exited() == 0  # the launcher's watch sees it and fails the run
