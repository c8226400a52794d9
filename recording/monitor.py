"""What the launcher learns from the bus during a run, and the ``result.json`` it makes of it.

A pure fold over decoded messages (state, links, commands, reports, stop), so the same code can recompute a
result from a recording.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from fleet_emu.core.access import allowed_src
from fleet_emu.core.codec import DecodeError, decode
from fleet_emu.core.faults import applied
from fleet_emu.core.grid import Cell
from fleet_emu.core.keys import BASE, parse_key
from fleet_emu.core.messages import (
    STALE,
    AgentReport,
    AgentTiming,
    BaseReport,
    Command,
    Links,
    Message,
    RxBundle,
    Stop,
    TxBundle,
    WorldClock,
    WorldState,
)
from fleet_emu.core.radio import RadioConfig
from fleet_emu.core.reach import BaseConnectivity
from fleet_emu.core.version import SCHEMA_VERSION, __version__
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


def airtime_result(lk: Links | None) -> dict[str, Any]:
    """``result.json``'s radio airtime keys from the last links: bytes on the air, queue drops, the largest
    queue, and the delay (ticks from hand-off to delivery) of the messages emitted, ``mean``, ``p95`` (nearest
    rank) and ``max`` (null values when none was)."""
    hist = np.array(lk.delays if lk else (), dtype=np.int64)
    n = int(hist.sum())
    delay: dict[str, Any] = {"mean": None, "p95": None, "max": None}
    if n:
        ticks = np.arange(len(hist))
        rank = int(np.searchsorted(np.cumsum(hist), math.ceil(0.95 * n)))
        delay = {"mean": round(float((ticks * hist).sum()) / n, 4), "p95": int(ticks[rank]),
                 "max": int(ticks[hist > 0].max())}
    return {"airtime_bytes": lk.airtime_bytes if lk else 0, "dropped_queue": lk.dropped_queue if lk else 0,
            "queued_max_bytes": lk.queued_max_bytes if lk else 0, "delay_ticks": delay}


def prediction_result(lk: Links | None, radio: dict[str, Any]) -> dict[str, Any]:
    """``result.json``'s ``radio.prediction`` in a run with shadowing (``shadowing_db`` > 0; nothing otherwise):
    the robot pairs over the ticks, and those whose link eq. 4 without the field called wrongly
    (``netem.channel.count_predictions``)."""
    if not radio.get("shadowing_db"):
        return {}
    return {"prediction": {"pair_ticks": lk.pair_ticks if lk else 0, "false_links": lk.false_links if lk else 0,
                           "missed_links": lk.missed_links if lk else 0}}


def fault_result(scenario: dict[str, Any], st: WorldState | None) -> dict[str, Any]:
    """``result.json``'s ``faults``, in a run whose scenario has some (docs/guides/faults.md): the entries of a
    tick the run reached, applied; and ``blocked_by``, in a run that missed its target where a failed robot's
    body cuts the live robots off from cells still to sense: each such robot, its cell and how many cells it
    holds off (``world.sim.World.blocking``)."""
    out: dict[str, Any] = {}
    if "faults" in scenario:
        out["faults"] = applied(scenario["faults"], st.tick if st else 0)
    if st is not None and st.blocked:
        out["blocked_by"] = {r: {"cell": list(st.poses[r]), "cut_off": n} for r, n in sorted(st.blocked.items())
                             if r in st.poses}
    return out


def allocator_params(scenario: dict[str, Any]) -> dict[str, Any]:
    """``result.json``'s ``allocator_params``: every parameter the allocator ran with, defaults filled in
    (:func:`fleet_emu.agents.brain.effective_allocator`); the scenario's table as given when its allocator cannot
    be loaded here (a report, on another machine, of a run whose plugin is not installed)."""
    from fleet_emu.agents.brain import effective_allocator  # at the end of a run only: the brain is heavy
    from fleet_emu.core.errors import FleetError
    from fleet_emu.core.scenario import Scenario

    try:
        return effective_allocator(Scenario.from_dict(scenario))
    except FleetError:
        return dict(scenario["allocator"])


@dataclasses.dataclass
class Monitor:
    """Folds the run's messages; ``result()`` gives the ``result.json`` keys (docs/reference/result.md)."""

    robots: tuple[str, ...]
    state: WorldState | None = None
    links: Links | None = None
    t90: int | None = None
    t99: int | None = None
    connected_ticks: int = 0
    link_ticks: int = 0
    decision_ms: list[float] = dataclasses.field(default_factory=list)
    reports: dict[str, AgentReport] = dataclasses.field(default_factory=dict)
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
    timing: dict[str, AgentTiming] = dataclasses.field(default_factory=dict)  # and each robot's summary
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

    def feed(self, key: str, data: bytes, wall_ns: int | None = None) -> Message | None:
        """Decode and fold one sample; returns the message (None if it is not one the monitor uses)."""
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
        if isinstance(msg, WorldState) and wall_ns is not None:
            self.first_state_ns = self.first_state_ns or wall_ns
            self.last_state_ns = wall_ns
        if isinstance(msg, WorldState | Command) and wall_ns is not None and self.state is not None:
            self._heard(wall_ns)
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
        elif isinstance(msg, AgentReport):
            self.reports[msg.src] = msg
        elif isinstance(msg, BaseReport) and msg.src == BASE:
            self.base_report = msg
        elif isinstance(msg, Stop):
            self._fold_stop(msg)
        elif isinstance(msg, WorldClock) and msg.src == "world":
            if self.clock is None or msg.tick >= self.clock.tick:
                self.clock = msg
            self.elapsed[msg.tick] = msg.elapsed
        elif isinstance(msg, AgentTiming):
            self.timing[msg.src] = msg
        elif isinstance(msg, TxBundle) and self.relay_stats is not None:
            self.relay_stats.fold_tx(msg)
        elif isinstance(msg, RxBundle) and self.relay_stats is not None and msg.src == "netem":
            self.relay_stats.fold_rx(msg)

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
        """One tick of base connectivity (``core/reach.py``): the robots' links and theirs to the base."""
        self.base_curve.append((lk.tick, self.base_reach.add(*base_graph(lk))))

    def base_result(self) -> dict[str, Any]:
        """A base-station run's keys: ``base_connected_fraction {overall, all_ticks, per_robot}`` (over the
        ticks netem published links for) and ``base {cell, known_cells, known_fraction, merged, ticks}``
        (the base's report; null values when it sent none: interrupted, or its process died)."""
        frac = self.base_reach.summary()
        rounded = {k: (round(v, 6) if isinstance(v, float) else v) for k, v in frac.items() if k != "per_robot"}
        rounded["per_robot"] = {r: round(v, 6) for r, v in frac["per_robot"].items()}
        rep = self.base_report
        base: dict[str, Any] = {
            "cell": list(rep.cell) if rep else None, "known_cells": rep.known_cells if rep else None,
            "known_fraction": round(rep.known_cells / rep.cells, 6) if rep else None,
            "merged": rep.merged if rep else None, "ticks": rep.ticks if rep else None}
        return {"base_connected_fraction": rounded, "base": base}

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

    def result(self, scenario: dict[str, Any], run_id: str, target: float) -> dict[str, Any]:
        """The ``result.json`` keys (docs/reference/result.md)."""
        st = self.state
        lk = self.links
        ms = np.array(self.decision_ms) if self.decision_ms else np.zeros(1)
        completed = bool(st is not None and st.coverage >= target)
        idle = self.idle()
        return {
            "run_id": run_id,
            "seed": scenario["seed"],
            "map": scenario["map"],
            "allocator": scenario["allocator"]["type"],
            "allocator_params": allocator_params(scenario),
            "robots": scenario["robots"],
            "loss": scenario["radio"]["loss"],
            "comm": scenario["radio"]["comm"],
            "loss_applied": RadioConfig(comm=scenario["radio"]["comm"], loss=scenario["radio"]["loss"]).applied_loss,
            "ticks": st.tick if st else 0,
            "completed": completed,
            "reason": (self.stop.reason if self.stop else None) or (st.reason if st else None),
            "coverage": round(st.coverage, 6) if st else 0.0,
            "t90": self.t90,
            "t99": self.t99,
            "path_length": [st.path_length.get(r, 0) if st else 0 for r in self.robots],
            "idle_robot_ticks": sum(idle.values()),
            "idle_by_status": idle,
            "connected_fraction": round(self.connected_ticks / self.link_ticks, 6) if self.link_ticks else None,
            "radio": {
                "sent": lk.sent if lk else 0,
                "delivered": lk.delivered if lk else 0,
                "dropped_loss": lk.dropped_loss if lk else 0,
                "dropped_signal": lk.dropped_signal if lk else 0,
                "bytes_sent": lk.bytes_sent if lk else 0,
            } | airtime_result(lk) | prediction_result(lk, scenario["radio"]),
            "decision_ms": {"mean": round(float(ms.mean()), 4), "p95": round(float(np.percentile(ms, 95)), 4)},
            "failed": sorted(set(self.robots) - set(st.live)) if st else [],
            "malformed_dropped": sum(self.dropped_by().values()),
            "malformed_dropped_by": self.dropped_by(),
            "agent_peak_rss_kb": {r: rep.peak_rss_kb for r, rep in sorted(self.reports.items())},
            "ticks_per_second": self.ticks_per_second(),
            "schema_version": SCHEMA_VERSION,
            "fleet_emu": __version__,
        } | (self.realtime() if self.clock is not None else {}) | (self.base_result() if self.base else {}) | (
            {"relay": {"policy": scenario.get("relay", "none"), "ttl": scenario.get("relay_ttl", 0),
                       "kinds": self.relay_stats.result()}} if self.relay_stats is not None else {}) | \
            fault_result(scenario, st)

    def realtime(self) -> dict[str, Any]:
        """A real-time run's keys (none in lockstep, which publishes no clock): ``realtime_hz``, and under
        ``realtime`` the world's ``overruns``, its achieved rate, the wall seconds at which coverage reached
        0.9 and 0.99 (``t90_s``, ``t99_s``: from tick 0's scheduled time), and per robot its ``late_commands``
        (decisions applied a tick late), ``late_steps`` (steps along the last plan that came late),
        ``missed_ticks`` (no command at all: it stood), ``decisions``, ``plan_steps``, ``waits`` and its
        decision-time percentiles (``decision_ms``: the whole step in its worker thread; ``allocator_ms``)."""
        ck = self.clock
        assert ck is not None
        robots = {}
        for r in self.robots:
            tm = self.timing.get(r)
            robots[r] = {"late_commands": ck.late.get(r, 0), "late_steps": ck.late_steps.get(r, 0),
                         "missed_ticks": ck.missed.get(r, 0)} | (
                {"decisions": tm.decisions, "plan_steps": tm.plan_steps, "waits": tm.waits,
                 "decision_ms": tm.decision_ms, "allocator_ms": tm.allocator_ms} if tm is not None else
                {"decisions": None, "plan_steps": None, "waits": None, "decision_ms": None, "allocator_ms": None})
        return {"realtime_hz": ck.hz, "realtime": {
            "world_overruns": ck.overruns, "elapsed_s": round(ck.elapsed, 3),
            "t90_s": self._wall(self.t90), "t99_s": self._wall(self.t99),
            "ticks_per_second": round(ck.tick / ck.elapsed, 3) if ck.elapsed > 0 else None,
            "late_commands": sum(ck.late.values()), "robots": robots}}

    def _wall(self, tick: int | None) -> float | None:
        """The world's wall seconds at ``tick`` since tick 0 was scheduled (None if its clock never came)."""
        at = self.elapsed.get(tick) if tick is not None else None
        return round(at, 3) if at is not None else None

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
