"""``fleet sweep STUDY --out DIR`` (a study's runs, in parallel, resumable), ``fleet sweep --list`` (the shipped
studies), ``fleet sweep report RESULTS`` (figures and tables) and ``fleet sweep rerun RESULTS ID --out DIR`` (one
point re-created as a run folder, checked against its row).

Exit codes: 0 when every run succeeded; 2 on bad input (one line, before any run); 130 on Ctrl-C (the rows
finished so far are kept and the tables written); 1 when the sweep's own files cannot be written (a full disk:
one line naming the failed runs and what has no row; every table that fits is written, and a resume runs the
points without a row); otherwise 200 + the number of failed runs (at most 255), a point of the grid without a
row counted as failed.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import errno
import os
import signal
import sys
import time
import tomllib
from collections.abc import Callable, Iterator
from pathlib import Path
from types import FrameType
from typing import Any

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.setting_names import plural

FAILED_BASE = 200
DISK_FULL = 1  # the sweep's own files (rows, tables) could not be written: a full disk


def add_parser(sub: Any) -> None:
    """The ``sweep`` subcommand of ``fleet``."""
    s = sub.add_parser("sweep", help="run a study (a grid of runs) in parallel; `fleet sweep report RESULTS`; "
                                     "`fleet sweep rerun RESULTS ID`")
    s.add_argument("args", nargs="*", metavar="STUDY",
                   help="a study TOML or a shipped study's name; or: report RESULTS; or: rerun RESULTS ID")
    s.add_argument("--out", type=Path, help="the results directory (a second call resumes there); rerun: the run "
                                            "folder (default runs/sweep-ID)")
    s.add_argument("--dask", metavar="ADDRESS", help="a Dask scheduler, e.g. tcp://192.0.2.10:8786")
    s.add_argument("--maps", type=Path, help="where the study's map files are, when it names them by path "
                        "(default: $FLEET_MAPS); a registry map is found by name (`fleet maps`)")
    s.add_argument("--list", action="store_true", help="list the studies shipped with fleet-emu")
    s.add_argument("--quick", action="store_true",
                   help="a quick look: one run of every grid point (its first seed), as --limit <points>")
    s.add_argument("--baseline", help="report: the allocator to compare with (default: the study's)")
    s.add_argument("--no-plots", action="store_true", help="report: the tables only")
    s.add_argument("--format", choices=("table", "csv", "markdown"), default=None,
                   help="report: the tables fitted to the terminal (table, the default; full width when piped), or "
                        "as CSV or Markdown on standard output (the other lines on standard error)")
    s.add_argument("--until-decided", action="store_true",
                   help="run the study's replicates, then more in doubling batches until every claim is decided "
                        "(reproduced or not) or --max-seeds is reached; looks corrected for (Bonferroni)")
    from fleet_emu.launch.setting_flags import add_setting_flags
    from fleet_emu.sweep.options import sweep_settings

    add_setting_flags(s, sweep_settings(), fallback="")  # --jobs, --limit, --seeds, --max-seeds, --level
    s.add_argument("--quiet", action="store_true", help="no progress bar")
    s.add_argument("--overwrite", action="store_true", help="rerun: replace the run that --out DIR holds")


#: The options each action of ``fleet sweep`` takes (the rest are refused, not ignored).
USES = {"sweep": {"out", "jobs", "dask", "maps", "limit", "quick", "seeds", "quiet", "until_decided", "max_seeds",
                  "level"},
        "report": {"baseline", "no_plots", "seeds", "format", "level"},
        "rerun": {"out", "maps", "overwrite", "quiet"}}
OPTIONS = {"out": "--out", "jobs": "--jobs", "dask": "--dask", "maps": "--maps", "limit": "--limit", "quick": "--quick",
           "seeds": "--seeds", "baseline": "--baseline", "no_plots": "--no-plots", "quiet": "--quiet",
           "overwrite": "--overwrite", "format": "--format", "until_decided": "--until-decided",
           "max_seeds": "--max-seeds", "level": "--level"}


def refuse_unused(args: argparse.Namespace, action: str) -> None:
    """One line naming the options given that ``action`` does not use (they would be silently ignored)."""
    given = [flag for dest, flag in OPTIONS.items()
             if dest not in USES[action] and getattr(args, dest, None) not in (None, False)]
    if given:
        what = {"sweep": "fleet sweep STUDY", "report": "fleet sweep report", "rerun": "fleet sweep rerun"}[action]
        raise ConfigError(f"{what} does not take {', '.join(given)}")


def cmd_sweep(args: argparse.Namespace) -> int:
    from fleet_emu.sweep.study import shipped

    if args.list:
        studies = shipped()
        width = max(map(len, studies), default=0)
        for name, desc in studies.items():
            print(f"{name:{width}s}  {desc}")
        return 0
    action = args.args[0] if args.args[:1] in (["report"], ["rerun"]) else "sweep"
    refuse_unused(args, action)
    if action == "report":
        if len(args.args) != 2:
            raise ConfigError("usage: fleet sweep report RESULTS (a sweep's --out directory or its results.parquet)")
        from fleet_emu.sweep.report import report

        report(Path(args.args[1]), baseline=args.baseline, plots=not args.no_plots, seeds=args.seeds,
               fmt=args.format or "table", boot=bootstrap(args.level))
        return 0
    if action == "rerun":
        if len(args.args) != 3:
            raise ConfigError("usage: fleet sweep rerun RESULTS ID --out DIR (a sweep's --out directory, a row's id)")
        from fleet_emu.sweep.rerun import rerun

        return rerun(Path(args.args[1]), args.args[2], args.out, overwrite=args.overwrite, maps=args.maps,
                     quiet=args.quiet)
    if len(args.args) != 1:
        raise ConfigError("usage: fleet sweep STUDY --out DIR (or --list, or report RESULTS, or rerun RESULTS ID)")
    if args.out is None:
        raise ConfigError("fleet sweep needs --out DIR (where the results go)")
    if args.max_seeds is not None and not args.until_decided:
        raise ConfigError("--max-seeds goes with --until-decided")
    from fleet_emu.sweep.options import check_sweep_options

    check_sweep_options(max_seeds=args.max_seeds)
    return sweep(args.args[0], args.out, jobs=args.jobs, dask=args.dask, maps=args.maps, limit=args.limit,
                 seeds=args.seeds, quiet=args.quiet, quick=args.quick,
                 until=Until(args.max_seeds, bootstrap(args.level)) if args.until_decided else None)


def bootstrap(level: float | None) -> Any:
    """The claims' interval settings from ``--level`` (one line when out of range; None: its declared default,
    :class:`~fleet_emu.sweep.options.SweepOptions`)."""
    from fleet_emu.sweep.intervals import Bootstrap
    from fleet_emu.sweep.options import SweepOptions, check_sweep_options

    check_sweep_options(level=level)
    return Bootstrap(level=SweepOptions().level if level is None else level)


@dataclasses.dataclass(frozen=True)
class Until:
    """``--until-decided``: the cap on replicates (None: the plan's default) and the intervals' settings."""

    cap: int | None
    boot: Any


def sweep(study_name: str, out: Path, *, jobs: int | None = None, dask: str | None = None, maps: Path | None = None,
          limit: int | None = None, seeds: int | None = None, quiet: bool = False, quick: bool = False,
          until: Until | None = None) -> int:
    """Run a study into ``out``, resuming what is there; the exit code (see the module docstring). ``until``:
    add replicates until every claim is decided (:mod:`fleet_emu.sweep.decide`)."""
    from fleet_emu.sweep.execute import connect_dask
    from fleet_emu.sweep.options import check_sweep_options
    from fleet_emu.sweep.spread import spread
    from fleet_emu.sweep.study import Study, param_label

    study = Study.load(study_name)
    check_sweep_options(jobs=jobs, limit=limit, seeds=seeds)
    if quick and limit is not None:
        raise ConfigError("--quick is --limit <the grid's points>: give one of them")
    if until is not None and (quick or limit is not None or seeds is not None):
        raise ConfigError("--until-decided chooses the replicates itself: it does not take --quick, --limit or "
                          "--seeds")
    if until is not None:
        from fleet_emu.sweep.decide import plan

        plan(study, until.cap, until.boot.level)  # a cap the study cannot meet: one line, before anything runs
    points = study.points(maps)
    if seeds is not None:
        points = [p for p in points if p.params["seed"] in study.seeds[:seeds]]
    if quick:
        limit = len(points) // len(study.seeds[:seeds] if seeds else study.seeds)
    if limit is not None:
        points = spread(points, {k: [param_label(v) for v in vs] for k, vs in study.grid.items()}, study.seeds)
    with contextlib.ExitStack() as stack:
        client = stack.enter_context(connect_dask(dask)) if dask else None  # before anything is written
        from fleet_emu.launch.outdir import lock_folder, make_folder

        make_folder(out)
        stack.callback(lock_folder(out).release)  # one sweep at a time in ``out``: refused naming the other's pid
        _claim(out, study)
        if until is not None:
            from fleet_emu.sweep.decide import until_decided

            def run(grown: Any) -> int:
                return _run(grown, grown.points(maps), out, jobs, client, dask, None, quiet)

            return until_decided(study, out, run, until.cap, until.boot, _say if not quiet else _silent)
        return _run(study, points, out, jobs, client, dask, limit, quiet)


def _say(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def _silent(_line: str) -> None:
    """``--quiet``: the looks of ``--until-decided`` are not told (``decided.json`` keeps them)."""


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[list[int]]:
    """SIGTERM stops a sweep as Ctrl-C does (the workers are interrupted, the rows kept, exit 143)."""
    got: list[int] = []

    def handle(signum: int, _frame: FrameType | None) -> None:
        got.append(signum)
        if len(got) == 1:
            raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, handle)
    try:
        yield got
    finally:
        signal.signal(signal.SIGTERM, previous)


def _run(study: Any, points: list[Any], out: Path, jobs: int | None, client: Any, dask: str | None,
         limit: int | None, quiet: bool) -> int:
    """The sweep proper, once every check passed and ``out`` is claimed."""
    from rich.console import Console

    from fleet_emu.sweep.execute import execute, read_rows, write_tables
    from fleet_emu.sweep.record import Keep

    done = {r["id"] for r in read_rows(out) if r.get("status") == "ok"}
    todo = [p for p in points if p.id not in done][:limit]
    jobs = jobs or os.cpu_count() or 1
    console = Console(stderr=True, quiet=quiet)  # --quiet: no status line, no bar; errors still one line each
    console.print(f"[bold]{study.name}[/bold]: {plural(len(points), 'run')}, {sum(p.id in done for p in points)} "
                  f"done, {len(todo)} to run ({study.engine} engine, "
                  f"{'Dask ' + dask if dask else plural(jobs, 'job')}) -> {out}")
    interrupted = False
    disk: str | None = None
    t0 = time.monotonic()
    with _bar(console, len(todo), quiet) as (bar, task):
        on_row = _Rows(out, lambda failed: bar.update(task, advance=1, failed=failed))
        with _sigterm_as_interrupt() as signals:
            try:
                execute(todo, jobs, on_row, client, Keep(study.record, str(out.absolute())))
            except KeyboardInterrupt:
                interrupted = True
            except _DiskFull as full:
                disk = full.why
            finally:
                on_row.close()
    rows = read_rows(out)
    tables, unwritable = write_tables(rows, out)
    missing = [p.id for p in points if p.id not in {r["id"] for r in rows}]
    failed_all = sum(r.get("status") != "ok" for r in rows) + (0 if limit or interrupted else len(missing))
    kept = sum(bool(r.get("run_dir")) for r in rows)
    console.print(f"{plural(len(rows), 'row')} of {plural(len(points), 'point')} ({failed_all} failed) in "
                  f"{' and '.join(str(t) for t in tables) or 'no table'}; this call ran {on_row.ran} of "
                  f"{len(todo)} in {time.monotonic() - t0:.1f} s"
                  + (f"; {plural(kept, 'run')} kept in {out / 'runs'} (record = {study.record!r})" if kept else ""))
    if interrupted:
        print(f"fleet: interrupted; the finished runs are in {out} (run again to resume)", file=sys.stderr)
        return 128 + (signals[0] if signals else signal.SIGINT)
    if disk is not None or unwritable:
        print(f"fleet: error: {_disk_line(out, disk, unwritable, rows, on_row.unwritten, missing)}",
              file=sys.stderr)
        return DISK_FULL
    if failed_all:
        gone = f"; {len(missing)} points have no row: {_ids(missing)} (run again)" if missing and not limit else ""
        ids = _ids([r["id"] for r in rows if r.get("status") != "ok"])
        print(f"fleet: error: {failed_all} of {plural(len(points), 'run')} failed (their rows hold the error): "
              f"{ids}{gone}",
              file=sys.stderr)
        return min(FAILED_BASE + failed_all, 255)
    return 0


class _Rows:
    """Each row as its run finishes: appended to ``rows.jsonl`` and counted (``tick(failed so far)``). A row
    the disk did not take, or a run whose own files it did not, stops the sweep (:class:`_DiskFull`)."""

    def __init__(self, out: Path, tick: Callable[[int], None]) -> None:
        from fleet_emu.sweep.execute import RowWriter

        try:
            self.writer = RowWriter(out)
        except OSError as exc:
            raise ConfigError(f"--out {out}: cannot write there ({exc.strerror or exc})") from None
        self.tick = tick
        self.ran = self.failed = 0
        self.unwritten: list[dict[str, Any]] = []  # rows of finished runs the disk did not take

    def __call__(self, row: dict[str, Any]) -> None:
        self.ran += 1
        self.failed += row.get("status") != "ok"
        self.tick(self.failed)
        try:
            self.writer.write(row)
        except OSError as exc:
            self.unwritten.append(row)
            raise _DiskFull(exc.strerror or str(exc)) from None
        error = str(row.get("error") or "")
        if error.startswith("DiskFault: "):  # the run's own files could not be written: the disk is full
            full = os.strerror(errno.ENOSPC)
            raise _DiskFull(full if full in error else error.split("; ")[0].removeprefix("DiskFault: "))

    def close(self) -> None:
        self.writer.close()


class _DiskFull(Exception):
    """A row the disk did not take, or a run whose own files it did not: the sweep stops (its workers
    interrupted) and says so in one line; ``why`` is the system's error."""

    def __init__(self, why: str) -> None:
        super().__init__(why)
        self.why = why


def _ids(ids: list[str], most: int = 8) -> str:
    return ", ".join(ids[:most]) + (f" and {len(ids) - most} more" if len(ids) > most else "")


def _disk_line(out: Path, disk: str | None, unwritable: dict[str, str], rows: list[dict[str, Any]],
               unwritten: list[dict[str, Any]], missing: list[str]) -> str:
    """The one line of a sweep whose own files the disk did not take: why, the runs that failed (their rows
    or not), what has no row (it runs again on a resume), and the tables not written."""
    why = disk if disk is not None else next(iter(unwritable.values()))
    failed = sorted({r["id"] for r in rows if r.get("status") != "ok"} |
                    {r["id"] for r in unwritten if r.get("status") != "ok"})
    parts = [f"cannot write the sweep's files in {out}: {why}",
             f"failed runs: {_ids(failed)}" if failed else "no run failed",
             f"{len(missing)} points have no row (run again to resume once there is space)" if missing else "",
             f"not written: {', '.join(unwritable)}" if unwritable else ""]
    return "; ".join(p for p in parts if p)


def _claim(out: Path, study: Any) -> None:
    """Make ``out`` and keep the study there; a directory holding another study's results is refused."""
    kept = out / "study.toml"
    try:
        out.mkdir(parents=True, exist_ok=True)
        if kept.exists():
            from fleet_emu.sweep.study import Study

            other = Study.from_dict(tomllib.loads(kept.read_text()), kept)
            if other.name != study.name or other.fleet != study.fleet or not _grown(other.grid, study.grid):
                raise ConfigError(f"--out {out} holds the results of another study ({other.name}); "
                                  f"choose another directory")
            if study.path is not None and study.path.resolve() != kept.resolve():
                # the grid grew (its finished runs stay, the new points run) or the [paper] changed: the report
                # judges the study as it is now
                _keep_study(study, kept)
        elif study.path is not None:
            _keep_study(study, kept)
    except OSError as exc:
        raise ConfigError(f"--out {out}: cannot write there ({exc.strerror or exc})") from None


def _keep_study(study: Any, kept: Path) -> None:
    """The study's text as ``study.toml`` in the results folder, renamed into place (a link is not followed)."""
    from fleet_emu.core.files import write_atomic

    text = study.text or Path(study.path).read_text()
    write_atomic(kept, lambda tmp: tmp.write_text(text))


def _grown(old: dict[str, list[Any]], new: dict[str, list[Any]]) -> bool:
    """The same grid keys, each old value still in the new list (a study extended by an allocator, a robot
    count, a loss...): every finished run is still a point of the new grid, under the same stable id."""
    return old.keys() == new.keys() and all(all(v in new[k] for v in vals) for k, vals in old.items())


class _bar:
    """A rich progress bar with the count, the failures and an ETA (nothing with ``quiet``)."""

    def __init__(self, console: Any, total: int, quiet: bool) -> None:
        from rich.progress import (
            BarColumn,
            MofNCompleteColumn,
            Progress,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self.progress = Progress(TextColumn("[bold]runs"), BarColumn(), MofNCompleteColumn(),
                                 TextColumn("failed {task.fields[failed]}"), TimeElapsedColumn(),
                                 TextColumn("ETA"), TimeRemainingColumn(), console=console, disable=quiet)
        self.task = self.progress.add_task("runs", total=total, failed=0)

    def __enter__(self) -> tuple[Any, Any]:
        self.progress.start()
        return self.progress, self.task

    def __exit__(self, *exc: object) -> None:
        self.progress.stop()
