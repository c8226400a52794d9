"""Robots on other machines: the host protocol's client side, the launcher's (``launch/host_server.py``, the
process ``fleet host`` runs on each remote machine, is the server side, which serves the requests sent here).

``fleet run --hosts N`` (or a scenario's ``[hosts]``, :class:`~fleet_emu.core.scenario.HostPlan`) deals the
robots round-robin over this machine and N hosts (:func:`placement`: ``r0`` here, ``r1`` on the first host,
..., or as many per host as ``[hosts] robots`` says; deterministic, and the result does not depend on it:
lockstep), and starts each host's robots there. The protocol, over the run's own Zenoh router, in the hosts' lobby
``fleet-host/<host>/...`` (outside every run's ``fleet/<run>/**``, so the recorder never records it):

1. A host (``fleet host --connect ENDPOINT --credentials FILE``) logs in as its own user ``hostK``, subscribes
   to ``fleet-host/hostK/spawn``, then declares its liveliness token ``fleet-host/hostK/alive``.
2. The launcher watches ``fleet-host/*/alive`` and waits up to ``--host-timeout`` seconds for N hosts (a one-line
   error naming the ones that came, after it), and takes the first N by number (or the ``[hosts] names``).
3. It puts a :class:`~fleet_emu.core.messages.HostAssign` on each host's ``spawn`` key: the run id, the
   scenario, the real-time rate (``--realtime``; 0 in lockstep), the host's robots and each robot's credential
   (``secrets``), repeated every second until the host
   answers ``accepted`` (or ``busy``: it serves another run) on ``fleet-host/hostK/status``.
4. The host writes the scenario, starts each robot exactly as the launcher would here (:func:`robot_argv`: the
   same argv, its own ``--connect``, the credential on standard input, its own process group, from a fork
   server unless turned off) and reports ``spawned`` (the pid) and ``exited`` (the exit code) per robot.
5. The launcher's supervisor holds a :class:`RemoteRobot` per robot, a handle like a local child's: a robot
   that exits (or whose host's token goes: the host died or lost the router) is failed and the run goes on
   without it. Tearing down sends ``HostAssign(end=True)``; the host also tears its robots down when the
   launcher's token ``fleet/<run>/alive/launcher/launcher`` goes, and on its own Ctrl-C or SIGTERM.

Security: ``spawn`` carries robots' passwords. The access control (``core/access.py``, :func:`lobby_rules`)
lets only host K subscribe to and receive ``fleet-host/K/spawn``, only the launcher put there, only host K put
on its ``status`` and declare its token; receivers also check a message's ``src`` against its key. Residual
risk: the router (trusted: it holds every password) and, on a ``tcp/`` link, anyone on the network path read
the request; use a ``tls/`` router (``fleet router-config --tls-cert``) across networks you do not trust. A
host's machine holds its robots' credentials while they run, which let it write only those robots' keys.
"""

from __future__ import annotations

import contextlib
import functools
import json
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import zenoh

from fleet_emu.core.access import Credential, read_users, role_of
from fleet_emu.core.bus import Publisher, publisher
from fleet_emu.core.codec import DecodeError, decode
from fleet_emu.core.errors import ConfigError, RunError
from fleet_emu.core.grid import Cell
from fleet_emu.core.keys import BASE, HostKeys, robot_ids
from fleet_emu.core.messages import HostAssign, HostStatus
from fleet_emu.core.node import Declared, undeclare
from fleet_emu.core.scenario import HostPlan, Scenario
from fleet_emu.launch.forked import FORK_TIMEOUT, NOT_STARTED

if TYPE_CHECKING:
    from fleet_emu.launch.supervisor import Supervisor

HOST_TIMEOUT = 60.0  # seconds ``fleet run --hosts N`` waits for N hosts by default
RESEND = 1.0  # seconds between repeats of an unanswered request
ACCEPT_TIMEOUT = 15.0  # seconds a host that came may take to accept its robots
HOST_LOST = -9  # the exit code of a robot whose host went away (as if killed)


class HostsError(RunError):
    """Not enough hosts came, or one refused its robots."""


