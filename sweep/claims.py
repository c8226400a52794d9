"""A study's ``[[paper.claims]]``: each of the paper's findings with a machine-checkable criterion, judged on
the sweep's runs with an interval over replicates as *reproduced*, *not reproduced*, *inconclusive* or *too few
runs* (:mod:`fleet_emu.sweep.intervals`).

```toml
[[paper.claims]]
text = "trade takes 4-19 % longer than Hungarian at no loss"   # the paper's words
metric = "vs_baseline_pct"     # a [[paper.rows]] metric, or reached_pct (% of the runs that reached the target)
allocator = "trade"            # the selection: allocator, robots, loss, map_sync (a list: pooled over them)
loss = 0.0
robots = [2, 3, 4]
each = "robots"                # optional: the criterion holds for each value the selection lists
within = [0, 25]               # the criterion, one of:
# at_least = 25 / at_most = 80 / above = 0 / below = 0     a bound (>=, <=, >, <)
# below = {allocator = "nearest"}                          ... or another selection's: the paired difference
# at_most = {allocator = "minpos", times = 1.8}             ... or, with a factor, the ratio; a list: each of them
# near = 42.7, tolerance = 10                              |ours - near| <= tolerance
# increasing = "loss"                                      strictly, over the listed values in their order
```

``[paper] beside = "map_sync"`` (any ``[grid]`` key) judges every claim once per value of that key, side by side
(a claim that names the key itself keeps its own). A claim that is a plain string is the paper's words, not
judged.

Pure: :func:`parse` reads the claims, :func:`judge` applies one to a sweep's runs
(:class:`~fleet_emu.sweep.figures.Runs`): every figure of the claim (one per ``each`` value, per other
selection, per step of a monotone claim) on every replicate and on bootstrap resamples of them, its interval,
and the verdict the interval allows.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from typing import Any

import numpy as np

from fleet_emu.core.errors import ConfigError
from fleet_emu.sweep.figures import Figure, Runs, difference, ratio, value
from fleet_emu.sweep.intervals import (
    Bootstrap,
    Interval,
    Region,
    Verdict,
    decide,
    interval,
    replicates_needed,
    resample_weights,
)

#: Keys a claim selects runs by.
SELECT = ("allocator", "robots", "loss", "map_sync")
BOUNDS = {"at_least": "≥", "at_most": "≤", "above": ">", "below": "<"}
CRITERIA = ("within", "near", "increasing", "decreasing", *BOUNDS)
_KEYS = {"text", "metric", "each", "tolerance", *SELECT, *CRITERIA}
#: Metrics besides the per-run ones of ``sweep.report.METRICS``.
AGGREGATES = ("vs_baseline_pct", "mean_std_ticks", "vs_loss0_pct", "std_ticks", "reached_pct")


@dataclasses.dataclass(frozen=True)
class Claim:
    """One claim: the paper's ``text``; without a ``kind`` (a plain string) it is not judged. ``select``: the
    runs; ``kind``: the criterion (one of :data:`CRITERIA`) and ``arg`` its value (a number, a pair, a key,
    or a tuple of other selections with their factors); ``each``: a key whose listed values are judged one by
    one."""

    text: str
    metric: str = ""
    select: dict[str, Any] = dataclasses.field(default_factory=dict)
    kind: str = ""
    arg: Any = None
    tolerance: float = 0.0
    each: str | None = None

    @property
    def others(self) -> tuple[tuple[dict[str, Any], float], ...]:
        """The other selections a bound compares with, each with its factor (none for a number)."""
        return self.arg if self.kind in BOUNDS and isinstance(self.arg, tuple) else ()

    def criterion(self) -> str:
        """The criterion as text: ``vs_baseline_pct in [0, 25], each robots``."""
        if not self.kind:
            return "-"
        if self.kind == "within":
            what = f"in [{_num(self.arg[0])}, {_num(self.arg[1])}]"
        elif self.kind == "near":
            what = f"{_num(self.arg)} ± {_num(self.tolerance)}"
        elif self.kind in ("increasing", "decreasing"):
            what = f"{self.kind} over {self.arg}"
        elif isinstance(self.arg, tuple):
            what = " and ".join(f"{BOUNDS[self.kind]} {_other(o, t)}" for o, t in self.arg)
        else:
            what = f"{BOUNDS[self.kind]} {_num(self.arg)}"
        return f"{self.metric} {what}" + (f", each {self.each}" if self.each else "")


# --- reading -----------------------------------------------------------------------------------------------

def parse(paper: dict[str, Any], where: str = "study", grid: dict[str, Any] | None = None) -> list[Claim]:
    """The ``[paper]`` table's claims; a bad one is one ConfigError naming it. ``grid``: the study's, to check
    that ``beside`` names one of its keys."""
    from fleet_emu.sweep.report import METRICS

    metrics = set(METRICS) | set(AGGREGATES)
    raw = paper.get("claims", [])
    if not isinstance(raw, list):
        raise ConfigError(f"{where}: [paper] claims must be a list of strings or [[paper.claims]] tables")
    beside = paper.get("beside")
    if beside is not None and grid is not None and (not isinstance(beside, str) or beside not in grid):
        raise ConfigError(f"{where}: [paper] beside must name a [grid] key (got {beside!r})")
    out = [_claim(c, f"{where}: claim {i + 1}", metrics) for i, c in enumerate(raw)]
    for i, c in enumerate(out):
        if grid is not None:
            _in_grid(c, grid, f"{where}: claim {i + 1}")
    return out


def _in_grid(claim: Claim, grid: dict[str, Any], where: str) -> None:
    """Every value a claim selects by a ``[grid]`` key is one of that key's (a value absent from the grid has
    no runs: the claim would say "no data" for ever)."""
    tables = [claim.select, *(o for o, _ in claim.others)]
    for table in tables:
        for k, v in table.items():
            if k not in grid or k == "map_sync":
                continue
            known = [_plain(x) for x in grid[k]]
            for x in (v if isinstance(v, list) else [v]):
                if _plain(x) not in known:
                    raise ConfigError(f"{where}: {k} = {x!r} is not in the [grid]'s {k} "
                                      f"({', '.join(map(str, grid[k]))}): no run would have it")


def _plain(x: Any) -> Any:
    """A grid value as the claims compare it: a table by its label (``trade(tasks=regions)``), numbers as
    floats."""
    if isinstance(x, dict):
        from fleet_emu.sweep.study import param_label

        return param_label(x)
    return float(x) if isinstance(x, int | float) and not isinstance(x, bool) else x


def _claim(c: Any, where: str, metrics: set[str]) -> Claim:
    if isinstance(c, str):
        return Claim(text=c)
    if not isinstance(c, dict):
        raise ConfigError(f"{where}: a claim is a string or a table (got {c!r})")
    if set(c) - _KEYS:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(sorted(set(c) - _KEYS))} "
                          f"(text, metric, {', '.join(SELECT)}, each, a criterion: {', '.join(CRITERIA)})")
    text, metric = c.get("text"), c.get("metric")
    if not isinstance(text, str) or not text:
        raise ConfigError(f"{where}: text must be the paper's words")
    if metric not in metrics:
        raise ConfigError(f"{where}: metric must be one of {', '.join(sorted(metrics))} (got {metric!r})")
    kinds = [k for k in CRITERIA if k in c]
    if len(kinds) != 1:
        raise ConfigError(f"{where}: give one criterion of {', '.join(CRITERIA)} (got {', '.join(kinds) or 'none'})")
    select = {k: c[k] for k in SELECT if k in c}
    kind = kinds[0]
    each = c.get("each")
    for key, what in ((each, "each"), (c.get(kind) if kind in ("increasing", "decreasing") else None, kind)):
        if key is not None and not (key in SELECT and isinstance(select.get(key), list) and select[key]):
            raise ConfigError(f"{where}: {what} must name a selection key given as a list (got {key!r})")
    if "tolerance" in c and kind != "near":
        raise ConfigError(f"{where}: tolerance goes with near")
    tolerance = c.get("tolerance", 0.0)
    if kind == "near" and not (_is_num(tolerance) and tolerance >= 0):
        raise ConfigError(f"{where}: tolerance must be a number >= 0 (got {tolerance!r})")
    return Claim(text, metric, select, kind, _arg(kind, c[kind], where), float(tolerance), each)


def _arg(kind: str, v: Any, where: str) -> Any:
    """A criterion's value, checked: ``within`` a pair lo <= hi, ``near`` a number, a monotone one a key, a
    bound a number or other selections (a table or a list of tables, each with an optional ``times``)."""
    if kind == "within":
        if not (isinstance(v, list) and len(v) == 2 and all(_is_num(x) for x in v) and v[0] <= v[1]):
            raise ConfigError(f"{where}: within must be [LOW, HIGH] with LOW <= HIGH (got {v!r})")
        return (float(v[0]), float(v[1]))
    if kind in ("increasing", "decreasing"):
        return v
    if _is_num(v):
        return float(v)
    if kind == "near":
        raise ConfigError(f"{where}: near must be a number (got {v!r})")
    tables = v if isinstance(v, list) else [v]
    out = []
    for t in tables:
        if not isinstance(t, dict) or not t or set(t) - {*SELECT, "times"}:
            raise ConfigError(f"{where}: {kind} must be a number or a selection table ({', '.join(SELECT)}, "
                              f"times; got {t!r})")
        times = t.get("times", 1.0)
        if not (_is_num(times) and times > 0):
            raise ConfigError(f"{where}: times must be a number > 0 (got {times!r})")
        out.append(({k: x for k, x in t.items() if k != "times"}, float(times)))
    return tuple(out)


def _is_num(x: Any) -> bool:
    """A finite number (an infinite bound or tolerance would hold whatever the runs say)."""
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


# --- judging -----------------------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Part:
    """One figure of a claim (a robot count of ``each``, one of several other selections, a step of a monotone
    claim): what it is (``label``, ``figure``), its interval, where it must lie and the verdict."""

    label: str
    figure: str
    interval: Interval
    region: Region
    verdict: Verdict
    needed: int | None = None


@dataclasses.dataclass(frozen=True)
class Judged:
    """A claim judged under one setting (``where``: ``beside``'s value): its parts and the claim's verdict,
    reproduced when every part is, not reproduced when one part is, else what the undecided parts say."""

    claim: Claim
    where: dict[str, Any]
    parts: tuple[Part, ...] = ()
    verdict: Verdict = Verdict.NOT_JUDGED

    @property
    def main(self) -> Part | None:
        """The part that decides the claim: a failing one, else the undecided one needing the most replicates,
        else the one nearest its criterion."""
        if not self.parts:
            return None
        for want in (Verdict.NOT_REPRODUCED, Verdict.NO_DATA, Verdict.TOO_FEW):
            for p in self.parts:
                if p.verdict == want:
                    return p
        open_ = [p for p in self.parts if p.verdict == Verdict.INCONCLUSIVE]
        if open_:
            return max(open_, key=lambda p: p.needed or 10**9)
        return min(self.parts, key=lambda p: min(p.region.distance(p.interval.low),
                                                 p.region.distance(p.interval.high)))


def judge(claim: Claim, runs: Runs, where: dict[str, Any] | None = None, boot: Bootstrap | None = None,
          level: float | None = None) -> Judged:
    """The claim on the runs (those ``where`` also selects; the claim's own selection wins), each figure with
    its bootstrap interval over replicates at ``level`` (default ``boot.level``)."""
    where = where or {}
    if not claim.kind:
        return Judged(claim, where)
    boot = boot or Bootstrap()
    level = boot.level if level is None else level
    n = len(runs.units)
    w = np.vstack([np.ones((1, n)), resample_weights(n, boot)]) if n else np.ones((1, 0))
    parts = [_part(label, what, fig, region, level) for label, what, fig, region in _figures(claim, runs,
                                                                                           where | claim.select, w)]
    return Judged(claim, where, tuple(parts), _overall([p.verdict for p in parts]))


def _part(label: str, what: str, fig: Figure, region: Region, level: float) -> Part:
    iv = interval(float(fig.values[0]), fig.values[1:], fig.n, level)
    verdict = decide(iv, region)
    needed = replicates_needed(iv, region) if verdict in (Verdict.INCONCLUSIVE, Verdict.TOO_FEW) else None
    return Part(label, what, iv, region, verdict, needed)


Figures = list[tuple[str, str, Figure, Region]]


def _figures(claim: Claim, runs: Runs, base: dict[str, Any], w: np.ndarray) -> Figures:
    """Every part of a claim: (label, what the figure is, the figure, the region where it must lie)."""
    if claim.kind in ("increasing", "decreasing"):
        key = claim.arg
        vals = [value(runs, base | {key: v}, claim.metric, w) for v in base[key]]
        region = Region(low=0.0, low_closed=False) if claim.kind == "increasing" else Region(high=0.0,
                                                                                             high_closed=False)
        return [(f"{key} {_num(a)} → {_num(b)}", f"{claim.metric} at {_num(b)} - at {_num(a)}",
                 difference(vb, va), region) for (a, va), (b, vb) in itertools.pairwise(zip(base[key], vals,
                                                                                              strict=True))]
    out: Figures = []
    for label, sel in _each(claim, base):
        ours = value(runs, sel, claim.metric, w)
        if not claim.others:
            out.append((label, claim.metric, ours, _region(claim)))
            continue
        for other, times in claim.others:
            theirs = value(runs, sel | other, claim.metric, w)
            vs = ", ".join(str(v) if k == "allocator" else f"{k}={_num(v)}" for k, v in other.items())
            if times != 1.0:  # a factor: the ratio against it
                fig, what, bound = ratio(ours, theirs), f"{claim.metric} / {vs}'s", times
            else:  # the paired difference against 0
                fig, what, bound = difference(ours, theirs), f"{claim.metric} - {vs}'s", 0.0
            out.append((", ".join(x for x in (label, f"vs {vs}") if x), what, fig,
                        _region(claim, bound)))
    return out


def _each(claim: Claim, base: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """The selections to judge: one, or one per value ``each`` lists."""
    if claim.each is None:
        return [("", base)]
    return [(f"{claim.each} {_num(v)}", base | {claim.each: v}) for v in base[claim.each]]


def _region(claim: Claim, bound: float | None = None) -> Region:
    """Where the figure must lie: the criterion's bound (or ``bound``, a factor or 0 for another selection)."""
    if claim.kind == "within":
        return Region(claim.arg[0], claim.arg[1])
    if claim.kind == "near":
        return Region(claim.arg - claim.tolerance, claim.arg + claim.tolerance)
    b = float(claim.arg) if bound is None else bound
    return {"at_least": Region(low=b), "at_most": Region(high=b), "above": Region(low=b, low_closed=False),
            "below": Region(high=b, high_closed=False)}[claim.kind]


def _overall(verdicts: list[Verdict]) -> Verdict:
    """A claim's verdict from its parts' (every part must hold)."""
    if not verdicts:
        return Verdict.NO_DATA
    for v in (Verdict.NOT_REPRODUCED, Verdict.NO_DATA, Verdict.TOO_FEW, Verdict.INCONCLUSIVE):
        if v in verdicts:
            return v
    return Verdict.REPRODUCED


def _num(v: Any) -> str:
    """A number as a table shows it: ``-`` for none, integers bare, else three significant figures."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if isinstance(v, bool) or not isinstance(v, int | float):
        return str(v).lower() if isinstance(v, bool) else str(v)
    if float(v).is_integer() and abs(v) < 1e6:
        return str(int(v))
    return f"{v:.1f}" if abs(v) >= 100 else f"{v:.3g}"


def _other(other: dict[str, Any], times: float) -> str:
    sel = ", ".join(f"{k}={_num(v)}" for k, v in other.items())
    return f"{_num(times)} x {sel}" if times != 1.0 else sel


# --- a study's claims --------------------------------------------------------------------------------------

def settings(study: dict[str, Any]) -> list[dict[str, Any]]:
    """The selections the claims are judged under: one per value of ``[paper] beside`` in the grid, or {}."""
    beside = study.get("paper", {}).get("beside")
    return [{beside: v} for v in study.get("grid", {}).get(beside, [])] if beside else [{}]


def evaluate(study: dict[str, Any], rows: list[dict[str, Any]], baseline: str | None,
             boot: Bootstrap | None = None, level: float | None = None) -> list[Judged]:
    """Every claim of a study (its TOML as a dict) judged on the rows, once per :func:`settings` entry, paired
    by the study's replicates (its seeds and ``[study] replicates`` keys)."""
    claims = parse(study.get("paper", {}), f"study {study.get('study', {}).get('name', '')}".strip(),
                   study.get("grid", {}))
    runs = Runs(rows, baseline, study.get("study", {}).get("replicates", []))
    return [judge(c, runs, w, boot, level) for c in claims for w in settings(study)]
