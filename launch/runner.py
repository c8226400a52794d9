"""One run of the fleet: embedded router, recorder and monitor, the nodes (as processes or in-process), the
progress display, and ``result.json`` — written on every exit path, Ctrl-C included."""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import json
import os
import queue
import secrets
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import zenoh

from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.brain import allocator_config
from fleet_emu.core.bus import client_config, publisher, router_config, router_locators
from fleet_emu.core.errors import ConfigError, RunError
from fleet_emu.core.keys import Keys, robot_ids
from fleet_emu.core.messages import Failed, Ready, Stop
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.progress import Progress
from fleet_emu.launch.supervisor import Supervisor
from fleet_emu.recording.foxglove import FoxgloveFold, FoxgloveWriter
from fleet_emu.recording.monitor import Monitor
from fleet_emu.recording.recorder import Recorder
from fleet_emu.world.maps import MapData, load_map
from fleet_emu.world.node import build_world

STOP_GRACE = 5.0


@dataclasses.dataclass(frozen=True)
class RunOptions:
    out_dir: Path
    in_process: bool = False
    record: bool = True
    connect: str | None = None
    quiet: bool = False
    run_id: str = ""
    grid_every: int | None = None  # Foxglove grids every k ticks (default: the scenario's belief_every)


def new_run_id() -> str:
    return time.strftime("%Y%m%d-%H%M%S") + "-" + secrets.token_hex(2)


def check(scenario: Scenario) -> MapData:
    """Everything that can be wrong with the user's input, found before any process starts."""
    scenario.validate()
    try:
        make_allocator(allocator_config(scenario))  # exactly what every agent will build
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    md = load_map(scenario.map, scenario.cell_size, scenario.seed)
    build_world(scenario, md).reset()  # raises StartAreaError when the robots do not fit
    return md


def run_fleet(scenario: Scenario, opts: RunOptions) -> dict[str, Any]:
    """Run one scenario to its end; returns the result (also written to ``out_dir/result.json``)."""
    map_data = check(scenario)
    run_id = opts.run_id or new_run_id()
    out = opts.out_dir
    out.mkdir(parents=True, exist_ok=True)
    scenario_path = out / "scenario.json"
    scenario_path.write_text(json.dumps(scenario.to_dict(), indent=2))
    keys = Keys(run_id)
    robots = tuple(robot_ids(scenario.robots))
    monitor = Monitor(robots)
    mcap_path = out / "run.mcap"
    recorder = Recorder(mcap_path, {"run_id": run_id, "scenario": scenario.to_dict()}) if opts.record else None
    viz = FoxgloveWriter(recorder, FoxgloveFold(scenario.to_dict(), map_data.grid, opts.grid_every, run_id)) \
        if recorder else None
    sup = Supervisor(log_dir=out)
    pids: dict[str, Any] = {}
    t_start = time.monotonic()
    interrupted = False
    error: str | None = None
    with contextlib.ExitStack() as stack:
        if opts.connect:
            endpoint = opts.connect
        else:
            router = stack.enter_context(zenoh.open(router_config()))
            endpoint = router_locators(router)[0]
        session = stack.enter_context(zenoh.open(client_config(endpoint)))
        samples: queue.Queue[tuple[str, bytes, int] | None] = queue.Queue()
        sub = session.declare_subscriber(
            keys.all, lambda s: samples.put((str(s.key_expr), s.payload.to_bytes(), time.time_ns())))
        pub_ready = publisher(session, keys.ready("launcher"))
        pub_stop = publisher(session, keys.stop)
        token = session.liveliness().declare_token(keys.alive("launcher", "launcher"))
        consumer = _Consumer(samples, monitor, recorder, pub_ready, robots, viz)
        consumer.start()
        nodes_thread: threading.Thread | None = None
        progress = Progress(scenario, run_id, quiet=opts.quiet)
        try:
            if opts.in_process:
                nodes_thread = _start_in_process(scenario, run_id, endpoint)
                pids = {"world": os.getpid(), "netem": os.getpid(), "agents": [os.getpid()] * len(robots)}
            else:
                common = ["--run", run_id, "--connect", endpoint, "--scenario", str(scenario_path)]
                sup.spawn("world", "fleet_emu.world", common)
                sup.spawn("netem", "fleet_emu.netem", common)
                for r in robots:
                    sup.spawn(r, "fleet_emu.agents", ["--robot", r, *common])
                p = sup.pids()
                pids = {"world": p["world"], "netem": p["netem"], "agents": [p[r] for r in robots]}
            with progress:
                error = _wait(monitor, consumer, sup, nodes_thread, progress,
                              lambda r: session.put(keys.failed(r), Failed(
                                  src="launcher", tick=monitor.tick, seq=0, robot=r, reason="process exited").encode(),
                                  congestion_control=zenoh.CongestionControl.BLOCK))
        except KeyboardInterrupt:
            interrupted = True
        finally:
            if monitor.stop is None or interrupted:
                with contextlib.suppress(Exception):
                    pub_stop.put(Stop(src="launcher", tick=monitor.tick, seq=1,
                                      reason="interrupted" if interrupted else "aborted").encode())
            if not sup.wait_all(STOP_GRACE):
                sup.kill_all()
            sup.kill_all()
            if nodes_thread is not None:
                nodes_thread.join(STOP_GRACE)
            time.sleep(0.1)  # let the last samples reach the subscriber
            sub.undeclare()
            samples.put(None)
            consumer.join()
            del token
    if viz is not None:
        viz.finish()
    messages = recorder.close() if recorder else 0
    result = monitor.result(scenario.to_dict(), run_id, scenario.target_coverage)
    if interrupted:
        result["reason"] = "interrupted"
    elif error:
        result["reason"] = "error"
        result["error"] = error
    wall = time.monotonic() - t_start
    result |= {
        "pids": pids,
        "recording": {"path": str(mcap_path) if recorder else None, "messages": messages},
        "wall_seconds": round(wall, 3),
        "scenario": scenario.to_dict(),
    }
    (out / "result.json").write_text(json.dumps(result, indent=2))
    if interrupted:
        raise KeyboardInterrupt
    if error:
        raise RunError(error)
    return result


