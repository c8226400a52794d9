"""One robot's decision for one tick, as a pure function of what it sensed and what the radio delivered.

Per tick (MinPos section 4: identify and cluster frontiers, compute distances, assign, navigate):
merge the observation and delivered map deltas into the belief, update teammates' last known poses,
cluster frontiers, run the allocator, and step down the wavefront of the assigned cluster. It then
broadcasts a pose beacon and a map delta of what it newly learned; a teammate heard again after a silence
also gets the whole known map. With map sync on (``agents/mapsync.py``: any radio that can lose a message,
unless the scenario's ``map_sync`` is false), deltas are numbered, a receiver asks a teammate in contact for
the ones it missed, and the teammate sends their cells again. No Zenoh, no files: the node shell does the I/O
and passes a clock in.

Teammates' positions. MinPos (section 4.3) ranks robots by their costs at the moment of the decision, but a
beacon arrives a tick after it was sent, and in that tick its sender has moved. So a beacon carries both the
sender's cell and the cell its command of the same tick moves it to (:class:`PoseBeacon`), and every
allocator and the navigation see a teammate at that next cell (:meth:`Teammate.expected`): where it stands
now if its move succeeded. Only what the teammate broadcast is used, plus one thing the robot knows for
sure: no two robots share a cell, so a teammate announced onto the robot's own cell did not get there and
is still on the cell it sent from. Navigation steps around a teammate heard last tick that stands still
(it announced no move, or its move cannot have happened); one that is moving on is followed, since the world
lets a line of robots advance in the same tick.
"""

from __future__ import annotations

import dataclasses
import operator
import threading
import time
from collections.abc import Callable, Sequence
from typing import Any

import msgspec
import numpy as np

from fleet_emu.agents.allocators import (
    Allocation,
    Allocator,
    AllocStatus,
    Problem,
    allocator_class,
    make_allocator,
)
from fleet_emu.agents.belief import Belief
from fleet_emu.agents.bodies import SILENT_AFTER, WreckNotice, Wrecks, as_cells, clear_of
from fleet_emu.agents.clusters import FrontierClusters
from fleet_emu.agents.hearing import Heard, hear
from fleet_emu.agents.mapsync import MapSync, SyncConfig
from fleet_emu.agents.navigation import next_move
from fleet_emu.agents.protocol import MapDelta, MapFill, PoseBeacon
from fleet_emu.agents.relay import Relay
from fleet_emu.core.codec import Context
from fleet_emu.core.errors import DecodeError
from fleet_emu.core.grid import FREE, MOVES, STAY, Cell
from fleet_emu.core.kernels import wavefront, wavefront_into
from fleet_emu.core.keys import BASE, robot_ids
from fleet_emu.core.messages import Command, Envelope, Observation, RadioMsg, seal
from fleet_emu.core.scenario import Scenario

#: The stages of :meth:`Brain.step` whose thread CPU ``Brain.cpu_ms`` sums: the allocator (``decision``), belief
#: merges (own observation and teammates' map deltas), frontier clusters, the radio payload decode, navigation
#: (wavefront descent and unsticking), the news sent (map delta, beacon, envelopes); ``step_cpu_ms`` minus their
#: sum is the rest (teammates' poses, the problem, the command).
STAGES = ("decision", "merge", "clusters", "decode", "navigation", "news")


@dataclasses.dataclass(frozen=True)
class BrainConfig:
    """``cluster_max``: frontier cells one sensing covers (MinPos 4.1); ``resync_after``: ticks of silence
    after which a teammate heard again gets the whole known map; ``map_sync``: recover lost map deltas
    (``agents/mapsync.py``, with ``sync``'s parameters), off by default and on in a run whose radio can lose a
    message unless its scenario turns it off (:func:`brain_config`); ``relay``: the relaying policy (``none``,
    or one of ``agents/relay.py``), and ``relay_ttl`` the hops left after the first on the messages the robot
    makes; ``deflate_maps``: send map data compact (:func:`~fleet_emu.core.envelope.seal`), on when the radio
    charges airtime."""

    cluster_max: int = 16
    resync_after: int = 10
    unstick_after: int = 2
    map_sync: bool = False
    sync: SyncConfig = dataclasses.field(default_factory=SyncConfig)
    relay: str = "none"
    relay_ttl: int = 0
    deflate_maps: bool = False
    silent_after: int = SILENT_AFTER  # ticks unheard after which a teammate's body is a wreck (agents/bodies.py)


