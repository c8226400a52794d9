"""The world process shell: ground truth, sensing and motion over Zenoh, and the lockstep clock.

Each tick t (docs/design/architecture.md, "Time"): publish every live robot's observation and the state, wait
for every live robot's command for t (a robot silent past the barrier timeout, or whose liveliness token goes,
is failed), apply the moves, advance. All the simulation is :class:`world.sim.World` and the lockstep's
messages are built in :mod:`world.messages` (as the memory engine builds them); this module only does I/O.

Real time (``realtime_hz``, ``fleet run --realtime HZ``): the world does not wait for the robots. It publishes
tick k, collects commands until tick k + 1 is due on its wall clock (:class:`world.realtime.TickClock`), applies
each live robot's last command received (:class:`world.realtime.CommandLatch`: a command stamped for an earlier
tick is late, applied now and counted) and advances, whether or not every robot answered. With every state it
publishes a :class:`WorldClock` (world/clock: late and missed commands per robot, its own overruns). A robot
nothing came from for ``barrier_timeout`` seconds is failed, as in lockstep.
"""

from __future__ import annotations

import argparse
import asyncio
import time

import msgspec
import zenoh

from fleet_emu.core.bus import Inbox, Publisher
from fleet_emu.core.codec import Context
from fleet_emu.core.grid import MapData
from fleet_emu.core.kernels import warm_up
from fleet_emu.core.keys import BASE, Keys, robot_ids
from fleet_emu.core.messages import STALE, Command, Failed, Ready, Stop, WorldClock
from fleet_emu.core.node import Declared, NodeShell, node_main, undeclare
from fleet_emu.core.pace import Pacer
from fleet_emu.core.scenario import Scenario
from fleet_emu.world.build import build_world
from fleet_emu.world.messages import hello, stop, tick_messages
from fleet_emu.world.realtime import CommandLatch, TickClock
from fleet_emu.world.sim import Reading

HELLO_PERIOD = 0.1  # seconds between the first hellos; each wait is 1.5 times the last, up to HELLO_MAX
HELLO_MAX = 0.5  # (every node answers every hello: at 256 robots a fixed 0.1 s gave ~80 rounds of 256 readies)
# How long the world waits for every node's ready: a base, and a second per robot (robots started afresh each
# import numpy, numba and scipy: 28 s for 32 of them on 2 loaded cores; 256 forked robots took 47 s).
STARTUP_TIMEOUT = 120.0
STARTUP_PER_ROBOT = 1.0


