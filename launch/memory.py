"""The in-memory engine: the same :class:`World`, :class:`Channel` and :class:`Brain` objects the node processes
run, stepped directly in lockstep, with no Zenoh, no threads and no clock (docs/design/determinism.md).

:class:`Fleet` follows PettingZoo's ``ParallelEnv`` (``reset(seed)`` gives the observations, ``step()`` one
tick): each tick it does what the three node shells do, in their order (``world/node.py``, ``netem/node.py``,
``agents/node.py``): the world's observations and state of tick t, netem's links (counters before tick t's
sends) and rx bundles of t, every live robot's brain (tx bundle, command, belief snapshot: the same draws
from each robot's one sequence counter), netem's sends of t, the world's moves; a base station (a scenario
with ``base``) is a :class:`~fleet_emu.agents.base.BaseStation` stepped with its rx bundle of t, as
``agents/base_node.py`` does, and reports after the stop. The launcher's own fold
(:class:`~fleet_emu.recording.monitor.Monitor`) gets the same messages the bus would carry, so
``result.json`` has the same deterministic keys as a run over Zenoh for the same seed.
"""

from __future__ import annotations

import contextlib
import functools
import os
import resource
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.allocators.mhm.station import station_planner
from fleet_emu.agents.base import BaseStation
from fleet_emu.agents.brain import Brain, Percept, allocator_config, brain_config, radio_team
from fleet_emu.agents.outputs import base_report, base_tx, first_cpu_ms, robot_outputs, robot_report
from fleet_emu.core.errors import RunError
from fleet_emu.core.grid import Cell, MapData
from fleet_emu.core.keys import BASE, Keys, robot_ids
from fleet_emu.core.malloc_tuning import collecting_less
from fleet_emu.core.messages import Envelope, Message, Observation, WorldState, ready
from fleet_emu.core.pace import Pacer
from fleet_emu.core.rng import generator
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.live import LiveOptions, open_live
from fleet_emu.launch.signals import Interrupts, signal_name
from fleet_emu.netem.channel import make_channel, radio_tick
from fleet_emu.recording.clock import RunClock
from fleet_emu.recording.monitor import Monitor
from fleet_emu.recording.result import Ending, Launcher, Result, build_result
from fleet_emu.world.build import base_cell, build_world
from fleet_emu.world.maps import BUILTIN_MAPS, load_map
from fleet_emu.world.messages import hello, stop, tick_messages
from fleet_emu.world.sim import Reading, StartAreaError

#: Called with (key expression, message, wall-clock ns) for every message the bus would carry (a recorder).
Tap = Callable[[str, Message, int], None]


@functools.lru_cache(maxsize=8)
def _cached_map(name: str, cell_size: float, seed: int | None, cell_size_given: bool) -> MapData:
    return load_map(name, cell_size, seed or 0, cell_size_given=cell_size_given)


def fleet_map(scenario: Scenario) -> MapData:
    """The scenario's true map; a map file is read once per process (its seed plays no part), a built-in
    map is generated per seed."""
    seed = scenario.seed if scenario.map in BUILTIN_MAPS else None
    return _cached_map(scenario.map, scenario.cell_size, seed, scenario.cell_size_given)