@dataclasses.dataclass
class Teammate:
    """A teammate's last beacon: ``cell`` where it stood when it sent it, ``next`` where its command of that
    tick moves it, ``heard`` the tick it was heard."""

    cell: Cell
    heard: int
    next: Cell | None = None

    def expected(self, mine: Cell) -> Cell:
        """Where the teammate stands now, as far as its beacon tells: its next cell, unless that is ``mine``
        (the deciding robot's own cell, which the teammate cannot have entered)."""
        nxt = self.cell if self.next is None else self.next
        return self.cell if nxt == mine else nxt


@dataclasses.dataclass(frozen=True)
class Plan:
    """What a decision leaves for the ticks after it (real-time mode, :mod:`agents.realtime`): the wavefront
    of the target cluster (``dist``, None when nothing was assigned), the target and status, and the cells
    navigation kept clear of (teammates standing still, as of the decision)."""

    dist: np.ndarray | None
    target: Cell | None
    status: str
    blocked: frozenset[Cell] = frozenset()
    passable: np.ndarray | None = None  # with ``sources``: ``dist`` is that wavefront, grown on the first step
    sources: np.ndarray | None = None

    def step(self, cell: Cell) -> Cell:
        """The next step along the plan from ``cell`` (stay when at the target, or off the plan's wavefront)."""
        dist = self.dist
        if dist is None and self.sources is not None and self.passable is not None:
            dist = wavefront(self.passable, self.sources, -1)  # only real time steps on a plan
            object.__setattr__(self, "dist", dist)
        return STAY if dist is None else next_move(dist, cell, self.blocked)


@dataclasses.dataclass(frozen=True)
class Percept:
    """What :meth:`Brain.perceive` leaves for :meth:`Brain.act`: the observation, the allocator's problem and
    protocol messages, and the radio work of the tick so far (messages to send, map-sync requests, relayed
    copies, teammates' expected cells)."""

    obs: Observation
    problem: Problem
    protocol: list[RadioMsg]
    outbox: list[RadioMsg]
    want: dict[str, tuple[int, ...]] | None
    forwards: list[Envelope]
    expected: dict[str, Cell]


def brain_config(scenario: Scenario) -> BrainConfig:
    """The scenario's brain: map sync on when the scenario asks for it (``map_sync``, the default) and the radio
    can lose a message: not on one that delivers every message (``ideal``, or ``full`` without loss), where it
    would only add bytes (and runs stay bit-identical to runs before it existed)."""
    r = scenario.radio
    lossless = r.comm == "ideal" or (r.comm == "full" and r.loss == 0)
    sync = scenario.map_sync and not lossless
    return BrainConfig(cluster_max=max(2, int(2 * scenario.sensor_cells)), map_sync=sync,
                       relay=scenario.relay, relay_ttl=scenario.relay_ttl, deflate_maps=r.limited)


def radio_team(scenario: Scenario) -> frozenset[str]:
    """Who a robot hears radio messages from: the robots, and the base station when it plans (``mhm``: its
    orders); a message from anyone else is dropped as malformed."""
    return frozenset(robot_ids(scenario.robots)) | ({BASE} if scenario.plans_at_base else set())


def allocator_config(scenario: Scenario) -> dict[str, Any]:
    """The scenario's allocator config, completed with the scenario fields its allocator declares
    (``Allocator.scenario_fields``: the radio of connectivity, the sensor range of utility, a plugin's own);
    a value the config sets wins. ConfigError on an unknown allocator or a plugin that does not load."""
    config = dict(scenario.allocator)
    for param, field in allocator_class(config.get("type")).scenario_fields.items():
        config.setdefault(param, operator.attrgetter(field)(scenario))
    return config


def effective_allocator(scenario: Scenario) -> dict[str, Any]:
    """Every parameter the run's allocator runs with, ``{"type": name, ...}``: the scenario's ``[allocator]``
    table, the scenario fields the allocator declares, and every other parameter at its declared default, as
    checked (what ``result.json`` records as ``allocator_params``, so that a later change of a default cannot
    change what a stored result meant). ConfigError as :func:`allocator_config`."""
    return make_allocator(allocator_config(scenario)).to_dict()


