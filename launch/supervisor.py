"""Spawning and tearing down the fleet's processes: each child in its own process group, killed on every
exit path of the runner (normal end, Ctrl-C, an exception); a child whose launcher dies exits by itself
(``fleet_emu.core.node.watch_parent``). With a fork server (:mod:`fleet_emu.launch.forked`) the robots, the
world, netem and the base are forked by it instead of started afresh: the same process groups, the same logs."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Protocol

from fleet_emu.core.files import open_new
from fleet_emu.launch.forked import ForkServer

AGENTS = "fleet_emu.agents"
AGAIN = 0.25  # seconds between the calls of wait_all's ``again``
#: The other nodes the fork server forks too (their package: what ``python -m`` runs), with the module each
#: imports, which the server loads before any fork: none of them pays an interpreter's start-up.
FORKED = {"fleet_emu.world": "fleet_emu.world.node", "fleet_emu.netem": "fleet_emu.netem.node",
          "fleet_emu.agents.base_node": "fleet_emu.agents.base_node"}


class Child(Protocol):
    """What the supervisor needs of a child: a process started here (``subprocess.Popen``), a robot the fork
    server forked (``launch.forked.ForkedProcess``) or a robot on a host (``launch.host_client.RemoteRobot``)."""

    @property
    def pid(self) -> int: ...

    def poll(self) -> int | None: ...

    def wait(self, timeout: float | None = None) -> int: ...


class Supervisor:
    """Owns the child processes of one run."""

    def __init__(self, log_dir: Path | None = None) -> None:
        self.children: dict[str, Child] = {}
        self.log_dir = log_dir
        self.server: ForkServer | None = None
        self._logs: list[IO[bytes]] = []

    def start_fork_server(self, scenario: Path | None = None) -> None:
        """Start the fork server now (it loads the robot code, and ``scenario``'s allocator, while the router
        opens): from then on, :meth:`spawn` forks every robot (module :data:`AGENTS`) and every node of
        :data:`FORKED` from it."""
        log = self.log_dir / "forkserver.log" if self.log_dir is not None else None
        self.server = ForkServer(log, scenario, tuple(FORKED.values()))

    def spawn(self, name: str, module: str, args: list[str], secret: str | None = None) -> Child:
        """Start ``python -m module args`` in a new session (its own process group); ``secret`` (one line) is
        written to its standard input, which is then closed. A robot comes from the fork server when there
        is one, and so do the world, netem and the base (its standard input then reads ``secret``)."""
        if (module == AGENTS or module in FORKED) and self.server is not None:
            log = self.log_dir / f"{name}.log" if self.log_dir is not None else None
            child = self.children[name] = self.server.spawn(name, args, log, secret,
                                                            None if module == AGENTS else module)
            return child
        stderr = None
        if self.log_dir is not None:
            stderr = open_new(self.log_dir / f"{name}.log")  # never through a link planted there; closed in kill_all
            self._logs.append(stderr)
        proc = subprocess.Popen([sys.executable, "-m", module, *args],
                                stdin=subprocess.DEVNULL if secret is None else subprocess.PIPE,
                                stdout=stderr, stderr=stderr, start_new_session=True)
        self.children[name] = proc
        if secret is not None and proc.stdin is not None:
            with contextlib.suppress(OSError):  # a child that died at once is seen by the runner's wait
                proc.stdin.write(secret.encode() + b"\n")
            with contextlib.suppress(OSError):
                proc.stdin.close()
        return proc

    def adopt(self, name: str, child: Child) -> None:
        """A child started elsewhere (a robot on a host, ``launch/host_client.py``), supervised like the others:
        signalling its group asks its host to tear it down."""
        self.children[name] = child

    def pids(self) -> dict[str, int]:
        """Every child's pid, and the fork server's (``fork_server``) when there is one."""
        server = {"fork_server": self.server.pid} if self.server is not None else {}
        return {name: p.pid for name, p in self.children.items()} | server

    def dead(self) -> dict[str, int]:
        """Children that exited, with their exit codes."""
        return {n: code for n, p in self.children.items() if (code := p.poll()) is not None}

    def wait_all(self, timeout: float, hurry: threading.Event | None = None,
                 again: Callable[[], None] | None = None) -> bool:
        """Wait for every child to exit by itself; True if they all did. Setting ``hurry`` (a second Ctrl-C)
        cuts the wait short; ``again`` is called every :data:`AGAIN` seconds meanwhile (the stop, put again for a
        node that subscribed after it was first put)."""
        start = time.monotonic()
        deadline, next_again = start + timeout, start + AGAIN
        while time.monotonic() < deadline and not (hurry is not None and hurry.is_set()):
            if all(p.poll() is not None for p in self.children.values()):
                return True
            if again is not None and time.monotonic() >= next_again:
                again()
                next_again += AGAIN
            time.sleep(0.05)
        return all(p.poll() is not None for p in self.children.values())

    def kill(self, name: str) -> bool:
        """SIGKILL the process group of the child ``name`` (a robot the scenario crashes, ``[[faults]]``), as
        ``kill -9`` would; False when there is no such child or it already exited. It is reaped with the
        others (:meth:`kill_all`)."""
        child = self.children.get(name)
        if child is None or child.poll() is not None:
            return False
        _signal_group(child, signal.SIGKILL)
        return True

    def kill_all(self, grace: float = 2.0) -> None:
        """SIGTERM every child's process group, then SIGKILL what is left after ``grace`` seconds."""
        alive = [p for p in self.children.values() if p.poll() is None]
        for p in alive:
            _signal_group(p, signal.SIGTERM)
        deadline = time.monotonic() + grace
        for p in alive:
            try:
                p.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                _signal_group(p, signal.SIGKILL)
                with contextlib.suppress(subprocess.TimeoutExpired):
                    p.wait(2.0)
        for p in self.children.values():  # also any grandchildren left in the groups
            _signal_group(p, signal.SIGKILL)
        if self.server is not None:  # it reaps and reports the robots it forked, then exits
            self.server.close(grace)
        for f in self._logs:
            with contextlib.suppress(OSError):
                f.close()
        self._logs.clear()


def _signal_group(p: Child, sig: signal.Signals) -> None:
    remote = getattr(p, "signal_group", None)
    if remote is not None:  # never a local kill of another machine's pid
        remote(sig)
        return
    if p.pid <= 0:  # a robot the fork server never forked: never this process's own group
        return
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(p.pid, sig)