class Fleet:
    """A whole fleet in memory, after PettingZoo's ``ParallelEnv``: ``reset(seed)`` then ``step()`` until
    ``done``; :meth:`result` is ``result.json``.

    ``agents`` are the live robots, ``possible_agents`` all of them. Observations are the world's
    :class:`Observation` messages of the tick; the reward of a tick is the coverage it added (shared by the
    team). ``step(actions)`` takes optional moves (``{robot: (drow, dcol)}``) that replace the brains' for
    those robots; every brain still runs and sends its radio messages. ``tap`` sees every message the bus
    would carry (``fleet run --engine memory`` records them).

    ``map_data`` replaces the scenario's map (a map drawn in a test: ``core.grid.from_ascii``), and ``starts``
    places the robots on given cells (``{robot: cell}`` for every robot, or one cell per robot in robot order)
    instead of around the start cell; the start cell is then the first robot's. Neither is in the scenario,
    so ``result.json``'s scenario alone does not reproduce such a fleet.
    """

    metadata: dict[str, Any] = {"name": "fleet_emu_memory_v0", "is_parallelizable": True}

    def __init__(self, scenario: Scenario, *, run_id: str = "memory", tap: Tap | None = None,
                 map_data: MapData | None = None, starts: Mapping[str, Cell] | Sequence[Cell] | None = None) -> None:
        from fleet_emu.launch.checks import pinned

        scenario = pinned(scenario)  # a policy file read once: every robot's allocator verifies its sha256
        scenario.validate()
        make_allocator(allocator_config(scenario))  # a ConfigError now, not at the first reset
        self.scenario = scenario
        self.run_id = run_id
        self.keys = Keys(run_id)
        self.tap = tap
        self.possible_agents: list[str] = robot_ids(scenario.robots)
        self._map_data = map_data
        self._starts = _placement(starts, self.possible_agents)
        self.agents: list[str] = []
        self.monitor = Monitor(tuple(self.possible_agents), base=scenario.has_base, relay=scenario.relay != "none")
        self._started: float | None = None

    # --- the ParallelEnv API ------------------------------------------------------------------------------

    def reset(self, seed: int | None = None, options: Mapping[str, Any] | None = None
              ) -> tuple[dict[str, Observation], dict[str, dict[str, Any]]]:
        """Start a run (the scenario's seed, or ``seed``); the observations of tick 0 and an info per robot."""
        if seed is not None:
            self.scenario = self.scenario.override(seed=seed)
        s = self.scenario
        self.map = self._map_data if self._map_data is not None else fleet_map(s)
        self.world = build_world(s, self.map, self._starts)
        self.occupied = self.map.grid > 0
        self.channel = make_channel(s.seed, s.radio, s.tick_s, self.map.grid.shape, s.cell_size)
        self.dropped = dict.fromkeys(self.possible_agents, 0)
        self.base: BaseStation | None = None
        self._base_dropped = 0
        team = radio_team(s)  # one set for every brain: a broadcast's decoded payload, kept on its envelope with
        # the context it was checked against, is then matched to the next receiver's by identity, not compared
        self.brains = {r: Brain(r, make_allocator(allocator_config(s)), generator(s.seed, r), brain_config(s),
                                team=team, on_drop=self._on_drop(r), shared_inbox=True)
                       for r in self.possible_agents}
        self.monitor = Monitor(tuple(self.possible_agents), base=s.has_base, relay=s.relay != "none")
        self._world_seq = self._netem_seq = 0
        self._first_cpu: dict[str, dict[str, float]] = {}  # each robot's first step's CPU (RobotReport)
        self._percepts: dict[str, Percept] = {}  # perceive()'s, for the next step to act on
        self._started = time.perf_counter()
        self.done = False
        self.reason: str | None = None
        readings = self.world.reset()
        cell = base_cell(s, self.map, self.world)  # after the reset: a random start is drawn there
        if cell is not None:
            self.base = BaseStation(cell, self.map.grid.shape, frozenset(self.possible_agents),
                                    planner=station_planner(s), on_drop=self._on_base_drop)
        self._base_tx: tuple[Envelope, ...] | None = None  # the base's tx bundle of the tick, when it sends
        self._handshake()
        self._publish(readings)
        return dict(self.obs), {r: {} for r in self.agents}

    def step(self, actions: Mapping[str, Cell] | None = None
             ) -> tuple[dict[str, Observation], dict[str, float], dict[str, bool], dict[str, bool], dict[str, Any]]:
        """One tick: every live robot decides, netem sends, the world moves; PettingZoo's five dicts."""
        if self.done:
            raise RunError("step() after the run ended: call reset()")
        w = self.world
        t, live, before = w.tick, tuple(self.agents), w.coverage
        bundles: dict[str, tuple[Envelope, ...]] = {}
        moves: dict[str, Cell] = {}
        known: dict[str, int] = {}
        for r in live:
            brain = self.brains[r]
            try:
                p = self._percepts.pop(r, None)
                cmd, out = brain.act(p) if p is not None else brain.step(self.obs[r], self.rx.get(r, ()))
            except Exception as exc:
                raise RunError(f"robot {r} failed at tick {t}: {type(exc).__name__}: {exc}") from exc
            bundles[r] = out
            tx, belief = robot_outputs(brain, t, out, self.scenario.belief_every)
            if r not in self._first_cpu:  # one process for every robot: no process or event-loop CPU of its own
                self._first_cpu[r] = first_cpu_ms(brain, 0.0, 0.0)
            self._emit(self.keys.tx(r), tx)
            self._emit(self.keys.cmd(r), cmd)
            if belief is not None and self.tap is not None:  # for the recording only, as the node's
                self._emit(self.keys.belief(r), belief)
            moves[r], known[r] = cmd.move, cmd.known
        if actions:
            moves |= {r: tuple(m) for r, m in actions.items() if r in moves}  # type: ignore[misc]
        if self._base_tx is not None:  # a planning base's orders (agents/base_node.py), sent after the robots'
            bundles[BASE] = self._base_tx
        self.channel.transmit(t, self.nodes, self.link, bundles)
        self._publish(w.step(moves, known))
        gain = w.coverage - before
        rewards = dict.fromkeys(live, gain)
        terminations: dict[str, bool] = {r: self.done and self.reason == "coverage" for r in live}
        truncations: dict[str, bool] = {r: self.reason != "coverage" if self.done else r not in self.agents
                                        for r in live}  # a robot that failed (a crash fault) leaves here
        infos = {r: {"tick": w.tick, "coverage": w.coverage} for r in live}
        return dict(self.obs), rewards, terminations, truncations, infos

    def perceive(self) -> dict[str, Percept]:
        """The first half of every live robot's step of this tick (:meth:`Brain.perceive`: belief, teammates,
        frontiers, the allocator's problem), kept for the next :meth:`step`, which acts on them: a learned policy
        (``fleet_emu.rl``) chooses in between, and the run is the one ``step`` alone would make."""
        if self.done:
            raise RunError("perceive() after the run ended: call reset()")
        for r in self.agents:
            if r not in self._percepts:
                try:
                    self._percepts[r] = self.brains[r].perceive(self.obs[r], self.rx.get(r, ()))
                except Exception as exc:
                    raise RunError(f"robot {r} failed at tick {self.world.tick}: {type(exc).__name__}: {exc}"
                                   ) from exc
        return dict(self._percepts)

    def close(self) -> None:
        """Nothing to release (kept for the ParallelEnv API)."""

    # --- whole runs ---------------------------------------------------------------------------------------

    def run(self, seed: int | None = None, on_tick: Callable[[Monitor], None] | None = None) -> Result:
        """Reset and step to the end; the run's :class:`Result` (``result.json`` and the coverage curve)."""
        self._play(seed, on_tick)
        return self.result()

    def _play(self, seed: int | None = None, on_tick: Callable[[Monitor], None] | None = None) -> None:
        """Reset and step to the end, ``on_tick`` told after every tick (the collector run less often meanwhile,
        as in a node process: ``core/malloc_tuning.py``)."""
        with collecting_less():
            self.reset(seed)
            while not self.done:
                self.step()
                if on_tick is not None:
                    on_tick(self.monitor)

    def result(self, ending: Ending | None = None, recording: Path | None = None, messages: int = 0,
               signal: str | None = None) -> Result:
        """``result.json`` of the run so far (the launcher's fold, as over Zenoh; ``pids`` are this process; no
        bus, so nothing authenticated), ended as ``ending`` says (by itself when None), with its ``recording``
        and the ``signal`` that ended it (:func:`~fleet_emu.recording.result.build_result`)."""
        s = self.scenario
        elapsed = time.perf_counter() - (self._started or time.perf_counter())
        pid = os.getpid()
        pids = {"world": pid, "netem": pid, "robots": [pid] * s.robots} | ({BASE: pid} if s.has_base else {})
        data = build_result(self.monitor, s.to_dict(), self.run_id, ending or Ending(), engine="memory", pids=pids,
                            recording=str(recording) if recording else None, messages=messages,
                            launcher=Launcher(elapsed, signal, None))
        return Result(data, tuple(self.monitor.coverage_curve))

    # --- the node shells' work, without the bus -----------------------------------------------------------

    def _on_drop(self, robot: str) -> Callable[[str, str], None]:
        def drop(_key: str, _why: str) -> None:
            self.dropped[robot] += 1
        return drop

    def _emit(self, key: str, msg: Message) -> None:
        """What a node would publish: the launcher's fold (and the tap) get it."""
        now = time.time_ns()
        self.monitor.fold(msg)
        if isinstance(msg, WorldState):  # the fold's speed measure, as the launcher times the states
            self.monitor.first_state_ns = self.monitor.first_state_ns or now
            self.monitor.last_state_ns = now
        if self.tap is not None:
            self.tap(key, msg, now)

    def _wseq(self) -> int:
        self._world_seq += 1
        return self._world_seq

    def _nseq(self) -> int:
        self._netem_seq += 1
        return self._netem_seq

    def _handshake(self) -> None:
        """The start handshake as the processes engine records it: the world's hello, then every node's ready
        (the launcher, netem, the base station, each robot), once each: nothing here can miss one."""
        self._emit(self.keys.hello, hello())
        pid = os.getpid()
        nodes = [("launcher", "launcher"), ("netem", "netem"), *([(BASE, BASE)] if self.scenario.has_base else []),
                 *((r, "agent") for r in self.possible_agents)]  # (id, role) as the node shells declare them
        for node, role in nodes:
            self._emit(self.keys.ready(node), ready(node, role, pid))

    def _publish(self, readings: dict[str, Reading]) -> None:
        """World then netem for the current tick (``WorldNode._publish``, ``NetemNode._publish_tick``), and
        the base station's step on its rx bundle (``BaseStationNode``)."""
        w, s = self.world, self.scenario
        self.obs, state = tick_messages(w, readings, s.cell_size, self._wseq, 0)  # no bus: nothing malformed
        for r, o in self.obs.items():
            self._emit(self.keys.obs(r), o)
        self._emit(self.keys.state, state)
        base = self.base.cell if self.base is not None else None
        radio = radio_tick(self.channel, self.occupied, self.possible_agents, base, s.cell_size, s.radio, state,
                           self._nseq, 0)
        self.nodes, self.link = radio.nodes, radio.link
        self._emit(self.keys.links, radio.links)
        self.agents = [r for r in radio.nodes if r != BASE]
        if w.done:
            self._finish()
            return
        self.rx = {b.dst: b.msgs for b in radio.rx}
        for b in radio.rx:
            self._emit(self.keys.rx(b.dst), b)
        if self.base is not None:  # the base process, driven by its rx bundle (agents/base_node.py)
            out = self.base.step(w.tick, self.rx[BASE])
            if self.scenario.plans_at_base:
                self._base_tx = out
                self._emit(self.keys.tx(BASE), base_tx(self.base, w.tick, out))

    def _on_base_drop(self, _key: str, _why: str) -> None:
        self._base_dropped += 1

    def _finish(self) -> None:
        """The world's stop, every live robot's report (``RobotNode.run`` after its lockstep) and the base's
        (``BaseStationNode.run``)."""
        w = self.world
        end = stop(w, self._wseq())
        self.done, self.reason = True, end.reason
        self._emit(self.keys.stop, end)
        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        if self.base is not None:
            self._emit(self.keys.report(BASE), base_report(self.base, w.tick, self._base_dropped, rss))
        for r in w.live:
            self._emit(self.keys.report(r), robot_report(self.brains[r], w.tick, self.dropped[r], rss,
                                                         first=self._first_cpu.get(r)))
        self.agents = []