class _Stage:
    """A stage of :meth:`Brain.step`: the thread CPU of its ``with`` block, in ms (``ms``), added to the brain's
    ``cpu_ms[name]`` on the way out (looked up then: a benchmark may replace the dict between steps)."""

    __slots__ = ("brain", "ms", "name", "start")

    def __init__(self, brain: Brain, name: str) -> None:
        self.brain, self.name = brain, name
        self.start = self.ms = 0.0

    def __enter__(self) -> _Stage:
        self.start = time.thread_time()
        return self

    def __exit__(self, *exc: object) -> None:
        self.ms = (time.thread_time() - self.start) * 1000.0
        self.brain.cpu_ms[self.name] += self.ms


class _Merges:
    """Teammates' map deltas and fills of one step, merged together (:meth:`Belief.merge_many`, the ``merge``
    stage) in the order they came, once every message is read or before anything reads the belief (a whole
    map for a teammate): the same belief as merging each as it comes."""

    __slots__ = ("belief", "brain", "pending")

    def __init__(self, brain: Brain, belief: Belief) -> None:
        self.brain, self.belief = brain, belief
        self.pending: list[tuple[np.ndarray, np.ndarray]] = []

    def add(self, cells: np.ndarray, values: np.ndarray) -> None:
        self.pending.append((cells, values))

    def flush(self) -> None:
        if self.pending:
            with self.brain._stage("merge"):
                self.belief.merge_many(self.pending)
            self.pending.clear()


