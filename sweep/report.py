"""``fleet sweep report RESULTS``: a sweep's rows as figures and tables.

Figures (matplotlib, beside the results): time to target against robot count per allocator with 95 %
confidence bands (``time_vs_robots.png``), mean coverage against tick per allocator (``coverage_vs_tick.png``),
time against loss per allocator (``time_vs_loss.png``). Tables: per group (map, radio, loss, robots) and
allocator, the mean ± std of the time to target (ticks; runs that reached the target), moves (cells
travelled, the team's total) and connected time, with the % difference of the mean time to the baseline
allocator's in the same group and the time's difference to it paired by seed (mean ± standard error); then
the study's ``[paper]`` rows, the paper's number beside ours.
"""

from __future__ import annotations

import json
import math
import tomllib
from collections import defaultdict
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.radio import bytes_per_robot_tick
from fleet_emu.sweep.execute import PARQUET
from fleet_emu.sweep.figures import Runs
from fleet_emu.sweep.intervals import Bootstrap

GROUP = ("map", "comm", "loss_applied", "bandwidth", "map_sync", "robots")
#: Grid keys the columns of :data:`GROUP` already show (or that every line splits by: allocator, seed).
_SHOWN = {"map", "comm", "loss", "bandwidth", "map_sync", "robots", "allocator", "seed"}


def axes(rows: Iterable[dict[str, Any]], replicates: Iterable[str] = ()) -> tuple[str, ...]:
    """The other grid keys that split the lines (``param.threshold``...): every ``param.*`` column but the
    ones :data:`GROUP` shows, the allocator, the seed and the study's ``replicates`` (pooled, as seeds are)."""
    pooled = _SHOWN | set(replicates)
    return tuple(sorted({k for r in rows for k in r if k.startswith("param.") and k[6:] not in pooled}))


def load(results: Path) -> tuple[list[dict[str, Any]], dict[str, Any], Path]:
    """The rows of a results directory (or its parquet/CSV file), its ``study.toml`` (or {}) and the directory."""
    out = results if results.is_dir() else results.parent
    path = results / PARQUET if results.is_dir() else results
    if not path.exists():
        raise ConfigError(f"no sweep results at {results} (expected a sweep's --out directory or its {PARQUET})")
    try:
        if path.suffix == ".csv":
            import pyarrow.csv as pacsv

            table = pacsv.read_csv(path)
        else:
            import pyarrow.parquet as pq

            table = pq.read_table(path)
    except Exception as exc:
        raise ConfigError(f"cannot read sweep results {path}: {exc}") from None
    study = _study_of(out)
    rows = table.to_pylist()
    for r in rows:  # the radio's rate: absent from an unlimited run's scenario; map sync, absent when on
        r["bandwidth"] = float(r.get("scenario.radio.bandwidth") or 0.0)
        r["map_sync"] = map_sync(r)
        if "param.allocator" not in r and r.get("allocator") is not None:  # set in [fleet], not a grid axis
            r["param.allocator"] = r["allocator"]
    return rows, study, out


def _study_of(out: Path) -> dict[str, Any]:
    """The results folder's ``study.toml`` (or {}): read only when a regular file, and within a size limit."""
    from fleet_emu.core.files import read_regular

    path = out / "study.toml"
    if not path.exists():
        return {}
    try:
        return tomllib.loads(read_regular(path, 4 << 20).decode())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ConfigError(f"cannot read {path}: {getattr(exc, 'strerror', None) or exc}") from None


def map_sync(row: dict[str, Any]) -> bool:
    """Whether the run repaired lost map deltas (the scenario's ``map_sync``: in ``result.json`` only when
    false; a row without a result has it from its point, :func:`~fleet_emu.sweep.execute.group_of`)."""
    return all(row.get(key) is not False for key in ("scenario.map_sync", "map_sync"))


def moves(row: dict[str, Any]) -> float:
    return float(sum(json.loads(row["path_length"]))) if row.get("path_length") else math.nan


