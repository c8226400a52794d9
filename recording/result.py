"""A run's ``result.json``: the one module that writes its keys, for every engine and for ``fleet recover``.

:func:`build_result` makes the whole file from the launcher's fold of the run's messages
(:class:`~fleet_emu.recording.monitor.Monitor`), how the run ended (:class:`Ending`: the one place ``reason`` is
decided) and what the launcher process alone knows (:class:`Launcher`). The processes engine
(``launch/runner.py``), the memory engine (``launch/memory.py``), ``fleet report``'s recomputation
(``recording/metrics.py``) and ``fleet recover`` (``recording/recover.py``) call it, and nothing adds a key
afterwards. The JSON Schema lies beside this file (``result.schema.json``); docs/reference/result.md documents
each key. :class:`Result` is what the Python API gives back.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
from collections.abc import Iterator, Mapping
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from fleet_emu.core.fields import Setting
from fleet_emu.core.radio import RadioConfig, radio_settings
from fleet_emu.core.version import SCHEMA_VERSION, __version__

if TYPE_CHECKING:
    from fleet_emu.core.messages import Links, WorldState
    from fleet_emu.recording.monitor import Monitor

#: ``result.json`` keys that depend on the clock, the processes, the engine or the bus, not on the seed: every
#: other key is the same for a seed whatever the engine (docs/design/determinism.md).
UNTIMED = frozenset({"run_id", "decision_ms", "robot_peak_rss_kb", "agent_peak_rss_kb", "ticks_per_second", "pids",
                     "recording",
                     "wall_seconds", "engine", "authenticated", "signal", "bus"})


@dataclasses.dataclass(frozen=True)
class Ending:
    """How a run ended beyond what its messages say: a signal stopped it (``interrupted``), it failed (``error``,
    its one line; ``""`` when a recording shows that it failed but not why), or its launcher died and
    ``fleet recover`` rebuilds its result from the recording (``crashed``)."""

    interrupted: bool = False
    error: str | None = None
    crashed: bool = False

    def reason(self, told: str | None) -> str | None:
        """``result.json``'s ``reason``, the only place it is decided: ``told`` (the world's stop, or its last
        state's reason) unless the launcher saw the run end otherwise."""
        if self.crashed:
            return "crashed"
        if self.interrupted:
            return "interrupted"
        return "error" if self.error is not None else told


@dataclasses.dataclass(frozen=True)
class Launcher:
    """What the launcher process alone knows, none of it on the bus (so a recording cannot give it back,
    :data:`NOT_RECORDED`): its wall time for the run, the signal that ended the run, whether the bus was
    authenticated (None without a bus), and ``bus`` (the nonce and foreign drops; None on the memory engine)."""

    wall_seconds: float
    signal: str | None
    authenticated: bool | None
    bus: dict[str, Any] | None = None


#: ``result.json`` keys that a recording cannot give back: :class:`Launcher`'s fields.
NOT_RECORDED = tuple(f.name for f in dataclasses.fields(Launcher))


#: Keys renamed, old name -> new (``outer.inner`` for a key inside another): ``result.json`` writes the old
#: name too, with the same value, until the next release; the schema marks it deprecated.
RENAMED = {"agent_peak_rss_kb": "robot_peak_rss_kb", "pids.agents": "pids.robots"}


def build_result(monitor: Monitor, scenario: dict[str, Any], run_id: str, ending: Ending, *,
                 engine: str | None, pids: dict[str, Any], recording: str | None, messages: int,
                 launcher: Launcher | None, realtime_hz: float | None = None) -> dict[str, Any]:
    """The whole of ``result.json``: the monitor's figures, then the run's engine, process ids, recording
    (``{path, messages}``), scenario and the :class:`Launcher` keys (absent when ``launcher`` is None: a result
    recomputed from a recording). ``engine`` None (a recording older than the key) leaves it out;
    ``realtime_hz`` is the rate asked, kept when the run stopped before the world's first clock."""
    data = fold_keys(monitor, scenario, run_id, scenario["target_coverage"], ending)
    if realtime_hz:
        data.setdefault("realtime_hz", realtime_hz)
    data |= ({"engine": engine} if engine is not None else {}) | {
        "pids": pids, "recording": {"path": recording, "messages": messages}, "scenario": scenario}
    for old, new in RENAMED.items():  # the old name beside the new, for one release
        outer, _, inner = new.partition(".")
        if inner and inner in data[outer]:
            data[outer] = {**data[outer], old.partition(".")[2]: data[outer][inner]}
        elif not inner and new in data:
            data[old] = data[new]
    if launcher is not None:
        data |= {"wall_seconds": round(max(launcher.wall_seconds, 0.0), 3), "signal": launcher.signal,
                 "authenticated": launcher.authenticated} | ({"bus": launcher.bus} if launcher.bus is not None
                                                             else {})
    return data


