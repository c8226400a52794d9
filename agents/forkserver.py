"""The fleet's fork server: imports the robot code (numpy, numba) and loads the compiled kernels once,
then forks one process per node on the launcher's request, so that the nodes share those pages and none pays
the interpreter's start-up (the imports and the kernels' loading: about a CPU second each).

``python -m fleet_emu.agents.forkserver [--scenario FILE.json] [--preload MODULE ...]``, started by the
launcher's :class:`~fleet_emu.launch.supervisor.Supervisor` in its own process group; ``--preload`` names the
other node modules it forks (the world, netem, the base: the launcher's choice, imported here before any fork).
It never opens a Zenoh session (Zenoh's runtime threads would not survive a fork): each forked node opens its
own, exactly as ``python -m MODULE`` does. The protocol is one JSON object a message:

- on standard input, a ``SOCK_SEQPACKET`` socket, requests: ``{"name": "r0", "argv": [...], "log":
  "/out/r0.log"}``, one per packet (with ``"module": "fleet_emu.world"`` for a node other than a robot: what
  ``python -m fleet_emu.world ARGV`` runs). A node with a credential gets it as its standard input, never on a
  command line or in the environment: the launcher writes the credential line into a pipe and passes the pipe's
  read end with the request (``SCM_RIGHTS``); the server hands that descriptor to the forked node and closes its
  own copy, so the credential travels launcher -> kernel pipe -> node and never enters this process's memory,
  where a node forked later (which inherits it) could find it. End of input (the launcher closed its socket, or
  died) ends the server: it kills what is left of its nodes, reaps them, reports them and exits.
- on standard output, events: ``{"spawned": "r0", "pid": 123}`` (or ``{"failed": "r0", "error": "..."}``) for
  each request, in order, and ``{"exited": 123, "code": 0}`` when a node ends (``code`` as
  :attr:`subprocess.Popen.returncode`: negative for a signal).

Each node is a direct child of the server, in a new session (its own process group), named ``fleet NAME``, with
its standard output and error on its log file and standard input on ``/dev/null``; its parent watchdog
(``core.node.watch_parent``) watches the server, which watches the launcher through its standard input.
"""

from __future__ import annotations

import argparse
import contextlib
import ctypes
import gc
import importlib
import io
import json
import logging
import os
import runpy
import select
import signal
import socket
import sys
import time
import traceback
from pathlib import Path
from typing import Any

# What a robot runs, imported here once, before any fork (numpy and numba come with it; zenoh is only
# imported: no session, no runtime thread exists until a robot opens one).
from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.brain import allocator_config
from fleet_emu.agents.node import main as agent_main
from fleet_emu.core.errors import FleetError
from fleet_emu.core.files import create_new
from fleet_emu.core.kernels import warm_up
from fleet_emu.core.scenario import Scenario

#: Modules a node imports on use, loaded here only when the run's allocator needs them (mhm: the base planner's
#: distance transform).
PRELOAD = {"hungarian": ("scipy.optimize",), "mhm": ("scipy.ndimage",)}
AGENTS = "fleet_emu.agents"  # a request's module when it names none: a robot
POLL = 0.05  # seconds between looks for exited robots
KILL_GRACE = 2.0  # seconds the robots left at the end get between SIGTERM and SIGKILL


