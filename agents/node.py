"""The robot process's shell (the ``agents/`` package holds the robot process): one robot. Waits for its
observation and rx bundle of each tick, runs the brain, publishes its tx bundle and command. Only this module
touches Zenoh and the clock.

In real-time mode (``realtime_hz``) it waits for nothing: decisions run in a worker thread and, while one runs,
the shell steps along the last plan every tick (:mod:`agents.realtime`); at the end it publishes its
:class:`RobotTiming` (robot/<robot>/timing) before its report."""

from __future__ import annotations

import asyncio
import contextlib
import resource
import threading
import time
from collections.abc import Callable
from typing import Any, cast

import msgspec
import zenoh

from fleet_emu.agents.allocators import make_allocator
from fleet_emu.agents.brain import Brain, allocator_config, brain_config, radio_team
from fleet_emu.agents.outputs import first_cpu_ms, robot_outputs, robot_report
from fleet_emu.agents.realtime import Timing, percentiles
from fleet_emu.core.bus import Inbox
from fleet_emu.core.codec import Context
from fleet_emu.core.faults import crashes
from fleet_emu.core.kernels import warm_up
from fleet_emu.core.keys import Keys
from fleet_emu.core.messages import Command, Envelope, Observation, RobotTiming, RxBundle, Stop
from fleet_emu.core.node import Declared, NodeShell, node_main, undeclare
from fleet_emu.core.rng import generator
from fleet_emu.core.scenario import Scenario


