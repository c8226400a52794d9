"""The user's view of a run: a live progress bar (coverage and tick) and the closing summary table."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from rich.console import Console
from rich.progress import BarColumn, TextColumn, TimeElapsedColumn
from rich.progress import Progress as RichProgress
from rich.table import Table

from fleet_emu.core.radio import airtime_line, bytes_line, radio_label
from fleet_emu.core.scenario import Scenario
from fleet_emu.recording.monitor import Monitor
from fleet_emu.recording.relaystats import relay_line


class Progress:
    """Coverage bar to the target, with the tick; silent with ``quiet`` or when stderr is not a terminal."""

    def __init__(self, scenario: Scenario, run_id: str, console: Console, quiet: bool = False) -> None:
        self.scenario = scenario
        self.enabled = not quiet
        self._bar = RichProgress(
            TextColumn("[bold]{task.description}"), BarColumn(), TextColumn("coverage {task.fields[cov]:6.1%}"),
            TextColumn("tick {task.fields[tick]:>5}/{task.fields[max]}"), TimeElapsedColumn(),
            console=console, transient=False, disable=quiet)
        self._task = self._bar.add_task(f"{scenario.allocator['type']} x{scenario.robots} on {scenario.map}",
                                        total=scenario.target_coverage, cov=0.0, tick=0, max=scenario.max_ticks)
        self._console = console
        self._run_id = run_id
        self._started = False

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._started:
            self._bar.stop()

    def update(self, monitor: Monitor) -> None:
        """Show the run's progress; the first call (once the fleet is starting, every check passed) shows
        the run id and starts the bar, so that bad input stays one line on stderr."""
        if not self._started:
            self._started = True
            if self.enabled:
                self._console.print(f"[dim]run {self._run_id}[/dim]")
            self._bar.start()
        self._bar.update(self._task, completed=min(monitor.coverage, self.scenario.target_coverage),
                         cov=monitor.coverage, tick=monitor.tick)


def summary_table(result: Mapping[str, Any], out_dir: str) -> Table:
    """The closing table of ``fleet run``."""
    t = Table(title=f"run {result['run_id']}", show_header=False, title_justify="left")
    t.add_column("metric", style="bold")
    t.add_column("value")
    radio = result["radio"]
    rows = [
        ("map / allocator", f"{result['map']} / {result['allocator']}"),
        ("robots / seed", f"{result['robots']} / {result['seed']}"),
        ("radio", radio_label(result["comm"], result["loss"])),
        ("completed", f"{result['completed']} ({result['reason']})"),
        ("failed robots", ", ".join(result["failed"]) or "none"),
        ("coverage", f"{result['coverage']:.1%}"),
        ("ticks", str(result["ticks"])),
        ("t90 / t99", f"{_shown(result['t90'])} / {_shown(result['t99'])}"),
        ("path length", f"{sum(result['path_length'])} cells ({', '.join(map(str, result['path_length']))})"),
        ("idle robot-ticks", _idle(result)),
        ("connected", "-" if result["connected_fraction"] is None else f"{result['connected_fraction']:.1%}"),
        ("radio msgs", f"sent {radio['sent']}, delivered {radio['delivered']}, lost {radio['dropped_loss']}, "
                       f"out of range {radio['dropped_signal']}"),
        ("bytes sent", bytes_line(radio["bytes_sent"], result["robots"], result["ticks"])),
        ("decision ms", f"mean {result['decision_ms']['mean']:.2f}, p95 {result['decision_ms']['p95']:.2f}"),
        ("speed", f"{result['ticks_per_second']} ticks/s ({result['wall_seconds']} s)"),
        ("recording", f"{result['recording']['messages']} messages" if result["recording"]["path"] else "off"),
        ("output", out_dir),
    ]
    if result.get("realtime"):
        rows.insert(-3, ("real time", _realtime(result)))
    if result.get("base_connected_fraction"):
        rows.insert(11, ("base connected", _base(result)))
    if result.get("relay"):
        rows.insert(-4, ("relaying", relay_line(result["relay"])))
    air = airtime_line(radio, result.get("scenario", {}).get("radio", {}))
    if air is not None:
        rows.insert(rows.index(next(r for r in rows if r[0] == "radio msgs")) + 1, ("airtime", air))
    hosts = (result.get("pids") or {}).get("hosts")
    if hosts:  # robots on other machines (`fleet host`): which ran where
        rows.insert(rows.index(next(r for r in rows if r[0] == "failed robots")) + 1,
                    ("on hosts", "; ".join(f"{h}: {', '.join(rs)}" for h, rs in hosts.items())))
    for k, v in rows:
        t.add_row(k, v)
    return t


def _shown(value: Any) -> str:
    """A value of the summary: ``-`` for one the run has none of (t90 of a run that never reached 90 %)."""
    return "-" if value is None else str(value)


def _realtime(result: Mapping[str, Any]) -> str:
    """A real-time run: the rate asked and achieved, the world's overruns, late commands per robot."""
    rt = result["realtime"]
    late = ", ".join(f"{r} {row['late_commands']}" for r, row in rt["robots"].items())
    return (f"{result['realtime_hz']:g} Hz asked, {rt['ticks_per_second']} ticks/s, {rt['world_overruns']} "
            f"overruns; late commands {rt['late_commands']} ({late})")


def _base(result: Mapping[str, Any]) -> str:
    """A run with a base station: the fractions connected to it, and what its map holds."""
    f, b = result["base_connected_fraction"], result.get("base") or {}

    def pct(v: float | None) -> str:
        return "-" if v is None else f"{v:.1%}"

    per = ", ".join(f"{r} {pct(v)}" for r, v in f["per_robot"].items())
    return (f"{pct(f['overall'])} of robot-ticks, all {pct(f['all_ticks'])} of ticks ({per}); "
            f"base at {b.get('cell')} knows {pct(b.get('known_fraction'))} of the map")


def _idle(result: Mapping[str, Any]) -> str:
    """Idle robot-ticks, with their split by the robots' status (``WAITING`` in a protocol round,
    ``ASSIGNED`` but blocked)."""
    by = result.get("idle_by_status") or {}
    split = ", ".join(f"{k.lower()} {v}" for k, v in sorted(by.items()))
    return _shown(result.get("idle_robot_ticks")) + (f" ({split})" if split else "")