class Server:
    """Reads requests on ``req`` and writes events on ``events`` (raw file descriptors)."""

    def __init__(self, req: int, events: int) -> None:
        self.req = req
        self.sock = socket.socket(fileno=req)  # the launcher's SOCK_SEQPACKET end: a request and its descriptor
        self.events = events
        self.alive: set[int] = set()

    def emit(self, **event: Any) -> None:
        data = (json.dumps(event) + "\n").encode()
        with contextlib.suppress(BrokenPipeError):  # the launcher is gone: the end of input follows
            while data:
                data = data[os.write(self.events, data):]

    def serve(self) -> None:
        """Fork on request and report exits until the end of input; then end the robots left."""
        while True:
            ready, _, _ = select.select([self.req], [], [], POLL)
            self.reap()
            if not ready:
                continue
            try:
                packet, fds, _, _ = socket.recv_fds(self.sock, 1 << 16, 1)
            except ConnectionError:
                break
            if not packet:
                for fd in fds:
                    os.close(fd)
                break
            self.handle(packet, fds[0] if fds else None)
        self.end_all()

    def handle(self, packet: bytes, secret: int | None) -> None:
        """One request; ``secret`` is the descriptor of the robot's credential pipe (closed here in any case)."""
        try:
            try:
                req = json.loads(packet)
                name, argv = str(req["name"]), [str(a) for a in req["argv"]]
                log, module = req.get("log"), str(req.get("module", AGENTS))
            except (ValueError, KeyError, TypeError) as exc:
                self.emit(failed="?", error=f"bad request: {exc}")
                return
            try:
                pid = self.fork(name, argv, log, secret, module)
            except OSError as exc:
                self.emit(failed=name, error=str(exc))
                return
            self.alive.add(pid)
            self.emit(spawned=name, pid=pid)
        finally:
            if secret is not None:
                os.close(secret)

    def fork(self, name: str, argv: list[str], log: str | None, secret: int | None, module: str = AGENTS) -> int:
        """Fork one node, ``python -m module argv`` (its credential pipe ``secret`` becomes its standard input);
        in the child, never return."""
        logfd = create_new(Path(log)) if log else None  # a new file: a link planted there is refused
        sys.stdout.flush()
        sys.stderr.flush()
        gc.freeze()  # what the server built is never scanned by the robots' collector: its pages stay shared
        pid = os.fork()
        if pid:
            if logfd is not None:
                os.close(logfd)
            return pid
        code = 1
        try:
            os.setsid()
            set_name(f"fleet {name}")
            self.sock.close()
            os.close(self.events)
            if logfd is not None:
                os.dup2(logfd, 1)
                os.dup2(logfd, 2)
                os.close(logfd)
            for sig in (signal.SIGTERM, signal.SIGCHLD):
                signal.signal(sig, signal.SIG_DFL)
            signal.signal(signal.SIGINT, signal.default_int_handler)
            sys.stdin = io.StringIO(_read_all(secret) if secret is not None else "")  # fd 0 stays /dev/null
            sys.argv = [module, *argv]
            code = run_robot(argv) if module == AGENTS else run_node(module)
        except BaseException:  # the child must never return into the server's loop
            traceback.print_exc()
        finally:
            logging.shutdown()
            with contextlib.suppress(Exception):
                sys.stdout.flush()
                sys.stderr.flush()
            os._exit(code)
        return 0  # unreachable

    def reap(self) -> None:
        """Report every robot that exited."""
        while self.alive:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                self.alive.clear()
                return
            if pid == 0:
                return
            self.alive.discard(pid)
            self.emit(exited=pid, code=os.waitstatus_to_exitcode(status))

    def end_all(self) -> None:
        """SIGTERM the process group of every robot left, SIGKILL them after :data:`KILL_GRACE`, reap them."""
        for sig, grace in ((signal.SIGTERM, KILL_GRACE), (signal.SIGKILL, 5.0)):
            for pid in list(self.alive):
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(pid, sig)
            deadline = time.monotonic() + grace
            while self.alive and time.monotonic() < deadline:
                time.sleep(POLL)
                self.reap()


def _read_all(fd: int) -> str:
    """What the launcher wrote into a credential pipe (it closed its end: this ends), the pipe closed."""
    chunks = []
    with open(fd, "rb") as pipe:
        while chunk := pipe.read(1 << 12):
            chunks.append(chunk)
    return b"".join(chunks).decode()


def set_name(name: str) -> None:
    """The process's name as ``ps`` and ``top`` show it (its command line stays the server's)."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(15, name.encode()[:15], 0, 0, 0)  # PR_SET_NAME


def run_robot(argv: list[str]) -> int:
    """What ``python -m fleet_emu.agents ARGV`` does, as an exit code (uncaught exceptions print and give 1)."""
    return _exit_code(agent_main, argv)


def run_node(module: str) -> int:
    """What ``python -m MODULE`` does with ``sys.argv`` as set, as an exit code (its ``__main__`` run afresh; the
    modules it imports were loaded before the fork)."""
    return _exit_code(lambda _: runpy.run_module(module, run_name="__main__", alter_sys=False), [])


def _exit_code(main: Any, argv: list[str]) -> int:
    """``main(argv)``'s exit code as the interpreter would give it."""
    try:
        main(argv)
    except SystemExit as exc:
        if exc.code is None or isinstance(exc.code, int):
            return exc.code or 0
        print(exc.code, file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        traceback.print_exc()
        return 128 + signal.SIGINT
    return 0


def preload(scenario_file: str | None, modules: list[str] | None = None) -> None:
    """Load the kernels and import ``modules`` (the other nodes' code); with the run's scenario, build its
    allocator once too (a plugin is imported, a kernel only it uses is loaded) and import what it imports on use
    (:data:`PRELOAD`)."""
    warm_up()
    for module in modules or ():
        importlib.import_module(module)
    if not scenario_file:
        return
    try:
        config = allocator_config(Scenario.from_json(scenario_file))
        make_allocator(config)
    except (OSError, ValueError, KeyError, FleetError) as exc:  # the robots will say it, each in its log
        print(f"forkserver: cannot preload the scenario's allocator: {exc}", file=sys.stderr)
        return
    for module in PRELOAD.get(str(config.get("type")), ()):
        importlib.import_module(module)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="forkserver")
    parser.add_argument("--scenario", help="the run's scenario (JSON): its allocator is loaded before any fork")
    parser.add_argument("--preload", action="append", default=[], metavar="MODULE",
                        help="a node module to import before any fork (a request may then name its package)")
    args = parser.parse_args(argv)
    preload(args.scenario, args.preload)
    # The protocol's pipes move off 0 and 1: a robot gets /dev/null and its log there, never the pipes.
    req, events = os.dup(0), os.dup(1)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.close(devnull)
    os.dup2(2, 1)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the launcher ends the server by closing its input
    gc.collect()
    Server(req, events).serve()


if __name__ == "__main__":
    main()