class RobotNode(NodeShell):
    """One robot's node: its brain between the barrier messages and its radio bundles."""

    role = "agent"  # the liveliness role on the bus (``fleet/<run>/alive/agent/<robot>``), part of the protocol

    def __init__(self, scenario: Scenario, run: str, robot: str, realtime_hz: float | None = None) -> None:
        super().__init__(Keys(run), robot)
        warm_up()  # compile (or load) the kernels before the first tick, not inside it
        self.scenario = scenario
        self.robot = robot
        allocator = make_allocator(allocator_config(scenario))
        self.brain = Brain(robot, allocator, generator(scenario.seed, robot), brain_config(scenario),
                           team=radio_team(scenario), on_drop=self.drop)
        self.ctx_world = Context(senders=frozenset({"world"}))
        self.realtime = bool(realtime_hz)
        self.timing = Timing()
        self.cpu0: float | None = None  # the process's CPU time when its first step began (RobotReport)
        self.loop_cpu0 = 0.0  # the event loop thread's CPU time then
        self.first_cpu_ms: dict[str, float] = {}  # the first step's CPU (RobotReport.first_cpu_ms)
        self.crash_at = dict(crashes(scenario.faults)).get(robot)  # the tick the scenario crashes it at, if any

    def next_seq(self) -> int:
        """The robot's one counter, shared with its brain."""
        return self.brain.next_seq()

    async def run(self, session: zenoh.Session) -> None:
        keys = self.keys
        inbox = self.inbox()
        handles: list[Declared] = [
            inbox.subscribe(session, keys.obs(self.robot)),
            inbox.subscribe(session, keys.rx(self.robot)),
            inbox.subscribe(session, keys.stop),
        ]
        self.pub_cmd = self.publisher(session, keys.cmd(self.robot))
        self.pub_tx = self.publisher(session, keys.tx(self.robot))
        pub_report = self.publisher(session, keys.report(self.robot))
        self.pub_belief = self.publisher(session, keys.belief(self.robot)) if self.scenario.belief_every else None
        handles += [self.pub_cmd, self.pub_tx, pub_report, *([self.pub_belief] if self.pub_belief else [])]
        pub_timing = self.publisher(session, keys.timing(self.robot)) if self.realtime else None
        handles += [*([pub_timing] if pub_timing else []), *self.declare_presence(session, inbox)]
        try:
            tick = await (self._realtime(inbox) if self.realtime else self._lockstep(inbox))
            if self.crash_at is not None and tick >= self.crash_at:  # crashed ([[faults]]): as a process killed
                return  # then (the launcher's, unless it runs in the launcher's process), it says nothing more
            if pub_timing is not None:
                tm = self.timing
                pub_timing.put(RobotTiming(
                    src=self.robot, tick=tick, seq=self.next_seq(), decisions=tm.decisions,
                    plan_steps=tm.plan_steps, waits=tm.waits, decision_ms=percentiles(tm.decision_ms),
                    allocator_ms=percentiles(self.brain.decision_ms[:tm.decisions])).encode())
            process_ms, loop_ms = self._clocks_ms()
            report = robot_report(
                self.brain, tick, self.dropped, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
                process_cpu_ms=process_ms, loop_cpu_ms=loop_ms, first=self.first_cpu_ms)
            pub_report.put(msgspec.structs.replace(report, foreign=self.foreign).encode())
            await asyncio.sleep(0.05)
        finally:
            undeclare(handles)

    async def _lockstep(self, inbox: Inbox) -> int:
        """Act on every tick whose observation and rx bundle have both come, until the stop; the next tick. Until
        a tick's rx bundle comes its observation (which comes first, as a rule) does not wake the loop: the
        bundle's wake-up takes both (:attr:`Inbox.quiet`), one wake-up a tick instead of two."""
        obs: dict[int, Observation] = {}
        rx: dict[int, RxBundle] = {}
        tick = 0
        obs_key = self.keys.obs(self.robot)
        while True:
            inbox.quiet = obs_key if tick not in rx else None
            item = await inbox.get()
            if item is None:
                continue
            key, data, _ = item
            channel = self.keys.channel(key)
            if channel == "stop":
                if self.decode(key, data, Stop) is not None:
                    return tick
            elif channel == "hello":
                self.answer_hello(key, data)
            elif channel == "obs":
                o = self.decode(key, data, Observation, self.ctx_world)
                if o is not None and o.robot == self.robot and o.tick >= tick and o.tick not in obs:
                    obs[o.tick] = o
                elif o is not None:  # a second one of a tick: first wins
                    self.drop(key, "observation for another robot, a past tick or a tick already observed")
            elif channel == "rx":
                b = self._rx(key, data)  # loosely: the brain checks each envelope against the team
                if b is not None and b.dst == self.robot and b.tick >= tick and b.tick not in rx:
                    rx[b.tick] = b
                elif b is not None:  # a second one of a tick: first wins
                    self.drop(key, "rx bundle for another robot, a past tick or a tick already received")
            while tick in obs and tick in rx:
                self._act(obs.pop(tick), rx.pop(tick))
                tick += 1

    def _act(self, obs: Observation, bundle: RxBundle) -> None:
        """One tick: the brain's decision, then the tx bundle, the command and (every few ticks) the belief."""
        self._start_clocks()
        self._send(obs, *self.brain.step(obs, bundle.msgs))

    def _rx(self, key: str, data: bytes) -> RxBundle | None:
        """An rx bundle, checked loosely (its envelopes' senders are checked by the brain, against the team);
        None when dropped."""
        return self.decode(key, data, RxBundle)

    def _start_clocks(self) -> None:
        """Start the report's CPU clocks when the first step begins."""
        if self.cpu0 is None:
            self.cpu0, self.loop_cpu0 = time.process_time(), time.thread_time()

    def _clocks_ms(self) -> tuple[float, float]:
        """The process's and the event loop thread's CPU in ms since the first step began (0 before it)."""
        if self.cpu0 is None:
            return 0.0, 0.0
        return (time.process_time() - self.cpu0) * 1000.0, (time.thread_time() - self.loop_cpu0) * 1000.0

    def _send(self, obs: Observation, cmd: Command, out: tuple[Envelope, ...]) -> None:
        """A decision's outputs, in either mode; after the first, its CPU is kept to be reported apart."""
        tx, belief = robot_outputs(self.brain, obs.tick, out, self.scenario.belief_every)
        self.pub_tx.put(tx.encode())
        self.pub_cmd.put(cmd.encode())
        if belief is not None and self.pub_belief is not None and self._belief_heard():
            self.pub_belief.put(belief.encode())
        if not self.first_cpu_ms:
            self.first_cpu_ms = first_cpu_ms(self.brain, *self._clocks_ms())

    def _belief_heard(self) -> bool:
        """Whether a subscriber (the recorder) listens to the belief snapshots: they are for the recording
        only, and a run that does not record would put a whole grid per robot on the bus for nobody (256 kB
        per robot every ``belief_every`` ticks on a 512 x 512 map)."""
        assert self.pub_belief is not None
        try:
            return bool(cast(zenoh.MatchingStatus, self.pub_belief.pub.matching_status).matching)  # a bool (stub)
        except zenoh.ZError:  # not known: send it, as before
            return True

    async def _realtime(self, inbox: Inbox) -> int:
        """Act on the newest observation as it comes (module docstring of :mod:`agents.realtime`), until the
        stop; the last tick seen plus one."""
        latest = -1
        absorbed: list[Observation] = []  # came while a decision ran: merged at the start of the next
        received: list[Envelope] = []  # radio messages for the next decision
        worker: asyncio.Future | None = None
        getter = asyncio.ensure_future(inbox.get())
        try:
            while True:
                await asyncio.wait({getter, *([worker] if worker else [])}, return_when=asyncio.FIRST_COMPLETED)
                if worker is not None and worker.done():
                    obs, cmd, out, wall_ms = worker.result()  # an allocator's exception ends the robot
                    worker = None
                    self.timing.decided(wall_ms)
                    self._send(obs, cmd, out)
                if not getter.done():
                    continue
                item, getter = getter.result(), asyncio.ensure_future(inbox.get())
                if item is None:
                    continue
                key, data, _ = item
                channel = self.keys.channel(key)
                if channel == "stop":
                    if self.decode(key, data, Stop) is not None:
                        if worker is not None:  # let a decision under way finish, briefly
                            with contextlib.suppress(TimeoutError):
                                await asyncio.wait_for(asyncio.shield(worker), 1.0)
                        return latest + 1
                elif channel == "hello":
                    self.answer_hello(key, data)
                elif channel == "obs":
                    o = self.decode(key, data, Observation, self.ctx_world)
                    if o is None or o.robot != self.robot or o.tick <= latest:
                        if o is not None:
                            self.drop(key, "observation for another robot or a past tick")
                        continue
                    latest = o.tick
                    if worker is not None or self.brain.plan is not None:  # the last plan, until a decision
                        self.pub_cmd.put(self.timing.stale_command(
                            self.robot, o.tick, self.next_seq(), o.cell, self.brain.plan).encode())
                    if worker is None:
                        worker = self._decide(o, absorbed, received)
                        absorbed, received = [], []
                    else:
                        absorbed.append(o)
                elif channel == "rx":
                    b = self._rx(key, data)
                    if b is not None and b.dst == self.robot:
                        received.extend(b.msgs)
                    elif b is not None:
                        self.drop(key, "rx bundle for another robot")
        finally:
            getter.cancel()

    def _decide(self, obs: Observation, absorbed: list[Observation], received: list[Envelope]) -> asyncio.Future:
        """One decision in a worker thread: merge ``absorbed``, step on ``obs`` with ``received``. The future
        gives ``(obs, command, tx messages, wall ms)``."""
        self._start_clocks()

        def work() -> tuple[Observation, Command, tuple[Envelope, ...], float]:
            t0 = time.perf_counter()
            for o in absorbed:
                self.brain.absorb(o)
            cmd, out = self.brain.step(obs, received)
            return obs, cmd, out, (time.perf_counter() - t0) * 1000.0

        return _in_thread(work, f"decide-{self.robot}")


def _in_thread(work: Callable[[], Any], name: str) -> asyncio.Future:
    """Run ``work`` in a daemon thread (one that never holds the process at exit); its result as a future of
    the running loop."""
    loop = asyncio.get_running_loop()
    future = loop.create_future()

    def settle(value: Any, error: BaseException | None) -> None:
        if not future.done():
            future.set_exception(error) if error is not None else future.set_result(value)

    def run() -> None:
        try:
            value, error = work(), None
        except BaseException as exc:  # handed to the loop: the shell re-raises it
            value, error = None, exc
        with contextlib.suppress(RuntimeError):  # the loop closed during shutdown
            loop.call_soon_threadsafe(settle, value, error)

    threading.Thread(target=run, daemon=True, name=name).start()
    return future


def main(argv: list[str] | None = None) -> None:
    """``python -m fleet_emu.agents --robot r0 --run RUN --connect ENDPOINT --scenario FILE.json``."""
    node_main("agents", lambda a: RobotNode(a.scenario, a.run, a.robot, realtime_hz=a.realtime), argv,
              lambda p: p.add_argument("--robot", required=True))