def _wait(monitor: Monitor, consumer: _Consumer, sup: Supervisor, nodes_thread: threading.Thread | None,
          progress: Progress, notify_failed: Callable[[str], None]) -> str | None:
    """Until the world's stop and every live agent's report; returns an error line, or None.
    An agent process that exits early is announced to the world, which goes on without it."""
    stop_seen: float | None = None
    announced: set[str] = set()
    while True:
        progress.update(monitor)
        if monitor.stop is not None:
            stop_seen = stop_seen or time.monotonic()
            live = set(monitor.state.live) if monitor.state else set()
            if live <= set(monitor.reports) or time.monotonic() - stop_seen > STOP_GRACE:
                return None if monitor.stop.reason != "startup" else "startup timed out: see the logs in --out"
        dead = sup.dead()
        new = set(dead) - announced - {"world", "netem"}
        announced |= new
        if monitor.stop is None:  # repeated until the first tick: the world may not be listening yet
            for name in sorted(announced if monitor.state is None else new):
                notify_failed(name)
        if "world" in dead and monitor.stop is None:
            return f"the world process exited with code {dead['world']} (see world.log in --out)"
        if "netem" in dead and monitor.stop is None:
            return f"the netem process exited with code {dead['netem']} (see netem.log in --out)"
        if nodes_thread is not None and not nodes_thread.is_alive() and monitor.stop is None:
            return "the in-process nodes ended before the run did"
        consumer.changed.wait(0.2)
        consumer.changed.clear()


class _Consumer(threading.Thread):
    """Takes samples off the subscriber's queue: records them, folds them, and answers the world's hello."""

    def __init__(self, samples: queue.Queue, monitor: Monitor, recorder: Recorder | None,
                 pub_ready: zenoh.Publisher, robots: tuple[str, ...], viz: FoxgloveWriter | None = None) -> None:
        super().__init__(daemon=True, name="recorder")
        self.samples = samples
        self.monitor = monitor
        self.recorder = recorder
        self.viz = viz
        self.pub_ready = pub_ready
        self.changed = threading.Event()
        self._seq = 0

    def run(self) -> None:
        while (item := self.samples.get()) is not None:
            key, data, wall_ns = item
            if self.recorder is not None:
                self.recorder.record(key, data, wall_ns)
            if key.endswith("/ctl/hello"):
                self._seq += 1
                self.pub_ready.put(Ready(src="launcher", tick=0, seq=self._seq, role="launcher",
                                         pid=os.getpid()).encode())
                continue
            msg = self.monitor.feed(key, data, wall_ns)
            if self.viz is not None:
                self.viz.feed(key, data, msg)
            if msg is not None:
                self.changed.set()


def _start_in_process(scenario: Scenario, run_id: str, endpoint: str) -> threading.Thread:
    """Every node in this process, each with its own Zenoh session to the same router."""
    from fleet_emu.agents.node import AgentNode
    from fleet_emu.netem.node import NetemNode
    from fleet_emu.world.node import WorldNode

    nodes = [WorldNode(scenario, run_id), NetemNode(scenario, run_id)]
    nodes += [AgentNode(scenario, run_id, r) for r in robot_ids(scenario.robots)]

    async def main() -> None:
        with contextlib.ExitStack() as stack:
            sessions = [stack.enter_context(zenoh.open(client_config(endpoint))) for _ in nodes]
            await asyncio.gather(*(n.run(s) for n, s in zip(nodes, sessions, strict=True)))

    thread = threading.Thread(target=lambda: asyncio.run(main()), daemon=True, name="nodes")
    thread.start()
    return thread


