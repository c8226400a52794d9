"""The figures of ``fleet sweep report`` (matplotlib, Agg): time to target vs robot count and vs loss, mean coverage
vs tick, time vs bandwidth; one line per allocator.

A band is drawn only over the replicates of one grid point: every other grid key the study varies gets a panel
of its own, never pooled into a line. A point's interval is Student's t interval of the mean at the report's
level, over that point's runs that reached the target; the legend says how many runs (n) each point rests on
and the level; a point of one run has no interval. Legends stand outside the axes. Coverage is in percent, as in
``fleet report``'s plots."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from fleet_emu.sweep.intervals import level_text
from fleet_emu.sweep.report import GROUP, axes, by, time_to_target

TITLES = {"time_vs_robots": "Time to the target against the robot count",
          "time_vs_loss": "Time to the target against the loss"}
#: The most panels a figure draws (the rest are left out, and the figure says so).
MOST_PANELS = 24


def draw(rows: list[dict[str, Any]], out: Path, replicates: Any = (), level: float = 0.95) -> list[Path]:
    """Write the figures into ``out``; the paths written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    written = []
    for name, x_key, x_label in (("time_vs_robots", "robots", "robots"),
                                 ("time_vs_loss", "loss_applied", "loss probability")):
        if len({r.get(x_key) for r in rows}) < 2 and name == "time_vs_loss":
            continue
        written.append(_time_figure(rows, out / f"{name}.png", x_key, x_label, TITLES[name], replicates, level,
                                    plt))
    if len({r.get("bandwidth") for r in rows}) > 1:
        written.append(_time_vs_bandwidth(rows, out, plt))
    written.append(_coverage(rows, out, plt, replicates))
    return written


def panel_keys(rows: list[dict[str, Any]], x_key: str | None, replicates: Any = ()) -> tuple[str, ...]:
    """The grid keys (as rows name them) that vary and are neither the x axis, the allocator, the seed nor a
    replicate: one panel per combination of their values."""
    keys = [k for k in (*GROUP, *axes(rows, replicates)) if k != x_key]
    return tuple(k for k in keys if len({json.dumps(r.get(k), default=str) for r in rows}) > 1)


def _panels(rows: list[dict[str, Any]], keys: tuple[str, ...]) -> list[tuple[str, list[dict[str, Any]]]]:
    if not keys:
        return [("", rows)]
    return [(", ".join(f"{_short(k)} {_val(v)}" for k, v in zip(keys, vals, strict=True)), runs)
            for vals, runs in by(rows, *keys).items()]


def _time_figure(rows: list[dict[str, Any]], path: Path, x_key: str, x_label: str, title: str, replicates: Any,
                 level: float, plt: Any) -> Path:
    panels = _panels(rows, panel_keys(rows, x_key, replicates))
    shown = panels[:MOST_PANELS]
    cols = min(len(shown), 4)
    grid = (len(shown) + cols - 1) // cols
    fig, axs = plt.subplots(grid, cols, figsize=(4.2 * cols + 2.2, 3.4 * grid + 0.9), squeeze=False)
    xs = sorted({float(r[x_key]) for r in rows if isinstance(r.get(x_key), int | float)})
    step = min(np.diff(xs)) if len(xs) > 1 else 1.0
    drawn = False
    for ax, (label, runs) in zip(axs.flat, shown, strict=False):
        series = by(runs, "param.allocator")
        for i, ((alloc,), pts) in enumerate(series.items()):
            drawn |= _time_line(ax, str(alloc), pts, x_key, (i - (len(series) - 1) / 2) * 0.05 * step, level)
        _x_axis(ax, xs, integer=x_key == "robots")
        ax.set(title=label or None, xlabel=x_label, ylabel=f"ticks to the target (mean, {level_text(level)} CI)")
        ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
    for ax in axs.flat[len(shown):]:
        ax.set_visible(False)
    handles, labels = axs.flat[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.0, 0.95), fontsize="small",
                   title=f"n: runs per point; bars: {level_text(level)} CI")
    more = f" ({len(panels) - len(shown)} more panels not drawn)" if len(panels) > len(shown) else ""
    fig.suptitle(title + ("" if drawn else " (no run reached the target)") + more)
    return _save(fig, path)


