"""The launcher's side of the robots' fork server (``fleet_emu.agents.forkserver``): starting it, asking it for
robots, and a handle per robot that behaves as the :class:`subprocess.Popen` the supervisor uses (``pid``,
``returncode``, ``poll()``, ``wait()``).

The server is the robots' parent, so it reaps them and reports their exit codes on its standard output; a thread
here reads those reports. When the server itself is gone (killed, crashed), the robots it left are killed (their
process groups: the pids it reported) and count as exited with ``-SIGKILL``; they would exit anyway, as their
parent watchdog sees their parent gone.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import IO

from fleet_emu.core.files import open_new

FORK_TIMEOUT = 120.0  # seconds a request may wait for the server (its imports, on a loaded machine)
NOT_STARTED = -1  # the pid of a robot that was never forked (and its exit code)


def fork_server_enabled(flag: bool | None = None) -> bool:
    """Whether robots are forked from a fork server: ``flag`` when given (``--fork-server`` /
    ``--no-fork-server``), else the environment's ``FLEET_FORK_SERVER`` (``0`` turns it off), else yes."""
    if flag is not None:
        return flag
    return os.environ.get("FLEET_FORK_SERVER", "1").strip().lower() not in ("0", "false", "no", "off")


class ForkedProcess:
    """A robot forked by the fork server: the parts of :class:`subprocess.Popen` the supervisor uses."""

    def __init__(self, name: str, server: ForkServer) -> None:
        self.name = name
        self.pid = 0  # set when the server reports it (NOT_STARTED when it never does)
        self.returncode: int | None = None
        self._server = server

    def poll(self) -> int | None:
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        """The exit code, as the server reports it; :class:`subprocess.TimeoutExpired` after ``timeout``."""
        with self._server.changed:
            if not self._server.changed.wait_for(lambda: self.returncode is not None, timeout):
                raise subprocess.TimeoutExpired(self.name, timeout or 0.0)
        assert self.returncode is not None
        return self.returncode


class ForkServer:
    """One fork server process (in its own process group) and the robots it forked."""

    def __init__(self, log: Path | None = None, scenario: Path | None = None, modules: tuple[str, ...] = ()) -> None:
        """``modules``: the other node modules (``fleet_emu.world.node``...) the server imports before any fork,
        so that a request naming their package forks a process that has them loaded."""
        stderr: IO[bytes] | None = open_new(log) if log is not None else None  # closed in close
        self._log = stderr
        preload = ["--scenario", str(scenario)] if scenario is not None else []
        preload += [arg for module in modules for arg in ("--preload", module)]
        # requests go on a SOCK_SEQPACKET socket (its standard input), so that a robot's credential pipe can
        # travel with its request; closing our end (or dying) is the server's end of input
        self._sock, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        try:
            self.proc = subprocess.Popen([sys.executable, "-m", "fleet_emu.agents.forkserver", *preload],
                                         stdin=theirs.fileno(), stdout=subprocess.PIPE, stderr=stderr,
                                         start_new_session=True)
        finally:
            theirs.close()
        self.pid = self.proc.pid
        self.changed = threading.Condition()
        self._by_pid: dict[int, ForkedProcess] = {}
        self._pending: list[ForkedProcess] = []  # requests sent, in order, not answered yet
        self._gone = False
        self._reader = threading.Thread(target=self._read, daemon=True, name="forkserver")
        self._reader.start()

    def spawn(self, name: str, argv: list[str], log: Path | None, secret: str | None,
              module: str | None = None) -> ForkedProcess:
        """Ask for one robot (``python -m fleet_emu.agents ARGV``), or another node (``python -m MODULE ARGV``),
        and wait for its pid. A node the server could not fork (it is gone, it failed, it did not answer in
        :data:`FORK_TIMEOUT`) comes back exited."""
        handle = ForkedProcess(name, self)
        request = {"name": name, "argv": argv, "log": str(log) if log is not None else None}
        if module is not None:
            request["module"] = module
        with self.changed:
            if self._gone:  # its output ended: it will answer nothing more
                self._fail(handle)
                return handle
            self._pending.append(handle)
        with contextlib.suppress(OSError, ValueError):  # the server is gone (or closed): the reader fails it
            self._send(json.dumps(request).encode(), secret)
        with self.changed:
            if not self.changed.wait_for(lambda: handle.pid != 0 or handle.returncode is not None, FORK_TIMEOUT):
                self._fail(handle)
        return handle

    def _send(self, request: bytes, secret: str | None) -> None:
        """One request; a credential goes into a pipe whose read end travels with it (the robot's stdin)."""
        if secret is None:
            self._sock.send(request)
            return
        r, w = os.pipe()
        try:
            os.write(w, (secret + "\n").encode())  # one line, far below the pipe's buffer
            os.close(w)
            w = -1
            socket.send_fds(self._sock, [request], [r])
        finally:
            os.close(r)
            if w >= 0:
                os.close(w)

    def _fail(self, handle: ForkedProcess) -> None:
        """Called with ``changed`` held: a request that will never be answered."""
        if handle in self._pending:
            self._pending.remove(handle)
        handle.pid = handle.pid or NOT_STARTED
        if handle.returncode is None:
            handle.returncode = NOT_STARTED
        self.changed.notify_all()

    def _read(self) -> None:
        """Apply the server's events until its output ends; then fail and kill whatever it left."""
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            try:
                event = json.loads(line)
            except ValueError:
                continue
            with self.changed:
                self._apply(event)
                self.changed.notify_all()
        with self.changed:
            self._gone = True
            for handle in list(self._pending):
                self._fail(handle)
            for pid, handle in self._by_pid.items():
                if handle.returncode is None:
                    _kill_group(pid, signal.SIGKILL)
                    handle.returncode = -signal.SIGKILL
            self.changed.notify_all()

    def _apply(self, event: dict) -> None:
        if "spawned" in event or "failed" in event:
            if not self._pending:
                return
            handle = self._pending.pop(0)
            if "spawned" in event:
                handle.pid = int(event["pid"])
                self._by_pid[handle.pid] = handle
            else:
                print(f"fleet: the fork server could not start {handle.name}: {event.get('error')}", file=sys.stderr)
                self._fail(handle)
        elif "exited" in event:
            exited = self._by_pid.get(int(event["exited"]))
            if exited is not None:
                exited.returncode = int(event["code"])

    def close(self, grace: float = 2.0) -> None:
        """End the server (it ends the robots it has left, reaps and reports them), SIGKILL its process group
        after ``grace`` seconds, and wait for the last reports. A server that forked nothing (the run ended before
        its first node: the hosts did not come) has nothing to reap or report: it is killed at once, not waited
        for while it is still loading the code."""
        with contextlib.suppress(OSError, ValueError):
            self._sock.close()
        with self.changed:
            forked = bool(self._by_pid or self._pending)
        # the server's own SIGTERM grace to its robots, and more
        deadline = time.monotonic() + (grace + 2.5 if forked else 0.0)
        try:
            self.proc.wait(max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            _kill_group(self.pid, signal.SIGKILL)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(2.0)
        _kill_group(self.pid, signal.SIGKILL)  # anything left in its group
        self._reader.join(5.0)
        if self._log is not None:
            with contextlib.suppress(OSError):
                self._log.close()


def _kill_group(pid: int, sig: signal.Signals) -> None:
    if pid <= 0:  # never 0 (this process's own group) nor a robot never forked
        return
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pid, sig)