def placement(robots: list[str], hosts: list[str], shares: tuple[int, ...] = ()) -> dict[str, str | None]:
    """Where each robot runs: dealt one at a time round this machine (None) and ``hosts``, in that order,
    skipping a machine that has its share (``shares``: each host's number of robots, the rest here; none:
    plain round-robin, which equal shares give too)."""
    slots: list[str | None] = [None, *hosts]
    room = [len(robots) - sum(shares), *shares] if shares else [len(robots)] * len(slots)
    where: dict[str, str | None] = {}
    i = 0
    for r in robots:
        while room[i % len(slots)] == 0:
            i += 1
        room[i % len(slots)] -= 1
        where[r] = slots[i % len(slots)]
        i += 1
    return where


def host_credentials(path: Path | None, plan: HostPlan | None = None) -> dict[str, Credential]:
    """The hosts' logins (``hostK:password`` lines of a users file) the embedded router accepts; a ConfigError
    when they cannot make ``plan`` (too few hosts, or one of its ``names`` missing)."""
    if path is None:
        raise ConfigError("--hosts (or a scenario's [hosts]) with the embedded router needs --credentials USERS, "
                          "whose hostK:password lines the hosts log in with (`fleet router-config --hosts N` writes "
                          "them)")
    users = read_users(path)
    hosts = {u: Credential(u, p) for u, p in users.items() if role_of(u) == "host"}
    if not hosts:
        raise ConfigError(f"--credentials {path} has no host user (hostK:password lines)")
    missing = [h for h in plan.names if h not in hosts] if plan is not None else []
    if missing:
        raise ConfigError(f"--credentials {path} has no user {missing[0]!r} of the scenario's [hosts] names")
    if plan is not None and plan.count > len(hosts):
        raise ConfigError(f"--credentials {path} has {len(hosts)} host user(s) for {plan.count} hosts: make them "
                          f"with `fleet router-config --hosts {plan.count}`")
    return hosts


def check_hosts(hosts: int, in_process: bool, connect: str | None, listen: str | None) -> None:
    """The ``--hosts`` options (``hosts``: how many, from the flag or the scenario's ``[hosts]``) that can be
    wrong before anything starts."""
    if hosts < 0 or hosts > 64:
        raise ConfigError(f"--hosts must be in 0..64 (got {hosts})")
    if hosts and in_process:
        raise ConfigError("--hosts (or a scenario's [hosts]) runs robots as processes on other machines: it "
                          "takes no --in-process")
    if hosts and connect is None and listen is None:
        raise ConfigError("--hosts (or a scenario's [hosts]) needs a router the hosts can reach: --listen "
                          "tcp/ADDRESS:PORT for the embedded one, or --connect")
    if listen is not None and connect is not None:
        raise ConfigError("--listen is the embedded router's: it takes no --connect")


LISTEN_PROTOCOLS = ("tcp", "tls", "quic")  # what the embedded router listens on (tls and quic: with a certificate)
SECURE_PROTOCOLS = ("tls", "quic")
LOOPBACK = "tcp/127.0.0.1:0"


def check_reliable(flag: str, endpoint: str) -> None:
    """A ConfigError for a ``udp/`` endpoint: Zenoh does not retransmit over UDP (its reliability is hop to hop,
    from the link), and the fleet's only losses must be the ones netem decides (docs/design/determinism.md)."""
    if endpoint.startswith("udp/"):
        raise ConfigError(f"{flag} {endpoint}: Zenoh does not retransmit over udp/, and a lockstep run may lose no "
                          f"message: use tcp/, tls/ or quic/")


def listen_endpoints(listen: str | None, tls_cert: Path | None, tls_key: Path | None) -> list[str]:
    """The embedded router's endpoints for ``--listen`` (``tcp/``, or ``tls/`` and ``quic/`` with
    ``--tls-cert`` and ``--tls-key``): the one given, and for a ``tls/`` or ``quic/`` one a loopback ``tcp/``
    one too, which this machine's own processes use (they need no CA). ``udp/`` is refused: Zenoh does not
    retransmit over UDP, and lockstep must lose no message but the ones netem decides (docs/design/determinism.md)."""
    proto, sep, address = (listen or LOOPBACK).partition("/")
    if not sep or not address:
        raise ConfigError(f"--listen {listen!r} is not an endpoint (expected <protocol>/<address>:<port>, e.g. "
                          f"tcp/192.0.2.1:7447)")
    check_reliable("--listen", listen or LOOPBACK)
    if proto not in LISTEN_PROTOCOLS:
        raise ConfigError(f"--listen {listen}: the embedded router listens on tcp/, tls/ or quic/ (got {proto}/)")
    secure = proto in SECURE_PROTOCOLS
    if secure and (tls_cert is None or tls_key is None):
        raise ConfigError(f"--listen {listen}: a {proto}/ router needs --tls-cert CERT.pem and --tls-key KEY.pem "
                          f"(signed by a CA the hosts trust: `fleet host --tls-ca CA.pem`)")
    if not secure and (tls_cert is not None or tls_key is not None):
        raise ConfigError("--tls-cert and --tls-key go with a tls/ or quic/ --listen")
    for flag, path in (("--tls-cert", tls_cert), ("--tls-key", tls_key)):
        if path is not None and not path.is_file():
            raise ConfigError(f"{flag} {path}: no such file")
    return [listen or LOOPBACK, LOOPBACK] if secure else [listen or LOOPBACK]


