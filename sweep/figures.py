"""A claim's figures computed on a sweep's rows under replicate weights, so that one pass gives the figure (every
replicate once) and its bootstrap resamples (each replicate drawn 0, 1, 2 ... times) together.

Every figure reduces to sums per replicate: for a selection of runs and a metric, ``S0[u]`` (how many runs of
replicate ``u`` give a value), ``S1[u]`` and ``S2[u]`` (the sum of the values and of their squares); under
weights ``W`` (one row per resample, one column per replicate) a mean is ``(W @ S1) / (W @ S0)``. The metrics are
those of ``[[paper.rows]]`` (:func:`fleet_emu.sweep.report.paper_value`, which calls :func:`value` at unit weights,
so the paper table and the claims read one definition):

- a per-run metric (``ticks``, ``moves``, ``connected_pct`` ...; :data:`fleet_emu.sweep.report.METRICS`): its mean
  over the selected runs that did not fail;
- ``reached_pct``: the share of the selected runs, failed ones included, that reached the target;
- ``std_ticks``: the standard deviation of the time over the selected runs;
- ``vs_baseline_pct``: per summary line (a grid point and an allocator) the % difference of its mean time to the
  baseline allocator's at the same point, averaged over the lines the selection holds;
- ``mean_std_ticks``: the time's standard deviation per line, averaged likewise;
- ``vs_loss0_pct``: the % change, from loss 0, of the mean times summed over the robot counts.
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings
from collections.abc import Iterable
from typing import Any

import numpy as np

#: How a selection key reads a row (the rest: ``param.<key>``, the grid value as the row holds it).
COLUMNS = {"allocator": "param.allocator", "loss": "loss_applied", "robots": "robots", "map_sync": "map_sync"}
#: Keys whose value is a cell, a list of two numbers.
CELLS = ("start", "base")


@dataclasses.dataclass(frozen=True)
class Figure:
    """A figure under every weight row (``values``; row 0 unit weights) and the replicates it rests on."""

    values: np.ndarray
    present: np.ndarray

    @property
    def n(self) -> int:
        return int(self.present.sum())


class Runs:
    """A sweep's rows as arrays: each row's replicate (its seed and the study's ``replicates`` keys) and its
    summary group (the grid point but for the allocator and the replicate), the selection columns and the
    metrics, read once."""

    def __init__(self, rows: list[dict[str, Any]], baseline: str | None, replicates: Iterable[str] = ()) -> None:
        from fleet_emu.sweep.report import GROUP, axes

        self.rows, self.baseline = rows, baseline
        reps = ["param.seed", *(f"param.{k}" for k in replicates)]
        self.unit, self.units = _index([tuple(key(r.get(k)) for k in reps) for r in rows])
        keys = GROUP + axes(rows, replicates)
        self.group, _ = _index([tuple(key(r.get(k)) for k in keys) for r in rows])
        self.ok = np.array([r.get("status") == "ok" for r in rows], dtype=bool)
        self._metrics: dict[str, np.ndarray] = {}

    def metric(self, name: str) -> np.ndarray:
        """A per-run metric for every row (NaN for a failed run or a run without it)."""
        if name not in self._metrics:
            from fleet_emu.sweep.report import METRICS

            if name == "reached":
                v = np.array([bool(r.get("completed")) and r.get("status") == "ok" for r in self.rows], float)
            else:
                v = np.array([METRICS[name](r) for r in self.rows], dtype=float)
                v[~self.ok] = np.nan
            self._metrics[name] = v
        return self._metrics[name]

    def select(self, sel: dict[str, Any]) -> np.ndarray:
        """The rows a selection picks (a list: any of its values)."""
        mask = np.ones(len(self.rows), dtype=bool)
        for k, want in sel.items():
            col = COLUMNS.get(k, f"param.{k}")
            wants = [key(w) for w in _choices(k, want)]
            got = [key(r.get(col)) for r in self.rows]
            mask &= np.array([g in wants for g in got], dtype=bool)
        return mask

    def sums(self, mask: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``S0, S1, S2`` per replicate over the rows of ``mask`` whose ``x`` is a number."""
        m = mask & ~np.isnan(x)
        n = len(self.units)
        s0 = np.bincount(self.unit[m], minlength=n).astype(float)
        s1 = np.bincount(self.unit[m], weights=x[m], minlength=n)
        s2 = np.bincount(self.unit[m], weights=x[m] ** 2, minlength=n)
        return s0, s1, s2


def value(runs: Runs, sel: dict[str, Any], metric: str, weights: np.ndarray) -> Figure:
    """A metric (one of the module docstring's) over a selection, under ``weights`` (resamples x replicates)."""
    if metric == "reached_pct":
        return _scale(_mean(runs, runs.select(sel), runs.metric("reached"), weights), 100.0)
    if metric == "std_ticks":
        return _std(runs, runs.select(sel), runs.metric("ticks"), weights)
    if metric in ("vs_baseline_pct", "mean_std_ticks"):
        return _per_line(runs, sel, metric, weights)
    if metric == "vs_loss0_pct":
        return _vs_loss0(runs, sel, weights)
    return _mean(runs, runs.select(sel), runs.metric(metric), weights)


def difference(a: Figure, b: Figure) -> Figure:
    """``a - b``, paired: on the replicates both rest on."""
    return Figure(a.values - b.values, a.present & b.present)


def ratio(a: Figure, b: Figure) -> Figure:
    with np.errstate(divide="ignore", invalid="ignore"):
        return Figure(np.where(b.values != 0, a.values / b.values, np.nan), a.present & b.present)


def _scale(f: Figure, k: float) -> Figure:
    return Figure(f.values * k, f.present)


def _mean(runs: Runs, mask: np.ndarray, x: np.ndarray, w: np.ndarray) -> Figure:
    s0, s1, _ = runs.sums(mask, x)
    with np.errstate(divide="ignore", invalid="ignore"):
        return Figure((w @ s1) / (w @ s0), s0 > 0)


def _std(runs: Runs, mask: np.ndarray, x: np.ndarray, w: np.ndarray) -> Figure:
    """The standard deviation (ddof 1) with each run counted as often as its replicate is drawn."""
    s0, s1, s2 = runs.sums(mask, x)
    n, t1, t2 = w @ s0, w @ s1, w @ s2
    with np.errstate(divide="ignore", invalid="ignore"):
        var = np.where(n > 1, (t2 - t1 * t1 / n) / (n - 1), np.nan)
    return Figure(np.sqrt(np.maximum(var, 0.0)), s0 > 0)


def _per_line(runs: Runs, sel: dict[str, Any], metric: str, w: np.ndarray) -> Figure:
    """``vs_baseline_pct`` or ``mean_std_ticks``: per summary line of the selection, averaged over the lines."""
    ticks = runs.metric("ticks")
    mask = runs.select(sel)
    base_mask = runs.select({"allocator": runs.baseline}) if runs.baseline is not None else None
    lines: list[Figure] = []
    allocs = np.array([str(r.get("param.allocator")) for r in runs.rows])
    for g in np.unique(runs.group[mask]):
        in_g = runs.group == g
        for a in np.unique(allocs[mask & in_g]):
            mine = mask & in_g & (allocs == a)
            if metric == "mean_std_ticks":
                std = _std(runs, mine, ticks, w)
                s0 = runs.sums(mine, ticks)[0]
                lines.append(Figure(np.where(w @ s0 > 1, std.values, np.nan), std.present))
            elif base_mask is not None:
                ours, theirs = _mean(runs, mine, ticks, w), _mean(runs, in_g & base_mask, ticks, w)
                with np.errstate(divide="ignore", invalid="ignore"):
                    pct = np.where(theirs.values != 0, 100.0 * (ours.values - theirs.values) / theirs.values, np.nan)
                lines.append(Figure(pct, ours.present & theirs.present))
    return _mean_of(lines, w)


def _vs_loss0(runs: Runs, sel: dict[str, Any], w: np.ndarray) -> Figure:
    """The % change from loss 0 of the sum over robot counts of the mean times (the counts both hold)."""
    ticks = runs.metric("ticks")
    at, zero = runs.select(sel), runs.select(sel | {"loss": 0.0})
    robots = np.array([key(r.get("robots")) for r in runs.rows], dtype=object)
    both = sorted(set(robots[at]) & set(robots[zero]), key=str)
    if not both:
        return _nothing(runs, w)
    sums = []
    for mask in (at, zero):
        means = [_mean(runs, mask & (robots == n), ticks, w) for n in both]
        sums.append(Figure(np.sum([m.values for m in means], axis=0),
                           np.logical_or.reduce([m.present for m in means])))
    with np.errstate(divide="ignore", invalid="ignore"):
        pct = 100.0 * (sums[0].values - sums[1].values) / sums[1].values
    return Figure(pct, sums[0].present & sums[1].present)


def _mean_of(lines: list[Figure], w: np.ndarray) -> Figure:
    """The mean over lines (each NaN left out), on the replicates any of them rests on."""
    if not lines:
        return Figure(np.full(w.shape[0], np.nan), np.zeros(w.shape[1], dtype=bool))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a resample without any line: NaN
        values = np.nanmean(np.array([f.values for f in lines]), axis=0)
    return Figure(values, np.logical_or.reduce([f.present for f in lines]))


def _nothing(runs: Runs, w: np.ndarray) -> Figure:
    return Figure(np.full(w.shape[0], np.nan), np.zeros(len(runs.units), dtype=bool))


def _index(keys: list[tuple[Any, ...]]) -> tuple[np.ndarray, tuple[tuple[Any, ...], ...]]:
    """Each key's index among the distinct keys (in order of first appearance), and those keys."""
    seen: dict[tuple[Any, ...], int] = {}
    idx = np.array([seen.setdefault(k, len(seen)) for k in keys], dtype=np.int64)
    return idx, tuple(seen)


def key(v: Any) -> Any:
    """A value as a comparable, hashable key: lists as tuples, integral floats as ints (a loss of 0 and 0.0, a
    robot count read back as 3.0, are one value)."""
    if isinstance(v, list | tuple):
        return tuple(key(x) for x in v)
    if isinstance(v, str) and v.startswith("["):  # a list the rows hold as JSON text (a start cell)
        try:
            return key(json.loads(v))
        except ValueError:
            return v
    if isinstance(v, float) and math.isfinite(v) and v.is_integer():
        return int(v)
    if isinstance(v, np.generic):
        return key(v.item())
    return v


def _choices(key: str, want: Any) -> list[Any]:
    """A selection's values: a list is any of them, but a cell (``start = [11, 6]``) is one value."""
    if not isinstance(want, list):
        return [want]
    if key in CELLS and not all(isinstance(x, list) for x in want):
        return [want]
    return want
