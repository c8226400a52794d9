"""A study's ``[[paper.claims]]``: each of the paper's findings with a machine-checkable criterion, judged on
the sweep's numbers as *reproduced*, *not reproduced* or *no data*.

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
# below = {allocator = "nearest"}                          ... or another selection's value of the metric,
# at_most = {allocator = "minpos", times = 1.8}             times a factor; a list of tables: each of them
# near = 42.7, tolerance = 10                              |ours - near| <= tolerance
# increasing = "loss"                                      strictly, over the listed values in their order
```

``[paper] beside = "map_sync"`` judges every claim once per value of that ``[grid]`` key, side by side (a claim
that names the key itself keeps its own). A claim that is a plain string is the paper's words, not judged.

Pure: :func:`parse` reads the claims, :func:`judge` applies one to a function that gives our number for a
selection and a metric (``fleet sweep report`` passes one over its rows, :func:`row_value`).
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from fleet_emu.core.errors import ConfigError

#: Keys a claim selects runs by.
SELECT = ("allocator", "robots", "loss", "map_sync")
BOUNDS = {"at_least": "≥", "at_most": "≤", "above": ">", "below": "<"}
CRITERIA = ("within", "near", "increasing", "decreasing", *BOUNDS)
_KEYS = {"text", "metric", "each", "tolerance", *SELECT, *CRITERIA}
#: Metrics besides the per-run ones of ``sweep.report.METRICS``.
AGGREGATES = ("vs_baseline_pct", "mean_std_ticks", "vs_loss0_pct", "std_ticks", "reached_pct")
REPRODUCED, NOT_REPRODUCED, NO_DATA, NOT_JUDGED = "reproduced", "not reproduced", "no data", "not judged"

#: Our number for a selection (``SELECT`` keys) and a metric; None when no run gives it.
Value = Callable[[dict[str, Any], str], "float | None"]


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


@dataclasses.dataclass(frozen=True)
class Verdict:
    """A claim judged: our numbers as text (``ours``) and the verdict (:data:`REPRODUCED` ...)."""

    claim: Claim
    ours: str
    verdict: str
    where: dict[str, Any] = dataclasses.field(default_factory=dict)


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
    return [_claim(c, f"{where}: claim {i + 1}", metrics) for i, c in enumerate(raw)]


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
    return isinstance(x, int | float) and not isinstance(x, bool) and not math.isnan(x)


# --- judging -----------------------------------------------------------------------------------------------

def judge(claim: Claim, value: Value, where: dict[str, Any] | None = None) -> Verdict:
    """The claim on our numbers (``value``), for the runs ``where`` also selects (``beside``'s value; the
    claim's own selection wins)."""
    where = where or {}
    if not claim.kind:
        return Verdict(claim, "", NOT_JUDGED, where)
    base = where | claim.select
    if claim.kind in ("increasing", "decreasing"):
        return _monotone(claim, value, base, where)
    parts, verdicts = [], []
    for label, sel in _each(claim, base):
        text, ok = _one(claim, value, sel)
        parts.append(f"{label}: {text}" if label else text)
        verdicts.append(ok)
    return Verdict(claim, "; ".join(parts), _overall(verdicts), where)


def _each(claim: Claim, base: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """The selections to judge: one, or one per value ``each`` lists."""
    if claim.each is None:
        return [("", base)]
    return [(f"{_num(v)}", base | {claim.each: v}) for v in base[claim.each]]


def _one(claim: Claim, value: Value, sel: dict[str, Any]) -> tuple[str, bool | None]:
    """Our number for one selection as text, and whether the criterion holds (None: no data)."""
    ours = _clean(value(sel, claim.metric))
    if claim.kind == "within":
        lo, hi = claim.arg
        return _num(ours), None if ours is None else lo <= ours <= hi
    if claim.kind == "near":
        return _num(ours), None if ours is None else abs(ours - claim.arg) <= claim.tolerance
    if not isinstance(claim.arg, tuple):
        return _num(ours), None if ours is None else _holds(claim.kind, ours, claim.arg)
    texts, oks = [], []
    for other, times in claim.arg:
        theirs = _clean(value(sel | other, claim.metric))
        texts.append(f"{_other(other, times)} {_num(theirs)}")
        oks.append(None if ours is None or theirs is None else _holds(claim.kind, ours, times * theirs))
    return f"{_num(ours)} vs " + ", ".join(texts), _overall_bool(oks)


def _holds(kind: str, ours: float, bound: float) -> bool:
    return {"at_least": ours >= bound, "at_most": ours <= bound, "above": ours > bound, "below": ours < bound}[kind]


def _monotone(claim: Claim, value: Value, base: dict[str, Any], where: dict[str, Any]) -> Verdict:
    """Strictly increasing (decreasing) over the listed values of the key, in their order."""
    key = claim.arg
    vals = [_clean(value(base | {key: v}, claim.metric)) for v in base[key]]
    text = " → ".join(f"{_num(k)}: {_num(v)}" for k, v in zip(base[key], vals, strict=True))
    if any(v is None for v in vals):
        return Verdict(claim, text, NO_DATA, where)
    pairs = itertools.pairwise(v for v in vals if v is not None)
    ok = all((b > a) if claim.kind == "increasing" else (b < a) for a, b in pairs)
    return Verdict(claim, text, REPRODUCED if ok else NOT_REPRODUCED, where)


def _overall_bool(oks: list[bool | None]) -> bool | None:
    """False when one fails, else None when one has no data, else True."""
    if any(ok is False for ok in oks):
        return False
    return None if any(ok is None for ok in oks) else True


def _overall(oks: list[bool | None]) -> str:
    ok = _overall_bool(oks)
    return NO_DATA if ok is None else REPRODUCED if ok else NOT_REPRODUCED


def _clean(v: float | None) -> float | None:
    return None if v is None or math.isnan(v) else float(v)


def _num(v: Any) -> str:
    """A number as a table shows it: ``-`` for none, integers bare, else one decimal."""
    if v is None:
        return "-"
    if isinstance(v, bool) or not isinstance(v, int | float):
        return str(v).lower() if isinstance(v, bool) else str(v)
    if float(v).is_integer():
        return str(int(v))
    return f"{v:.1f}" if abs(v) >= 1 else f"{v:.2g}"


def _other(other: dict[str, Any], times: float) -> str:
    sel = ", ".join(f"{k}={_num(v)}" for k, v in other.items())
    return f"{_num(times)} x {sel}" if times != 1.0 else sel


# --- the report --------------------------------------------------------------------------------------------

def row_value(rows: list[dict[str, Any]], lines: list[dict[str, Any]], baseline: str | None) -> Value:
    """Our number for a selection and a metric, from a sweep's rows (every run, failed ones too) and its
    summary lines against ``baseline`` (``sweep.report.summary``): ``reached_pct`` over every run selected,
    the rest as ``[[paper.rows]]`` get theirs (``sweep.report.paper_value``, over the runs that did not fail)."""
    from fleet_emu.sweep.report import paper_value

    ok = [r for r in rows if r.get("status") == "ok"]

    def value(sel: dict[str, Any], metric: str) -> float | None:
        if metric == "reached_pct":
            mine = [r for r in rows if _selected(r, sel)]
            done = sum(bool(r.get("completed")) and r.get("status") == "ok" for r in mine)
            return 100.0 * done / len(mine) if mine else None
        return paper_value(sel | {"metric": metric}, ok, lines, baseline)

    return value


def _selected(row: dict[str, Any], sel: dict[str, Any]) -> bool:
    """Whether a sweep row is one of a selection's runs (a list: any of its values)."""
    for k, want in sel.items():
        got = row.get({"allocator": "param.allocator", "loss": "loss_applied"}.get(k, k))
        if k == "map_sync":
            got = got is not False
        if not (got in want if isinstance(want, list) else got == want):
            return False
    return True


def settings(study: dict[str, Any]) -> list[dict[str, Any]]:
    """The selections the claims are judged under: one per value of ``[paper] beside`` in the grid, or {}."""
    beside = study.get("paper", {}).get("beside")
    return [{beside: v} for v in study.get("grid", {}).get(beside, [])] if beside else [{}]


def evaluate(study: dict[str, Any], rows: list[dict[str, Any]], lines: list[dict[str, Any]],
             baseline: str | None) -> list[list[Verdict]]:
    """Every claim of a study (its TOML as a dict) judged on the rows, once per :func:`settings` entry."""
    claims = parse(study.get("paper", {}), f"study {study.get('study', {}).get('name', '')}".strip(),
                   study.get("grid", {}))
    value = row_value(rows, lines, baseline)
    return [[judge(c, value, w) for w in settings(study)] for c in claims]


def table(judged: list[list[Verdict]], source: str) -> Any:
    """``claim | criterion | ours | verdict``, an ours and a verdict column per setting (``beside``)."""
    from rich.table import Table

    t = Table(title=f"the paper's claims, judged on ours — {source}")
    t.add_column("claim")
    t.add_column("criterion")
    heads = [_setting(v.where) for v in judged[0]] if judged else [""]
    for head in heads:
        t.add_column(f"ours{head}")
        t.add_column(f"verdict{head}", no_wrap=True)
    style = {REPRODUCED: "green", NOT_REPRODUCED: "red", NO_DATA: "dim", NOT_JUDGED: "dim"}
    for verdicts in judged:
        claim = verdicts[0].claim
        cells = [x for v in verdicts for x in (v.ours or "-", f"[{style[v.verdict]}]{v.verdict}[/]")]
        t.add_row(claim.text, claim.criterion(), *cells)
    return t


def _setting(where: dict[str, Any]) -> str:
    return "".join(f", {k} = {_num(v)}" for k, v in where.items())


def write_json(judged: list[list[Verdict]], path: Path) -> Path:
    """The verdicts as JSON (``claims.json`` beside the results): per claim its text, criterion, and per setting
    the selection it adds, our numbers and the verdict."""
    doc = [{"claim": v[0].claim.text, "criterion": v[0].claim.criterion(),
            "judged": [{"where": x.where, "ours": x.ours, "verdict": x.verdict} for x in v]} for v in judged]
    path.write_text(json.dumps(doc, indent=1, ensure_ascii=False) + "\n")
    return path