def fold_keys(m: Monitor, scenario: dict[str, Any], run_id: str, target: float,
              ending: Ending = Ending()) -> dict[str, Any]:
    """The keys the launcher's fold gives (docs/reference/result.md): all but the engine's, the process ids,
    the recording, the scenario and :class:`Launcher`'s."""
    st, lk = m.state, m.links
    ms = np.array(m.decision_ms) if m.decision_ms else np.zeros(1)
    idle = m.idle()
    reason = ending.reason((m.stop.reason if m.stop else None) or (st.reason if st else None))
    radio = scenario["radio"]
    return {
        "run_id": run_id, "seed": scenario["seed"], "map": scenario["map"],
        "allocator": scenario["allocator"]["type"], "allocator_params": allocator_params(scenario),
        "robots": scenario["robots"], "loss": radio["loss"], "comm": radio["comm"],
        "loss_applied": RadioConfig(comm=radio["comm"], loss=radio["loss"]).applied_loss,
        "ticks": st.tick if st else 0,
        "completed": bool(st is not None and st.coverage >= target and not ending.crashed),
        "reason": reason,
        **({"error": ending.error} if reason == "error" and ending.error else {}),
        "coverage": round(st.coverage, 6) if st else 0.0,
        "t90": m.t90, "t99": m.t99,
        "path_length": [st.path_length.get(r, 0) if st else 0 for r in m.robots],
        "idle_robot_ticks": sum(idle.values()), "idle_by_status": idle,
        "connected_fraction": round(m.connected_ticks / m.link_ticks, 6) if m.link_ticks else None,
        "radio": {"sent": lk.sent if lk else 0, "delivered": lk.delivered if lk else 0,
                  "dropped_loss": lk.dropped_loss if lk else 0, "dropped_signal": lk.dropped_signal if lk else 0,
                  "bytes_sent": lk.bytes_sent if lk else 0} | _airtime(lk) | _prediction(lk, radio),
        "decision_ms": {"mean": round(float(ms.mean()), 4), "p95": round(float(np.percentile(ms, 95)), 4)},
        "failed": m.failed(),
        "malformed_dropped": sum(m.dropped_by().values()), "malformed_dropped_by": m.dropped_by(),
        "robot_peak_rss_kb": {r: rep.peak_rss_kb for r, rep in sorted(m.reports.items())},
        "ticks_per_second": m.ticks_per_second(),
        "schema_version": SCHEMA_VERSION, "fleet_emu": __version__,
    } | (_realtime(m) if m.clock is not None else {}) | (_base(m) if m.base else {}) | (
        {"relay": {"policy": scenario.get("relay", "none"), "ttl": scenario.get("relay_ttl", 0),
                   "kinds": m.relay_stats.result()}} if m.relay_stats is not None else {}) | _faults(scenario, st)


def _airtime(lk: Links | None) -> dict[str, Any]:
    """``radio``'s airtime keys from the last links: bytes on the air, queue drops, the largest queue, and the
    delay (ticks from hand-off to delivery) of the messages emitted, ``mean``, ``p95`` (nearest rank) and
    ``max`` (null values when none was)."""
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


def _prediction(lk: Links | None, radio: dict[str, Any]) -> dict[str, Any]:
    """``radio.prediction`` in a run with shadowing (``shadowing_db`` > 0; nothing otherwise): the robot pairs
    over the ticks, and those whose link eq. 4 without the field called wrongly
    (``netem.channel.count_predictions``)."""
    if not radio.get("shadowing_db"):
        return {}
    return {"prediction": {"pair_ticks": lk.pair_ticks if lk else 0, "false_links": lk.false_links if lk else 0,
                           "missed_links": lk.missed_links if lk else 0}}


def _faults(scenario: dict[str, Any], st: WorldState | None) -> dict[str, Any]:
    """``faults``, in a run whose scenario has some (docs/guides/faults.md): the entries of a tick the run
    reached, applied; and ``blocked_by``, in a run that missed its target where a failed robot's body cuts the
    live robots off from cells still to sense: each such robot, its cell and how many cells it holds off
    (``world.sim.World.blocking``)."""
    from fleet_emu.core.faults import applied

    out: dict[str, Any] = {}
    if "faults" in scenario:
        out["faults"] = applied(scenario["faults"], st.tick if st else 0)
    if st is not None and st.blocked:
        out["blocked_by"] = {r: {"cell": list(st.poses[r]), "cut_off": n} for r, n in sorted(st.blocked.items())
                             if r in st.poses}
    return out


