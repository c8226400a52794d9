"""The metrics of a run, recomputed from its recorded bus messages (a pure fold, like :mod:`.monitor`).

:class:`RunMetrics` feeds every recorded sample to a :class:`.monitor.Monitor` — the same fold that makes
``result.json`` live, so the recomputed result has the same keys and values — and folds the rest of the stream
(observations, tx/rx bundles, commands, ready messages) into:

- ``t100``: the first tick at 100 % coverage, beside ``result.json``'s ``t90`` and ``t99`` (the world's coverage: the
  fraction of the free cells reachable from the start that some robot has sensed);
- ``path``: cells travelled per robot and in total;
- ``efficiency``: distinct free cells sensed by the team per cell travelled by the team;
- ``overlap``: cells sensed by more than one robot (from the observations), and their fraction of the cells the
  team sensed;
- ``share``: how evenly the exploring was shared. Each robot is credited with the cells it sensed first (a cell
  first sensed by k robots in the same tick gives each 1/k); ``share`` is each robot's fraction of that credit.
  Evenness is **Jain's fairness index** J = (sum x)^2 / (n sum x^2) over the credits (1 = perfectly even,
  1/n = one robot did it all); the Gini coefficient of the same credits is given too (0 = even);
- ``connectivity``: the fraction of ticks the team's link graph was connected, and for each pair of robots the
  fraction of ticks they had a link (Benavides et al.'s "connection time %");
- ``radio``: ``result.json``'s (netem's counters) and :data:`RADIO_MORE`: the share delivered, the counts by payload
  kind, per robot the messages and bytes it sent (the encoded tx bundles' sizes), bytes per tick, and the messages
  it received;
- ``decision_ms``: ``result.json``'s mean and p95 of the decisions' time (every command is one call), and their
  p50, max, count and each robot's mean.

A quantity has one name in ``result.json``, ``metrics.json`` and the summary tables; the groups of the first layout
(``exploration_time``, ``radio_detail``, ``decision_time``) are written beside for one release
(:data:`DEPRECATED_GROUPS`).

The per-tick series (coverage, connectivity, messages per tick) and the trajectories are kept for the plots.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from fleet_emu.core.base_connectivity import base_connected
from fleet_emu.core.codec import DecodeError, decode
from fleet_emu.core.keys import parse_key, robot_ids
from fleet_emu.core.messages import (
    STALE,
    Command,
    Envelope,
    Links,
    Observation,
    Ready,
    RxBundle,
    Stop,
    TxBundle,
    WorldState,
)
from fleet_emu.core.radio import bytes_per_robot_tick
from fleet_emu.recording.first_seen import FirstSeen
from fleet_emu.recording.monitor import Monitor, base_graph
from fleet_emu.recording.result import NOT_RECORDED as NOT_RECORDED  # where it was: the keys a recording lacks
from fleet_emu.recording.result import Ending, build_result

#: What ``metrics.json``'s ``radio`` adds to ``result.json``'s: the share delivered, the counts by payload kind,
#: each robot's messages and bytes, and the bytes per robot-tick.
RADIO_MORE = ("delivered_fraction", "by_kind", "per_robot", "bytes_per_robot_per_tick")

#: ``metrics.json``'s groups of its first layout, written beside their quantities' names (``t90``, ``t99``,
#: ``t100``; ``radio``; ``decision_ms``) for one release, then removed: each old key and the key it is now.
DEPRECATED_GROUPS = {
    "exploration_time": {"t90": "t90", "t99": "t99", "t100": "t100"},
    "radio_detail": {"sent": "radio.sent", "delivered": "radio.delivered", "dropped.loss": "radio.dropped_loss",
                     "dropped.signal": "radio.dropped_signal", "bytes_sent": "radio.bytes_sent",
                     **{k: f"radio.{k}" for k in RADIO_MORE}},
    "decision_time": {"calls": "decision_ms.calls", "mean_ms": "decision_ms.mean", "p50_ms": "decision_ms.p50",
                      "p95_ms": "decision_ms.p95", "max_ms": "decision_ms.max",
                      "per_robot_mean_ms": "decision_ms.per_robot_mean"},
}


def jain(x: list[float] | np.ndarray) -> float | None:
    """Jain's fairness index of non-negative values: 1 when all are equal, 1/n when one has everything."""
    a = np.asarray(x, dtype=float)
    if len(a) == 0 or not (a**2).sum():
        return None
    return float(a.sum() ** 2 / (len(a) * (a**2).sum()))


