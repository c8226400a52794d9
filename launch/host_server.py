"""The host protocol's server side, ``fleet host``: start, on this machine, the robots a ``fleet run --hosts N``
elsewhere assigns to it.

The protocol has two sides: this module is the *server*, the process on the remote machine that waits for spawn
requests and serves them; ``launch/host_client.py`` is the *client*, the launcher's side, which sends them (the
protocol's steps are in its docstring). Here: log in as this host's user (``--credentials``,
a ``hostK:password`` line), subscribe to ``fleet-host/hostK/spawn``, declare the token ``fleet-host/hostK/alive``,
and serve runs one at a time (``--once``: one, then exit). For a run: answer ``accepted`` (``busy`` to another
run's request meanwhile), write its scenario, start each robot as the launcher would (``robot_argv``, this host's
own ``--connect``, the run's ``--realtime`` rate, the robot's credential on its standard input with this host's
``--tls-ca``, its own process group, from a fork server unless turned off), report ``spawned``/``exited`` per
robot, and ``ended`` once every robot is gone. The robots are torn down (SIGTERM to their groups, then SIGKILL)
when the launcher asks, when its token ``fleet/<run>/alive/launcher/launcher`` goes, and on this process's
SIGINT/SIGTERM (exit 130/143); a robot whose host dies exits by itself (its parent watchdog). A malformed
request, or one not from the launcher, is counted and dropped.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import queue
import sys
import tempfile
import time
from pathlib import Path

import zenoh

from fleet_emu.core.access import Credential, read_users, role_of
from fleet_emu.core.bus import open_client, publisher
from fleet_emu.core.codec import DecodeError, decode
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.files import write_atomic
from fleet_emu.core.keys import HOST_ID, HostKeys, Keys
from fleet_emu.core.messages import HostAssign, HostStatus
from fleet_emu.core.node import Declared, undeclare
from fleet_emu.launch.forked import fork_server_enabled
from fleet_emu.launch.host_client import check_reliable, robot_argv
from fleet_emu.launch.signals import Interrupts
from fleet_emu.launch.supervisor import AGENTS, Supervisor

LAUNCHER_GRACE = 10.0  # seconds the launcher's token may take to show up before the run counts as abandoned
POLL = 0.1


def host_login(path: Path | None, name: str | None, tls_ca: Path | None) -> tuple[str, Credential | None]:
    """This host's id and login, from ``--credentials`` (and ``--name``); without a file, ``--name`` (or
    ``host0``) on an unauthenticated router."""
    if tls_ca is not None and not tls_ca.is_file():
        raise ConfigError(f"--tls-ca {tls_ca}: no such file")
    ca = str(tls_ca.absolute()) if tls_ca is not None else None
    if name is not None and not HOST_ID.fullmatch(name):
        raise ConfigError(f"--name must be host0, host1, ... (got {name!r})")
    if path is None:
        return name or "host0", None
    users = read_users(path)
    hosts = sorted(u for u in users if role_of(u) == "host")
    if name is None and len(hosts) != 1:
        raise ConfigError(f"--credentials {path} holds {len(hosts)} host users ({', '.join(hosts) or 'none'}): "
                          f"give it one hostK:password line, or say which with --name")
    name = name or hosts[0]
    if name not in users:
        raise ConfigError(f"--credentials {path} has no user {name!r}")
    return name, Credential(name, users[name], ca)


class Host:
    """One host's session: requests in, robots started and watched, reports out."""

    def __init__(self, session: zenoh.Session, name: str, endpoint: str, tls_ca: str | None, out: Path | None,
                 fork_server: bool | None, interrupts: Interrupts) -> None:
        self.session = session
        self.name = name
        self.endpoint = endpoint
        self.tls_ca = tls_ca
        self.out = out
        self.fork_server = fork_server
        self.interrupts = interrupts
        self.keys = HostKeys(name)
        self.requests: queue.Queue[bytes] = queue.Queue()
        self.dropped = 0
        self.reported: set[str] = set()  # the current run's robots whose exit was reported
        self._seq = 0
        self._status = publisher(session, self.keys.status)
        self._handles: list[Declared] = [self._status, session.declare_subscriber(
            self.keys.spawn, lambda s: self.requests.put(s.payload.to_bytes()))]
        self._handles.append(session.liveliness().declare_token(self.keys.alive))  # last: subscriptions are in

    def close(self) -> None:
        undeclare(self._handles)

    def report(self, run: str, event: str, *, robot: str = "", pid: int = 0, code: int = 0, error: str = "") -> None:
        self._seq += 1
        msg = HostStatus(src=self.name, tick=0, seq=self._seq, run=run, event=event, robot=robot, pid=pid, code=code,
                         error=error)
        with contextlib.suppress(zenoh.ZError):
            self._status.put(msg.encode())

    def next_request(self, timeout: float) -> HostAssign | None:
        """The next well-formed request from the launcher to this host, or None after ``timeout``."""
        try:
            data = self.requests.get(timeout=timeout)
        except queue.Empty:
            return None
        try:
            msg = decode(data, expected=HostAssign)
        except DecodeError as exc:
            self._drop(str(exc))
            return None
        if msg.src != "launcher" or msg.host != self.name:
            self._drop(f"a request from {msg.src!r} for {msg.host!r}")
            return None
        return msg

    def _drop(self, why: str) -> None:
        self.dropped += 1
        print(f"fleet host {self.name}: dropped request #{self.dropped}: {why}", file=sys.stderr)
        return None

    def serve(self, once: bool) -> None:
        """Serve runs until interrupted (after one with ``once``)."""
        while not self.interrupts.requested.is_set():
            req = self.next_request(0.2)
            if req is None or req.end:
                continue  # an end for a run this host no longer serves
            try:
                self.run(req)
            except OSError as exc:  # its output directory cannot be written: the launcher fails the robots
                print(f"fleet host {self.name}: run {req.run}: {exc.strerror or exc}", file=sys.stderr)
                self.report(req.run, "ended", error=str(exc.strerror or exc))
            if once:
                return
            self.say("waiting for a run")

    def run(self, req: HostAssign) -> None:
        """Start ``req``'s robots, report them, tear them down when the run ends for any reason."""
        self.report(req.run, "accepted")
        self.reported = set()
        launcher = {"seen": False, "gone": False}

        def on_launcher(sample: zenoh.Sample) -> None:
            launcher["seen" if sample.kind == zenoh.SampleKind.PUT else "gone"] = True

        with contextlib.ExitStack() as stack:
            work = self.out / req.run / self.name if self.out is not None else \
                Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="fleet-host-")))
            work.mkdir(parents=True, exist_ok=True)
            scenario = work / "scenario.json"
            write_atomic(scenario, lambda tmp: tmp.write_text(req.scenario))  # never through a link there
            watch = self.session.liveliness().declare_subscriber(Keys(req.run).alive("launcher", "launcher"),
                                                                  on_launcher, history=True)
            sup = Supervisor(log_dir=work)
            self.say(f"joined run {req.run}: robots {', '.join(req.robots) or 'none'} (logs in {work})")
            try:
                self._start(req, sup, scenario)
                self._watch(req, sup, launcher)
            finally:
                sup.kill_all()
                dead = sup.dead()
                for name, code in dead.items():
                    if name not in self.reported:
                        self.report(req.run, "exited", robot=name, code=code)
                self.report(req.run, "ended")
                undeclare([watch])
                codes = ", ".join(f"{r} {dead[r]}" for r in req.robots if r in dead) or "none started"
                self.say(f"left run {req.run} (exit codes: {codes})")

    def say(self, line: str) -> None:
        """One line on this host's console (standard error), prefixed with its name."""
        print(f"fleet host {self.name}: {line}", file=sys.stderr, flush=True)

    def _start(self, req: HostAssign, sup: Supervisor, scenario: Path) -> None:
        flag = self.fork_server if self.fork_server is not None else req.fork_server
        if fork_server_enabled(flag) and req.robots:
            sup.start_fork_server(scenario)
        for robot in req.robots:
            secret = None
            if robot in req.secrets:  # the launcher's login for it, with this host's CA
                obj = json.loads(req.secrets[robot])
                secret = Credential(str(obj["user"]), str(obj["password"]), self.tls_ca).to_json()
            argv = robot_argv(robot, req.run, self.endpoint, scenario, secret is not None, req.realtime_hz or None,
                              req.nonce)
            child = sup.spawn(robot, AGENTS, argv, secret)
            self.report(req.run, "spawned", robot=robot, pid=child.pid)

    def _watch(self, req: HostAssign, sup: Supervisor, launcher: dict[str, bool]) -> None:
        """Report exits until every robot is gone, or the run must be torn down."""
        reported = self.reported
        start = time.monotonic()
        while not self.interrupts.requested.is_set():
            for name, code in sup.dead().items():
                if name not in reported:
                    reported.add(name)
                    self.report(req.run, "exited", robot=name, code=code)
            if len(reported) == len(req.robots):
                return
            if launcher["gone"] or (not launcher["seen"] and time.monotonic() - start > LAUNCHER_GRACE):
                print(f"fleet host {self.name}: the launcher of run {req.run} is gone; ending its robots",
                      file=sys.stderr)
                return
            other = self.next_request(POLL)
            if other is None:
                continue
            if other.run != req.run:
                self.report(other.run, "busy", error=f"serving run {req.run}")
            elif other.end:
                return
            else:
                self.report(req.run, "accepted")  # a repeat: the first answer was lost or late


def cmd_host(args: argparse.Namespace, interrupts: Interrupts) -> int:
    """``fleet host``: 0 after serving (``--once``), 130/143 on a signal, 2 on bad input or a refused login."""
    name, cred = host_login(args.credentials, args.name, args.tls_ca)
    check_reliable("--connect", args.connect)
    if not 0 < args.connect_timeout <= 3600:
        raise ConfigError(f"--connect-timeout must be in (0, 3600] seconds (got {args.connect_timeout:g})")
    if cred is None:
        print("fleet: warning: fleet host without --credentials: only an unauthenticated router lets it in",
              file=sys.stderr)
    session = open_client(args.connect, cred, args.connect_timeout, example="tcp/192.0.2.1:7447",
                          refused=f" or it refused {name}'s credentials" if cred
                          else "; a router with authentication needs --credentials")
    out = args.out if args.out is not None else Path("runs")
    with session:
        host = Host(session, name, args.connect, cred.tls_ca if cred else None, out, args.fork_server, interrupts)
        print(f"fleet host {name}: connected to {args.connect} (pid {os.getpid()}), waiting for a run",
              file=sys.stderr)
        try:
            host.serve(args.once)
        finally:
            host.close()
    return interrupts.exit_code if interrupts.signum is not None else 0
