"""The terminal tables of ``fleet report``: one run's summary, and several runs side by side (``--compare``)."""

from __future__ import annotations

from typing import Any

from rich.table import Table

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


def summary_table(run: Run) -> Table:
    """One run's metrics, a row each."""
    m = run.metrics
    t = Table(title=f"report {m['run_id']}  [dim]{run.path}[/dim]", show_header=False, title_justify="left")
    t.add_column("metric", style="bold")
    t.add_column("value")
    et, rd, conn, dt, sh = m["exploration_time"], m["radio_detail"], m["connectivity"], m["decision_time"], m["share"]
    pairs = _each(conn["pair_link_fraction"], pct=True)
    per_robot = rd["per_robot"]
    rows = [
        ("map / allocator", f"{m['map']} / {m['allocator']}"),
        ("robots / seed", f"{m['robots']} / {m['seed']}"),
        ("radio", radio_label(m["comm"], m["loss"])),
        ("completed", f"{m['completed']} ({m['reason']})" + ("  [yellow]recording cut[/yellow]"
                                                            if m.get("truncated") else "")),
        ("coverage", fmt(m["coverage"], True)),
        ("ticks", str(m["ticks"])),
        ("t90 / t99 / t100", f"{fmt(et['t90'])} / {fmt(et['t99'])} / {fmt(et['t100'])}"),
        ("path length", f"{m['path']['total']} cells ({_each(m['path']['per_robot'])})"),
        ("efficiency", f"{fmt(m['efficiency']['value'])} free cells sensed per cell travelled"),
        ("overlap", f"{m['overlap']['cells']} cells sensed by 2+ robots ({fmt(m['overlap']['fraction'], True)})"),
        ("share (first sensed)", _each(sh["share"], pct=True)),
        ("evenness", f"Jain {fmt(sh['jain'])}, Gini {fmt(sh['gini'])}"),
        ("connected", fmt(m["connected_fraction"], True)),
        ("link time per pair", pairs or "-"),
        *([("base connected", _base(m))] if m.get("base_connected_fraction") else []),
        ("radio msgs", f"sent {rd['sent']}, delivered {rd['delivered']}, lost {rd['dropped']['loss']}, "
                       f"out of range {rd['dropped']['signal']}"),
        *([("relaying", relay_line(m["relay"]))] if m.get("relay") else []),
        ("bytes sent", f"{bytes_line(m['radio']['bytes_sent'], m['robots'], m['ticks'])} "
                       f"({_each({r: v['bytes_per_tick'] for r, v in per_robot.items()})})"),
        *([("airtime", air)] if (air := airtime_line(m["radio"], m["scenario"].get("radio", {}))) else []),
        ("decision ms", f"mean {fmt(dt['mean_ms'])}, p50 {fmt(dt['p50_ms'])}, p95 {fmt(dt['p95_ms'])}, "
                        f"max {fmt(dt['max_ms'])} ({dt['calls']} calls)"),
        ("recording", f"{m['recording']['messages']} messages"),
    ]
    for k, v in rows:
        t.add_row(k, v)
    return t


def _base(m: dict[str, Any]) -> str:
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
    ("t90", lambda m: fmt(m["exploration_time"]["t90"])),
    ("t99", lambda m: fmt(m["exploration_time"]["t99"])),
    ("t100", lambda m: fmt(m["exploration_time"]["t100"])),
    ("path", lambda m: m["path"]["total"]),
    ("efficiency", lambda m: fmt(m["efficiency"]["value"])),
    ("overlap", lambda m: fmt(m["overlap"]["fraction"], True)),
    ("Jain", lambda m: fmt(m["share"]["jain"])),
    ("connected", lambda m: fmt(m["connected_fraction"], True)),
    ("delivered", lambda m: fmt(m["radio_detail"]["delivered_fraction"], True)),
    ("B/robot/tick", lambda m: fmt(m["radio_detail"]["bytes_per_robot_per_tick"])),
    ("decision ms", lambda m: fmt(m["decision_time"]["mean_ms"])),
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