def _placement(starts: Mapping[str, Cell] | Sequence[Cell] | None, robots: list[str]) -> tuple[Cell, ...] | None:
    """Explicit start cells in robot order (the world checks that they are free and distinct)."""
    if starts is None:
        return None
    if isinstance(starts, Mapping):
        if set(starts) != set(robots):
            raise StartAreaError(f"starts must give a cell for each of the robots {', '.join(robots)} "
                                 f"(got {', '.join(sorted(starts)) or 'none'})")
        starts = [starts[r] for r in robots]
    cells = tuple((int(c[0]), int(c[1])) for c in starts)
    if len(cells) != len(robots):
        raise StartAreaError(f"{len(cells)} start cells given for {len(robots)} robots")
    return cells


def seed_test(scenario: Scenario, seed: int = 0, ticks: int = 60) -> None:
    """PettingZoo's ``seed_test`` for :class:`Fleet`: two fleets reset with the same seed give the same
    observations, rewards and ends, tick by tick, and a fleet reset again with that seed replays its run.
    Raises AssertionError naming the first difference."""
    a, b = Fleet(scenario), Fleet(scenario)
    first = _trace(a, seed, ticks)
    assert first == _trace(b, seed, ticks), "two fleets reset with the same seed differ"
    assert first == _trace(a, seed, ticks), "a fleet reset again with the same seed differs"


