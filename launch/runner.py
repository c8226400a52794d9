"""One run of the fleet: embedded router, recorder and monitor, the nodes (as processes or in-process), and
``result.json`` — written on every exit path, Ctrl-C included. No console and no global state: the CLI passes
a progress callback in."""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import os
import queue
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import zenoh

from fleet_emu.core.access import LAUNCHER, RECORDER, Credential, Grant
from fleet_emu.core.bus import Publisher, client_config, new_nonce, publisher, router_config, router_locators
from fleet_emu.core.errors import RunError
from fleet_emu.core.faults import crashes
from fleet_emu.core.grid import Cell, MapData
from fleet_emu.core.keys import BASE, Keys, robot_ids
from fleet_emu.core.messages import Failed, Stop
from fleet_emu.core.node import Declared, undeclare
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.causes import flood
from fleet_emu.launch.checks import (
    check,
    check_logins,
    check_machine,
    check_options,
    credentials,
    new_run_id,
    pinned,
)
from fleet_emu.launch.forked import fork_server_enabled
from fleet_emu.launch.host_client import (
    HOST_TIMEOUT,
    Hosts,
    HostsError,
    listen_endpoints,
    spawn_nodes,
)
from fleet_emu.launch.live import LiveOptions, open_live
from fleet_emu.launch.outdir import DiskFault, claimed, disk_fault, write_atomic, write_json
from fleet_emu.launch.router_process import RouterProcess, router_process, router_spec
from fleet_emu.launch.signals import Interrupts, signal_name
from fleet_emu.launch.supervisor import Supervisor
from fleet_emu.launch.watch import STOP_GRACE, Consumer, Drain, wait_for_end
from fleet_emu.recording.clock import RunClock
from fleet_emu.recording.foxglove import FoxgloveFold
from fleet_emu.recording.foxglove_writer import FoxgloveWriter
from fleet_emu.recording.monitor import Monitor
from fleet_emu.recording.recorder import Recorder
from fleet_emu.recording.result import Ending, Launcher, Result, build_result
from fleet_emu.world.build import base_cell


@dataclasses.dataclass(frozen=True)
class RunOptions:
    """How to run: ``out_dir`` keeps ``result.json``, ``scenario.json``, ``map.npz``, the process logs and
    (with ``record``) ``run.mcap``; without it nothing is kept. ``in_process`` runs every node in this process
    (a session each); ``connect`` uses an external router; ``on_progress`` is called with the monitor as the
    run goes."""

    out_dir: Path | None = None
    in_process: bool = False
    record: bool = True
    connect: str | None = None
    run_id: str = ""
    grid_every: int | None = None  # Foxglove grids every k ticks (default: the scenario's belief_every)
    on_progress: Callable[[Monitor], None] | None = None
    credentials: Path | None = None  # with ``connect``: the users file of `fleet router-config`
    tls_ca: Path | None = None  # with a ``tls/`` ``connect``: the CA certificate that signed the router's
    interrupts: Interrupts | None = None  # the CLI's signal state (None: Ctrl-C raises KeyboardInterrupt)
    on_warning: Callable[[str], None] | None = None  # told once the input is checked (an unauthenticated bus)
    on_note: Callable[[str], None] | None = None  # told what the run waits for (its hosts), for the console
    on_spawn: Callable[[dict[str, Any]], None] | None = None  # told result.json's ``pids`` once the nodes start
    fork_server: bool | None = None  # robots forked from one fork server (None: unless FLEET_FORK_SERVER=0)
    listen: str | None = None  # the embedded router's endpoint (default: loopback, a port the OS picks)
    tls_cert: Path | None = None  # with a ``tls/`` or ``quic/`` ``listen``: the router's certificate (PEM) ...
    tls_key: Path | None = None  # ... and its private key
    host_timeout: float = HOST_TIMEOUT  # seconds to wait for the hosts
    realtime_hz: float | None = None  # real time: the world ticks at this rate on the wall clock (None: lockstep)
    overwrite: bool = False  # an ``out_dir`` holding a run: remove that run's files first (else refused)
    live: LiveOptions | None = None  # serve the run to Foxglove viewers (`fleet run --live`)
    companions: tuple[Companion, ...] = ()  # clients of the run's bus started with it (`fleet run --ros2`)
    grants: tuple[Grant, ...] = ()  # the embedded router's access beyond the run's keys, for the companions ...
    grant_users: dict[str, str] = dataclasses.field(default_factory=dict)  # ... and the users they add