def _time_line(ax: Any, alloc: str, runs: list[dict[str, Any]], x_key: str, dodge: float, level: float) -> bool:
    """One allocator's mean time to the target against ``x_key`` (shifted by ``dodge`` so that the allocators'
    bars stay apart), each point's interval over its own runs; False when none reached the target."""
    xs, mean, half, n = [], [], [], []
    for (x,), pts in by(runs, x_key).items():
        v = np.array([time_to_target(r) for r in pts], dtype=float)
        v = v[~np.isnan(v)]
        if len(v):
            xs.append(float(x) + dodge)
            mean.append(v.mean())
            half.append(t_half(v, level))
            n.append(len(v))
    if not xs:
        return False
    order = np.argsort(xs)
    x, m, h = np.array(xs)[order], np.array(mean)[order], np.nan_to_num(np.array(half)[order])
    low = np.minimum(h, m)  # never below 0 ticks
    ax.errorbar(x, m, yerr=[low, h], marker="o", capsize=4, label=f"{alloc} ({runs_label(n)})")
    return True


def t_half(v: np.ndarray, level: float) -> float:
    """Half-width of Student's t interval of the mean at ``level``; NaN under two values."""
    if len(v) < 2:
        return math.nan
    from scipy.special import stdtrit  # Student's t quantile, without importing scipy.stats

    return float(stdtrit(len(v) - 1, 0.5 + level / 2) * v.std(ddof=1) / math.sqrt(len(v)))


def runs_label(n: list[int]) -> str:
    """What a line's points rest on: ``n = 5``, ``n = 2-5``; one run has no interval."""
    lo, hi = min(n), max(n)
    if hi == 1:
        return "n = 1, no interval"
    return f"n = {lo}" if lo == hi else f"n = {lo}-{hi}"


def _short(key: str) -> str:
    return {"loss_applied": "loss", "map_sync": "map sync"}.get(key, key.removeprefix("param."))


def _val(v: Any) -> str:
    if isinstance(v, bool):
        return "on" if v else "off"
    return Path(v).stem if isinstance(v, str) and "/" in v else f"{v:g}" if isinstance(v, float) else str(v)


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


def _coverage(rows: list[dict[str, Any]], out: Path, plt: Any, replicates: Any = ()) -> Path:
    """Mean coverage (%) against tick, a curve per allocator, a panel per grid point (but the allocator and the
    replicate); a run that ended holds its last coverage."""
    panels = _panels(rows, panel_keys(rows, None, replicates))
    shown = panels[:MOST_PANELS]
    cols = min(len(shown), 5)
    grid = (len(shown) + cols - 1) // cols
    fig, axs = plt.subplots(grid, cols, figsize=(3.2 * cols + 2.2, 3.0 * grid + 0.8), squeeze=False,
                            sharey=True)
    for ax, (label, runs) in zip(axs.flat, shown, strict=False):
        for (alloc,), pts in by(runs, "param.allocator").items():
            curves = [np.array(json.loads(r["curve"]), dtype=float) for r in pts if r.get("curve")]
            if not curves:
                continue
            every = int(pts[0].get("curve_every") or 1)
            size = max(len(c) for c in curves)
            padded = np.array([np.pad(c, (0, size - len(c)), mode="edge") for c in curves])
            ax.plot(np.arange(size) * every, 100 * padded.mean(axis=0), label=f"{alloc} (n = {len(curves)})")
        ax.set(title=label or "Coverage by tick", xlabel="tick", ylim=(0, 102))
        ax.title.set_fontsize("small")
        ax.grid(alpha=0.3)
    for ax in axs.flat[len(shown):]:
        ax.set_visible(False)
    for row in axs:
        row[0].set_ylabel("coverage (%, mean of runs)")
    handles, labels = axs.flat[0].get_legend_handles_labels()
    if handles:
        fig.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.0, 0.95), fontsize="small")
    more = f" ({len(panels) - len(shown)} more panels not drawn)" if len(panels) > len(shown) else ""
    fig.suptitle("Coverage by tick, mean of runs" + more)
    return _save(fig, out / "coverage_vs_tick.png")


def _save(fig: Any, path: Path) -> Path:
    fig.tight_layout()
    from fleet_emu.core.files import write_atomic

    # the legends outside the axes included; written whole, never through a link planted at its name
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=110, bbox_inches="tight"))
    import matplotlib.pyplot as plt

    plt.close(fig)
    return path
