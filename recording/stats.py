"""The per-tick stats channel ``/viz/stats``: the numbers a researcher plots against time, as JSON with a JSON
schema (``fleet_emu.Stats``) so Foxglove's Plot panel reads them (``/viz/stats.coverage``,
``/viz/stats.robots.r0.decision_ms``, ``/viz/stats.radio.tick.delivered``...).

:class:`TickStats` is pure: it is handed one flushed tick at a time (the world's state, netem's links and the
robots' commands of that tick, and the next tick's state when known) by
:class:`~fleet_emu.recording.foxglove.FoxgloveFold`, and keeps the running totals.
"""

from __future__ import annotations

import dataclasses
import json
from typing import Any

from fleet_emu.core.base_connectivity import BaseConnectivity
from fleet_emu.core.messages import Command, Links, WorldState
from fleet_emu.recording.monitor import base_graph

TOPIC_STATS = "/viz/stats"
SCHEMA_STATS = "fleet_emu.Stats"
RADIO_COUNTERS = ("sent", "delivered", "dropped_loss", "dropped_signal", "bytes_sent")

_TIME = {"type": "object", "properties": {"sec": {"type": "integer", "minimum": 0},
                                          "nsec": {"type": "integer", "minimum": 0}}, "required": ["sec", "nsec"]}
_COUNTERS = {"type": "object", "properties": {k: {"type": "integer"} for k in RADIO_COUNTERS},
             "required": list(RADIO_COUNTERS), "additionalProperties": False}
_ROBOT = {"type": "object", "additionalProperties": False, "required": ["live", "path_length", "idle_ticks"],
          "properties": {
              "live": {"type": "boolean", "description": "the robot takes part (false once it failed)"},
              "path_length": {"type": "integer", "description": "cells moved since the start"},
              "decision_ms": {"type": ["number", "null"], "description": "its last decision's time (ms)"},
              "status": {"type": ["string", "null"], "description": "its command's status at the tick"},
              "idle_ticks": {"type": "integer", "description": "ticks it had a target and stood, so far"}}}

#: The JSON schema of ``/viz/stats`` (draft 2020-12).
STATS_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": SCHEMA_STATS,
    "description": "One tick of a fleet-emu run: coverage, connectivity, per robot progress, radio counters",
    "type": "object",
    "additionalProperties": False,
    "required": ["timestamp", "tick", "coverage", "connected", "connected_fraction", "links", "robots", "radio"],
    "properties": {
        "timestamp": _TIME,
        "tick": {"type": "integer", "minimum": 0},
        "coverage": {"type": "number", "description": "fraction of the free cells the team sensed"},
        "connected": {"type": ["boolean", "null"], "description": "the team's radio graph is connected"},
        "connected_fraction": {"type": ["number", "null"], "description": "of the ticks so far, connected"},
        "base_connected_fraction": {"type": ["number", "null"],
                                    "description": "live robots with a (multi-hop) path to the base"},
        "links": {"type": "integer", "description": "radio links between robots at the tick"},
        "robots": {"type": "object", "additionalProperties": _ROBOT},
        "radio": {"type": "object", "additionalProperties": False, "required": ["tick", "total"],
                  "properties": {"tick": _COUNTERS, "total": _COUNTERS}},
    },
}


def stats_schema_text() -> bytes:
    return json.dumps(STATS_SCHEMA, sort_keys=True).encode()


@dataclasses.dataclass
class TickStats:
    """Running totals behind ``/viz/stats``; :meth:`tick` gives one tick's message. Not a fold of messages
    (``core/fold.py``): :class:`~fleet_emu.recording.foxglove.FoxgloveFold` hands it whole ticks."""

    robots: tuple[str, ...]
    base: bool = False
    link_ticks: int = 0
    connected_ticks: int = 0
    idle: dict[str, int] = dataclasses.field(default_factory=dict)
    decision: dict[str, float] = dataclasses.field(default_factory=dict)
    total: dict[str, int] = dataclasses.field(default_factory=lambda: dict.fromkeys(RADIO_COUNTERS, 0))
    reach: BaseConnectivity = dataclasses.field(default_factory=BaseConnectivity)

    def tick(self, stamp: dict[str, int], st: WorldState, lk: Links | None, cmds: dict[str, Command],
             after: WorldState | None) -> dict[str, Any]:
        """Tick ``st.tick``'s stats; ``after`` is the next tick's state (to tell who stood), if known."""
        connected: bool | None = None
        links = 0
        base_frac: float | None = None
        now = dict(self.total)
        if lk is not None:
            self.link_ticks += 1
            connected = bool(lk.connected)
            self.connected_ticks += int(connected)
            link = lk.link | lk.link.T
            links = int(link.sum()) // 2
            now = {k: int(getattr(lk, k)) for k in RADIO_COUNTERS}
            if self.base and lk.base_link is not None:
                base_frac = round(self.reach.add(*base_graph(lk)), 6)
        delta = {k: now[k] - self.total[k] for k in RADIO_COUNTERS}
        self.total = now
        return {
            "timestamp": stamp, "tick": st.tick, "coverage": round(float(st.coverage), 6), "connected": connected,
            "connected_fraction": round(self.connected_ticks / self.link_ticks, 6) if self.link_ticks else None,
            "base_connected_fraction": base_frac, "links": links,
            "robots": {r: self._robot(r, st, cmds.get(r), after) for r in self.robots if r in st.poses},
            "radio": {"tick": delta, "total": now},
        }

    def _robot(self, r: str, st: WorldState, cmd: Command | None, after: WorldState | None) -> dict[str, Any]:
        live = r in st.live
        if cmd is not None:
            self.decision[r] = float(cmd.decision_ms)
            stood = after is not None and r in after.live and after.poses.get(r) == st.poses[r]
            if live and cmd.status != "NO_FRONTIER" and stood:
                self.idle[r] = self.idle.get(r, 0) + 1
        return {"live": live, "path_length": int(st.path_length.get(r, 0)), "decision_ms": self.decision.get(r),
                "status": cmd.status if cmd is not None else None, "idle_ticks": self.idle.get(r, 0)}