@dataclasses.dataclass(frozen=True)
class BusAccess:
    """What a companion gets once the run's router is up: where it is, the launcher's own login (a companion
    publishes as the launcher: the router's ACL knows no other writer), the run's nonce (on each of its
    messages), the scenario, the true map, the run's clock and the run's folder."""

    endpoint: str
    run_id: str
    login: Credential | None
    nonce: bytes
    scenario: Scenario
    map_data: MapData
    clock: RunClock
    work: Path
    grid_every: int | None


#: A client of the bus that runs beside the fleet (docs/design/architecture.md, "Companions"): given the
#: run's :class:`BusAccess`, a context manager open from before the nodes start until after they stopped. A
#: layer above launch (the ROS 2 bridge) provides it; the launcher never waits on it.
Companion = Callable[[BusAccess], contextlib.AbstractContextManager[object]]


def run_fleet(scenario: Scenario, opts: RunOptions) -> Result:
    """Run one scenario to its end. ``result.json`` is written (atomically) when ``opts.out_dir`` is given,
    on every exit path; Ctrl-C re-raises KeyboardInterrupt after it, and a failed run raises RunError
    (:class:`~fleet_emu.launch.outdir.DiskFault` when the run's files could not be written). Bad input (the
    scenario, the options, an unwritable ``out_dir``, one that holds a run without ``opts.overwrite``, one
    another run holds) raises ConfigError before any process starts and leaves no output directory behind.
    The folder is locked (:mod:`~fleet_emu.launch.outdir`) from before the first write to after the last."""
    scenario = pinned(scenario)  # a policy file read once, here: the robots verify its sha256
    map_data = check(scenario)
    check_machine(scenario, map_data, "in-process" if opts.in_process else "processes",
                  not opts.in_process and fork_server_enabled(opts.fork_server))
    check_logins(opts.connect, opts.credentials, opts.tls_ca, scenario.hosts is not None)
    creds = credentials(scenario, opts)
    check_options(opts, creds, scenario.hosts.count if scenario.hosts else 0)
    if opts.connect is not None and creds is None and opts.on_warning is not None:
        opts.on_warning("--connect without --credentials: this run's bus is not authenticated "
                        "(see `fleet router-config`)")
    run_id = opts.run_id or new_run_id()
    with contextlib.ExitStack() as files:
        files.enter_context(claimed(opts.out_dir, opts.overwrite))  # to the last write: no other run writes here
        work = opts.out_dir or Path(files.enter_context(tempfile.TemporaryDirectory(prefix="fleet-run-")))
        recording = work / "run.mcap" if opts.record and opts.out_dir is not None else None
        try:
            write_json(work / "scenario.json", scenario.to_dict())
            write_atomic(work / "map.npz", map_data.save)
            result, failure = _Run(scenario, map_data, run_id, work, recording, opts, creds).execute()
            if opts.out_dir is not None:
                _write_result(work, result, failure)
        except OSError as exc:  # a full disk, a directory removed under the run
            raise disk_fault(work, exc) from None
    if failure == "disk":
        raise DiskFault(result["error"])
    if failure == "interrupted" and opts.interrupts is None:
        raise KeyboardInterrupt
    if failure == "error":
        raise RunError(result["error"])
    return result


