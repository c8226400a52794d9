"""The terminal tables of a run: its summary (``fleet run``'s closing table and ``fleet report``'s, one renderer
of the one vocabulary), and several runs side by side (``fleet report --compare``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rich.table import Table

from fleet_emu.core.keys import robot_ids
from fleet_emu.core.radio import airtime_line, bytes_line, radio_label
from fleet_emu.recording.read import Run
from fleet_emu.recording.relaystats import relay_line


def fmt(v: Any, pct: bool = False) -> str:
    """A value for a table cell: ``-`` for None, a percentage, or three significant digits."""
    if v is None:
        return "-"
    if pct:
        return f"{v:.1%}"
    if isinstance(v, float):
        return f"{v:.3g}" if abs(v) < 1000 else f"{v:.0f}"
    return str(v)


def _each(values: dict[str, Any], pct: bool = False) -> str:
    return ", ".join(f"{k} {fmt(v, pct)}" for k, v in values.items())


def summary_table(m: Mapping[str, Any], out_dir: str | None = None, title: str | None = None) -> Table:
    """The one summary of a run, a row each: ``fleet run``'s closing table from its ``result.json`` (``out_dir``:
    where its files are), and ``fleet report``'s from its ``metrics.json`` (the same keys, and the analysis
    groups: their rows where the data has them). ``title`` defaults to ``run RUN_ID``."""
    t = Table(title=title or f"run {m['run_id']}", show_header=False, title_justify="left")
    t.add_column("metric", style="bold")
    t.add_column("value")
    for k, v in [*_outcome_rows(m), *_team_rows(m), *_radio_rows(m), *_process_rows(m)]:
        t.add_row(k, v)
    if out_dir is not None:
        t.add_row("output", out_dir)
    return t


def _outcome_rows(m: Mapping[str, Any]) -> list[tuple[str, str]]:
    """What ran and how it ended: coverage, ticks, the first ticks at 90/99(/100) %, the path travelled."""
    hosts = (m.get("pids") or {}).get("hosts")  # robots on other machines (`fleet host`): which ran where
    path = m["path_length"]
    cut = "  [yellow]recording cut[/yellow]" if m.get("truncated") else ""
    return [
        ("map / allocator", f"{m['map']} / {m['allocator']}"),
        ("robots / seed", f"{m['robots']} / {m['seed']}"),
        ("radio", radio_label(m["comm"], m["loss"])),
        ("completed", f"{m['completed']} ({m['reason']})" + cut),
        ("failed robots", ", ".join(m["failed"]) or "none"),
        *([("on hosts", "; ".join(f"{h}: {', '.join(rs)}" for h, rs in hosts.items()))] if hosts else []),
        ("coverage", fmt(m["coverage"], True)),
        ("ticks", str(m["ticks"])),
        ("t90 / t99" + (" / t100" if "t100" in m else ""),
         " / ".join(fmt(m[k]) for k in ("t90", "t99", "t100") if k in m)),
        ("path length", f"{sum(path)} cells ({_each(dict(zip(robot_ids(len(path)), path, strict=True)))})"),
        ("idle robot-ticks", _idle(m)),
    ]


def _team_rows(m: Mapping[str, Any]) -> list[tuple[str, str]]:
    """How the team shared the work and kept in touch: the report's analysis groups where present."""
    rows = []
    if "efficiency" in m:
        sh = m["share"]
        rows += [("efficiency", f"{fmt(m['efficiency']['value'])} free cells sensed per cell travelled"),
                 ("overlap", f"{m['overlap']['cells']} cells sensed by 2+ robots "
                             f"({fmt(m['overlap']['fraction'], True)})"),
                 ("share (first sensed)", _each(sh["share"], pct=True)),
                 ("evenness", f"Jain {fmt(sh['jain'])}, Gini {fmt(sh['gini'])}")]
    rows.append(("connected", fmt(m["connected_fraction"], True)))
    if "connectivity" in m:
        rows.append(("link time per pair", _each(m["connectivity"]["pair_link_fraction"], pct=True) or "-"))
    if m.get("base_connected_fraction"):
        rows.append(("base connected", _base(m)))
    return rows


