"""The user's view of a run as it goes: a live progress bar (coverage and tick). The closing summary table is
:func:`fleet_emu.recording.tables.summary_table`, the one ``fleet report`` prints too."""

from __future__ import annotations

from rich.console import Console
from rich.progress import BarColumn, TextColumn, TimeElapsedColumn
from rich.progress import Progress as RichProgress

from fleet_emu.core.scenario import Scenario
from fleet_emu.recording.monitor import Monitor


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