def robot_argv(robot: str, run_id: str, endpoint: str, scenario_file: Path, auth: bool,
               realtime_hz: float | None = None, nonce: str = "") -> list[str]:
    """The command line of robot ``robot`` (``python -m fleet_emu.agents ARGV``), here or on a host; ``nonce``:
    the run's, in hex."""
    return ["--robot", robot, "--run", run_id, "--connect", endpoint, "--scenario", str(scenario_file),
            *(["--realtime", repr(float(realtime_hz))] if realtime_hz else []), *(["--auth-stdin"] if auth else []),
            *(["--nonce", nonce] if nonce else [])]


def spawn_nodes(sup: Supervisor, scenario: Scenario, run_id: str, endpoint: str, work: Path,
                creds: dict[str, Credential] | None, remote: Hosts | None = None,
                requested: threading.Event | None = None, realtime_hz: float | None = None,
                base: Cell | None = None, pace_hz: float | None = None, nonce: str = "") -> dict[str, list[str]]:
    """world, netem, the base station (when the scenario has one: at ``base``, its cell as
    ``world.build.base_cell`` resolved it) and one process per robot, each with its
    own credential on standard input; with
    ``remote``, first wait for its hosts and start their robots there. The hosts and their robots."""
    robots = robot_ids(scenario.robots)
    hosts = remote.gather(requested or threading.Event()) if remote is not None else []
    if remote is not None and not hosts:  # a signal while waiting: nothing is started
        raise KeyboardInterrupt
    where = placement(robots, hosts, scenario.hosts.robots if scenario.hosts else ())
    common = ["--run", run_id, "--connect", endpoint, "--scenario", str(work / "scenario.json")]
    common += ["--realtime", repr(float(realtime_hz))] if realtime_hz else []
    common += ["--nonce", nonce] if nonce else []
    auth = ["--auth-stdin"] if creds else []
    truth = ["--map-file", str(work / "map.npz")]

    def secret(node: str) -> str | None:
        return creds[node].to_json() if creds else None

    pace = ["--pace", repr(float(pace_hz))] if pace_hz else []  # --live-hz: the world paces the lockstep
    sup.spawn("world", "fleet_emu.world", [*common, *truth, *pace, *auth], secret("world"))
    at_base = ["--base-cell", f"{base[0]},{base[1]}"] if base is not None else []
    sup.spawn("netem", "fleet_emu.netem", [*common, *truth, *at_base, *auth], secret("netem"))
    if scenario.has_base:  # the base station: on this machine, like world and netem
        sup.spawn(BASE, "fleet_emu.agents.base_node", [*common, *truth, *at_base, *auth], secret(BASE))
    for r in robots:
        if where[r] is None:
            sup.spawn(r, "fleet_emu.agents", robot_argv(r, run_id, endpoint, work / "scenario.json", bool(creds),
                                                        realtime_hz, nonce), secret(r))
    plan = {h: [r for r in robots if where[r] == h] for h in hosts}
    if remote is not None:
        secrets = {r: json.dumps({"user": creds[r].user, "password": creds[r].password}) for r in robots} \
            if creds else {}
        text = (work / "scenario.json").read_text()
        for name, handle in remote.start(run_id, plan, text, secrets, sup.server is not None, realtime_hz,
                                         nonce).items():
            sup.adopt(name, handle)
    return plan


def _number(host: str) -> int:
    return int(host[4:])