class _Run:
    """The run itself, in phases: :meth:`open` (the fork server, the router, the sessions and subscriptions, the
    consumer thread), :meth:`start` (the nodes), :meth:`wait` (until the run ends), :meth:`teardown` (stop and
    reap the nodes, drain the bus); then :meth:`result`, and how the run failed. A signal
    (``opts.interrupts``) is only ever a request: the teardown and the files are never cut short. A failure
    while opening closes what was opened and propagates."""

    # set by open
    endpoint: str
    session: zenoh.Session
    pub_stop: Publisher
    handles: list[Declared]
    samples: queue.Queue[tuple[str, bytes, int] | None]
    drains: list[Drain]
    remote: Hosts | None
    consumer: Consumer

    def __init__(self, scenario: Scenario, map_data: MapData, run_id: str, work: Path, recording: Path | None,
                 opts: RunOptions, creds: dict[str, Credential] | None) -> None:
        self.scenario, self.map_data, self.run_id, self.work = scenario, map_data, run_id, work
        self.recording, self.opts, self.creds = recording, opts, creds
        self.keys = Keys(run_id)
        self.nonce = new_nonce()  # on every message of this run; a message without it is dropped and counted
        self.robots = tuple(robot_ids(scenario.robots))
        self.monitor = Monitor(self.robots, base=scenario.has_base, relay=scenario.relay != "none")
        self.engine = "in-process" if opts.in_process else "processes"
        meta: dict[str, Any] = {"run_id": run_id, "scenario": scenario.to_dict(), "engine": self.engine}
        if opts.realtime_hz:
            meta["realtime_hz"] = opts.realtime_hz
        self.clock = RunClock.now(scenario.tick_s)  # the scenario's seconds per tick
        self.recorder = Recorder(recording, meta, self.clock) if recording is not None else None
        self.base = base_cell(scenario, map_data)  # resolved once here: netem and the base process take it as given
        self.viz = FoxgloveWriter(self.recorder, FoxgloveFold(
            scenario.to_dict(), map_data.grid, opts.grid_every, run_id, self.base, self.clock), self.keys) \
            if self.recorder or opts.live else None
        self.sup = Supervisor(log_dir=work)
        self.pids: dict[str, Any] = {}
        self.t_start = time.monotonic()
        signals = opts.interrupts
        self.requested = signals.requested if signals else threading.Event()
        self.hurry = signals.hurry if signals else threading.Event()
        self.interrupted = False
        self.error: str | None = None
        self.router_child: RouterProcess | None = None
        self.nodes_thread: threading.Thread | None = None

    def execute(self) -> tuple[Result, str | None]:
        """Every phase in turn; the result and how the run failed (``interrupted``, ``error`` or None)."""
        with contextlib.ExitStack() as stack:
            self.open(stack)
            try:
                self.start()
                self.wait()
            except KeyboardInterrupt:
                self.requested.set()
            except HostsError as exc:  # too few hosts came: the run ends as an error, its files written
                self.error = str(exc)
            finally:
                self.teardown()
        return self.result()

    def open(self, stack: contextlib.ExitStack) -> None:
        """The fork server (it loads while the router opens), the router (unless ``connect``), the launcher's
        and the listener's sessions, the subscriptions feeding the consumer thread, the hosts; each closed by
        ``stack``."""
        opts, keys = self.opts, self.keys
        if not opts.in_process and not self.requested.is_set() and fork_server_enabled(opts.fork_server):
            self.sup.start_fork_server(self.work / "scenario.json")  # before any session
        if self.viz is not None:
            self.viz.live = open_live(stack, opts.live, self.clock, robot_ids(self.scenario.robots))
        self.endpoint = endpoint = opts.connect if opts.connect else self._router(stack)
        login = self.creds or {}
        self.session = stack.enter_context(_closing(zenoh.open(client_config(endpoint, login.get(LAUNCHER)))))
        listener = stack.enter_context(_closing(zenoh.open(client_config(endpoint, login.get(RECORDER)))))
        self.samples = queue.Queue()
        # everything when recording; else only what the fold reads (Keys.folded): at 256 robots the rest (obs,
        # the radio bundles with every first contact's whole maps, belief snapshots) was most of the bus
        self.drains = [Drain(listener, k, self.samples, self.nonce) for k in (
            (keys.all,) if self.viz is not None else keys.folded(radio=self.scenario.relay != "none"))]
        pub_ready = publisher(self.session, keys.ready("launcher"), self.nonce)
        self.pub_stop = publisher(self.session, keys.stop, self.nonce)
        self.handles = [pub_ready, self.pub_stop,
                        self.session.liveliness().declare_token(keys.alive("launcher", "launcher"))]
        access = BusAccess(endpoint, self.run_id, login.get(LAUNCHER), self.nonce, self.scenario, self.map_data,
                           self.clock, self.work, opts.grid_every)
        for companion in opts.companions:
            stack.enter_context(companion(access))
        hosts = self.scenario.hosts
        reach = opts.connect or opts.listen or endpoint  # the endpoint the hosts connect to
        self.remote = stack.enter_context(Hosts(self.session, hosts, opts.host_timeout, reach,
                                                opts.on_note)) if hosts else None
        self.consumer = Consumer(keys, self.samples, self.monitor, self.recorder, pub_ready, self.viz)
        self.consumer.start()

    def _router(self, stack: contextlib.ExitStack) -> str:
        """The embedded router (in this process with ``in_process``, else its own process: the launcher's Python
        work never holds up the fleet's routing); the endpoint this machine's processes connect to."""
        opts = self.opts
        listen = listen_endpoints(opts.listen, opts.tls_cert, opts.tls_key)
        tls = (str(opts.tls_cert.absolute()), str(opts.tls_key.absolute())) \
            if opts.tls_cert is not None and opts.tls_key is not None else None
        if opts.in_process:  # one process by design: the router too
            try:
                router = stack.enter_context(_closing(_open_router(self.run_id, self.creds, listen, tls,
                                                                   (opts.grants, opts.grant_users))))
            except zenoh.ZError as exc:
                raise RunError(f"cannot open the embedded Zenoh router: {str(exc).splitlines()[0]}") from None
            locators = router_locators(router)
        else:
            self.router_child = stack.enter_context(router_process(self.run_id, self.creds, listen, tls, self.work,
                                                                   (opts.grants, opts.grant_users)))
            locators = self.router_child.endpoints
        # the router's first endpoint, or with tls/ or quic/ its loopback tcp/ one
        return next(loc for loc in locators if tls is None or loc.startswith("tcp/"))

    def start(self) -> None:
        """The nodes, in this process or as processes (here and on the hosts), and their pids told to
        ``opts.on_spawn``; nothing once a stop was requested (a signal while opening)."""
        if self.requested.is_set():
            return
        scenario, opts, robots = self.scenario, self.opts, self.robots
        if opts.in_process:
            self.nodes_thread = _start_in_process(scenario, self.map_data, self.run_id, self.endpoint, self.creds,
                                                  self.base, opts.realtime_hz,
                                                  opts.live.hz if opts.live is not None else None, self.nonce)
            self.pids = {"world": os.getpid(), "netem": os.getpid(), "robots": [os.getpid()] * len(robots)}
            self.pids |= {BASE: os.getpid()} if scenario.has_base else {}
        else:
            plan = spawn_nodes(self.sup, scenario, self.run_id, self.endpoint, self.work, self.creds, self.remote,
                               self.requested, opts.realtime_hz, self.base,
                               opts.live.hz if opts.live is not None else None, self.nonce.hex())
            p = self.sup.pids()
            pids = {"world": p["world"], "netem": p["netem"], "robots": [p[r] for r in robots]}
            pids |= {BASE: p[BASE]} if BASE in p else {}
            pids |= ({"fork_server": p["fork_server"]} if "fork_server" in p else {}) | \
                ({"router": self.router_child.proc.pid} if self.router_child is not None else {}) | \
                ({"hosts": plan} if plan else {})
            self.pids = pids
        if self.pids and opts.on_spawn is not None:
            opts.on_spawn(self.pids)  # e.g. benchmarks/scale.py samples their /proc while the run goes

    def wait(self) -> None:
        """Until the run ends (:func:`~fleet_emu.launch.watch.wait_for_end`); an agent process that exits early
        is announced to the world as failed. A failed run's error line is kept."""
        keys, monitor, session, nonce = self.keys, self.monitor, self.session, self.nonce

        def failed(robot: str) -> None:
            session.put(keys.failed(robot), Failed(src="launcher", tick=monitor.tick, seq=0, robot=robot,
                                                   reason="process exited").encode(),
                        congestion_control=zenoh.CongestionControl.BLOCK, attachment=nonce)

        crash = _Crashes(self.scenario, self.sup, self.opts.on_progress)
        self.error = wait_for_end(monitor, self.consumer, self.sup, self.nodes_thread, crash.watch,
                                  self.requested, failed, self.router_child,
                                  None if self.opts.realtime_hz else self.scenario.barrier_timeout)

    def teardown(self) -> None:
        """The stop (unless the world stopped the run by itself: a signal after its stop is the teardown's), the
        nodes reaped (killed after the grace, sooner once hurried), then the last samples in and the consumer
        ended, and the launcher's declarations undone."""
        monitor, sup, hurry = self.monitor, self.sup, self.hurry
        # a disk fault stays the run's end, whatever signal comes with it (the signal sets only the exit code)
        self.interrupted = self.requested.is_set() and monitor.stop is None and self.consumer.fault is None
        again = None
        if monitor.stop is None or self.interrupted:
            stop = Stop(src="launcher", tick=monitor.tick, seq=1,
                        reason="interrupted" if self.interrupted else "aborted").encode()

            def again() -> None:  # a node still starting subscribes after the first put: it takes a later one
                with contextlib.suppress(zenoh.ZError):
                    self.pub_stop.put(stop)

            again()
        if not sup.wait_all(STOP_GRACE, hurry, again):
            sup.kill_all(grace=0.5 if hurry.is_set() else 2.0)
        sup.kill_all()
        if self.nodes_thread is not None:
            self.nodes_thread.join(STOP_GRACE)
        time.sleep(0.1)  # let the last samples reach the subscriber
        for drain in self.drains:
            drain.undeclare()
        self.samples.put(None)
        self.consumer.join()  # it may still answer a hello on pub_ready: undeclare that only after it ends
        undeclare(self.handles)
        if self.viz is not None:  # the last tick's scene and grids, while the live server is still up
            self.viz.finish()

    def bus(self) -> dict[str, Any]:
        """``result.json``'s ``bus``: the run's nonce and the messages each process dropped for not carrying it
        (the launcher's own from its subscribers)."""
        foreign_by = self.monitor.foreign_by(sum(d.foreign for d in self.drains))
        return {"nonce": self.nonce.hex(), "foreign_dropped": sum(foreign_by.values()),
                "foreign_dropped_by": foreign_by}

    def result(self) -> tuple[Result, str | None]:
        """The recording closed, and the result (``result.json``, :func:`~fleet_emu.recording.result.build_result`)
        with how the run ended."""
        if self.viz is not None:
            self.viz.finish()
        messages = self.recorder.close() if self.recorder else 0
        scenario, opts, recording, interrupted = self.scenario, self.opts, self.recording, self.interrupted
        if not interrupted and self.error is None:  # robots failed by a flood: the flood is the cause
            self.error = flood(self.monitor.failed(), sum(d.foreign for d in self.drains))
        if self.error and not interrupted and opts.out_dir is None:  # its logs go with the temporary folder
            self.error += f" ({_last_log_line(self.work, self.error)})"
        launcher = Launcher(time.monotonic() - self.t_start, signal_name(opts.interrupts, interrupted),
                            self.creds is not None, self.bus())
        data = build_result(self.monitor, scenario.to_dict(), self.run_id,
                            Ending(interrupted=interrupted, error=None if interrupted else self.error),
                            engine=self.engine, pids=self.pids, recording=str(recording) if recording else None,
                            messages=messages, launcher=launcher, realtime_hz=opts.realtime_hz)
        failure = "interrupted" if interrupted else ("error" if self.error else None)
        if failure == "error" and self.consumer.fault is not None and self.error == self.consumer.fault:
            failure = "disk"
        return Result(data, tuple(self.monitor.coverage_curve), recording.parent if recording else None), failure