class Brain:
    """The functional core of one agent; ``step`` is called once per tick."""

    def __init__(self, me: str, allocator: Allocator, rng: np.random.Generator, config: BrainConfig,
                 clock: Callable[[], float] = time.perf_counter, team: frozenset[str] | None = None,
                 on_drop: Callable[[str, str], None] | None = None, shared_inbox: bool = False) -> None:
        self.me = me
        self.team = team
        # the envelopes it hears are the objects its teammates hear too (the memory engine): what it decodes is
        # kept on them for the next receiver (agents/hearing.py)
        self.shared_inbox = shared_inbox
        self.on_drop = on_drop
        self.allocator = allocator
        self.rng = rng
        self.config = config
        self.clock = clock
        self.allocator.reset(rng)
        self.belief: Belief | None = None
        self.frontiers: FrontierClusters | None = None
        self.teammates: dict[str, Teammate] = {}  # in id order (sorted again when one joins)
        self.seq = 0
        self.last_cell: Cell | None = None
        self.last_move: Cell = STAY
        self.last_target: Cell | None = None  # the previous decision's target, passed to the allocator
        self.stuck = 0
        self.decision_ms: list[float] = []
        self.decision_cpu_ms = 0.0  # this thread's CPU in the allocator, summed over decisions
        self.step_cpu_ms = 0.0  # and in the whole of step (decision, belief, clusters, radio decode, navigation)
        self.cpu_ms = dict.fromkeys(STAGES, 0.0)  # thread CPU of step by stage, summed (benchmarks/brain_step.py)
        self.ctx: Context | None = None
        self.plan: Plan | None = None  # what the last step decided, for the ticks until the next decision
        self._seq_lock = threading.Lock()  # real-time mode draws from the counter in two threads
        self.sync: MapSync | None = MapSync(config.sync) if config.map_sync else None
        # relaying (agents/relay.py); under ``tree`` its routes come from ``relay.set_routes`` (the hook a
        # base-station allocator fills; with none, ``tree`` forwards nothing)
        self.relay: Relay | None = Relay(me, config.relay) if config.relay != "none" else None
        self.wrecks = Wrecks(config.silent_after)  # bodies of robots that no longer speak (agents/bodies.py)

    def next_seq(self) -> int:
        """The robot's one sequence counter: envelopes, commands, bundles and reports all draw from it."""
        with self._seq_lock:
            self.seq += 1
            return self.seq

    def _belief(self, obs: Observation) -> Belief:
        if self.belief is None:
            self.belief = Belief(obs.shape)
            self.frontiers = FrontierClusters(obs.shape, self.config.cluster_max)
            self.ctx = Context(senders=self.team, shape=obs.shape)
        return self.belief

    def absorb(self, obs: Observation) -> None:
        """Merge what the sensor saw at a tick the robot made no decision for (real-time mode: it came while a
        decision ran); it goes out as map news with the next step's."""
        self._belief(obs).merge(obs.cells, obs.values)

    def open(self, inbox: Sequence[Envelope]) -> list[Heard]:
        """What the radio delivered, checked against the grid and the team and decoded, in the order it came
        (:func:`~fleet_emu.agents.hearing.hear`); what does not validate (an unknown payload kind included) is
        dropped and reported to ``on_drop``, which counts it."""
        assert self.ctx is not None
        return hear(inbox, self.ctx, self.on_drop, self.shared_inbox)

    def relay_inbox(self, inbox: Sequence[Envelope]) -> tuple[list[Envelope], list[Envelope]]:
        """With relaying on: the envelopes of ``inbox`` to deliver (first copies for this robot or everyone)
        and the copies to forward (:meth:`Relay.handle`); a header that does not validate is dropped and
        counted, never forwarded. Without relaying, the inbox as it is and nothing to forward."""
        if self.relay is None:
            return list(inbox), []
        deliver: list[Envelope] = []
        forward: list[Envelope] = []
        for env in inbox:
            try:
                env.validate(self.ctx)
            except DecodeError as exc:
                if self.on_drop is not None:
                    self.on_drop(f"radio/{env.payload_kind}", str(exc))
                continue
            d = self.relay.handle(env)
            if d.deliver:
                deliver.append(env)
            if d.forward is not None:
                forward.append(d.forward)
        return deliver, forward

    def step(self, obs: Observation, inbox: Sequence[Envelope]) -> tuple[Command, tuple[Envelope, ...]]:
        """Decide the move for ``obs.tick`` and the radio messages to send (with relaying on, the copies it
        forwards go out after its own): :meth:`perceive`, then :meth:`act` with the allocator's decision. Each
        stage's thread CPU is added to ``cpu_ms`` (:data:`STAGES`), the whole step's to ``step_cpu_ms``."""
        return self.act(self.perceive(obs, inbox))

    def perceive(self, obs: Observation, inbox: Sequence[Envelope]) -> Percept:
        """The first half of :meth:`step`: merge the observation and what the radio delivered, hear teammates,
        cluster frontiers; the :class:`Percept` holds the allocator's problem (a learned policy reads it)."""
        c0 = time.thread_time()
        t = obs.tick
        belief = self._belief(obs)
        with self._stage("merge"):
            belief.merge(obs.cells, obs.values)
        with self._stage("decode"):
            delivered, forwards = self.relay_inbox(inbox)
            opened = self.open(delivered)
        outbox: list[RadioMsg] = []
        protocol, rejoined = self._read(opened, t, belief, outbox)
        heard, expected = self._poses(obs.cell)
        want = self._requests(t, heard, rejoined)
        wrecks = self.wrecks.update(obs, self.teammates)
        notice = self.wrecks.notice(t)
        if notice is not None:
            outbox.append(RadioMsg(notice))
        with self._stage("clusters"):
            assert self.frontiers is not None
            clusters = clear_of(list(self.frontiers.update(belief.grid, belief.take_changed())), wrecks, obs.shape[1])
        problem = Problem(me=self.me, poses={self.me: obs.cell} | expected, belief=belief.grid, clusters=clusters,
                          tick=t, heard=heard, previous_target=self.last_target, obstacles=wrecks)
        self.step_cpu_ms += (time.thread_time() - c0) * 1000.0
        return Percept(obs, problem, protocol, outbox, want, forwards, expected)

    def act(self, p: Percept) -> tuple[Command, tuple[Envelope, ...]]:
        """The second half of :meth:`step`: the allocator's decision on ``p.problem``, the move toward it and the
        news sent (the beacon announces the move taken)."""
        c0 = time.thread_time()
        alloc = self._decide(p.problem, p.protocol)
        with self._stage("navigation"):
            move = self._navigate(p.obs.cell, p.obs.tick, alloc, p.problem, p.expected)
        with self._stage("news"):
            p.outbox.extend(alloc.outbox)
            sealed = self._news(p.obs, move, p.want, p.outbox, p.forwards)
        assert self.belief is not None
        cmd = Command(src=self.me, tick=p.obs.tick, seq=self.next_seq(), move=move, target=alloc.target,
                      status=alloc.status.name, decision_ms=round(self.decision_ms[-1], 4),
                      known=self.belief.known_cells)
        self.step_cpu_ms += (time.thread_time() - c0) * 1000.0
        return cmd, sealed

    def _stage(self, name: str) -> _Stage:
        """A ``with`` block whose thread CPU counts to the stage ``name`` of ``cpu_ms``."""
        return _Stage(self, name)

    def _read(self, opened: list[Heard], t: int, belief: Belief, outbox: list[RadioMsg]
              ) -> tuple[list[RadioMsg], list[str]]:
        """Teammates' messages of the tick, in the order they came: beacons (:meth:`_beacon`, the usual one
        inline), map deltas and fills (merged into the belief: the ``merge`` stage), and the rest, the
        allocator's protocol. Returns the protocol messages and the teammates heard again after a silence."""
        sync, me, resync = self.sync, self.me, self.config.resync_after
        peers = sync.peers if sync is not None else {}
        teammates = self.teammates
        merges = _Merges(self, belief)
        protocol: list[RadioMsg] = []
        rejoined: list[str] = []
        joined = False
        for env, body in opened:
            origin, tick = env.origin, env.tick
            if origin == me:
                continue
            if isinstance(body, MapDelta):
                merges.add(body.cells, body.values)
                if sync is not None and body.n is not None:
                    peer = peers.get(origin) or sync.peer(origin)
                    peer.received(body.n)
                    if body.covers:
                        peer.filled(body.covers, 0)
            elif isinstance(body, MapFill):
                merges.add(body.cells, body.values)
                if sync is not None:
                    sync.peer(origin).filled(body.seqs, body.upto)
            elif isinstance(body, PoseBeacon):
                prev = teammates.get(origin)
                seqs = body.want.get(me) if sync is not None and body.want else None
                if prev is None or t - prev.heard > resync or seqs is not None:
                    joined = joined or prev is None
                    if self._beacon(origin, tick, body, t, outbox, merges, seqs):
                        rejoined.append(origin)
                    continue
                if tick >= prev.heard:  # heard lately, asks nothing of this robot: _beacon's usual case inline
                    prev.cell, prev.heard, prev.next = body.cell, max(t, tick), body.next
                if sync is not None and body.maps is not None:
                    (peers.get(origin) or sync.peer(origin)).exists(body.maps)
            elif isinstance(body, WreckNotice):  # a teammate's wrecks (agents/bodies.py)
                self.wrecks.hear(body)
            else:
                protocol.append(RadioMsg(body, dst=env.dst, ttl=env.ttl, src=env.src, origin=origin, tick=tick,
                                         seq=env.seq))
        merges.flush()
        if joined:  # new teammates: the dict in id order again
            self.teammates = dict(sorted(teammates.items()))
        return protocol, rejoined

    def _beacon(self, origin: str, tick: int, beacon: PoseBeacon, t: int, outbox: list[RadioMsg],
                merges: _Merges, asks: tuple[int, ...] | None) -> bool:
        """A teammate's beacon: its pose (:meth:`_heard`; True when it rejoined), and with map sync the deltas
        it numbered so far and ``asks``, those it asks this robot for again (its :attr:`~PoseBeacon.want`). The
        pending merges go in first whenever the belief is about to be sent."""
        prev = self.teammates.get(origin)
        if prev is not None and t - prev.heard <= self.config.resync_after:  # heard lately: its pose only
            if tick >= prev.heard:
                prev.cell, prev.heard, prev.next = beacon.cell, max(t, tick), beacon.next
            rejoined = False
        else:  # it may get our whole map
            merges.flush()
            rejoined = self._heard(origin, tick, beacon, t, outbox)
        sync = self.sync
        if sync is not None:
            maps = beacon.maps
            if maps is not None:
                sync.peer(origin).exists(maps)
            if asks is not None:
                if sync.sends_whole(asks):
                    merges.flush()
                fill = sync.answer(asks, merges.belief)
                if fill is not None:
                    outbox.append(RadioMsg(fill, dst=origin))
        return rejoined

    def _poses(self, mine: Cell) -> tuple[dict[str, int], dict[str, Cell]]:
        """Every teammate's last tick heard, and where it is expected (:meth:`Teammate.expected`), in id order."""
        heard, expected = {}, {}
        for r, tm in self.teammates.items():
            heard[r] = tm.heard
            expected[r] = tm.expected(mine)
        return heard, expected

    def _requests(self, t: int, heard: dict[str, int], rejoined: list[str]) -> dict[str, tuple[int, ...]] | None:
        """With map sync, the deltas to ask teammates for again (:attr:`PoseBeacon.want`); None without."""
        if self.sync is None:
            return None
        for r in rejoined:  # it sends us its whole map as we send it ours: ask only if that is lost
            self.sync.peer(r).hold(t)
        return self.sync.requests(t, heard)

    def _decide(self, problem: Problem, protocol: list[RadioMsg]) -> Allocation:
        """The allocator's decision: its wall time (``clock``) goes to ``decision_ms`` and the command, its
        thread CPU to ``decision_cpu_ms`` and the ``decision`` stage."""
        with self._stage("decision") as stage:
            t0 = self.clock()
            alloc = self.allocator.allocate(problem, protocol)
            self.decision_ms.append((self.clock() - t0) * 1000.0)
        self.decision_cpu_ms += stage.ms
        return alloc

    def _navigate(self, cell: Cell, t: int, alloc: Allocation, problem: Problem, expected: dict[str, Cell]) -> Cell:
        """The move down the wavefront of the assigned cluster (or a planner's goal cell), around teammates
        heard last tick that stand still, then unstuck (:meth:`_unstick`); the decision kept as ``plan``, its
        target as ``last_target``."""
        self.last_target = alloc.target
        move = STAY
        wants = False  # the robot wants to move but a teammate stands on every way down the wavefront
        dist, blocked, sources = None, set(), None
        going = alloc.status is AllocStatus.GOAL and alloc.target is not None  # a planner's goal cell (mhm)
        if (alloc.status is AllocStatus.ASSIGNED and alloc.cluster is not None) or going:
            blocked = {expected[r] for r, tm in self.teammates.items()
                       if tm.heard >= t - 1 and expected[r] == tm.cell}
            if problem.obstacles:
                blocked |= as_cells(problem.obstacles, problem.belief.shape[1])
            if going:
                mask = alloc.passable if alloc.passable is not None else problem.passable
                dist = goal_wavefront(mask, alloc.target)  # type: ignore[arg-type]
                move = next_move(dist, cell, blocked)
                wants = move == STAY and dist[cell] > 0
            elif "wavefronts" in problem.__dict__:  # the allocator computed them all
                dist = problem.wavefronts[alloc.cluster]  # type: ignore[index]
                move = next_move(dist, cell, blocked)
                wants = move == STAY and dist[cell] > 0
            else:
                sources = problem.clusters[alloc.cluster].cells.astype(np.int64)  # type: ignore[index]
                move, wants = self._descend(problem.passable, sources, cell, blocked)
        if alloc.routes is not None and self.relay is not None:
            self.relay.set_routes(alloc.routes)  # a base planner's tree (mhm), for the next ticks' forwarding
        self.plan = Plan(dist, alloc.target, alloc.status.name, frozenset(blocked),
                         problem.passable if sources is not None else None, sources)
        assert self.belief is not None
        occupied = set(expected.values()) | as_cells(problem.obstacles, problem.belief.shape[1])
        return self._unstick(cell, move, wants, self.belief.grid, occupied, alloc.passable if going else None)

    def _descend(self, passable: np.ndarray, sources: np.ndarray, cell: Cell, blocked: set[Cell]) -> tuple[Cell, bool]:
        """The move down the wavefront from ``sources`` (:func:`~fleet_emu.agents.navigation.next_move`) and
        whether the robot wants to move but cannot. The wavefront stops at the robot's cell (the descent from
        there reads only nearer cells) and is grown in arrays kept per thread and set back after: a fresh one
        writes its whole grid-sized array each tick, the cold memory a robot among a hundred processes pays
        most for."""
        rows, cols = passable.shape
        dist, queue = _scratch(rows * cols)
        count = wavefront_into(passable, sources, cell[0] * cols + cell[1], dist, queue)
        try:
            grid = dist.reshape(rows, cols)
            move = next_move(grid, cell, blocked)
            return move, bool(move == STAY and grid[cell] > 0)
        finally:
            dist[queue[:count]] = -1

    def _news(self, obs: Observation, move: Cell, want: dict[str, tuple[int, ...]] | None,
              outbox: list[RadioMsg], forwards: list[Envelope]) -> tuple[Envelope, ...]:
        """The tick's envelopes: the pose beacon, the map delta of what the robot newly learned (with map sync
        numbered, and with the cells of deltas asked for again), then ``outbox``, then with relaying on the
        copies it forwards."""
        assert self.belief is not None
        belief, sync = self.belief, self.sync
        cells, values = belief.take_news()
        n = covers = None
        if sync is not None:
            fresh = cells
            cells, covers = sync.news(cells)  # with the cells of deltas asked for again
            if covers is not None:
                values = belief.grid.reshape(-1)[cells].copy()
            n = sync.number(fresh) if len(cells) else None  # a later request for it gets its news only
        delta = MapDelta(cells=cells, values=values, n=n, covers=covers)
        news = [RadioMsg(PoseBeacon(cell=obs.cell, next=(obs.cell[0] + move[0], obs.cell[1] + move[1]),
                                    maps=sync.sent if sync is not None else None, want=want))]
        if len(cells):
            news.append(RadioMsg(delta))
        deflate = self.config.deflate_maps
        sealed = tuple(seal(m, self.me, obs.tick, self.next_seq(), deflate) for m in news + outbox)
        if self.relay is not None:
            ttl = self.config.relay_ttl
            sealed = tuple(e if e.ttl >= ttl else msgspec.structs.replace(e, ttl=ttl) for e in sealed)
            for e in sealed:
                self.relay.sent(e)
            sealed += tuple(forwards)
        return sealed

    def _heard(self, origin: str, tick: int, beacon: PoseBeacon, t: int, outbox: list[RadioMsg]) -> bool:
        """A teammate's pose; one heard for the first time, or again after a silence, gets our whole map
        (True then; with map sync as a fill that stands for every delta so far)."""
        prev = self.teammates.get(origin)
        if prev is not None and tick < prev.heard:
            return False
        rejoined = (prev is None or t - prev.heard > self.config.resync_after) and self.belief is not None
        if rejoined and self.sync is not None:
            outbox.append(RadioMsg(self.sync.whole(self.belief), dst=origin))  # type: ignore[arg-type]
        elif rejoined:
            cells, values = self.belief.known()  # type: ignore[union-attr]
            outbox.append(RadioMsg(MapDelta(cells=cells, values=values), dst=origin))
        if prev is None:  # a new teammate: the dict is put back in id order once every message is read (_read)
            self.teammates[origin] = Teammate(cell=beacon.cell, heard=max(t, tick), next=beacon.next)
        else:  # updated in place: a robot hears every teammate's beacon every tick
            prev.cell, prev.heard, prev.next = beacon.cell, max(t, tick), beacon.next
        return rejoined

    def _unstick(self, cell: Cell, move: Cell, wants: bool, grid: np.ndarray, occupied: set[Cell],
                 passable: np.ndarray | None = None) -> Cell:
        """A robot whose moves keep failing, or that keeps waiting for a teammate to clear its way (two
        robots head-on in a corridor), tries a random free step (not onto a cell in ``occupied``, the
        teammates' expected cells; inside ``passable`` when a planner's goal restricts it), drawn from its own
        generator."""
        if (self.last_cell == cell and self.last_move != STAY) or wants:
            self.stuck += 1
        else:
            self.stuck = 0
        if (move != STAY or wants) and self.stuck >= self.config.unstick_after:
            options = [m for m in MOVES if _free(grid, (cell[0] + m[0], cell[1] + m[1]))
                       and (cell[0] + m[0], cell[1] + m[1]) not in occupied
                       and (passable is None or passable[cell[0] + m[0], cell[1] + m[1]])]
            if options:
                move = options[int(self.rng.integers(len(options)))]
        self.last_cell, self.last_move = cell, move
        return move


_SCRATCH = threading.local()


def _scratch(n: int) -> tuple[np.ndarray, np.ndarray]:
    """A wavefront's arrays for a grid of ``n`` cells, every distance -1, kept per thread (the memory engine's
    brains step one after another in one)."""
    kept = getattr(_SCRATCH, "arrays", None)
    if kept is None or kept[0].size != n:
        kept = _SCRATCH.arrays = (np.full(n, -1, dtype=np.int32), np.empty(n, dtype=np.int64))
    return kept


def goal_wavefront(passable: np.ndarray, goal: Cell) -> np.ndarray:
    """BFS distance to ``goal`` over ``passable`` cells (-1 unreached: a robot steps down it only from a
    passable cell)."""
    return wavefront(passable, np.array([goal[0] * passable.shape[1] + goal[1]], dtype=np.int64), -1)


def _free(grid: np.ndarray, cell: Cell) -> bool:
    return 0 <= cell[0] < grid.shape[0] and 0 <= cell[1] < grid.shape[1] and grid[cell] == FREE
