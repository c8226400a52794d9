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

from fleet_emu.core.access import LAUNCHER, RECORDER, Credential
from fleet_emu.core.bus import client_config, publisher, router_config, router_locators
from fleet_emu.core.errors import RunError
from fleet_emu.core.grid import MapData
from fleet_emu.core.keys import BASE, Keys, robot_ids
from fleet_emu.core.messages import Failed, Stop
from fleet_emu.core.node import Declared, undeclare
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.checks import (
    check,
    check_logins,
    check_machine,
    check_options,
    credentials,
    make_out,
    new_run_id,
)
from fleet_emu.launch.forked import fork_server_enabled
from fleet_emu.launch.hosts import (
    HOST_TIMEOUT,
    Hosts,
    HostsError,
    listen_endpoints,
    spawn_nodes,
)
from fleet_emu.launch.result import Result, write_json_atomic
from fleet_emu.launch.router_process import RouterProcess, router_process, router_spec
from fleet_emu.launch.signals import Interrupts
from fleet_emu.launch.supervisor import Supervisor
from fleet_emu.launch.watch import STOP_GRACE, Consumer, Drain, wait_for_end
from fleet_emu.recording.foxglove import FoxgloveFold
from fleet_emu.recording.foxglove_writer import FoxgloveWriter
from fleet_emu.recording.monitor import Monitor
from fleet_emu.recording.recorder import Recorder
from fleet_emu.world.node import base_cell


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
    on_spawn: Callable[[dict[str, Any]], None] | None = None  # told result.json's ``pids`` once the nodes start
    fork_server: bool | None = None  # robots forked from one fork server (None: unless FLEET_FORK_SERVER=0)
    listen: str | None = None  # the embedded router's endpoint (default: loopback, a port the OS picks)
    tls_cert: Path | None = None  # with a ``tls/`` or ``quic/`` ``listen``: the router's certificate (PEM) ...
    tls_key: Path | None = None  # ... and its private key
    host_timeout: float = HOST_TIMEOUT  # seconds to wait for the hosts
    realtime_hz: float | None = None  # real time: the world ticks at this rate on the wall clock (None: lockstep)


def run_fleet(scenario: Scenario, opts: RunOptions) -> Result:
    """Run one scenario to its end. ``result.json`` is written (atomically) when ``opts.out_dir`` is given,
    on every exit path; Ctrl-C re-raises KeyboardInterrupt after it, and a failed run raises RunError.
    Bad input (the scenario, the options, an unwritable ``out_dir``) raises ConfigError before any process
    starts and leaves no output directory behind."""
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
    if opts.out_dir is not None:
        make_out(opts.out_dir)
    with contextlib.ExitStack() as files:
        work = opts.out_dir or Path(files.enter_context(tempfile.TemporaryDirectory(prefix="fleet-run-")))
        recording = work / "run.mcap" if opts.record and opts.out_dir is not None else None
        try:
            write_json_atomic(work / "scenario.json", scenario.to_dict())
            map_data.save(work / "map.npz")
            result, failure = _run(scenario, map_data, run_id, work, recording, opts, creds)
            if opts.out_dir is not None:
                write_json_atomic(work / "result.json", result.data)
            elif failure == "error":
                result.data["error"] += f" ({_last_log_line(work, result.data['error'])})"
        except OSError as exc:  # a full disk, a directory removed under the run
            raise RunError(f"cannot write the run's files in {work}: {exc.strerror or exc}") from None
    if failure == "interrupted" and opts.interrupts is None:
        raise KeyboardInterrupt
    if failure == "error":
        raise RunError(result["error"])
    return result


