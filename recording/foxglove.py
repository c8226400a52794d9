"""Foxglove views of a run, written into ``run.mcap`` beside the raw msgpack channels.

:class:`FoxgloveFold` is a pure fold: decoded bus messages in, derived messages out, each a
:class:`Derived` (topic, schema name, JSON bytes, tick). It uses the official Foxglove JSON schemas shipped in
``recording/schemas/`` (schema encoding ``jsonschema``, message encoding ``json``):

- ``/viz/map/truth``: ``foxglove.Grid``, once (it never changes; a live viewer gets it on subscribing);
- ``/viz/map/coverage`` and ``/viz/belief/<robot>``: ``foxglove.Grid``, every ``grid_every`` ticks (beliefs as
  their snapshots come, at most once per ``grid_every`` ticks);
- ``/viz/scene``: ``foxglove.SceneUpdate`` every tick — robots at their true poses, their targets with a line
  from robot to target, and the radio links coloured by signal strength; in a run with a base station, the base
  (a white cylinder at its cell, entity ``base``) and its links to the robots;
- ``/viz/log``: ``foxglove.Log`` for notable events — the start, a robot failing, coverage milestones, the team's
  radio graph splitting or joining, the end of the run;
- ``/viz/stats``: ``fleet_emu.Stats`` (JSON schema, :mod:`~fleet_emu.recording.stats`) every tick, to plot.

Every timestamp is the tick's time on the run's clock (:class:`~fleet_emu.recording.clock.RunClock`).

Frames: everything is in frame ``map``, x to the right (columns) and y up, so the map appears upright seen from
above: cell ``(row, col)`` has its centre at ``((col + .5) * cell_size, (rows - row - .5) * cell_size)``.
Grid cells carry one ``int8`` field ``occupancy`` (-1 unknown, 0 free, 100 occupied) and ``red``/``green``/``blue``/
``alpha`` bytes (choose "RGBA (separate fields)" as the colour mode in the 3D panel).

:class:`~fleet_emu.recording.foxglove_writer.FoxgloveWriter` is the launcher's shell around the fold: it
decodes what the fold needs and writes the derived messages through the recorder.
"""

from __future__ import annotations

import base64
import dataclasses
import json
from collections.abc import Sequence
from importlib import resources
from typing import Any

import numpy as np

from fleet_emu.core.keys import robot_ids
from fleet_emu.core.messages import BeliefSnapshot, Command, Links, Message, Observation, Stop, WorldState
from fleet_emu.recording.clock import EPOCH, RunClock
from fleet_emu.recording.first_seen import FirstSeen, fold_team
from fleet_emu.recording.stats import SCHEMA_STATS, TOPIC_STATS, TickStats, stats_schema_text

SCHEMAS = ("foxglove.Grid", "foxglove.SceneUpdate", "foxglove.Log", SCHEMA_STATS)
FRAME = "map"
TOPIC_TRUTH = "/viz/map/truth"
TOPIC_COVERAGE = "/viz/map/coverage"
TOPIC_SCENE = "/viz/scene"
TOPIC_LOG = "/viz/log"
MILESTONES = (0.25, 0.5, 0.75, 0.9, 0.99, 1.0)
#: Ticks a tick's scene and stats may wait for its commands and links, which travel from other processes than the
#: world's states and may reach the launcher after the next state: after that, the tick is drawn as it stands.
LAG = 3

# foxglove enums (from the schemas)
UINT8, INT8 = 1, 2
LINE_STRIP, LINE_LIST = 0, 2
DELETE_MATCHING_ID = 0
INFO, WARNING = 2, 3

PALETTE = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22",
           "#7f7f7f")

# RGBA per cell class: unknown, free, occupied
_MAP_RGBA = np.array([[128, 128, 128, 60], [235, 235, 235, 255], [20, 20, 20, 255]], dtype=np.uint8)
_COVER_RGBA = np.array([[0, 0, 0, 0], [60, 200, 90, 140], [20, 90, 40, 200]], dtype=np.uint8)
_BELIEF_RGBA = np.array([[128, 128, 128, 80], [250, 250, 250, 200], [30, 30, 30, 230]], dtype=np.uint8)