def _trace(fleet: Fleet, seed: int, ticks: int) -> list[Any]:
    obs, _ = fleet.reset(seed)
    out: list[Any] = [_digest(obs)]
    for _ in range(ticks):
        if fleet.done:
            break
        obs, rew, term, trunc, _info = fleet.step()
        out.append((_digest(obs), rew, term, trunc, dict(fleet.world.poses)))
    return out


def _digest(obs: Mapping[str, Observation]) -> list[Any]:
    return [(r, o.tick, o.cell, o.cells.tobytes(), o.values.tobytes()) for r, o in sorted(obs.items())]


def run_memory(scenario: Scenario, out_dir: Path | None = None, *, record: bool = True, run_id: str = "",
               grid_every: int | None = None, on_progress: Callable[[Monitor], None] | None = None,
               interrupts: Interrupts | None = None, overwrite: bool = False,
               live: LiveOptions | None = None) -> Result:
    """``fleet run --engine memory``: one run in this process, writing what ``run_fleet`` writes under
    ``out_dir`` (``result.json``, ``scenario.json``, ``map.npz``, and with ``record`` a ``run.mcap`` that
    ``fleet report`` reads). Bad input raises ConfigError before anything is written. With ``interrupts``
    (the CLI's signal state) a signal ends the run after the current tick, as ``run_fleet`` does; without,
    Ctrl-C re-raises KeyboardInterrupt once the files are written. ``out_dir`` is guarded as ``run_fleet``'s
    (:mod:`~fleet_emu.launch.outdir`: locked, refused when it holds a run unless ``overwrite``); a write that
    fails ends the run with :class:`~fleet_emu.launch.outdir.DiskFault`. ``live`` serves the run to Foxglove
    (``fleet run --live``). The recording's clock counts the scenario's ``tick_s`` seconds per tick."""
    from fleet_emu.launch.checks import check, check_machine, new_run_id, pinned
    from fleet_emu.launch.outdir import claimed

    scenario = pinned(scenario)
    map_data = check(scenario)
    check_machine(scenario, map_data, "memory")
    run_id = run_id or new_run_id()
    with claimed(out_dir, overwrite):  # to the last write: no other run writes here
        try:
            result, interrupted = _run_and_write(scenario, map_data, out_dir, record, run_id, grid_every,
                                                 on_progress, interrupts, live)
        except OSError as exc:  # a full disk before the run or at its end
            from fleet_emu.launch.outdir import disk_fault

            raise disk_fault(out_dir or Path("."), exc) from None
    if interrupted and interrupts is None:
        raise KeyboardInterrupt
    return result