class _Crashes:
    """The scenario's crash faults in the processes engine: once the world's state shows a robot it crashed
    (``world/sim.py`` takes it out of the run at its tick, in every engine alike), its process is killed, as
    ``kill -9`` would (robots in the launcher's process, ``--in-process``, are left to the run's stop). Called
    with the monitor every time the launcher's watch wakes, before ``on_progress``."""

    def __init__(self, scenario: Scenario, sup: Supervisor, on_progress: Callable[[Monitor], None] | None) -> None:
        self.pending = dict(crashes(scenario.faults))
        self.sup, self.on_progress = sup, on_progress

    def watch(self, monitor: Monitor) -> None:
        st = monitor.state
        if self.pending and st is not None:
            for robot, tick in list(self.pending.items()):
                if st.tick >= tick and robot not in st.live:
                    del self.pending[robot]
                    self.sup.kill(robot)
        if self.on_progress is not None:
            self.on_progress(monitor)


def _write_result(work: Path, result: Result, failure: str | None) -> None:
    """``result.json``, atomically; after a disk fault, a failed write changes nothing of what is told."""
    try:
        write_json(work / "result.json", result.data)
    except OSError:
        if failure != "disk":
            raise


def _last_log_line(work: Path, error: str) -> str:
    """The last line a failed process wrote (its log is not kept when there is no output directory)."""
    for name in ("world", "netem"):
        if error.startswith(f"the {name} process"):
            lines = (work / f"{name}.log").read_text(errors="replace").strip().splitlines()
            return lines[-1] if lines else "it wrote nothing"
    return "no log"