def _radio_rows(m: Mapping[str, Any]) -> list[tuple[str, str]]:
    """The radio's counts, its airtime on a limited radio, relaying, and the bytes sent (per robot where known)."""
    radio = m["radio"]
    rows = [("radio msgs", f"sent {radio['sent']}, delivered {radio['delivered']}, lost {radio['dropped_loss']}, "
                           f"out of range {radio['dropped_signal']}")]
    if (air := airtime_line(radio, (m.get("scenario") or {}).get("radio", {}))) is not None:
        rows.append(("airtime", air))
    if m.get("relay"):
        rows.append(("relaying", relay_line(m["relay"])))
    per = radio.get("per_robot")
    rows.append(("bytes sent", bytes_line(radio["bytes_sent"], m["robots"], m["ticks"]) + (
        f" ({_each({r: v['bytes_per_tick'] for r, v in per.items()})})" if per else "")))
    return rows


def _process_rows(m: Mapping[str, Any]) -> list[tuple[str, str]]:
    """The decisions' time, real time, the speed, the recording."""
    dm = m["decision_ms"]
    full = "calls" in dm  # the report's: the median, the largest and how many, too
    rows = [("decision ms", f"mean {fmt(dm['mean'])}" + (f", p50 {fmt(dm['p50'])}" if full else "")
             + f", p95 {fmt(dm['p95'])}" + (f", max {fmt(dm['max'])} ({dm['calls']} calls)" if full else ""))]
    if m.get("realtime"):
        rows.append(("real time", _realtime(m)))
    wall = f" ({m['wall_seconds']} s)" if "wall_seconds" in m else ""
    rows.append(("speed", f"{fmt(m.get('ticks_per_second'))} ticks/s{wall}"))
    rec = m["recording"]
    rows.append(("recording", f"{rec['messages']} messages" if rec["path"] else "off"))
    return rows


def _realtime(m: Mapping[str, Any]) -> str:
    """A real-time run: the rate asked and achieved, the world's overruns, late commands per robot."""
    rt = m["realtime"]
    late = ", ".join(f"{r} {row['late_commands']}" for r, row in rt["robots"].items())
    return (f"{m['realtime_hz']:g} Hz asked, {rt['ticks_per_second']} ticks/s, {rt['world_overruns']} "
            f"overruns; late commands {rt['late_commands']} ({late})")


def _idle(m: Mapping[str, Any]) -> str:
    """Idle robot-ticks, with their split by the robots' status (``WAITING`` in a protocol round, ``ASSIGNED``
    but blocked)."""
    by = m.get("idle_by_status") or {}
    split = ", ".join(f"{k.lower()} {v}" for k, v in sorted(by.items()))
    return fmt(m.get("idle_robot_ticks")) + (f" ({split})" if split else "")


def _base(m: Mapping[str, Any]) -> str:
    """The base-station rows: the base-connected fractions and what its team map holds."""
    f, b = m["base_connected_fraction"], m.get("base") or {}
    return (f"{fmt(f['overall'], True)} of robot-ticks, all {fmt(f['all_ticks'], True)} of ticks "
            f"({_each(f['per_robot'], pct=True)}); base at {b.get('cell')} knows {fmt(b.get('known_fraction'), True)}"
            f" of the map")


COMPARE_ROWS = (
    ("map", lambda m: m["map"]),
    ("allocator", lambda m: m["allocator"]),
    ("robots", lambda m: m["robots"]),
    ("radio", lambda m: radio_label(m["comm"], m["loss"])),
    ("completed", lambda m: f"{m['completed']} ({m['reason']})"),
    ("coverage", lambda m: fmt(m["coverage"], True)),
    ("ticks", lambda m: m["ticks"]),
    ("t90", lambda m: fmt(m["t90"])),
    ("t99", lambda m: fmt(m["t99"])),
    ("t100", lambda m: fmt(m["t100"])),
    ("path", lambda m: m["path"]["total"]),
    ("efficiency", lambda m: fmt(m["efficiency"]["value"])),
    ("overlap", lambda m: fmt(m["overlap"]["fraction"], True)),
    ("Jain", lambda m: fmt(m["share"]["jain"])),
    ("connected", lambda m: fmt(m["connected_fraction"], True)),
    ("delivered", lambda m: fmt(m["radio"]["delivered_fraction"], True)),
    ("B/robot/tick", lambda m: fmt(m["radio"]["bytes_per_robot_per_tick"])),
    ("decision ms", lambda m: fmt(m["decision_ms"]["mean"])),
)


def compare_table(runs: list[Run]) -> Table:
    """One row per metric, one column per run (readable in a terminal for a handful of runs)."""
    t = Table(title="comparison", title_justify="left")
    t.add_column("metric", style="bold")
    for run in runs:
        t.add_column(run.name, justify="right", overflow="fold")
    t.add_row("run id", *(str(run.metrics["run_id"]) for run in runs))
    for name, get in COMPARE_ROWS:
        t.add_row(name, *(str(get(run.metrics)) for run in runs))
    return t