def time_to_target(row: dict[str, Any]) -> float:
    return float(row["ticks"]) if row.get("completed") else math.nan


def connected_pct(row: dict[str, Any]) -> float:
    v = row.get("connected_fraction")
    return 100.0 * v if v is not None else math.nan


def base_connected_pct(row: dict[str, Any]) -> float:
    """Runs with a base station: the mean share of live robots with a path to the base (``result.json``'s
    ``base_connected_fraction.overall``); NaN for runs without one."""
    v = row.get("base_connected_fraction.overall")
    return 100.0 * v if v is not None else math.nan


def missed_coverage(row: dict[str, Any]) -> float:
    """The final coverage (%) of a run that ended without the target; NaN for a run that reached it or holds
    no result."""
    if row.get("completed") or row.get("coverage") is None:
        return math.nan
    return 100.0 * row["coverage"]


def sent_kb(row: dict[str, Any]) -> float:
    """Kilobytes sent per robot-tick: ``radio.bytes_sent`` over robots and ticks
    (:func:`fleet_emu.core.radio.bytes_per_robot_tick`, the rate ``fleet report`` shows)."""
    ticks, robots, sent = row.get("ticks"), row.get("robots"), row.get("radio.bytes_sent")
    rate = bytes_per_robot_tick(sent, int(robots), int(ticks)) if ticks and robots and sent is not None else None
    return math.nan if rate is None else rate / 1e3


def mispredicted_pct(row: dict[str, Any]) -> float:
    """The % of robot pair-ticks where eq. 4 alone (what the connectivity allocator predicts from) disagreed with
    the link netem applied under shadowing (``radio.prediction``); NaN for a run without shadowing."""
    pairs = row.get("radio.prediction.pair_ticks")
    if not pairs:
        return math.nan
    wrong = (row.get("radio.prediction.false_links") or 0) + (row.get("radio.prediction.missed_links") or 0)
    return 100.0 * wrong / pairs


METRICS: dict[str, Callable[[dict[str, Any]], float]] = {
    "sent_kb": sent_kb, "mispredicted_pct": mispredicted_pct,
    "ticks": time_to_target, "moves": moves, "connected_pct": connected_pct,
    "coverage_pct": lambda r: 100.0 * r["coverage"] if r.get("coverage") is not None else math.nan,
    "base_connected_pct": base_connected_pct, "missed_coverage_pct": missed_coverage,
}


def stats(rows: Iterable[dict[str, Any]], metric: str) -> tuple[float, float, int]:
    """Mean, std (ddof 1) and count of a metric over rows (NaN left out)."""
    v = np.array([METRICS[metric](r) for r in rows], dtype=float)
    v = v[~np.isnan(v)]
    if not len(v):
        return math.nan, math.nan, 0
    return float(v.mean()), float(v.std(ddof=1)) if len(v) > 1 else 0.0, len(v)


def by(rows: Iterable[dict[str, Any]], *keys: str) -> dict[tuple[Any, ...], list[dict[str, Any]]]:
    out: dict[tuple[Any, ...], list[dict[str, Any]]] = defaultdict(list)
    for r in rows:
        out[tuple(r.get(k) for k in keys)].append(r)
    return dict(sorted(out.items(), key=lambda kv: tuple(_order(x) for x in kv[0])))


def _order(x: Any) -> tuple[int, Any]:
    """Numbers in numeric order, before text (robot counts 1, 2, ..., 10)."""
    return (0, x) if isinstance(x, int | float) and not isinstance(x, bool) else (1, str(x))


def pct(a: float, b: float) -> float:
    return 100.0 * (a - b) / b if b and not math.isnan(a) and not math.isnan(b) else math.nan


def _twin(row: dict[str, Any]) -> tuple[Any, ...]:
    """What pairs a run with the baseline's: every grid value but the allocator (the seed, a replicate)."""
    return tuple(sorted((k, str(v)) for k, v in row.items() if k.startswith("param.") and k != "param.allocator"))