def allocator_params(scenario: dict[str, Any]) -> dict[str, Any]:
    """``allocator_params``: every parameter the allocator ran with, defaults filled in
    (:func:`fleet_emu.agents.brain.effective_allocator`); the scenario's table as given when its allocator cannot
    be loaded here (a report, on another machine, of a run whose plugin is not installed)."""
    from fleet_emu.agents.brain import effective_allocator  # at the end of a run only: the brain is heavy
    from fleet_emu.core.errors import FleetError
    from fleet_emu.core.scenario import Scenario

    try:
        return effective_allocator(Scenario.from_dict(scenario))
    except FleetError:
        return dict(scenario["allocator"])


def _base(m: Monitor) -> dict[str, Any]:
    """A base-station run's keys: ``base_connected_fraction {overall, all_ticks, per_robot}`` (over the ticks
    netem published links for) and ``base {cell, known_cells, known_fraction, merged, ticks}`` (the base's
    report; null values when it sent none: interrupted, or its process died)."""
    frac = m.base_reach.summary()
    rounded = {k: (round(v, 6) if isinstance(v, float) else v) for k, v in frac.items() if k != "per_robot"}
    rounded["per_robot"] = {r: round(v, 6) for r, v in frac["per_robot"].items()}
    rep = m.base_report
    base: dict[str, Any] = {
        "cell": list(rep.cell) if rep else None, "known_cells": rep.known_cells if rep else None,
        "known_fraction": round(rep.known_cells / rep.cells, 6) if rep else None,
        "merged": rep.merged if rep else None, "ticks": rep.ticks if rep else None}
    return {"base_connected_fraction": rounded, "base": base}


def _realtime(m: Monitor) -> dict[str, Any]:
    """A real-time run's keys (none in lockstep, which publishes no clock): ``realtime_hz``, and under
    ``realtime`` the world's ``overruns``, its achieved rate, the wall seconds at which coverage reached 0.9 and
    0.99 (``t90_s``, ``t99_s``: from tick 0's scheduled time), and per robot its ``late_commands`` (decisions
    applied a tick late), ``late_steps`` (steps along the last plan that came late), ``missed_ticks`` (no
    command at all: it stood), ``decisions``, ``plan_steps``, ``waits`` and its decision-time percentiles
    (``decision_ms``: the whole step in its worker thread; ``allocator_ms``)."""
    ck = m.clock
    assert ck is not None
    robots = {}
    for r in m.robots:
        tm = m.timing.get(r)
        robots[r] = {"late_commands": ck.late.get(r, 0), "late_steps": ck.late_steps.get(r, 0),
                     "missed_ticks": ck.missed.get(r, 0)} | (
            {"decisions": tm.decisions, "plan_steps": tm.plan_steps, "waits": tm.waits,
             "decision_ms": tm.decision_ms, "allocator_ms": tm.allocator_ms} if tm is not None else
            {"decisions": None, "plan_steps": None, "waits": None, "decision_ms": None, "allocator_ms": None})

    def wall(tick: int | None) -> float | None:  # the world's wall seconds at ``tick`` since tick 0 was scheduled
        at = m.elapsed.get(tick) if tick is not None else None
        return round(at, 3) if at is not None else None

    return {"realtime_hz": ck.hz, "realtime": {
        "world_overruns": ck.overruns, "elapsed_s": round(ck.elapsed, 3), "t90_s": wall(m.t90), "t99_s": wall(m.t99),
        "ticks_per_second": round(ck.tick / ck.elapsed, 3) if ck.elapsed > 0 else None,
        "late_commands": sum(ck.late.values()), "robots": robots}}


# --- reading a result ------------------------------------------------------------------------------------------

def deterministic(data: Mapping[str, Any]) -> dict[str, Any]:
    """``result.json`` without the :data:`UNTIMED` keys, nor the scenario's ``hosts`` (where the robots ran):
    what a seed reproduces on every engine, on one machine or several."""
    out = {k: v for k, v in data.items() if k not in UNTIMED}
    if isinstance(out.get("scenario"), dict) and "hosts" in out["scenario"]:
        out["scenario"] = {k: v for k, v in out["scenario"].items() if k != "hosts"}
    return out


def unexpected_failures(data: Mapping[str, Any]) -> list[str]:
    """The robots of ``result.json``'s ``failed`` that no fault of the scenario crashed (``faults``): the failures
    nobody asked for, which make a run's exit code 1 and a study's row failed."""
    crashed = {f.get("robot") for f in data.get("faults", []) if isinstance(f, dict)}
    return [r for r in data.get("failed", []) if r not in crashed]