def _run_and_write(scenario: Scenario, map_data: MapData, out_dir: Path | None, record: bool, run_id: str,
                   grid_every: int | None, on_progress: Callable[[Monitor], None] | None,
                   interrupts: Interrupts | None, live: LiveOptions | None) -> tuple[Result, bool]:
    """The run and its files (in ``out_dir``, already claimed); the result and whether a signal ended it. A
    recording that fails ends the run: its ``result.json`` is written if it can be, and DiskFault raised."""
    from fleet_emu.launch.outdir import DiskFault, disk_fault, write_atomic, write_json

    with contextlib.ExitStack() as stack:
        recording = out_dir / "run.mcap" if record and out_dir is not None else None
        clock = RunClock.now(scenario.tick_s)
        server = open_live(stack, live, clock, robot_ids(scenario.robots))
        pacer = Pacer(live.hz if live is not None else None, server.first_tick if server is not None else 0.0)
        tap, finish = _recording_tap(stack, scenario, map_data, run_id, recording, grid_every, clock, server)
        fleet = Fleet(scenario, run_id=run_id, tap=tap)
        if out_dir is not None:
            write_json(out_dir / "scenario.json", scenario.to_dict())
            write_atomic(out_dir / "map.npz", map_data.save)
        interrupted, fault = False, None

        def tick(monitor: Monitor) -> None:
            pacer.wait()
            if on_progress is not None:
                on_progress(monitor)
            if interrupts is not None and interrupts.requested.is_set():
                raise KeyboardInterrupt

        try:
            if interrupts is not None and interrupts.requested.is_set():
                raise KeyboardInterrupt  # a signal before the first tick
            pacer.wait()  # a live run: the viewers' moment to subscribe before tick 0 (launch/live.py)
            fleet._play(on_tick=tick)
        except KeyboardInterrupt:  # result.json of what ran, as the processes engine writes it
            interrupted = True
        except OSError as exc:  # the recording failed (a full disk): the run ends here
            fault = str(disk_fault(out_dir or Path("."), exc, "run.mcap"))
        finally:
            messages = finish()
        result = fleet.result(Ending(interrupted=interrupted, error=fault), recording, messages,
                              signal_name(interrupts, interrupted))
        if out_dir is not None:
            try:
                write_json(out_dir / "result.json", result.data)
            except OSError:
                if fault is None:
                    raise
        if fault is not None:
            raise DiskFault(fault)
    return Result(result.data, result.curve, out_dir), interrupted