def belief_topic(robot: str) -> str:
    return f"/viz/belief/{robot}"


def live_topics(robots: Sequence[str]) -> list[tuple[str, str]]:
    """Every (topic, schema) the fold of a run of ``robots`` writes, in a stable order: what a live server
    advertises from its start, before any client can subscribe."""
    return [(TOPIC_SCENE, "foxglove.SceneUpdate"), (TOPIC_TRUTH, "foxglove.Grid"), (TOPIC_COVERAGE, "foxglove.Grid"),
            *((belief_topic(r), "foxglove.Grid") for r in robots), (TOPIC_LOG, "foxglove.Log"),
            (TOPIC_STATS, SCHEMA_STATS)]


def schema_text(name: str) -> bytes:
    """The official JSON schema of ``foxglove.<Name>`` (shipped as package data), or the stats channel's."""
    if name == SCHEMA_STATS:
        return stats_schema_text()
    short = name.removeprefix("foxglove.")
    return (resources.files("fleet_emu.recording") / "schemas" / f"{short}.json").read_bytes()


def robot_rgb(robot: str, robots: list[str] | tuple[str, ...]) -> tuple[float, float, float]:
    i = list(robots).index(robot) if robot in robots else 0
    h = PALETTE[i % len(PALETTE)]
    return tuple(int(h[k:k + 2], 16) / 255 for k in (1, 3, 5))  # type: ignore[return-value]


@dataclasses.dataclass(frozen=True)
class Derived:
    """One derived message: written on ``topic`` with schema ``schema``, logged at ``tick``."""

    topic: str
    schema: str
    data: bytes
    tick: int

    def obj(self) -> Any:
        return json.loads(self.data)


def stamp(tick: int, clock: RunClock = EPOCH) -> dict[str, int]:
    return clock.stamp(tick)


def _vec(x: float, y: float, z: float) -> dict[str, float]:
    return {"x": float(x), "y": float(y), "z": float(z)}