class RemoteRobot:
    """A robot on a host: the parts of :class:`subprocess.Popen` the supervisor uses, from the host's reports."""

    def __init__(self, name: str, host: str, hosts: Hosts) -> None:
        self.name = name
        self.host = host
        self.pid = 0  # the host's pid (another machine's), once reported
        self.returncode: int | None = None
        self._hosts = hosts

    def poll(self) -> int | None:
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        import subprocess

        with self._hosts.changed:
            if not self._hosts.changed.wait_for(lambda: self.returncode is not None, timeout):
                raise subprocess.TimeoutExpired(self.name, timeout or 0.0)
        assert self.returncode is not None
        return self.returncode

    def signal_group(self, _sig: int) -> None:
        """Ask its host to tear the run down (the host signals the robots' process groups there)."""
        if self.returncode is None:
            self._hosts.end(self.host)


class Hosts:
    """The launcher's view of the hosts, over its own session: who is there, and their robots' handles."""

    def __init__(self, session: zenoh.Session, plan: HostPlan, timeout: float = HOST_TIMEOUT,
                 endpoint: str = "", say: Callable[[str], None] | None = None) -> None:
        self.session = session
        self.endpoint = endpoint  # the router the hosts connect to, as a timeout's message names it
        self.say = say  # the launcher's console: what it waits for, and who came
        self.count = plan.count
        self.names = plan.names  # the hosts to wait for (none: any ``count``)
        self.timeout = timeout
        self.changed = threading.Condition()
        self.alive: set[str] = set()
        self.dropped = 0
        self.run = ""
        self.answers: dict[str, HostStatus] = {}  # host -> its accepted/busy answer for this run
        self.robots: dict[str, RemoteRobot] = {}
        self._pubs: dict[str, Publisher] = {}
        self._ended: set[str] = set()
        self._handles: list[Declared] = [
            session.liveliness().declare_subscriber(HostKeys.ALL_ALIVE, self._on_alive, history=True)]

    def __enter__(self) -> Hosts:
        return self

    def __exit__(self, *_: object) -> None:
        for host in list(self.answers):  # a host whose robots were never adopted (an error while starting)
            self.end(host)
        self._handles += self._pubs.values()
        undeclare(self._handles)
        self._pubs.clear()

    # --- zenoh callbacks: update the state and return ---------------------------------------------------------

    def _on_alive(self, sample: zenoh.Sample) -> None:
        host = HostKeys.host_of(sample.key_expr)
        if host is None:
            return
        with self.changed:
            if sample.kind == zenoh.SampleKind.PUT:
                self.alive.add(host)
            else:
                self.alive.discard(host)
                for robot in self.robots.values():  # its robots die with it (their parent watchdog)
                    if robot.host == host and robot.returncode is None:
                        robot.pid = robot.pid or NOT_STARTED
                        robot.returncode = HOST_LOST
            self.changed.notify_all()

    def _on_status(self, sample: zenoh.Sample) -> None:
        host = HostKeys.host_of(sample.key_expr)
        try:
            msg = decode(sample.payload.to_bytes(), expected=HostStatus)
        except DecodeError:
            msg = None
        with self.changed:
            if host is None or msg is None or msg.src != host:  # behind the router's ACL, the second line
                self.dropped += 1
                return
            if msg.run != self.run:
                return
            robot = self.robots.get(msg.robot)
            if msg.event in ("accepted", "busy"):
                self.answers.setdefault(host, msg)
            elif robot is not None and robot.host == host and msg.event == "spawned":
                robot.pid = msg.pid
            elif robot is not None and robot.host == host and msg.event == "exited" and robot.returncode is None:
                robot.pid = robot.pid or NOT_STARTED
                robot.returncode = msg.code
            elif msg.event == "ended":
                for r in self.robots.values():
                    if r.host == host and r.returncode is None:
                        r.pid = r.pid or NOT_STARTED
                        r.returncode = NOT_STARTED
            self.changed.notify_all()

    # --- the launcher's side -------------------------------------------------------------------------------

    def gather(self, requested: threading.Event) -> list[str]:
        """The :attr:`names` hosts, or the first :attr:`count` by number, once they are there; [] if
        ``requested`` (a signal) is set first; :class:`HostsError` after :attr:`timeout` seconds."""
        deadline = time.monotonic() + self.timeout
        wanted = ", ".join(self.names) if self.names else f"{self.count} host(s)"
        if self.say is not None:
            self.say(f"waiting up to {self.timeout:g} s at {self.endpoint} for {wanted} (`fleet host --connect "
                     f"{self.endpoint} --credentials hostK.txt` on each)")
        came = self._gathered(requested, deadline)
        if came and self.say is not None:
            self.say(f"{', '.join(came)} came; starting the run")
        return came

    def _gathered(self, requested: threading.Event, deadline: float) -> list[str]:
        """:meth:`gather`'s wait, until ``deadline`` (a ``time.monotonic()`` value) and not a moment past it."""
        with self.changed:
            while not (set(self.names) <= self.alive if self.names else len(self.alive) >= self.count):
                if requested.is_set():
                    return []
                left = deadline - time.monotonic()
                if left <= 0:
                    came = ", ".join(sorted(self.alive, key=_number)) or "none"
                    how = f"`fleet host --connect {self.endpoint or 'ENDPOINT'} --credentials hostK.txt`"
                    if self.names:
                        missing = ", ".join(h for h in self.names if h not in self.alive)
                        raise HostsError(f"[hosts] names: waited {self.timeout:g} s at {self.endpoint} for "
                                         f"{missing} ({how}); came: {came}")
                    raise HostsError(f"--hosts {self.count}: waited {self.timeout:g} s at {self.endpoint} for "
                                     f"{self.count} host(s) ({how}), {len(self.alive)} came ({came})")
                self.changed.wait(min(0.2, left))
            return list(self.names) or sorted(self.alive, key=_number)[:self.count]

    def start(self, run: str, plan: dict[str, list[str]], scenario: str, secrets: dict[str, str],
              fork_server: bool, realtime_hz: float | None = None, nonce: str = "") -> dict[str, RemoteRobot]:
        """Send every host its robots (with the run's real-time rate, if any); repeat until each accepts; wait
        for their pids (a robot not reported within :data:`FORK_TIMEOUT` counts as never started).
        :class:`HostsError` if a host refuses or is silent."""
        for host in plan:  # one subscriber per host: a wildcard one never reaches a host through the ACL
            self._handles.append(self.session.declare_subscriber(HostKeys(host).status, self._on_status))
        with self.changed:
            self.run = run
            for host, names in plan.items():
                for name in names:
                    self.robots[name] = RemoteRobot(name, host, self)
        requests = {h: HostAssign(src="launcher", tick=0, seq=0, host=h, run=run, robots=tuple(rs), scenario=scenario,
                                  secrets={r: secrets[r] for r in rs if r in secrets}, fork_server=fork_server,
                                  realtime_hz=float(realtime_hz or 0.0), nonce=nonce)
                    for h, rs in plan.items()}
        deadline = time.monotonic() + ACCEPT_TIMEOUT
        while True:
            with self.changed:
                waiting = [h for h in plan if h not in self.answers and h in self.alive]
                gone = [h for h in plan if h not in self.answers and h not in self.alive]
                busy = [f"{h} ({a.error})" for h, a in self.answers.items() if a.event == "busy"]
            if busy or gone:
                raise HostsError(f"host {(busy or gone)[0]} " + ("is busy" if busy else "went away before accepting"))
            if not waiting:
                break
            if time.monotonic() > deadline:
                raise HostsError(f"host {waiting[0]} did not accept its robots within {ACCEPT_TIMEOUT:g} s")
            for h in waiting:
                self._put(h, requests[h])
            with self.changed:
                self.changed.wait_for(functools.partial(self._answered, waiting), RESEND)
        with self.changed:
            self.changed.wait_for(lambda: all(r.pid or r.returncode is not None for r in self.robots.values()),
                                  FORK_TIMEOUT)
            for r in self.robots.values():
                if not r.pid and r.returncode is None:
                    r.pid, r.returncode = NOT_STARTED, NOT_STARTED
            return dict(self.robots)

    def _answered(self, hosts: list[str]) -> bool:
        return all(h in self.answers for h in hosts)

    def end(self, host: str) -> None:
        """Ask ``host`` to tear this run's robots down (once)."""
        if host in self._ended:
            return
        self._ended.add(host)
        self._put(host, HostAssign(src="launcher", tick=0, seq=1, host=host, run=self.run, end=True))

    def _put(self, host: str, msg: HostAssign) -> None:
        if host not in self._pubs:
            self._pubs[host] = publisher(self.session, HostKeys(host).spawn)
        with contextlib.suppress(zenoh.ZError):  # the session is closing: the host sees the launcher's token go
            self._pubs[host].put(msg.encode())