def paired(runs: list[dict[str, Any]], base: list[dict[str, Any]]) -> tuple[float, float, int]:
    """Mean and standard error (sd / sqrt(n)) of the time difference ``run - base`` paired by seed and by the
    other grid values (a seed draws the same start for every allocator; a replicate is the same point), over the
    pairs where both reached the target; and n."""
    mine = {_twin(r): time_to_target(r) for r in runs}
    theirs = {_twin(r): time_to_target(r) for r in base}
    d = np.array([mine[s] - theirs[s] for s in mine.keys() & theirs.keys()], dtype=float)
    d = d[~np.isnan(d)]
    if len(d) < 2:
        return math.nan, math.nan, len(d)
    return float(d.mean()), float(d.std(ddof=1) / math.sqrt(len(d))), len(d)


def summary(rows: list[dict[str, Any]], baseline: str | None, replicates: Iterable[str] = ()) -> list[dict[str, Any]]:
    """One line per point (group, the other grid axes, allocator), failed runs included: the metrics' mean and
    std over the runs that succeeded, the runs that reached the target, failed, and the final coverage of those
    that missed it; the time's % difference to baseline, and its difference to baseline paired by seed (mean ±
    standard error). ``replicates``: grid keys pooled like seeds."""
    lines = []
    keys = GROUP + axes(rows, replicates)
    for group, members in by(rows, *keys).items():
        per_alloc = by(members, "param.allocator")
        ok_of = {k: [r for r in v if r.get("status") == "ok"] for k, v in per_alloc.items()}
        base = ok_of.get((baseline,))
        base_mean = stats(base, "ticks")[0] if base else math.nan
        for (alloc,), every in per_alloc.items():
            runs = ok_of[(alloc,)]
            line: dict[str, Any] = dict(zip(keys, group, strict=True)) | {
                "allocator": alloc, "runs": len(every), "failed": len(every) - len(runs),
                "reached": sum(bool(r.get("completed")) for r in runs)}
            for m in METRICS:
                line[m] = stats(runs, m)
            line["missed_coverage_pct"] = stats(every, "missed_coverage_pct")
            line["vs_baseline_pct"] = pct(line["ticks"][0], base_mean)
            line["paired"] = paired(runs, base) if base and alloc != baseline else (math.nan, math.nan, 0)
            lines.append(line)
    return lines


def report(results: Path, baseline: str | None = None, plots: bool = True, seeds: int | None = None,
           fmt: str = "table", boot: Bootstrap | None = None) -> None:
    """Print the tables (and draw the figures) of a sweep's results; with ``seeds``, only the runs of the
    study's first N seeds (every point then has the same seeds); ``fmt``: how the tables are printed
    (:mod:`fleet_emu.sweep.tables`: fitted to the terminal, or ``csv`` / ``markdown``, the other lines then on
    standard error); ``boot``: the claims' intervals (level, resamples, seed)."""
    from rich.console import Console

    from fleet_emu.sweep.tables import FORMATS, show

    if fmt not in FORMATS:
        raise ConfigError(f"--format must be one of {', '.join(FORMATS)} (got {fmt!r})")

    boot = boot or Bootstrap()
    rows, study, out = load(results)
    if seeds is not None:
        listed = study.get("study", {}).get("seeds", 0)
        keep = set(listed[:seeds] if isinstance(listed, list) else range(seeds))
        rows = [r for r in rows if r.get("param.seed") in keep]
    ok = [r for r in rows if r.get("status") == "ok"]
    failed = len(rows) - len(ok)
    allocators = sorted({str(r["param.allocator"]) for r in rows if r.get("param.allocator") is not None})
    head = study.get("study", {})
    baseline = baseline or head.get("baseline") or (allocators[0] if allocators else None)
    tables = Console()
    console = tables if fmt == "table" else Console(stderr=True)  # csv, markdown: only the tables on stdout
    console.print(f"[bold]{head.get('name', out.name)}[/bold]: {len(rows)} runs, {failed} failed; "
                  f"baseline {baseline}" + (f"; the first {seeds} seeds" if seeds else ""))
    replicates = head.get("replicates", [])
    lines = summary(rows, baseline, replicates)
    show(tables, _summary_table(lines, baseline, axes(rows, replicates)), fmt)
    _odd_runs(console, rows, out)
    paper = study.get("paper", {})
    if paper:  # the paper's rows compare with the study's own baseline (the paper's), whatever --baseline says
        base = head.get("baseline") or baseline
        runs = Runs(rows, base, replicates)
        show(tables, _paper_table(paper, runs, base), fmt)
        _claims(console, tables, fmt, study, rows, base, out, boot)
    if plots and ok:
        from fleet_emu.sweep.plots import draw

        for path in draw(ok, out, replicates, boot.level):
            console.print(f"wrote {path}")