def _pose(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> dict[str, Any]:
    return {"position": _vec(x, y, z), "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}


def _color(rgb: tuple[float, float, float], a: float = 1.0) -> dict[str, float]:
    return {"r": float(rgb[0]), "g": float(rgb[1]), "b": float(rgb[2]), "a": float(a)}


def _entity(eid: str, ts: dict[str, int], **prims: list[dict[str, Any]]) -> dict[str, Any]:
    e: dict[str, Any] = {
        "timestamp": ts, "frame_id": FRAME, "id": eid, "lifetime": {"sec": 0, "nsec": 0},
        "frame_locked": False, "metadata": prims.pop("metadata", []),
    }
    for k in ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models"):
        e[k] = prims.pop(k, [])
    return e


def _line(points: list[dict[str, float]], rgb: tuple[float, float, float], a: float, thickness: float,
          kind: int = LINE_STRIP) -> dict[str, Any]:
    return {"type": kind, "pose": _pose(), "thickness": thickness, "scale_invariant": True, "points": points,
            "color": _color(rgb, a), "colors": [], "indices": []}


def grid_message(values: np.ndarray, rgba_lut: np.ndarray, cell_size: float, tick: int, z: float = 0.0,
                 clock: RunClock = EPOCH) -> dict[str, Any]:
    """A ``foxglove.Grid`` of an occupancy array (row 0 at the top), drawn upright in frame ``map``."""
    v = np.asarray(values, dtype=np.int8)
    rows, cols = v.shape
    cls = np.where(v < 0, 0, np.where(v >= 50, 2, 1))
    packed = np.empty((rows, cols, 5), dtype=np.uint8)
    packed[..., 0] = v.view(np.uint8)
    packed[..., 1:] = rgba_lut[cls]
    data = np.ascontiguousarray(packed[::-1]).tobytes()  # grid data row 0 is y = 0: the map's bottom row
    fields = [{"name": "occupancy", "offset": 0, "type": INT8}]
    fields += [{"name": n, "offset": i + 1, "type": UINT8} for i, n in enumerate(("red", "green", "blue", "alpha"))]
    return {
        "timestamp": clock.stamp(tick), "frame_id": FRAME, "pose": _pose(0.0, 0.0, z), "column_count": cols,
        "cell_size": {"x": float(cell_size), "y": float(cell_size)}, "row_stride": cols * 5, "cell_stride": 5,
        "fields": fields, "data": base64.b64encode(data).decode("ascii"),
    }


def decode_grid(msg: dict[str, Any]) -> np.ndarray:
    """The occupancy array (row 0 at the top) back from a Grid message made by :func:`grid_message`."""
    raw = np.frombuffer(base64.b64decode(msg["data"]), dtype=np.uint8)
    cols = msg["column_count"]
    packed = raw.reshape(-1, msg["row_stride"])[:, : cols * msg["cell_stride"]].reshape(-1, cols, msg["cell_stride"])
    return packed[::-1, :, 0].view(np.int8).copy()


def _components(link: np.ndarray) -> int:
    """Number of connected groups of an (undirected) link matrix."""
    n = len(link)
    seen = np.zeros(n, dtype=bool)
    groups = 0
    for s in range(n):
        if seen[s]:
            continue
        groups += 1
        stack = [s]
        seen[s] = True
        while stack:
            i = stack.pop()
            for j in np.flatnonzero((link[i] | link[:, i]) & ~seen):
                seen[j] = True
                stack.append(int(j))
    return groups


class FoxgloveFold:
    """Bus messages in, Foxglove messages out (see the module doc). Pure: no I/O, no clock: a fold fed
    messages (:meth:`fold`; ``core/fold.py``)."""

    def __init__(self, scenario: dict[str, Any], truth: np.ndarray | None = None, grid_every: int | None = None,
                 run_id: str = "", base_cell: tuple[int, int] | None = None, clock: RunClock = EPOCH) -> None:
        self.scenario = scenario
        self.clock = clock
        self.base_cell = base_cell  # the base station's cell (``world.build.base_cell``), in a run with one
        self.run_id = run_id
        self.robots = tuple(robot_ids(scenario["robots"]))
        self.cell_size = float(scenario["cell_size"])
        self.threshold = float(scenario.get("radio", {}).get("threshold", 0.0))
        self.grid_every = max(1, int(grid_every or scenario.get("belief_every") or 10))
        self.truth = None if truth is None else np.asarray(truth, dtype=np.int8)
        self.shape: tuple[int, int] | None = None if truth is None else self.truth.shape  # type: ignore[union-attr]
        self.coverage: FirstSeen | None = None  # the cells the team sensed (from the first observation on)
        self.states: dict[int, WorldState] = {}
        self.links: dict[int, Links] = {}
        self.cmds: dict[int, dict[str, Command]] = {}
        self.targets: dict[str, tuple[int, int] | None] = {}
        self.emitted: set[str] = set()  # scene entity ids currently shown
        self.flushed = -1  # last tick whose scene was emitted
        self.live: tuple[str, ...] | None = None
        self.milestones = sorted({*MILESTONES, float(scenario.get("target_coverage", 1.0))})
        self.connected: bool | None = None
        self.belief_tick: dict[str, int] = {}
        self.started = False
        self.ended = False
        self.truth_sent = False
        self.stats = TickStats(self.robots, base=base_cell is not None)

    # --- input ------------------------------------------------------------------------------------------

    def fold(self, msg: Message) -> list[Derived]:
        """One decoded, checked message in; the Foxglove messages it completes (a ``MessageFold``,
        ``core/fold.py``)."""
        out: list[Derived] = []
        if isinstance(msg, Observation):
            self._observe(msg)
        elif isinstance(msg, WorldState) and msg.src == "world":
            out += self._state(msg)
        elif isinstance(msg, Links) and msg.src == "netem":
            self.links[msg.tick] = msg
            out += self._connectivity(msg)
            out += self._advance()
        elif isinstance(msg, Command):
            if msg.tick > self.flushed:
                self.cmds.setdefault(msg.tick, {})[msg.src] = msg
                out += self._advance()
        elif isinstance(msg, BeliefSnapshot):
            out += self._belief(msg)
        elif isinstance(msg, Stop):
            out += self._stop(msg)
        return out

    def finish(self) -> list[Derived]:
        """Emit what is still pending (the last tick's scene and grids)."""
        return self._flush(max(self.states, default=self.flushed), final=True)

    # --- folds --------------------------------------------------------------------------------------------

    def _observe(self, o: Observation) -> None:
        self.coverage = fold_team(self.coverage, self.shape, o)
        self.shape = self.coverage.shape

    def _state(self, st: WorldState) -> list[Derived]:
        out: list[Derived] = []
        if not self.started:
            self.started = True
            alloc = self.scenario.get("allocator", {}).get("type", "?")
            out.append(self._log(st.tick, INFO, "launcher",
                                 f"run {self.run_id} started: {len(self.robots)} robots, {alloc}, "
                                 f"map {self.scenario.get('map')}"))
        if self.live is not None:
            for r in sorted(set(self.live) - set(st.live)):
                out.append(self._log(st.tick, WARNING, r, f"{r} failed at tick {st.tick} "
                                                          f"(left the barrier at {st.poses.get(r)})"))
        self.live = st.live
        while self.milestones and st.coverage >= self.milestones[0] - 1e-9:
            m = self.milestones.pop(0)
            out.append(self._log(st.tick, INFO, "world", f"coverage {m:.0%} reached at tick {st.tick} "
                                                         f"({st.coverage:.1%})"))
        self.states[st.tick] = st
        out += self._advance()
        return out

    def _ready(self, t: int) -> bool:
        """Whether tick ``t`` is complete: the next state is in (the world finished ``t``), and so are the links
        of ``t`` and the command of ``t`` of every robot the world still had next, the same in every engine and
        whatever order the processes' messages arrived in; or ``t`` is :data:`LAG` ticks old."""
        after = self.states.get(t + 1)
        if after is None:
            return False
        if max(self.states) - t >= LAG:
            return True
        return t in self.links and set(after.live) <= set(self.cmds.get(t, {}))

    def _advance(self) -> list[Derived]:
        """The scenes of the ticks now complete, in order (a tick waits for the ones before it)."""
        upto = self.flushed
        for t in sorted(t for t in self.states if t > self.flushed):
            if not self._ready(t):
                break
            upto = t
        return self._flush(upto) if upto > self.flushed else []

    def _connectivity(self, lk: Links) -> list[Derived]:
        if self.connected is None or bool(lk.connected) != self.connected:
            was = self.connected
            self.connected = bool(lk.connected)
            if was is not None or not lk.connected:
                groups = _components(np.asarray(lk.link, dtype=bool)) if len(lk.robots) else 0
                text = "team connected" if lk.connected else \
                    f"team split into {groups} radio groups" if groups > 1 else "team disconnected"
                return [self._log(lk.tick, INFO, "netem", f"{text} at tick {lk.tick}")]
        return []

    def _belief(self, b: BeliefSnapshot) -> list[Derived]:
        last = self.belief_tick.get(b.src)
        if last is not None and b.tick - last < self.grid_every:
            return []
        self.belief_tick[b.src] = b.tick
        z = 0.02 + 0.001 * (self.robots.index(b.src) if b.src in self.robots else 0)
        return [self._grid(belief_topic(b.src), b.grid, _BELIEF_RGBA, b.tick, z)]

    def _stop(self, s: Stop) -> list[Derived]:
        if s.src == "world":
            if self.ended:
                return []
            self.ended = True
            # what is complete now; the last tick's scene (and any still missing a command or links, which travel
            # apart from the stop and may reach the launcher after it) waits for finish()
            out = self._advance()
            cov = self.states[max(self.states)].coverage if self.states else 0.0
            level = INFO if s.reason == "coverage" else WARNING
            out.append(self._log(s.tick, level, "world", f"run ended at tick {s.tick}: {s.reason} "
                                                         f"(coverage {cov:.1%})"))
            return out
        return [self._log(s.tick, WARNING, s.src, f"{s.src} stopped the run at tick {s.tick}: {s.reason}")]

    # --- output -------------------------------------------------------------------------------------------

    def _flush(self, upto: int, final: bool = False) -> list[Derived]:
        """The scenes (and grids) of every pending tick up to ``upto``."""
        out: list[Derived] = []
        for t in sorted(t for t in self.states if self.flushed < t <= upto):
            last = final and t == upto
            out += self._scene(t)
            out.append(self._stats(t))
            if t % self.grid_every == 0 or last:
                out += self._maps(t)
            self.flushed = t
        for d in (self.states, self.links, self.cmds):
            for t in [t for t in d if t < self.flushed]:
                del d[t]
        return out

    def _maps(self, t: int) -> list[Derived]:
        out = []
        if self.truth is not None and not self.truth_sent:
            self.truth_sent = True
            out.append(self._grid(TOPIC_TRUTH, self.truth, _MAP_RGBA, t, 0.0))
        if self.coverage is not None:
            out.append(self._grid(TOPIC_COVERAGE, self.coverage.grid(t), _COVER_RGBA, t, 0.01))
        return out

    def _xy(self, cell: tuple[int, int]) -> tuple[float, float]:
        rows = self.shape[0] if self.shape else 0
        return (cell[1] + 0.5) * self.cell_size, (rows - cell[0] - 0.5) * self.cell_size

    def _scene(self, t: int) -> list[Derived]:
        """The tick's scene: the robots and their targets, the radio links, the base; entities shown before and
        not now are deleted."""
        st = self.states[t]
        lk = self.links.get(t)
        entities = self._robots(t, st)
        entities.append(self._links(t, st, lk))
        if self.base_cell is not None:
            entities.append(self._base_station(t, st, lk))
        shown = {e["id"] for e in entities}
        gone = sorted(self.emitted - shown)
        self.emitted = shown
        msg = {"deletions": [{"timestamp": self.clock.stamp(t), "type": DELETE_MATCHING_ID, "id": g} for g in gone],
               "entities": entities}
        return [_derived(TOPIC_SCENE, "foxglove.SceneUpdate", msg, t)]

    def _robots(self, t: int, st: WorldState) -> list[dict[str, Any]]:
        """Each robot at its true pose (a cube in its colour, grey once failed, and its name), and a live
        robot's target (a sphere, and a line to it) as its last command set it."""
        cs = self.cell_size
        cmds = self.cmds.get(t, {})
        entities: list[dict[str, Any]] = []
        for r in self.robots:
            if r not in st.poses:
                continue
            x, y = self._xy(st.poses[r])
            live = r in st.live
            rgb = robot_rgb(r, self.robots) if live else (0.5, 0.5, 0.5)
            cmd = cmds.get(r)
            if cmd is not None:
                self.targets[r] = cmd.target
            meta = [{"key": "cell", "value": str(tuple(st.poses[r]))}, {"key": "live", "value": str(live)},
                    {"key": "path_length", "value": str(st.path_length.get(r, 0))}]
            if cmd is not None:
                meta += [{"key": "status", "value": cmd.status}, {"key": "decision_ms", "value": str(cmd.decision_ms)}]
            entities.append(_entity(
                f"robot/{r}", self.clock.stamp(t), metadata=meta,
                cubes=[{"pose": _pose(x, y, 0.4 * cs), "size": _vec(0.8 * cs, 0.8 * cs, 0.8 * cs),
                        "color": _color(rgb)}],
                texts=[{"pose": _pose(x, y, 1.2 * cs), "billboard": True, "font_size": 14.0,
                        "scale_invariant": True, "color": _color((1.0, 1.0, 1.0)),
                        "text": r if live else f"{r} (failed)"}]))
            target = self.targets.get(r)
            if live and target is not None:
                tx, ty = self._xy(target)
                entities.append(_entity(
                    f"target/{r}", self.clock.stamp(t),
                    spheres=[{"pose": _pose(tx, ty, 0.3 * cs), "size": _vec(0.6 * cs, 0.6 * cs, 0.6 * cs),
                              "color": _color(rgb, 0.8)}],
                    lines=[_line([_vec(x, y, 0.4 * cs), _vec(tx, ty, 0.3 * cs)], rgb, 0.8, 2.0)]))
        return entities

    def _links(self, t: int, st: WorldState, lk: Links | None) -> dict[str, Any]:
        """The radio links between robots (either way) at the tick, coloured by signal strength, and whether
        the team's radio graph is connected."""
        lines, meta = [], []
        if lk is not None:
            link = np.asarray(lk.link, dtype=bool)
            strength = np.asarray(lk.strength, dtype=float)
            for i, a in enumerate(lk.robots):
                for j in range(i + 1, len(lk.robots)):
                    b = lk.robots[j]
                    if not (link[i, j] or link[j, i]) or a not in st.poses or b not in st.poses:
                        continue
                    line, label = self._signal(self._xy(st.poses[a]), self._xy(st.poses[b]),
                                               max(strength[i, j], strength[j, i]))
                    lines.append(line)
                    meta.append({"key": f"{a}-{b}", "value": label})
            meta.append({"key": "connected", "value": str(bool(lk.connected))})
        return _entity("links", self.clock.stamp(t), lines=lines, metadata=meta)

    def _signal(self, a: tuple[float, float], b: tuple[float, float], p: float) -> tuple[dict[str, Any], str]:
        """A radio link from ``a`` to ``b`` (map coordinates) of strength ``p`` dB (not finite: the threshold):
        a line from red at the threshold to green 20 dB above it, and its label."""
        p = float(p) if np.isfinite(p) else self.threshold
        s = float(np.clip((p - self.threshold) / 20.0, 0.0, 1.0))
        z = 0.5 * self.cell_size
        return _line([_vec(a[0], a[1], z), _vec(b[0], b[1], z)], (1.0 - s, s, 0.2), 0.9, 3.0, LINE_LIST), \
            f"{p:.1f} dB"

    def _base_station(self, t: int, st: WorldState, lk: Links | None) -> dict[str, Any]:
        """The base station: a white cylinder at its cell, and a line to each robot linked to it (coloured by
        signal strength as the robots' links)."""
        assert self.base_cell is not None
        cs = self.cell_size
        bx, by = self._xy(self.base_cell)
        lines, meta = [], [{"key": "cell", "value": str(tuple(self.base_cell))}]
        if lk is not None and lk.base_link is not None and lk.base_strength is not None:
            for r, linked, p in zip(lk.robots, lk.base_link, lk.base_strength, strict=True):
                if not linked or r not in st.poses:
                    continue
                line, label = self._signal((bx, by), self._xy(st.poses[r]), p)
                lines.append(line)
                meta.append({"key": f"base-{r}", "value": label})
        return _entity(
            "base", self.clock.stamp(t), metadata=meta, lines=lines,
            cylinders=[{"pose": _pose(bx, by, 0.6 * cs), "size": _vec(0.9 * cs, 0.9 * cs, 1.2 * cs),
                        "bottom_scale": 1.0, "top_scale": 0.6, "color": _color((1.0, 1.0, 1.0))}],
            texts=[{"pose": _pose(bx, by, 1.6 * cs), "billboard": True, "font_size": 14.0, "scale_invariant": True,
                    "color": _color((1.0, 1.0, 0.6)), "text": "base"}])

    def _grid(self, topic: str, values: np.ndarray, lut: np.ndarray, tick: int, z: float) -> Derived:
        return _derived(topic, "foxglove.Grid", grid_message(values, lut, self.cell_size, tick, z, self.clock), tick)

    def _stats(self, t: int) -> Derived:
        """The tick's ``/viz/stats`` message (the next tick's state, when already in, tells who stood)."""
        msg = self.stats.tick(self.clock.stamp(t), self.states[t], self.links.get(t), self.cmds.get(t, {}),
                              self.states.get(t + 1))
        return _derived(TOPIC_STATS, SCHEMA_STATS, msg, t)

    def _log(self, tick: int, level: int, name: str, text: str) -> Derived:
        msg = {"timestamp": self.clock.stamp(tick), "level": level, "message": text, "name": name, "file": "",
               "line": 0}
        return _derived(TOPIC_LOG, "foxglove.Log", msg, tick)


def _derived(topic: str, schema: str, obj: Any, tick: int) -> Derived:
    return Derived(topic, schema, json.dumps(obj, separators=(",", ":")).encode(), tick)
