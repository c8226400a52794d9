"""Watching a run's processes from outside: alive or not (a zombie is not), a launcher's children, the fleet's
node processes under it, and a polling wait with a deadline; a free loopback port."""

from __future__ import annotations

import os
import socket
import time
from collections.abc import Callable, Sequence
from pathlib import Path


def free_port() -> int:
    """A loopback port nothing listens on (bound, then released)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_for(predicate: Callable[[], object], timeout: float) -> None:
    """Poll ``predicate`` every 0.1 s; AssertionError after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError("timed out waiting")
        time.sleep(0.1)


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:  # a zombie is not alive
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return False
    return state != "Z"


def all_pids(res: dict) -> list[int]:
    """Every process of the run: world, netem, the agents, and the fork server, the router and the base (when
    there were)."""
    more = [res["pids"][k] for k in ("fork_server", "router", "base") if k in res["pids"]]
    return sorted({res["pids"]["world"], res["pids"]["netem"], *res["pids"]["robots"], *more})


def nothing_left(pids: Sequence[int], timeout: float = 15) -> None:
    """Wait until none of ``pids`` is alive (AssertionError after ``timeout`` seconds)."""
    wait_for(lambda: not any(pid_alive(p) for p in pids), timeout)


def children_of(pid: int) -> list[int]:
    """The direct children of ``pid``."""
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if int((d / "stat").read_text().split(")")[-1].split()[1]) == pid:
                    found.append(int(d.name))
            except (OSError, ValueError, IndexError):
                pass
    return found


def _runs(pid: int, module: bytes) -> bool:
    try:
        return module in Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False


def is_fork_server(pid: int) -> bool:
    """Whether a launcher's child is the robots' fork server (the robots it forks share its command line)."""
    return _runs(pid, b"fleet_emu.agents.forkserver")


def is_router(pid: int) -> bool:
    """Whether a launcher's child is the run's router process."""
    return _runs(pid, b"fleet_emu.launch.router_process")


def fleet_processes(launcher: int) -> list[int]:
    """The fleet's node processes under a launcher: its children but the fork server and the router, and the
    robots the fork server forked."""
    found = []
    for pid in children_of(launcher):
        if not is_router(pid):
            found += children_of(pid) if is_fork_server(pid) else [pid]
    return found