def _claims(console: Any, tables: Any, fmt: str, study: dict[str, Any], rows: list[dict[str, Any]],
            baseline: str | None, out: Path, boot: Bootstrap) -> None:
    """The ``[[paper.claims]]`` judged (:mod:`fleet_emu.sweep.claims`) with their intervals: a table (on
    ``tables``, in ``fmt``), and ``claims.json`` in ``out`` (said on ``console``). After ``--until-decided``
    each claim is judged as its look decided it (:mod:`fleet_emu.sweep.decide`)."""
    from fleet_emu.sweep import verdicts
    from fleet_emu.sweep.decide import judged_as_decided
    from fleet_emu.sweep.tables import show

    judged, entries, level, note = judged_as_decided(study, rows, baseline, out, boot)
    if judged:
        show(tables, verdicts.table(judged, str(study.get("paper", {}).get("source", "")), level), fmt)
        if note:
            console.print(note, soft_wrap=True)
        console.print(f"wrote {verdicts.write_json(entries, out / 'claims.json')}")


def _odd_runs(console: Any, rows: list[dict[str, Any]], out: Path, most: int = 10) -> None:
    """The runs that failed or missed the target, by id (at most ``most``), and where to open them."""
    from fleet_emu.sweep.record import odd

    runs = sorted((r for r in rows if odd(r)), key=lambda r: (r.get("status") == "ok", str(r["id"])))
    if not runs:
        return
    console.print(f"{len(runs)} runs failed or missed the target; `fleet sweep rerun {out} ID --out DIR` "
                  f"re-creates one, `fleet report DIR` opens it:", soft_wrap=True)
    for r in runs[:most]:
        params = ", ".join(f"{k[6:]}={v}" for k, v in r.items() if k.startswith("param."))
        what = (f"failed: {r.get('error')}" if r.get("status") != "ok" else
                f"{r.get('reason')} at tick {r.get('ticks')}, coverage {100 * (r.get('coverage') or 0):.1f} %")
        kept = f" (kept: {out / r['run_dir']})" if r.get("run_dir") else ""
        console.print(f"  {r['id']}  {params}  {what}{kept}", soft_wrap=True, highlight=False)
    if len(runs) > most:
        console.print(f"  ... and {len(runs) - most} more (results.csv: the rows whose completed is false)")


def _fmt(mean_std: tuple[float, float, int], digits: int = 1) -> str:
    """``mean ± std``; ``mean, n = 1`` for one value (it has no spread); ``-`` for none."""
    mean, std, n = mean_std
    if n == 0:
        return "-"
    return f"{mean:.{digits}f}, n = 1" if n == 1 else f"{mean:.{digits}f} ± {std:.{digits}f}"