class WorldNode(NodeShell):
    role = "world"

    def __init__(self, scenario: Scenario, run: str, map_data: MapData, startup_timeout: float | None = None,
                 realtime_hz: float | None = None, pace_hz: float | None = None) -> None:
        super().__init__(Keys(run), "world")
        warm_up()  # compile (or load) the kernels before the first tick, not inside it
        self.scenario = scenario
        self.world = build_world(scenario, map_data)
        self.robots = robot_ids(scenario.robots)
        self.startup_timeout = startup_timeout if startup_timeout is not None else \
            STARTUP_TIMEOUT + STARTUP_PER_ROBOT * scenario.robots
        self.stopped_early = False
        self.interrupted = False
        self.lost_at_start: set[str] = set()
        self.realtime_hz = realtime_hz
        self.pacer = Pacer(pace_hz)  # lockstep: at most this many ticks a wall-clock second (a viewer's)
        self.known: dict[str, int] = {}  # each robot's last command's ``known`` cells (the stall rule's signal)

    async def run(self, session: zenoh.Session) -> str:
        """Run the whole episode; returns the reason it ended."""
        keys = self.keys
        inbox = self.inbox()
        handles: list[Declared] = [
            inbox.subscribe(session, keys.wildcard("robot", "*", "cmd")),
            inbox.subscribe(session, keys.ready_all),
            inbox.subscribe(session, keys.stop),
            inbox.subscribe(session, keys.failed("*")),
            inbox.watch_liveliness(session, keys.wildcard("alive", "agent", "*")),
        ]
        self.pub_obs = {r: self.publisher(session, keys.obs(r)) for r in self.robots}
        self.pub_state = self.publisher(session, keys.state)
        pub_hello = self.publisher(session, keys.hello)
        pub_stop = self.publisher(session, keys.stop)
        self.pub_clock = self.publisher(session, keys.clock) if self.realtime_hz else None
        handles += [*self.pub_obs.values(), self.pub_state, pub_hello, pub_stop,
                    *([self.pub_clock] if self.pub_clock else []),
                    session.liveliness().declare_token(keys.alive("world", "world"))]
        self.ctx = Context(senders=frozenset(self.robots), shape=self.world.shape)
        self.ctx_launcher = Context(senders=frozenset({"launcher"}))
        try:
            return await self._episode(inbox, pub_hello, pub_stop)
        finally:
            undeclare(handles)

    async def _episode(self, inbox: Inbox, pub_hello: Publisher, pub_stop: Publisher) -> str:
        if not await self._handshake(inbox, pub_hello):
            pub_stop.put(Stop(src="world", tick=0, seq=self.next_seq(), reason="startup").encode())
            return "startup"
        if self.stopped_early:
            return "interrupted"
        readings = self.world.reset(failed=self.lost_at_start)  # agents whose process died before tick 0
        if self.realtime_hz:
            await self._realtime(inbox, readings, self.realtime_hz)
        else:
            await self._lockstep(inbox, readings)
        end = stop(self.world, self.next_seq(), self.interrupted)
        pub_stop.put(end.encode())
        await asyncio.sleep(0.05)
        return end.reason

    async def _handshake(self, inbox: Inbox, pub_hello: Publisher) -> bool:
        """Repeat the hello, less and less often, until the launcher (its recorder), netem and every agent
        answered: their subscriptions are then in place, so nothing of tick 0 is published into the void."""
        waiting = {"launcher", "netem", *([BASE] if self.scenario.has_base else []), *self.robots}
        deadline = time.monotonic() + self.startup_timeout
        next_hello, period = 0.0, HELLO_PERIOD
        while waiting:
            now = time.monotonic()
            if now > deadline:
                self.drop("ctl/ready", f"startup timed out waiting for {sorted(waiting)}")
                return False
            if now >= next_hello:
                pub_hello.put(hello().encode())
                next_hello = now + period
                period = min(HELLO_MAX, period * 1.5)
            item = await inbox.get(timeout=max(0.0, next_hello - time.monotonic()))
            if item is None:
                continue
            key, data, is_put = item
            if self._interrupted(key, data):
                self.stopped_early = True
                return True
            lost = self._lost(key, data, is_put)
            if lost in waiting:
                self.lost_at_start.add(lost)
                waiting.discard(lost)
            parsed = self.keys.parse(key)
            if parsed is not None and parsed.channel == "ready":
                ready = self.decode(key, data, Ready)
                if ready is not None and ready.src == parsed.node:
                    waiting.discard(ready.src)
        return True

    def _lost(self, key: str, data: bytes, is_put: bool) -> str | None:
        """The robot a liveliness deletion or the launcher's failure notice is about, or None."""
        parsed = self.keys.parse(key)
        if parsed is None:
            return None
        if parsed.channel == "alive" and parsed.role == "agent":
            return None if is_put else parsed.node
        if parsed.channel == "failed":
            msg = self.decode(key, data, Failed, self.ctx_launcher)
            return msg.robot if msg is not None else None
        return None

    def _interrupted(self, key: str, data: bytes) -> bool:
        """The launcher's stop (Ctrl-C) ends the run at once."""
        if key != self.keys.stop:
            return False
        stop = self.decode(key, data, Stop)
        return stop is not None and stop.src == "launcher"

    def _publish(self, readings: dict[str, Reading]) -> None:
        obs, state = tick_messages(self.world, readings, self.scenario.cell_size, self.next_seq, self.dropped)
        for r, o in obs.items():
            self.pub_obs[r].put(o.encode())
        self.pub_state.put((msgspec.structs.replace(state, foreign=self.foreign) if self.foreign else state).encode())

    async def _lockstep(self, inbox: Inbox, readings: dict[str, Reading]) -> None:
        """Tick when every live robot has answered, until the run is done (or the launcher stops it)."""
        while True:
            self._publish(readings)
            if self.world.done:
                return
            moves = await self._barrier(inbox)
            if (wait := self.pacer.delay()) > 0:  # the wall clock only: the tick's moves are already decided
                await asyncio.sleep(wait)
            if self.interrupted:
                return
            readings = self.world.step(moves, self.known)

    async def _realtime(self, inbox: Inbox, readings: dict[str, Reading], hz: float) -> None:
        """Tick on the wall clock until the run is done (or the launcher stops it)."""
        w = self.world
        start = time.monotonic()
        clock = TickClock(hz, start)  # its t0 moves on an overrun; ``start`` stays
        latch = CommandLatch(self.robots, start)
        while True:
            self._publish(readings)
            now = time.monotonic()
            assert self.pub_clock is not None
            self.pub_clock.put(WorldClock(
                src="world", tick=w.tick, seq=self.next_seq(), hz=hz, elapsed=round(now - start, 6),
                overruns=clock.overruns, late=dict(latch.late), late_steps=dict(latch.late_steps),
                missed=dict(latch.missed)).encode())
            if w.done:
                return
            deadline = clock.deadline(w.tick, now)
            await self._collect(inbox, latch, deadline)
            if self.interrupted:
                return
            for r in latch.silent(list(w.live), time.monotonic(), self.scenario.barrier_timeout):
                w.fail(r)
            readings = w.step(latch.take(list(w.live)), self.known)

    async def _collect(self, inbox: Inbox, latch: CommandLatch, deadline: float) -> None:
        """Take commands (and failures, and the launcher's stop) until ``deadline``."""
        t = self.world.tick
        while (wait := deadline - time.monotonic()) > 0:
            item = await inbox.get(timeout=wait)
            if item is None:
                return
            key, data, is_put = item
            if self._interrupted(key, data):
                self.interrupted = True
                return
            lost = self._lost(key, data, is_put)
            if lost is not None:
                self.world.fail(lost)
                continue
            parsed = self.keys.parse(key)
            if parsed is None or parsed.channel != "cmd":
                continue
            cmd = self.decode(key, data, Command, self.ctx)
            if cmd is not None and parsed.node in self.world.live:
                self.known[parsed.node] = max(self.known.get(parsed.node, 0), cmd.known)
            if cmd is not None and parsed.node in self.world.live \
                    and not latch.receive(parsed.node, cmd.tick, cmd.move, t, time.monotonic(), cmd.status != STALE):
                self.drop(key, f"command stamped for tick {cmd.tick}, not yet published (now {t})")

    async def _barrier(self, inbox: Inbox) -> dict[str, tuple[int, int]]:
        """Wait for every live robot's command for this tick; fail the silent ones: those still missing when no
        command came for ``barrier_timeout`` seconds (a deadline from the last command, not from the tick's
        start, so that a large fleet sharing a few cores is not failed for being many)."""
        t = self.world.tick
        waiting = set(self.world.live)
        moves: dict[str, tuple[int, int]] = {}
        deadline = time.monotonic() + self.scenario.barrier_timeout
        while waiting:
            item = await inbox.get(timeout=max(0.0, deadline - time.monotonic()))
            if item is None:
                for r in sorted(waiting):
                    self.world.fail(r)
                break
            key, data, is_put = item
            if self._interrupted(key, data):
                self.interrupted = True
                break
            lost = self._lost(key, data, is_put)
            if lost is not None:
                if lost in waiting:
                    waiting.discard(lost)
                    self.world.fail(lost)
                continue
            parsed = self.keys.parse(key)
            if parsed is None or parsed.channel != "cmd":
                continue
            robot = parsed.node
            cmd = self.decode(key, data, Command, self.ctx)
            if cmd is None:
                continue
            if cmd.tick == t and robot in waiting:  # decode checked that robot sent it
                moves[robot], self.known[robot] = cmd.move, cmd.known
                waiting.discard(robot)
                deadline = time.monotonic() + self.scenario.barrier_timeout  # silent since the last command
            elif cmd.tick == t and robot in moves:  # a robot commands once a tick: a second is not its own
                self.drop(key, f"a second command of {robot} for tick {t} (the first is kept)")
        return moves


def main(argv: list[str] | None = None) -> None:
    """``python -m fleet_emu.world --run RUN --connect ENDPOINT --scenario FILE.json --map-file MAP.npz``."""
    node_main("world", lambda a: WorldNode(a.scenario, a.run, a.map_file, realtime_hz=a.realtime, pace_hz=a.pace),
              argv, extra=_add_pace, map_file=True)


def _add_pace(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--pace", type=float, default=None, metavar="HZ",
                        help="lockstep: at most HZ ticks per wall-clock second (fleet run --live-hz)")
