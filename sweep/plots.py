"""The figures of ``fleet sweep report`` (matplotlib, Agg): time to target vs robot count with 95 % confidence
bands, mean coverage vs tick, time vs loss and time vs bandwidth; one line per allocator.

An interval says how many seeds it rests on (in the legend) and is never drawn below 0 ticks; with one seed a point
has none. Coverage is in percent, as in ``fleet report``'s plots, with one panel per robot count when the study
has several (a mean over robot counts would mix fleets that explore at different speeds). Titles are short enough
to fit their panel; what a figure averages is said in its axis labels."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from fleet_emu.sweep.report import by, ci95, time_to_target

TITLES = {"time_vs_robots": "Time to the target against the robot count",
          "time_vs_loss": "Time to the target against the loss"}


def draw(rows: list[dict[str, Any]], out: Path) -> list[Path]:
    """Write the figures into ``out``; the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for name, x_key, x_label in (("time_vs_robots", "robots", "robots"),
                                 ("time_vs_loss", "loss_applied", "loss probability")):
        if name == "time_vs_loss" and len({r.get("loss_applied") for r in rows}) < 2:
            continue
        fig, ax = plt.subplots(figsize=(7, 4.5))
        xs = sorted({float(r[x_key]) for r in rows if isinstance(r.get(x_key), int | float)})
        step = min(np.diff(xs)) if len(xs) > 1 else 1.0 if x_key == "robots" else max(0.2, abs(xs[0]) if xs else 1)
        groups = _series(rows)
        drawn = sum(_time_line(ax, label, runs, x_key, (i - (len(groups) - 1) / 2) * 0.05 * step)
                    for i, (label, runs) in enumerate(groups.items()))
        _x_axis(ax, xs, integer=x_key == "robots")
        ax.set_title(TITLES[name] + ("" if drawn else " (no run reached the target)"))
        ax.set_xlabel(x_label)
        ax.set_ylabel("ticks to the target (mean, 95 % CI)")
        ax.grid(alpha=0.3)
        if drawn:
            ax.set_ylim(bottom=0)  # a wide confidence interval does not reach below no time
            ax.legend()
        written.append(_save(fig, out / f"{name}.png"))
    if len({r.get("bandwidth") for r in rows}) > 1:
        written.append(_time_vs_bandwidth(rows, out, plt))
    written.append(_coverage(rows, out, plt))
    return written


def _series(rows: list[dict[str, Any]]) -> dict[str, list[dict[str, Any]]]:
    """The lines of a figure: one per allocator, and per map sync setting when the study has both."""
    both = len({r.get("map_sync") is not False for r in rows}) > 1
    out: dict[str, list[dict[str, Any]]] = {}
    for (alloc, sync), runs in by(rows, "param.allocator", "map_sync").items():
        label = f"{alloc}, map sync {'on' if sync is not False else 'off'}" if both else str(alloc)
        out.setdefault(label, []).extend(runs)
    return out


def _time_line(ax: Any, alloc: str, runs: list[dict[str, Any]], x_key: str, dodge: float) -> bool:
    """One allocator's mean time to the target against ``x_key`` (shifted by ``dodge``, so that the
    allocators' bars stay apart), with its 95 % CI as error bars and a band; False when none of its runs
    reached the target."""
    xs, mean, half, n = [], [], [], []
    for (x,), pts in by(runs, x_key).items():
        v = np.array([time_to_target(r) for r in pts], dtype=float)
        v = v[~np.isnan(v)]
        if len(v):
            xs.append(float(x) + dodge)
            mean.append(v.mean())
            half.append(ci95(v) if len(v) > 1 else 0.0)
            n.append(len(v))
    if not xs:
        return False
    order = np.argsort(xs)
    x, m, h = np.array(xs)[order], np.array(mean)[order], np.nan_to_num(np.array(half)[order])
    low = np.minimum(h, m)  # never below 0 ticks
    ax.errorbar(x, m, yerr=[low, h], marker="o", capsize=4, label=f"{alloc} ({seeds_label(n)})")
    if len(x) > 1:
        ax.fill_between(x, m - low, m + h, alpha=0.2)
    return True