def _run(scenario: Scenario, map_data: MapData, run_id: str, work: Path, recording: Path | None,
         opts: RunOptions, creds: dict[str, Credential] | None) -> tuple[Result, str | None]:
    """The run itself: router, recorder, nodes, the wait, the teardown; the result and how it failed.
    A signal (``opts.interrupts``) is only ever a request: the teardown and the files are never cut short."""
    keys = Keys(run_id)
    robots = tuple(robot_ids(scenario.robots))
    monitor = Monitor(robots, base=scenario.has_base, relay=scenario.relay != "none")
    engine = "in-process" if opts.in_process else "processes"
    meta: dict[str, Any] = {"run_id": run_id, "scenario": scenario.to_dict(), "engine": engine}
    if opts.realtime_hz:
        meta["realtime_hz"] = opts.realtime_hz
    recorder = Recorder(recording, meta) if recording is not None else None
    viz = FoxgloveWriter(recorder, FoxgloveFold(scenario.to_dict(), map_data.grid, opts.grid_every, run_id,
                                                base_cell(scenario, map_data)), keys) if recorder else None
    sup = Supervisor(log_dir=work)
    pids: dict[str, Any] = {}
    t_start = time.monotonic()
    signals = opts.interrupts
    requested = signals.requested if signals else threading.Event()
    hurry = signals.hurry if signals else threading.Event()
    interrupted = False
    error: str | None = None
    router_child: RouterProcess | None = None
    with contextlib.ExitStack() as stack:
        if not opts.in_process and not requested.is_set() and fork_server_enabled(opts.fork_server):
            sup.start_fork_server(work / "scenario.json")  # before any session: it loads while the router opens
        if opts.connect:
            endpoint = opts.connect
        else:
            listen = listen_endpoints(opts.listen, opts.tls_cert, opts.tls_key)
            tls = (str(opts.tls_cert.absolute()), str(opts.tls_key.absolute())) \
                if opts.tls_cert is not None and opts.tls_key is not None else None
            if opts.in_process:  # one process by design: the router too
                try:
                    router = stack.enter_context(_closing(_open_router(run_id, creds, listen, tls)))
                except zenoh.ZError as exc:
                    raise RunError(f"cannot open the embedded Zenoh router: {str(exc).splitlines()[0]}") from None
                locators = router_locators(router)
            else:  # its own process: the launcher's Python work never holds up the fleet's routing
                router_child = stack.enter_context(router_process(run_id, creds, listen, tls, work))
                locators = router_child.endpoints
            # this machine's processes: the router's first endpoint, or with tls/ or quic/ its loopback tcp/ one
            endpoint = next(loc for loc in locators if tls is None or loc.startswith("tcp/"))
        login = creds or {}
        session = stack.enter_context(_closing(zenoh.open(client_config(endpoint, login.get(LAUNCHER)))))
        listener = stack.enter_context(_closing(zenoh.open(client_config(endpoint, login.get(RECORDER)))))
        samples: queue.Queue[tuple[str, bytes, int] | None] = queue.Queue()
        # everything when recording; else only what the fold reads (Keys.folded): at 256 robots the rest (obs,
        # the radio bundles with every first contact's whole maps, belief snapshots) was most of the bus
        drains = [Drain(listener, k, samples)
                  for k in ((keys.all,) if recorder is not None else keys.folded(radio=scenario.relay != "none"))]
        pub_ready = publisher(session, keys.ready("launcher"))
        pub_stop = publisher(session, keys.stop)
        handles: list[Declared] = [pub_ready, pub_stop,
                                   session.liveliness().declare_token(keys.alive("launcher", "launcher"))]
        remote = stack.enter_context(Hosts(session, scenario.hosts, opts.host_timeout)) if scenario.hosts else None
        consumer = Consumer(keys, samples, monitor, recorder, pub_ready, viz)
        consumer.start()
        nodes_thread: threading.Thread | None = None
        try:
            if requested.is_set():
                pass  # interrupted while starting: nothing more is started
            elif opts.in_process:
                nodes_thread = _start_in_process(scenario, map_data, run_id, endpoint, creds, opts.realtime_hz)
                pids = {"world": os.getpid(), "netem": os.getpid(), "agents": [os.getpid()] * len(robots)}
                pids |= {BASE: os.getpid()} if scenario.has_base else {}
            else:
                plan = spawn_nodes(sup, scenario, run_id, endpoint, work, creds, remote, requested,
                                   opts.realtime_hz)
                p = sup.pids()
                pids = {"world": p["world"], "netem": p["netem"], "agents": [p[r] for r in robots]}
                pids |= {BASE: p[BASE]} if BASE in p else {}
                pids |= ({"fork_server": p["fork_server"]} if "fork_server" in p else {}) | \
                    ({"router": router_child.proc.pid} if router_child is not None else {}) | \
                    ({"hosts": plan} if plan else {})
            if pids and opts.on_spawn is not None:
                opts.on_spawn(pids)  # e.g. benchmarks/scale.py samples their /proc while the run goes
            error = wait_for_end(monitor, consumer, sup, nodes_thread, opts.on_progress, requested,
                          lambda r: session.put(keys.failed(r), Failed(
                              src="launcher", tick=monitor.tick, seq=0, robot=r, reason="process exited").encode(),
                              congestion_control=zenoh.CongestionControl.BLOCK), router_child)
        except KeyboardInterrupt:
            requested.set()
        except HostsError as exc:  # too few hosts came: the run ends as an error, its files written
            error = str(exc)
        finally:
            interrupted = requested.is_set() and monitor.stop is None  # a signal after the stop is teardown's
            if monitor.stop is None or interrupted:
                with contextlib.suppress(zenoh.ZError):
                    pub_stop.put(Stop(src="launcher", tick=monitor.tick, seq=1,
                                      reason="interrupted" if interrupted else "aborted").encode())
            if not sup.wait_all(STOP_GRACE, hurry):
                sup.kill_all(grace=0.5 if hurry.is_set() else 2.0)
            sup.kill_all()
            if nodes_thread is not None:
                nodes_thread.join(STOP_GRACE)
            time.sleep(0.1)  # let the last samples reach the subscriber
            for drain in drains:
                drain.undeclare()
            samples.put(None)
            consumer.join()  # it may still answer a hello on pub_ready: undeclare that only after it ends
            undeclare(handles)
    if viz is not None:
        viz.finish()
    messages = recorder.close() if recorder else 0
    data = monitor.result(scenario.to_dict(), run_id, scenario.target_coverage)
    if opts.realtime_hz:
        data.setdefault("realtime_hz", opts.realtime_hz)  # also when stopped before tick 0
    if interrupted:
        data["reason"] = "interrupted"
        data.pop("error", None)
    elif error:
        data["reason"] = "error"
        data["error"] = error
    data |= {
        "engine": engine,
        "pids": pids,
        "recording": {"path": str(recording) if recording else None, "messages": messages},
        "wall_seconds": round(time.monotonic() - t_start, 3),
        "scenario": scenario.to_dict(),
        "signal": signals.name if signals else ("SIGINT" if interrupted else None),
        "authenticated": creds is not None,
    }
    failure = "interrupted" if interrupted else ("error" if error else None)
    return Result(data, tuple(monitor.coverage_curve), recording.parent if recording else None), failure


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
                 tls: tuple[str, str] | None = None) -> zenoh.Session:
    """The router embedded in this process (``--in-process``), set up as the router process's
    (:func:`~fleet_emu.launch.router_process.router_spec`); its users file lives in a private temporary
    directory only while it opens (Zenoh reads it then)."""
    with tempfile.TemporaryDirectory(prefix="fleet-auth-") as private:  # mode 0700
        return zenoh.open(router_config(**router_spec(Path(private), run_id, creds, listen, tls)))


