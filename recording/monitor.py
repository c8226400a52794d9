"""What the launcher learns from the bus during a run: the figures ``result.json`` is made of
(:mod:`fleet_emu.recording.result` writes its keys).

A pure fold over decoded messages (state, links, commands, reports, stop), so the same code can recompute a
result from a recording.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from fleet_emu.core.access import allowed_src
from fleet_emu.core.base_connectivity import BaseConnectivity
from fleet_emu.core.codec import DecodeError, decode
from fleet_emu.core.grid import Cell
from fleet_emu.core.keys import BASE, parse_key
from fleet_emu.core.messages import (
    STALE,
    BaseReport,
    Command,
    Links,
    Message,
    RobotReport,
    RobotTiming,
    RxBundle,
    Stop,
    TxBundle,
    WorldClock,
    WorldState,
)
from fleet_emu.recording.relaystats import RelayStats

#: The channels the monitor folds (``ParsedKey.channel``); the rest is not even decoded.
_FOLDED = frozenset({"state", "links", "stop", "report", "cmd", "clock", "timing"})
_RADIO = frozenset({"tx", "rx"})  # folded too in a relaying run (recording/relaystats.py)
#: The channels whose key names the node that sends on it: only the run's robots (and its base) do.
_BY_NODE = frozenset({"cmd", "timing", "report", "tx"})


def base_graph(lk: Links) -> tuple[tuple[str, ...], np.ndarray]:
    """The link graph of a tick with the base station: its nodes (the live robots, then ``base``) and their
    link matrix, from a :class:`Links` that has ``base_link``."""
    assert lk.base_link is not None
    n = len(lk.robots)
    full = np.zeros((n + 1, n + 1), dtype=bool)
    full[:n, :n] = lk.link
    full[:n, n] = full[n, :n] = lk.base_link
    return (*lk.robots, BASE), full


@dataclasses.dataclass
class Monitor:
    """Folds the run's messages; ``result()`` gives the ``result.json`` keys (docs/reference/result.md). A fold
    (``core/fold.py``) with both entry points: :meth:`feed` a bus sample, :meth:`fold` a checked message."""

    robots: tuple[str, ...]
    state: WorldState | None = None
    links: Links | None = None
    t90: int | None = None
    t99: int | None = None
    connected_ticks: int = 0
    link_ticks: int = 0
    decision_ms: list[float] = dataclasses.field(default_factory=list)
    reports: dict[str, RobotReport] = dataclasses.field(default_factory=dict)
    stop: Stop | None = None
    # the first stop sent as anyone but the world (the launcher's own included), or in the world's name when the
    # world cannot have sent it (:meth:`world_sent`)
    outside_stop: Stop | None = None
    # a stop in the world's name for a tick whose state has not come yet (messages on different keys may arrive
    # out of order): judged by :meth:`world_sent` once a state of its tick or later comes
    pending_stop: Stop | None = None
    last_activity_ns: int | None = None  # when the last world state or robot command came (lockstep's heartbeat)
    activity_tick: int = 0  # the world's tick then
    longest_silence: tuple[float, int] = (0.0, 0)  # the longest gap between them: seconds, and the tick it began at
    malformed: int = 0
    coverage_curve: list[tuple[int, float]] = dataclasses.field(default_factory=list)
    first_state_ns: int | None = None
    last_state_ns: int | None = None
    cells: dict[int, dict[str, Cell]] = dataclasses.field(default_factory=dict)  # tick -> live robots' cells
    status: dict[tuple[int, str], str] = dataclasses.field(default_factory=dict)  # (tick, robot) -> cmd status
    clock: WorldClock | None = None  # real-time runs only: the world's last clock
    elapsed: dict[int, float] = dataclasses.field(default_factory=dict)  # and its wall seconds by tick
    timing: dict[str, RobotTiming] = dataclasses.field(default_factory=dict)  # and each robot's summary
    base: bool = False  # the run has a base station: fold base connectivity and the base's report
    base_reach: BaseConnectivity = dataclasses.field(default_factory=BaseConnectivity)
    base_curve: list[tuple[int, float]] = dataclasses.field(default_factory=list)  # (tick, fraction connected)
    base_report: BaseReport | None = None
    relay: bool = False  # the run relays: fold the radio bundles' headers into ``relay_stats``
    relay_stats: RelayStats | None = None

    def __post_init__(self) -> None:
        if self.relay and self.relay_stats is None:
            self.relay_stats = RelayStats(len(self.robots) + int(self.base))
        self._nodes = frozenset(self.robots) | ({BASE} if self.base else frozenset())

    def feed(self, key: str, data: bytes, time_ns: int | None = None) -> Message | None:
        """Decode and fold one sample (received at ``time_ns``, wall clock, when known); returns the message (None
        if it is not one the monitor uses)."""
        got = parse_key(key)
        if got is None or not (got[1].channel in _FOLDED or (self.relay and got[1].channel in _RADIO)):
            return None
        if got[1].channel in _BY_NODE and got[1].node not in self._nodes:  # a node this run does not have
            self.malformed += 1
            return None
        try:
            msg: Message = decode(data)
        except DecodeError:
            self.malformed += 1
            return None
        allowed = allowed_src(got[1])
        if allowed is not None and msg.src not in allowed:  # a spoofed sender: never folded
            self.malformed += 1
            return None
        self.fold(msg)
        if isinstance(msg, WorldState) and time_ns is not None:
            self.first_state_ns = self.first_state_ns or time_ns
            self.last_state_ns = time_ns
        if isinstance(msg, WorldState | Command) and time_ns is not None and self.state is not None:
            self._heard(time_ns)
        return msg

    def _heard(self, wall_ns: int) -> None:
        """A state or a command came at ``wall_ns``: the longest silence of the lockstep so far, and its tick."""
        if self.last_activity_ns is not None:
            gap = (wall_ns - self.last_activity_ns) / 1e9
            if gap > self.longest_silence[0]:
                self.longest_silence = (gap, self.activity_tick)
        self.last_activity_ns = max(wall_ns, self.last_activity_ns or 0)
        self.activity_tick = self.tick

    def fold(self, msg: Message) -> None:
        """One decoded message whose sender was checked against its key (the memory engine's, or :meth:`feed`'s)."""
        if isinstance(msg, WorldState) and msg.src == "world":
            if self.state is None or msg.tick >= self.state.tick:
                self.state = msg
            if self.pending_stop is not None and msg.tick >= self.pending_stop.tick:
                pending, self.pending_stop = self.pending_stop, None
                self._fold_stop(pending)
            self.coverage_curve.append((msg.tick, msg.coverage))
            self.cells[msg.tick] = {r: msg.poses[r] for r in msg.live if r in msg.poses}
            if self.t90 is None and msg.coverage >= 0.90:
                self.t90 = msg.tick
            if self.t99 is None and msg.coverage >= 0.99:
                self.t99 = msg.tick
        elif isinstance(msg, Links) and msg.src == "netem":
            self.link_ticks += 1
            self.connected_ticks += int(msg.connected)
            if self.links is None or msg.tick >= self.links.tick:
                self.links = msg
            if msg.base_link is not None:
                self._fold_base(msg)
        elif isinstance(msg, Command):
            if msg.status != STALE:  # a step along the last plan decided nothing
                self.decision_ms.append(msg.decision_ms)
            self.status[(msg.tick, msg.src)] = msg.status
        elif isinstance(msg, RobotReport):
            self.reports[msg.src] = msg
        elif isinstance(msg, BaseReport) and msg.src == BASE:
            self.base_report = msg
        elif isinstance(msg, Stop):
            self._fold_stop(msg)
        elif isinstance(msg, WorldClock) and msg.src == "world":
            if self.clock is None or msg.tick >= self.clock.tick:
                self.clock = msg
            self.elapsed[msg.tick] = msg.elapsed
        elif isinstance(msg, RobotTiming):
            self.timing[msg.src] = msg
        elif isinstance(msg, TxBundle | RxBundle) and self.relay_stats is not None:
            self.relay_stats.fold(msg)

    def _fold_stop(self, msg: Stop) -> None:
        """The world's first stop is the run's (never replaced by a later one); a stop in the world's name that
        the world cannot have sent, or anyone else's, is kept apart (:attr:`outside_stop`)."""
        if msg.src == "world" and self.stop is None and self.world_sent(msg):
            self.stop = msg
        elif msg.src == "world" and self.stop is None and self._ahead(msg):
            self.pending_stop = self.pending_stop or msg
        elif (msg.src != "world" or self.stop is None) and self.outside_stop is None:
            self.outside_stop = msg

    def _ahead(self, msg: Stop) -> bool:
        """Whether a stop in the world's name is of a tick whose state has not come yet (so not judged yet)."""
        return msg.reason not in ("startup", "interrupted") and self.state is not None and self.state.tick < msg.tick

    def world_sent(self, msg: Stop) -> bool:
        """Whether the world can have sent this stop in its name: it stops a run only when its start-up timed
        out (before any state), after its last state (``done``, of the stop's tick), or when the launcher
        stopped it (a stop of the launcher's came first)."""
        st = self.state
        if msg.reason == "startup":
            return st is None
        if msg.reason == "interrupted":
            return self.outside_stop is not None and self.outside_stop.src == "launcher"
        return st is not None and st.done and st.tick == msg.tick and msg.reason in (st.reason, "done")

    def _fold_base(self, lk: Links) -> None:
        """One tick of base connectivity (``core/base_connectivity.py``): the robots' links and theirs to the base."""
        self.base_curve.append((lk.tick, self.base_reach.add(*base_graph(lk))))

    def idle(self) -> dict[str, int]:
        """Idle robot-ticks by the status of the robot's command: a robot that had something to do (its
        command for tick t is not ``NO_FRONTIER``) and is on the same cell at t + 1 (it waited, or its move
        was blocked), live at both ticks. Counted from the states and commands alone, in any order."""
        idle: dict[str, int] = {}
        for (t, robot), status in sorted(self.status.items()):
            before, after = self.cells.get(t, {}), self.cells.get(t + 1, {})
            if status != "NO_FRONTIER" and robot in before and before[robot] == after.get(robot):
                idle[status] = idle.get(status, 0) + 1
        return idle

    @property
    def tick(self) -> int:
        return self.state.tick if self.state else 0

    @property
    def coverage(self) -> float:
        return self.state.coverage if self.state else 0.0

    def failed(self) -> list[str]:
        """The robots that left the run (not live at the last state), sorted."""
        return sorted(set(self.robots) - set(self.state.live)) if self.state else []

    def dropped_by(self) -> dict[str, int]:
        """Messages each process dropped as malformed or spoofed: the launcher's own count, the world's and
        netem's from their last state and links, each robot's from its report."""
        return {"launcher": self.malformed, "world": self.state.dropped if self.state else 0,
                "netem": self.links.dropped if self.links else 0,
                **({BASE: self.base_report.dropped} if self.base_report is not None else {}),
                **{r: rep.dropped for r, rep in sorted(self.reports.items())}}

    def foreign_by(self, launcher: int) -> dict[str, int]:
        """Messages each process dropped for not carrying the run's nonce (another run's, a replayed
        recording's): the launcher's own count (``launcher``), the world's and netem's from their last state
        and links, each robot's and the base's from its report."""
        return {"launcher": launcher, "world": self.state.foreign if self.state else 0,
                "netem": self.links.foreign if self.links else 0,
                **({BASE: self.base_report.foreign} if self.base_report is not None else {}),
                **{r: rep.foreign for r, rep in sorted(self.reports.items())}}

    def ticks_per_second(self) -> float | None:
        """Lockstep speed from the first state to the last (start-up excluded)."""
        if self.state is None or not self.first_state_ns or self.last_state_ns in (None, self.first_state_ns):
            return None
        return round(self.state.tick / ((self.last_state_ns - self.first_state_ns) / 1e9), 3)