@dataclasses.dataclass(frozen=True)
class Result(Mapping[str, Any]):
    """A run's result: ``result["ticks"]`` (or ``result.ticks`` for the main keys) reads ``result.json``'s keys;
    :meth:`coverage_curve` gives coverage against ticks; ``out_dir`` is where the run's files are (None when
    nothing was kept)."""

    data: dict[str, Any]
    curve: tuple[tuple[int, float], ...] = ()
    out_dir: Path | None = None

    def __getitem__(self, key: str) -> Any:
        return self.data[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.data)

    def __len__(self) -> int:
        return len(self.data)

    @property
    def ticks(self) -> int:
        return int(self.data["ticks"])

    @property
    def completed(self) -> bool:
        return bool(self.data["completed"])

    @property
    def coverage(self) -> float:
        return float(self.data["coverage"])

    def coverage_curve(self) -> tuple[np.ndarray, np.ndarray]:
        """Ticks and the team's coverage at each (from the world's state messages)."""
        if not self.curve:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        ticks, cov = zip(*self.curve, strict=True)
        return np.asarray(ticks, dtype=np.int64), np.asarray(cov, dtype=float)

    def to_dict(self) -> dict[str, Any]:
        return dict(self.data)


def _schema_file(name: str) -> dict[str, Any]:
    schema: dict[str, Any] = json.loads((resources.files("fleet_emu.recording") / name).read_text())
    return schema


def scenario_schema(tables: dict[str, Any]) -> dict[str, Any]:
    """The schema of ``result.json``'s ``scenario`` (its ``$defs.scenario``), from the scenario's and the radio's
    declared settings (``core.fields.json_schema``: a field declared once is in it, with its range); ``tables``:
    the schema of each setting whose own code checks it (``$defs.scenario_tables``). ``python docs/hooks.py``
    writes it into ``result.schema.json``, and a test keeps the two equal."""
    from fleet_emu.core.fields import json_schema
    from fleet_emu.core.scenario import scenario_settings

    def table(specs: tuple[Setting, ...], given: dict[str, Any]) -> dict[str, Any]:
        return {"type": "object", "additionalProperties": False, "required": [s.name for s in specs if not s.quiet],
                "properties": {s.name: json_schema(s) or given[s.name] for s in specs}}
    return table(scenario_settings(), {**tables, "radio": table(radio_settings(), {})})


def result_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of ``result.json``, shipped in the package beside this module as
    ``fleet_emu/recording/result.schema.json`` (docs/reference/result.md documents each key)."""
    return _schema_file("result.schema.json")


def metrics_schema() -> dict[str, Any]:
    """The JSON Schema of ``fleet report``'s ``metrics.json``: :func:`result_schema` with ``metrics.schema.json``
    laid over it (a group of ``result.json``'s that the report adds to gains its properties), the launcher's own
    keys (:data:`NOT_RECORDED`) and their rule for ``error`` (a recording holds no failure's line) left out. The
    former groups it still writes are marked ``deprecated``."""
    schema, over = result_schema(), _schema_file("metrics.schema.json")
    props = schema["properties"]
    for key, spec in over["properties"].items():
        if key in props and "properties" in props[key]:
            spec = props[key] | spec | {"properties": props[key]["properties"] | spec["properties"],
                                        "required": props[key].get("required", []) + spec.get("required", [])}
        props[key] = spec
    schema["required"] = [k for k in schema["required"] if k not in NOT_RECORDED] + over["required"]
    schema["allOf"] = [rule for rule in schema["allOf"] if rule.get("then") != {"required": ["error"]}]
    schema["$defs"] |= over["$defs"]
    return schema | {k: over[k] for k in ("$id", "title", "description")}


@functools.cache
def _validator(name: str) -> Any:
    try:
        import jsonschema
    except ImportError:
        raise ImportError(f"validate_{name} needs the jsonschema package (pip install 'fleet-emu[dev]')") from None
    schema = result_schema() if name == "result" else metrics_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def validate_result(data: Mapping[str, Any]) -> None:
    """Check a run's ``result.json`` (or :attr:`Result.data`) against :func:`result_schema`, as it would be
    written (through JSON); ValueError listing every key that breaks it. Needs ``jsonschema`` (the test extra)."""
    _validate(data, "result")


def validate_metrics(data: Mapping[str, Any]) -> None:
    """Check ``fleet report``'s ``metrics.json`` (or ``Run.metrics``) against :func:`metrics_schema`, as
    :func:`validate_result` does a result."""
    _validate(data, "metrics")


def _validate(data: Mapping[str, Any], name: str) -> None:
    doc = json.loads(json.dumps(dict(data)))
    errors = sorted(_validator(name).iter_errors(doc), key=lambda e: list(map(str, e.absolute_path)))
    if errors:
        lines = [f"{'/'.join(map(str, e.absolute_path)) or '(top)'}: {e.message}" for e in errors]
        raise ValueError(f"{name}.json breaks its schema ({len(errors)} error(s)):\n  " + "\n  ".join(lines))