def seeds_label(n: list[int]) -> str:
    """What a line's intervals rest on: ``CI of 5 seeds``, ``CI of 2-5 seeds``; one seed has no interval."""
    lo, hi = min(n), max(n)
    if hi == 1:
        return "1 seed, no CI"
    return f"CI of {lo} seeds" if lo == hi else f"CI of {lo}-{hi} seeds"


def _x_axis(ax: Any, xs: list[float], integer: bool) -> None:
    """Ticks at the grid's values (robot counts as integers), with room around a single value."""
    if not xs:
        return
    ax.set_xticks(xs, [f"{x:g}" for x in xs])
    if len(xs) == 1:
        pad = 1.0 if integer else max(0.1, abs(xs[0]) * 0.5)
        ax.set_xlim(xs[0] - pad, xs[0] + pad)


def _time_vs_bandwidth(rows: list[dict[str, Any]], out: Path, plt: Any) -> Path:
    """Time to the target against the radio's bandwidth per allocator, one panel per map and robot count; the
    rates are categories from unlimited (0) down, each point the mean over the runs that reached the target."""
    rates = sorted({float(r.get("bandwidth") or 0.0) for r in rows}, key=lambda b: -b if b else -float("inf"))
    panels = by(rows, "map", "robots")
    fig, axes = plt.subplots(1, len(panels), figsize=(4.5 * len(panels), 4.2), squeeze=False, sharey=False)
    for ax, ((map_name, robots), runs) in zip(axes[0], panels.items(), strict=True):
        for (alloc,), pts in by(runs, "param.allocator").items():
            at = {float(b or 0.0): [time_to_target(r) for r in p] for (b,), p in by(pts, "bandwidth").items()}
            ys = [np.nanmean(at[b]) if b in at and not np.isnan(at[b]).all() else np.nan for b in rates]
            ax.plot(range(len(rates)), ys, marker="o", label=str(alloc))
        ax.set_xticks(range(len(rates)), [f"{b:g}" if b else "unlimited" for b in rates])
        ax.set_title(f"{Path(str(map_name)).stem}, {robots} robots")
        ax.set_xlabel("bandwidth (kbit/s)")
        ax.grid(alpha=0.3)
    axes[0][0].set_ylabel("ticks to the target (mean of runs that reached it)")
    axes[0][-1].legend(fontsize="small")
    return _save(fig, out / "time_vs_bandwidth.png")


def _coverage(rows: list[dict[str, Any]], out: Path, plt: Any) -> Path:
    """Mean coverage (%) against tick, a curve per allocator, a panel per robot count (a run that ended holds its
    last coverage)."""
    panels = by(rows, "robots")
    cols = min(len(panels), 5)
    grid = (len(panels) + cols - 1) // cols
    fig, axes = plt.subplots(grid, cols, figsize=(3.2 * cols + 1.5, 3.0 * grid + 0.8), squeeze=False,
                             sharey=True)
    for ax, ((robots,), runs) in zip(axes.flat, panels.items(), strict=False):
        for (alloc,), pts in by(runs, "param.allocator").items():
            curves = [np.array(json.loads(r["curve"]), dtype=float) for r in pts if r.get("curve")]
            if not curves:
                continue
            every = int(pts[0].get("curve_every") or 1)
            n = max(len(c) for c in curves)
            padded = np.array([np.pad(c, (0, n - len(c)), mode="edge") for c in curves])
            ax.plot(np.arange(n) * every, 100 * padded.mean(axis=0), label=f"{alloc} ({len(curves)} runs)")
        ax.set_title(f"{robots} robot{'s' if robots != 1 else ''}" if len(panels) > 1 else "Coverage by tick")
        ax.set(xlabel="tick", ylim=(0, 102))
        ax.grid(alpha=0.3)
        ax.legend(fontsize="x-small")
    for ax in axes.flat[len(panels):]:
        ax.set_visible(False)
    for row in axes:
        row[0].set_ylabel("coverage (%, mean of runs)")
    if len(panels) > 1:
        fig.suptitle("Coverage by tick, per robot count")
    return _save(fig, out / "coverage_vs_tick.png")


def _save(fig: Any, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path