def _start_in_process(scenario: Scenario, map_data: MapData, run_id: str, endpoint: str,
                      creds: dict[str, Credential] | None, realtime_hz: float | None = None) -> threading.Thread:
    """Every node in this process, each with its own Zenoh session (and its own login) to the same router."""
    from fleet_emu.agents.node import AgentNode
    from fleet_emu.netem.node import NetemNode
    from fleet_emu.world.node import WorldNode

    nodes = [WorldNode(scenario, run_id, map_data, realtime_hz=realtime_hz),
             NetemNode(scenario, run_id, map_data, realtime_hz=realtime_hz)]
    nodes += [AgentNode(scenario, run_id, r, realtime_hz=realtime_hz) for r in robot_ids(scenario.robots)]
    if scenario.has_base:
        from fleet_emu.agents.base_node import BaseNode

        nodes.append(BaseNode(scenario, run_id, map_data))

    async def main() -> None:
        with contextlib.ExitStack() as stack:
            sessions = [stack.enter_context(zenoh.open(client_config(endpoint, creds[n.node_id] if creds else None)))
                        for n in nodes]
            await asyncio.gather(*(n.run(s) for n, s in zip(nodes, sessions, strict=True)))

    thread = threading.Thread(target=lambda: asyncio.run(main()), daemon=True, name="nodes")
    thread.start()
    return thread


