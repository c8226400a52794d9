"""The ROS 2 guide's client, ``docs/ros2/listen.py``: a line per message however many threads call back, and
one line (exit 2) for a credentials file that is not there, an endpoint that is not one, or no router."""

from __future__ import annotations

import contextlib
import io
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from docs.ros2 import listen
from tests.harness.cli import ROOT
from tests.harness.procs import free_port

LISTEN = [sys.executable, str(ROOT / "docs" / "ros2" / "listen.py")]


def test_lines_from_many_threads_are_never_run_together() -> None:
    out = io.StringIO()

    def write(k: int) -> None:
        for i in range(200):
            listen.say(f"r{k} pose {i}.000000000 13.25 4.75")

    with contextlib.redirect_stdout(out):
        threads = [threading.Thread(target=write, args=(k,)) for k in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    lines = out.getvalue().splitlines()
    assert len(lines) == 800 and all(ln.count("pose") == 1 and ln.endswith("13.25 4.75") for ln in lines)


@pytest.mark.parametrize("args, line", [
    (["tcp/127.0.0.1:7447", "2", "--credentials", "nowhere/ros2.users"],
     "listen.py: error: --credentials nowhere/ros2.users: No such file or directory"),
    (["127.0.0.1", "2"], "listen.py: error: '127.0.0.1' is not a tcp/HOST:PORT endpoint"),
])
def test_bad_input_is_one_line(args: list[str], line: str, tmp_path: Path) -> None:
    proc = subprocess.run([*LISTEN, *args], capture_output=True, text=True, cwd=tmp_path, timeout=60)
    assert proc.returncode == 2 and proc.stderr.startswith(line) and proc.stderr.count("\n") == 1, proc.stderr


def test_no_router_is_one_line(tmp_path: Path) -> None:
    pytest.importorskip("zenoh_ros2_sdk")
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    proc = subprocess.run([*LISTEN, endpoint, "1", "--seconds", "1"], capture_output=True, text=True, cwd=tmp_path,
                          timeout=120)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert proc.stderr.startswith(f"listen.py: error: no Zenoh router at {endpoint} let us in"), proc.stderr