def _recording_tap(stack: contextlib.ExitStack, scenario: Scenario, map_data: MapData, run_id: str,
                   recording: Path | None, grid_every: int | None, clock: RunClock, live: Any = None
                   ) -> tuple[Tap | None, Callable[[], int]]:
    """A tap that encodes every message into ``run.mcap`` (with the Foxglove channels) and serves those
    channels to ``live`` viewers, and its closer."""
    if recording is None and live is None:
        return None, lambda: 0
    from fleet_emu.recording.foxglove import FoxgloveFold
    from fleet_emu.recording.foxglove_writer import FoxgloveWriter
    from fleet_emu.recording.recorder import Recorder

    recorder = Recorder(recording, {"run_id": run_id, "scenario": scenario.to_dict(), "engine": "memory"},
                        clock) if recording is not None else None
    fold = FoxgloveFold(scenario.to_dict(), map_data.grid, grid_every, run_id, base_cell(scenario, map_data), clock)
    viz = FoxgloveWriter(recorder, fold, Keys(run_id), live)
    closed: list[int] = []

    def tap(key: str, msg: Message, wall_ns: int) -> None:
        data = msg.encode() if recorder is not None else b""
        if recorder is not None:
            recorder.record(key, data, wall_ns)
        viz.feed(key, data, wall_ns, msg)
        if recorder is not None and recorder.failed is not None:  # a full disk: the run ends (run_memory says why)
            raise recorder.failed

    def finish() -> int:
        if not closed:
            viz.finish()
            closed.append(recorder.close() if recorder is not None else 0)
        return closed[0]

    stack.callback(finish)
    return tap, finish