def _summary_table(lines: list[dict[str, Any]], baseline: str | None, extra: tuple[str, ...] = ()) -> Any:
    """The summary lines as a table; ``extra``: the other grid axes (:func:`axes`), a column each."""
    from rich.table import Table

    base = any(ln["base_connected_pct"][2] for ln in lines)  # a column only for studies with a base station
    failed = any(ln["failed"] for ln in lines)  # a column only when a run failed
    rated = any(ln.get("bandwidth") for ln in lines)  # and one only for studies of a limited radio
    t = Table(title="mean ± std per allocator (time: ticks to the target, runs that reached it; missed: the "
                    "final coverage of the runs that did not" + ("; sent kB: kilobytes sent per robot-tick)"
                                                                 if rated else ")"))
    for col in ("map", "radio", "robots", *(k[6:] for k in extra), "allocator", "reached",
                *(["failed"] if failed else []), "time",
                f"vs {baseline}", "paired Δ ± s.e.", "missed: coverage %", "moves", "connected %",
                *(["sent kB"] if rated else []), *(["base connected %"] if base else [])):
        t.add_column(col, justify="right" if col not in ("map", "radio", "allocator") else "left")
    for ln in lines:
        t.add_row(Path(str(ln["map"])).stem, _radio(ln), str(ln["robots"]), *(str(ln[k]) for k in extra),
                  str(ln["allocator"]),
                  f"{ln['reached']} / {ln['runs']}", *([str(ln["failed"])] if failed else []), _fmt(ln["ticks"]),
                  "-" if math.isnan(ln["vs_baseline_pct"]) else f"{ln['vs_baseline_pct']:+.1f} %",
                  "-" if math.isnan(ln["paired"][0]) else f"{ln['paired'][0]:+.1f} ± {ln['paired'][1]:.1f}",
                  _fmt(ln["missed_coverage_pct"]), _fmt(ln["moves"]), _fmt(ln["connected_pct"]),
                  *([_fmt(ln["sent_kb"], 2)] if rated else []),
                  *([_fmt(ln["base_connected_pct"])] if base else []))
    return t


def _radio(line: dict[str, Any]) -> str:
    loss, rate = line["loss_applied"], f", {line['bandwidth']:g} kbit/s" if line.get("bandwidth") else ""
    sync = ", no map sync" if line.get("map_sync") is False else ""
    return (f"{line['comm']}, loss {loss:g}" if isinstance(loss, int | float) else str(line["comm"])) + rate + sync


def _paper_table(paper: dict[str, Any], runs: Runs, baseline: str | None) -> Any:
    """The paper's rows (``[[paper.rows]]``: what, allocator, metric, value, and optional robots/loss filters)
    with ours beside them; ``metric`` is one of :data:`METRICS`, ``std_ticks``, ``vs_baseline_pct`` (mean over
    the matching groups), ``mean_std_ticks`` (the time's std, mean over the matching groups) or ``vs_loss0_pct``
    (the % change, from loss 0, of the mean times summed over the robot counts)."""
    from rich.table import Table

    t = Table(title=f"the paper beside ours — {paper.get('source', '')} (baseline {baseline})")
    for col in ("what", "paper", "ours"):
        t.add_column(col, justify="left" if col == "what" else "right")
    for claim in paper.get("claims", []):
        if isinstance(claim, str):  # a claim with a criterion is judged in the claims' table
            t.add_row(claim, "", "")
    for pr in paper.get("rows", []):
        ours = paper_value(pr, runs)
        t.add_row(str(pr.get("what", pr.get("metric"))), str(pr.get("value", "")),
                  "-" if ours is None or math.isnan(ours) else f"{ours:.1f}")
    return t


def paper_value(pr: dict[str, Any], runs: Runs) -> float | None:
    """Our number for one ``[[paper.rows]]`` entry: the figure of :mod:`fleet_emu.sweep.figures` on every
    replicate once (the claims read the same definition)."""
    from fleet_emu.sweep.claims import SELECT
    from fleet_emu.sweep.figures import value

    keep: dict[str, Any] = {k: pr[k] for k in SELECT if k in pr}
    v = float(value(runs, keep, pr.get("metric", "ticks"), np.ones((1, len(runs.units)))).values[0])
    return None if math.isnan(v) else v
