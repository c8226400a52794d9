"""``fleet report``: metrics, plots and a table from a recording alone.

Each recording is read with :func:`.read.load_recording`; the report writes ``metrics.json`` and the PNGs of
:data:`.plots.PLOTS` (``coverage.png``, ``connectivity.png``, ``map.png``, ``messages.png``) beside it, prefixed
with the recording's name when it is not ``run.mcap``, prints :func:`.tables.summary_table`, and says whether a
``result.json`` beside the recording agrees. ``--compare`` puts several runs in one table and overlays their
coverage curves in one PNG. Every file is written atomically (:mod:`fleet_emu.core.files`).
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console

from fleet_emu.core.errors import ReportError
from fleet_emu.core.files import write_atomic, write_json
from fleet_emu.recording.plots import PLOTS, base_plot, compare_plot
from fleet_emu.recording.read import Run, load_recording
from fleet_emu.recording.result import NOT_RECORDED
from fleet_emu.recording.tables import compare_table, summary_table


def output_paths(mcap: Path) -> dict[str, Path]:
    """Where the report of a recording goes: ``metrics`` and each plot's PNG."""
    prefix = "" if mcap.name == "run.mcap" else mcap.stem + "."
    out = {"metrics": mcap.parent / f"{prefix}metrics.json"}
    out |= {p: mcap.parent / f"{prefix}{p}.png" for p in PLOTS}
    return out


def write_report(run: Run, plots: bool = True) -> dict[str, Path]:
    """metrics.json and the PNGs beside the recording; returns their paths."""
    paths = output_paths(run.path)
    write_json(paths["metrics"], run.metrics)
    if plots:
        for name, plot in PLOTS.items():
            write_atomic(paths[name], functools.partial(plot, run))
        if run.fold.monitor.base:  # a run with a base station: its connectivity over time
            paths["base"] = paths["metrics"].with_name(paths["metrics"].name.replace("metrics.json", "base.png"))
            write_atomic(paths["base"], functools.partial(base_plot, run))
    else:
        for name in PLOTS:
            paths.pop(name)
    return paths


def report(paths: list[Path], compare: bool = False, out: Path | None = None, plots: bool = True,
           console: Console | None = None, partial: bool = False) -> list[Run]:
    """What ``fleet report`` does; raises ReportError on bad input (a cut or inconsistent recording too, unless
    ``partial``: then it is reported as far as it reads, and a line says how far)."""
    console = console or Console()
    if out is not None and not compare:
        raise ReportError("--out goes with --compare (a single report is written beside its recording)")
    runs = [load_recording(p, partial=partial) for p in paths]
    for run in runs:
        if run.truncated:
            of = f" (its run recorded {run.recorded} messages)" if run.recorded is not None else ""
            console.print(f"{run.path}: partial: {run.extent}{of}; reported as far as it reads", soft_wrap=True)
    if compare:
        out = out or Path("compare.png")
        if out.is_dir():
            out = out / "compare.png"
        if not out.parent.exists():
            raise ReportError(f"no such directory: {out.parent}")
        console.print(compare_table(runs))
        write_atomic(out, lambda tmp: compare_plot(runs, tmp))
        console.print(f"coverage curves: {out}")
        return runs
    for run in runs:
        written = write_report(run, plots=plots)
        console.print(summary_table(run.metrics, title=f"report {run.metrics['run_id']}  [dim]{run.path}[/dim]"))
        console.print("wrote " + ", ".join(str(p) for p in written.values()))
        if run.truncated:
            console.print(f"[yellow]{run.path} was cut (no summary): read up to its last complete chunk[/yellow]")
        _check_result(run, console)
    return runs


def _check_result(run: Run, console: Console) -> None:
    """Where the live result.json sits beside the recording, say whether the recomputed values agree."""
    live = run.path.parent / "result.json"
    if run.path.name != "run.mcap" or not live.is_file():
        return
    try:
        res = json.loads(live.read_text())
    except (OSError, ValueError):
        return
    if isinstance(res, dict) and res.get("reason") == "crashed":
        console.print("result.json was recovered from this recording (reason crashed)")
        return
    diff = differences(res, run.result)
    if diff:
        console.print(f"[yellow]differs from result.json: {', '.join(diff)}[/yellow]")
    else:
        console.print("[green]matches result.json[/green]")


def differences(result: dict[str, Any], metrics: dict[str, Any]) -> list[str]:
    """Keys of a live result.json whose values the recomputed ones (``Run.result``) do not reproduce."""
    skip = {*NOT_RECORDED, "pids"}  # the launcher's clock, signals and process ids are not on the bus
    out = []
    for k, v in result.items():
        if k in skip:
            continue
        w = metrics.get(k)
        if k == "recording":
            v, w = (v or {}).get("messages"), (w or {}).get("messages")
        if not _same(v, w):
            out.append(k)
    return out


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, float) or isinstance(b, float):
        return a is not None and b is not None and bool(np.isclose(a, b, rtol=0, atol=1e-9))
    return a == b
