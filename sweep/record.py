"""The runs a sweep keeps beside its rows: ``[study] record = "failed"`` (the default: the runs that failed or
ended without the target), ``"all"`` or ``"none"``. A kept run is a run folder, ``DIR/runs/ID`` (``result.json``,
``scenario.json``, ``map.npz``, ``run.mcap``; with the processes engine the process logs too), that ``fleet report``
and Foxglove open; its row names it in ``run_dir``.

A processes run records as it goes and its folder is removed when it is not kept (a failure there may not repeat).
A memory run is deterministic and cheaper without a recording: with ``"failed"`` it runs without one, and a run
to keep is run once more, recording, into its folder (the same seed gives the same run).
"""

from __future__ import annotations

import contextlib
import dataclasses
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

from fleet_emu.sweep.study import Point

RUNS = "runs"
#: The files of a run folder: a folder holding one of them holds a run.


@dataclasses.dataclass(frozen=True)
class Keep:
    """What a worker keeps: the study's ``record`` mode and the results folder (absolute, as the workers see it)."""

    mode: str
    results: str

    def folder(self, point_id: str) -> Path:
        return Path(self.results) / RUNS / point_id

    def relative(self, point_id: str) -> str:
        return f"{RUNS}/{point_id}"


def run_id(point: Point) -> str:
    """The run id of a sweep's run (and of its re-creation: ``fleet sweep rerun``)."""
    return f"sweep-{point.id}"


def run(point: Point, folder: Path | None, on_progress: Callable[[Any], None] | None = None,
        overwrite: bool = False) -> Any:
    """One run of a point, on its engine; into ``folder`` with its recording, or keeping nothing;
    ``on_progress`` is told the run's monitor as it goes (a kept run's)."""
    from fleet_emu.core.scenario import Scenario

    scenario = Scenario.from_dict(point.scenario)
    if point.engine == "memory":
        if folder is None:
            from fleet_emu.launch.memory import Fleet

            return Fleet(scenario, run_id=run_id(point)).run()
        from fleet_emu.launch.memory import run_memory

        return run_memory(scenario, folder, record=True, run_id=run_id(point), on_progress=on_progress,
                          overwrite=overwrite)
    from fleet_emu.launch.runner import RunOptions, run_fleet

    return run_fleet(scenario, RunOptions(out_dir=folder, record=folder is not None, run_id=run_id(point),
                                          on_progress=on_progress, overwrite=overwrite))


def records_now(point: Point, keep: Keep | None) -> bool:
    """Whether the point runs into its folder at once (every kept processes run; every run with ``"all"``)."""
    return keep is not None and keep.mode != "none" and (keep.mode == "all" or point.engine != "memory")


def clear(point: Point, keep: Keep | None) -> None:
    """Remove the folder an earlier attempt of this point left (a failed run that runs again): the sweep
    owns ``DIR/runs/ID``, and its row is replaced too."""
    if keep is not None and keep.mode != "none":
        shutil.rmtree(keep.folder(point.id), ignore_errors=True)


def odd(row: dict[str, Any]) -> bool:
    """A run a researcher wants to open: it failed, or it ended without the target."""
    return row.get("status") != "ok" or not row.get("completed")


def settle(point: Point, keep: Keep | None, row: dict[str, Any]) -> dict[str, Any]:
    """After the run: keep its folder (recording a memory run now when it is one to keep) or remove it; the row
    with ``run_dir`` (None when nothing is kept)."""
    if keep is None or keep.mode == "none":
        return row | {"run_dir": None}
    folder = keep.folder(point.id)
    wanted = keep.mode == "all" or odd(row)
    if wanted and not records_now(point, keep) and "ticks" in row:  # a memory run to keep: once more, recording
        with contextlib.suppress(Exception):  # the row stands; a folder that could not be written is not named
            run(point, folder)
    if not wanted:
        shutil.rmtree(folder, ignore_errors=True)
    there = folder.is_dir() and any(folder.iterdir())
    if there and (said := _whole(folder)) is not None:
        row = row | {"error": f"{row.get('error') or 'the run'}; {said}"}
        there = folder.is_dir()
    return row | {"run_dir": keep.relative(point.id) if there else None}


def _whole(folder: Path) -> str | None:
    """A kept folder whose recording was cut (a full disk mid-run) is recovered (``fleet recover``), or removed
    when that cannot be done: a sweep never names a recording no reader opens. What was done, or None."""
    from fleet_emu.core.errors import FleetError
    from fleet_emu.launch.recover import is_cut, recover

    if not is_cut(folder):
        return None
    try:
        recover(folder)
    except (FleetError, OSError) as exc:
        shutil.rmtree(folder, ignore_errors=True)
        return f"its folder was removed: its recording was cut and could not be recovered ({exc})"
    return "its recording was cut, and recovered"
