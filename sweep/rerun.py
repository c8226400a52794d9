"""``fleet sweep rerun RESULTS ID --out DIR``: one point of a sweep re-created as a run folder (the same scenario,
seed and engine, recording on) that ``fleet report`` and Foxglove open, checked against its row: every
deterministic value of the run (``result.json`` without its clock and process keys, and the coverage curve)
must equal the row's, or the command says which differ and exits 1.
"""

from __future__ import annotations

import itertools
import json
import sys
from pathlib import Path
from typing import Any

from fleet_emu.core.errors import ConfigError
from fleet_emu.sweep.execute import PARQUET, ROWS, curve, flatten, read_rows
from fleet_emu.sweep.record import run, run_id
from fleet_emu.sweep.study import Point, Study, param_label, point_id

#: The exit code when the re-created run differs from its row.
DIFFERS = 1


def results_dir(results: Path) -> Path:
    """A sweep's results folder, given as the folder or one of its files."""
    out = results if results.is_dir() else results.parent
    if not (out / ROWS).exists() and not (out / PARQUET).exists():
        raise ConfigError(f"no sweep results at {results} (expected a sweep's --out directory)")
    return out


def find_row(out: Path, wanted: str) -> dict[str, Any]:
    """The row of a point: its id, or the start of one that no other id shares."""
    rows = read_rows(out)
    if not rows:
        from fleet_emu.sweep.report import load

        rows = load(out)[0]
    exact = [r for r in rows if r["id"] == wanted]
    found = exact or [r for r in rows if str(r["id"]).startswith(wanted)]
    if len(found) != 1:
        what = "no row has" if not found else f"{len(found)} rows have"
        raise ConfigError(f"{what} the id {wanted} in {out} ({len(rows)} rows; `fleet sweep report {out}` lists "
                          f"the points, results.csv their ids)")
    return found[0]


def find_point(out: Path, row: dict[str, Any], maps: Path | None) -> Point:
    """The row's point, from the study kept beside the rows: the grid values whose id is the row's, and the
    map the row ran on when that file is still there."""
    kept = out / "study.toml"
    if not kept.exists():
        raise ConfigError(f"{out} has no study.toml: its points cannot be re-created")
    study = Study.load(kept)  # a regular file of bounded size, or one line (a FIFO is never waited on)
    keys = list(study.grid)
    for values in itertools.product(*(study.grid[k] for k in keys)):
        params = dict(zip(keys, values, strict=True))
        for seed in study.seeds:
            if point_id(params, seed) != row["id"]:
                continue
            given = str(row.get("scenario.map") or row.get("map") or "")
            ran_on = {"map": given} if given and Path(given).is_absolute() and Path(given).exists() else {}
            scenario = study.scenario(params | ran_on, seed, maps)
            label = {k: param_label(v) for k, v in params.items()} | {"seed": seed}
            return Point(row["id"], label, scenario.to_dict(), str(row.get("engine") or study.engine))
    raise ConfigError(f"the point {row['id']} is not in {kept} (was the study file changed?)")


def differences(row: dict[str, Any], result: Any) -> list[str]:
    """The deterministic values of the run that are not the row's: ``key (row X, rerun Y)``."""
    from fleet_emu.recording.result import deterministic

    mine = dict(flatten(deterministic(result.to_dict()))) | {"curve": curve(result)}
    out = []
    for key, value in mine.items():
        theirs = row.get(key, "<missing>")
        if not _same(theirs, value):
            out.append(f"{key} (row {_short(theirs)}, rerun {_short(value)})")
    return out


def _same(a: Any, b: Any) -> bool:
    """Equal as the row stores them (a table column may hold an int as a float)."""
    if isinstance(a, int | float) and isinstance(b, int | float) and not isinstance(a, bool):
        return float(a) == float(b)
    return bool(a == b)


def _short(value: Any) -> str:
    text = value if isinstance(value, str) else json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


def rerun(results: Path, wanted: str, out: Path | None, *, overwrite: bool = False, maps: Path | None = None,
          quiet: bool = False) -> int:
    """Re-create a sweep's point in ``out`` (default ``runs/sweep-ID``); 0 when the run equals its row,
    :data:`DIFFERS` (and one line) when it does not."""
    from rich.console import Console

    from fleet_emu.core.scenario import Scenario
    from fleet_emu.launch.outdir import refuse_held
    from fleet_emu.launch.progress import Progress

    folder = results_dir(results)
    row = find_row(folder, wanted)
    point = find_point(folder, row, maps)
    out = out if out is not None else Path("runs") / run_id(point)
    refuse_held(out, overwrite)  # before anything is said or run, in the words of ``fleet run``

    def say(line: str) -> None:
        if not quiet:
            print(line, file=sys.stderr)

    params = ", ".join(f"{k}={v}" for k, v in point.params.items())
    say(f"re-creating {point.id} ({params}) on the {point.engine} engine -> {out}")
    try:
        with Progress(Scenario.from_dict(point.scenario), run_id(point), Console(stderr=True), quiet) as progress:
            result = run(point, out, progress.update, overwrite)
    except Exception as exc:  # a point whose row failed with an error: the same error is its re-creation
        error, theirs = f"{type(exc).__name__}: {exc}", str(row.get("error") or "")
        how = " again, as its row says" if theirs.startswith(error) else ""
        also = "" if how else f" (its row: {theirs or 'no error'})"
        wrote = f"; what it wrote is in {out}" if out.is_dir() and any(out.iterdir()) else ""
        print(f"fleet: error: the point {point.id} failed{how}: {error}{also}{wrote}", file=sys.stderr)
        return DIFFERS
    if row.get("ticks") is None:
        print(f"fleet: error: the point {point.id} ran, but its row holds no run ({row.get('error')}); "
              f"the run is in {out}", file=sys.stderr)
        return DIFFERS
    diff = differences(row, result)
    if diff:
        print(f"fleet: error: the rerun of {point.id} differs from its row in {len(diff)} "
              f"value{'s' if len(diff) > 1 else ''}: "
              f"{'; '.join(diff)}", file=sys.stderr)
        return DIFFERS
    say(f"{point.id}: the run equals its row ({result['reason']} at tick {result['ticks']}, coverage "
        f"{result['coverage']:.1%}); open it with `fleet report {out}`")
    if quiet:
        print(out / "result.json")
    return 0