@contextlib.contextmanager
def _closing(session: zenoh.Session) -> Iterator[zenoh.Session]:
    """The session, closed on the way out; a close that times out (Zenoh gives up after a while: the router's
    with 256 robots on a loaded machine did) is let go, since the run's files are still to be written."""
    try:
        yield session
    finally:
        with contextlib.suppress(zenoh.ZError):
            session.close()


def _open_router(run_id: str, creds: dict[str, Credential] | None, listen: list[str],
                 tls: tuple[str, str] | None = None,
                 grants: tuple[tuple[Grant, ...], dict[str, str]] = ((), {})) -> zenoh.Session:
    """The router embedded in this process (``--in-process``), set up as the router process's
    (:func:`~fleet_emu.launch.router_process.router_spec`); its users file lives in a private temporary
    directory only while it opens (Zenoh reads it then)."""
    with tempfile.TemporaryDirectory(prefix="fleet-auth-") as private:  # mode 0700
        return zenoh.open(router_config(**router_spec(Path(private), run_id, creds, listen, tls, grants)))


def _start_in_process(scenario: Scenario, map_data: MapData, run_id: str, endpoint: str,
                      creds: dict[str, Credential] | None, base: Cell | None,
                      realtime_hz: float | None = None, pace_hz: float | None = None,
                      nonce: bytes | None = None) -> threading.Thread:
    """Every node in this process, each with its own Zenoh session (and its own login) to the same router;
    ``base``: the base station's cell (``world.build.base_cell``), in a run with one; ``pace_hz``: the
    lockstep world's cap on ticks per second (``--live-hz``)."""
    from fleet_emu.agents.node import RobotNode
    from fleet_emu.netem.node import NetemNode
    from fleet_emu.world.node import WorldNode

    nodes = [WorldNode(scenario, run_id, map_data, realtime_hz=realtime_hz, pace_hz=pace_hz),
             NetemNode(scenario, run_id, map_data, base, realtime_hz=realtime_hz)]
    nodes += [RobotNode(scenario, run_id, r, realtime_hz=realtime_hz) for r in robot_ids(scenario.robots)]
    if base is not None:
        from fleet_emu.agents.base_node import BaseStationNode

        nodes.append(BaseStationNode(scenario, run_id, map_data, base))

    for n in nodes:
        n.bind(nonce)

    async def main() -> None:
        with contextlib.ExitStack() as stack:
            sessions = [stack.enter_context(zenoh.open(client_config(endpoint, creds[n.node_id] if creds else None)))
                        for n in nodes]
            await asyncio.gather(*(n.run(s) for n, s in zip(nodes, sessions, strict=True)))

    thread = threading.Thread(target=lambda: asyncio.run(main()), daemon=True, name="nodes")
    thread.start()
    return thread