def gini(x: list[float] | np.ndarray) -> float | None:
    """The Gini coefficient of non-negative values: 0 when all are equal, (n-1)/n when one has everything."""
    a = np.sort(np.asarray(x, dtype=float))
    n = len(a)
    if n == 0 or not a.sum():
        return None
    return float((2 * np.arange(1, n + 1) - n - 1) @ a / (n * a.sum()))


def radio_kind(msg: Envelope) -> str:
    """The kind of a radio message inside a tx/rx bundle (the ``by_kind`` counts): its envelope's payload kind,
    read without decoding the payload."""
    return msg.payload_kind


def _r(x: float | np.floating | None, nd: int = 6) -> float | None:
    return None if x is None else round(float(x), nd)


@dataclasses.dataclass
class TickSeries:
    """Per-tick values for the plots."""

    connected: dict[int, bool] = dataclasses.field(default_factory=dict)
    links: dict[int, int] = dataclasses.field(default_factory=dict)
    strength: dict[int, float] = dataclasses.field(default_factory=dict)  # mean signal over live pairs, dB
    tx_msgs: dict[int, int] = dataclasses.field(default_factory=dict)
    tx_bytes: dict[int, int] = dataclasses.field(default_factory=dict)
    rx_msgs: dict[int, int] = dataclasses.field(default_factory=dict)
    base: dict[int, dict[str, bool]] = dataclasses.field(default_factory=dict)  # per live robot: a path to the base

    def arrays(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        d: dict[int, Any] = getattr(self, name)
        ticks = np.array(sorted(d), dtype=int)
        return ticks, np.array([d[t] for t in ticks], dtype=float)


class RunMetrics:
    """Fold of one run's recorded samples (fed by :meth:`feed`, ``core/fold.py``); ``metrics()`` is what ``fleet
    report`` writes to metrics.json."""

    def __init__(self, scenario: dict[str, Any], run_id: str, engine: str | None = None) -> None:
        self.scenario = scenario
        self.run_id = run_id
        self.engine = engine
        self.robots = tuple(robot_ids(int(scenario["robots"])))
        self.monitor = Monitor(self.robots, base=scenario.get("base", False) is not False,
                               relay=scenario.get("relay", "none") != "none")
        self.messages = 0
        self.undecodable = 0
        self.team: FirstSeen | None = None  # every robot's observations (its values: the true map, where sensed)
        self.first_seen: dict[str, FirstSeen] = {}  # each robot's own
        self.trajectory: dict[str, list[tuple[int, tuple[int, int]]]] = {r: [] for r in self.robots}
        self.pair_ticks: dict[tuple[str, str], int] = {}
        self.tx_msgs = dict.fromkeys(self.robots, 0)
        self._bytes_sent = 0  # netem's cumulative bytes sent at the last Links folded
        self.tx_bundles = dict.fromkeys(self.robots, 0)
        self.rx_msgs = dict.fromkeys(self.robots, 0)
        self.kinds: dict[str, int] = {}
        self.decisions: dict[str, list[float]] = {r: [] for r in self.robots}
        self.pids: dict[str, int] = {}
        self.launcher_stop: Stop | None = None
        self.series = TickSeries()
        self._traj_tick = -1

    # --- the fold ---------------------------------------------------------------------------------------

    def feed(self, key: str, data: bytes, time_ns: int | None = None) -> None:
        """One recorded msgpack sample (topic, bytes, its publish time)."""
        self.messages += 1
        msg = self.monitor.feed(key, data, time_ns)
        if msg is None:
            got = parse_key(key)
            if got is None or got[1].channel not in ("obs", "tx", "rx", "ready"):
                return
            try:
                msg = decode(data)
            except DecodeError:
                self.undecodable += 1
                return
        if isinstance(msg, WorldState) and msg.src == "world":
            self._state(msg)
        elif isinstance(msg, Links) and msg.src == "netem":
            self._links(msg)
        elif isinstance(msg, Observation) and msg.src == "world":
            self._observe(msg)
        elif isinstance(msg, TxBundle) and msg.src in self.tx_msgs:
            self.tx_msgs[msg.src] += len(msg.msgs)
            self.tx_bundles[msg.src] += 1
            self.series.tx_msgs[msg.tick] = self.series.tx_msgs.get(msg.tick, 0) + len(msg.msgs)
            for m in msg.msgs:
                kind = radio_kind(m)
                self.kinds[kind] = self.kinds.get(kind, 0) + 1
        elif isinstance(msg, RxBundle) and msg.dst in self.rx_msgs:
            self.rx_msgs[msg.dst] += len(msg.msgs)
            self.series.rx_msgs[msg.tick] = self.series.rx_msgs.get(msg.tick, 0) + len(msg.msgs)
        elif isinstance(msg, Command) and msg.src in self.decisions and msg.status != STALE:  # real time: a step
            # along the last plan, not a decision
            self.decisions[msg.src].append(msg.decision_ms)
        elif isinstance(msg, Ready):
            self.pids[msg.src] = msg.pid
        elif isinstance(msg, Stop) and msg.src == "launcher":
            self.launcher_stop = msg

    def _state(self, st: WorldState) -> None:
        if st.tick <= self._traj_tick:
            return
        self._traj_tick = st.tick
        for r in self.robots:
            if r in st.poses:
                cell = (int(st.poses[r][0]), int(st.poses[r][1]))
                traj = self.trajectory[r]
                if not traj or traj[-1][1] != cell:
                    traj.append((st.tick, cell))

    def _links(self, lk: Links) -> None:
        t = lk.tick
        if lk.bytes_sent >= self._bytes_sent:  # the bytes emitted this tick (netem's counters are cumulative)
            self.series.tx_bytes[t] = self.series.tx_bytes.get(t, 0) + lk.bytes_sent - self._bytes_sent
            self._bytes_sent = lk.bytes_sent
        link = np.asarray(lk.link, dtype=bool)
        strength = np.asarray(lk.strength, dtype=float)
        n = len(lk.robots)
        iu = np.triu_indices(n, 1)
        und = link | link.T
        self.series.connected[t] = bool(lk.connected)
        if lk.base_link is not None:
            self.series.base[t] = base_connected(*base_graph(lk))
        self.series.links[t] = int(und[iu].sum())
        if n > 1:
            sym = np.maximum(strength, strength.T)[iu]
            sym = sym[np.isfinite(sym)]
            if len(sym):
                self.series.strength[t] = float(sym.mean())
        for i, j in zip(*iu, strict=True):
            if und[i, j]:
                a, b = sorted((lk.robots[i], lk.robots[j]), key=self._order)
                self.pair_ticks[a, b] = self.pair_ticks.get((a, b), 0) + 1

    def _order(self, r: str) -> int:
        return self.robots.index(r) if r in self.robots else len(self.robots)

    def _observe(self, o: Observation) -> None:
        if self.team is None:
            self.team = FirstSeen(o.shape)
        if tuple(o.shape) != self.team.shape:
            return
        if o.robot not in self.first_seen:
            self.first_seen[o.robot] = FirstSeen(self.team.shape)
        self.first_seen[o.robot].observe(o.tick, o.cells, o.values)
        self.team.observe(o.tick, o.cells, o.values)

    # --- results --------------------------------------------------------------------------------------------

    def ending(self) -> Ending:
        """How the run ended, as far as its recording shows: the launcher's stop says it was interrupted, or
        that a process died (a launcher's ``aborted``), as does a world that stopped at start-up; the failure's
        line is not on the bus."""
        if self.launcher_stop is not None and self.launcher_stop.reason == "interrupted":
            return Ending(interrupted=True)
        if self.launcher_stop is not None or getattr(self.monitor.stop, "reason", None) == "startup":
            return Ending(error="")
        return Ending()

    def recorded_pids(self) -> dict[str, Any]:
        """The process ids the nodes' ready messages gave (None for a node whose ready was not recorded: the
        world sends none)."""
        return {"world": self.pids.get("world"), "netem": self.pids.get("netem"),
                "robots": [self.pids.get(r) for r in self.robots]}

    def result(self, recording_path: str | None = None, messages: int | None = None) -> dict[str, Any]:
        """result.json, recomputed (:func:`~fleet_emu.recording.result.build_result`; but :data:`NOT_RECORDED`);
        ``messages``: the recording's (default: the samples folded). The recording's metadata says which engine
        ran it (none before it did)."""
        return build_result(self.monitor, self.scenario, self.run_id, self.ending(), engine=self.engine,
                            pids=self.recorded_pids(), recording=recording_path,
                            messages=self.messages if messages is None else messages, launcher=None)

    def coverage_stats(self) -> dict[str, Any]:
        """Team, per-robot and overlapping sensed cells, first-discovery credit and its evenness."""
        if self.team is None:
            n = len(self.robots)
            return {"team_cells": 0, "free_cells": 0, "per_robot": dict.fromkeys(self.robots, 0),
                    "overlap_cells": 0, "overlap_fraction": None, "credit": dict.fromkeys(self.robots, 0.0),
                    "share": dict.fromkeys(self.robots, None), "jain": None, "gini": None, "n": n}
        big = np.iinfo(np.int32).max
        empty = np.full(len(self.team.tick), -1, dtype=np.int32)
        stack = np.stack([self.first_seen[r].tick if r in self.first_seen else empty for r in self.robots])
        sensed = stack >= 0
        team = sensed.any(axis=0)
        firsts = np.where(sensed, stack, big)
        team_first = firsts.min(axis=0)
        discoverer = sensed & (firsts == team_first) & team
        k = discoverer.sum(axis=0)
        credit = (discoverer / np.maximum(k, 1)).sum(axis=1)
        total = float(credit.sum())
        overlap = int((sensed.sum(axis=0) >= 2).sum())
        team_cells = int(team.sum())
        return {
            "team_cells": team_cells,
            "free_cells": int((self.team.value == 0).sum()),
            "per_robot": {r: int(sensed[i].sum()) for i, r in enumerate(self.robots)},
            "overlap_cells": overlap,
            "overlap_fraction": _r(overlap / team_cells) if team_cells else None,
            "credit": {r: round(float(credit[i]), 3) for i, r in enumerate(self.robots)},
            "share": {r: _r(credit[i] / total) if total else None for i, r in enumerate(self.robots)},
            "jain": _r(jain(credit)),
            "gini": _r(gini(credit)),
        }

    def first_tick_at(self, level: float) -> int | None:
        for t, c in self.monitor.coverage_curve:
            if c >= level - 1e-12:
                return t
        return None

    def metrics(self, recording_path: str | None = None) -> dict[str, Any]:
        """Everything ``fleet report`` writes: result.json's keys, then the analysis groups."""
        res = self.result(recording_path)
        return res | self.analysis(res)

    def analysis(self, res: dict[str, Any]) -> dict[str, Any]:
        """The analysis groups of metrics.json, given the recomputed result (:meth:`result`)."""
        cov = self.coverage_stats()
        path = res["path_length"]
        total_path = int(sum(path))
        detail, decisions = self._radio_detail(), self._decision_time()
        return {
            "t100": self.first_tick_at(1.0),
            "radio": res["radio"] | {k: detail[k] for k in RADIO_MORE},
            "decision_ms": res["decision_ms"] | {"p50": decisions["p50_ms"], "max": decisions["max_ms"],
                                                "calls": decisions["calls"],
                                                "per_robot_mean": decisions["per_robot_mean_ms"]},
            "path": {"per_robot": dict(zip(self.robots, path, strict=True)), "total": total_path},
            "efficiency": {
                "definition": "distinct free cells sensed by the team per cell travelled by the team",
                "free_cells_sensed": cov["free_cells"],
                "cells_travelled": total_path,
                "value": _r(cov["free_cells"] / total_path) if total_path else None,
            },
            "overlap": {"cells": cov["overlap_cells"], "fraction": cov["overlap_fraction"],
                        "team_cells_sensed": cov["team_cells"], "per_robot_cells_sensed": cov["per_robot"]},
            "share": {
                "definition": "cells each robot sensed first (simultaneous firsts split evenly); "
                              "evenness by Jain's fairness index (1 = even, 1/n = one robot), and Gini (0 = even)",
                "credit": cov["credit"], "share": cov["share"], "jain": cov["jain"], "gini": cov["gini"],
            },
            "connectivity": self._connectivity(res),
            "undecodable": self.undecodable,
            # the same quantities under their former names, for one release (DEPRECATED_GROUPS)
            "exploration_time": {"t90": res["t90"], "t99": res["t99"], "t100": self.first_tick_at(1.0)},
            "radio_detail": detail,
            "decision_time": decisions,
        } | ({"base_connectivity": {
            "definition": "per tick, the share of live robots with a path of links to the base station",
            "fraction_by_tick": [[t, _r(f)] for t, f in self.monitor.base_curve]}} if self.monitor.base else {})

    def _connectivity(self, res: dict[str, Any]) -> dict[str, Any]:
        """metrics.json's ``connectivity``: the team's connected share of ticks, each pair's linked share, the
        mean number of links and signal strength."""
        link_ticks = self.monitor.link_ticks
        pairs = {}
        for i, a in enumerate(self.robots):
            for b in self.robots[i + 1:]:
                n = self.pair_ticks.get((a, b), 0)
                pairs[f"{a}-{b}"] = _r(n / link_ticks) if link_ticks else None
        return {
            "connected_fraction": res["connected_fraction"],
            "ticks": link_ticks,
            "pair_link_fraction": pairs,
            "mean_links": _r(np.mean(list(self.series.links.values()))) if self.series.links else None,
            "mean_signal_db": _r(np.mean(list(self.series.strength.values())), 3) if self.series.strength else None,
        }

    def _radio_detail(self) -> dict[str, Any]:
        """metrics.json's ``radio_detail``: messages sent, delivered and dropped, by kind and per robot."""
        lk = self.monitor.links
        sent = lk.sent if lk else 0
        ticks = self.monitor.tick
        by = lk.bytes_by if lk and (lk.bytes_by or not lk.bytes_sent) else None  # None: a recording before it
        return {
            "sent": sent,
            "delivered": lk.delivered if lk else 0,
            "dropped": {"loss": lk.dropped_loss if lk else 0, "signal": lk.dropped_signal if lk else 0},
            "delivered_fraction": _r(lk.delivered / sent) if lk and sent else None,
            "by_kind": dict(sorted(self.kinds.items())),
            "per_robot": {r: {
                "msgs_sent": self.tx_msgs[r],
                "bytes_sent": by.get(r, 0) if by is not None else None,
                "bytes_per_tick": _r(by.get(r, 0) / ticks, 2) if by is not None and ticks else None,
                "msgs_received": self.rx_msgs[r],
            } for r in self.robots},
            "bytes_sent": lk.bytes_sent if lk else 0,
            "bytes_per_robot_per_tick": _r(rate, 2) if (rate := bytes_per_robot_tick(
                lk.bytes_sent if lk else 0, len(self.robots), ticks)) is not None else None,
        }

    def _decision_time(self) -> dict[str, Any]:
        """metrics.json's ``decision_time``: the decisions' wall time, over the team and per robot."""
        all_ms = np.array([m for r in self.robots for m in self.decisions[r]], dtype=float)
        some = len(all_ms) > 0
        return {
            "calls": len(all_ms),
            "mean_ms": _r(all_ms.mean(), 4) if some else None,
            "p50_ms": _r(np.percentile(all_ms, 50), 4) if some else None,
            "p95_ms": _r(np.percentile(all_ms, 95), 4) if some else None,
            "max_ms": _r(all_ms.max(), 4) if some else None,
            "per_robot_mean_ms": {r: _r(np.mean(v), 4) if v else None for r, v in self.decisions.items()},
        }
