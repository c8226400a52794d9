"""The PNG plots of ``fleet report`` (matplotlib's Agg canvas: no display needed).

:data:`PLOTS` maps each plot a report writes beside a recording to the function drawing it; ``--compare``
overlays several runs' coverage curves with :func:`compare_plot`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from fleet_emu.recording.foxglove import robot_rgb
from fleet_emu.recording.read import Run
from fleet_emu.recording.tables import fmt


def _figure(rows: int = 1, height: float = 3.6) -> tuple[Any, Any]:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, height * rows if rows > 1 else height), dpi=110, layout="constrained")
    axes = fig.subplots(rows, 1, sharex=True) if rows > 1 else fig.subplots()
    return fig, axes


def coverage_plot(run: Run, path: Path) -> None:
    fig, ax = _figure()
    t, c = run.coverage_curve()
    ax.plot(t, 100 * c, color="tab:blue", lw=2, label="team coverage")
    target = run.fold.scenario.get("target_coverage", 0.99)
    for level, style in ((0.9, ":"), (0.99, "--")):
        ax.axhline(100 * level, color="grey", ls=style, lw=1)
    m = run.metrics
    for key, label in (("t90", "90 %"), ("t99", "99 %"), ("t100", "100 %")):
        if m[key] is not None:
            ax.axvline(m[key], color="tab:red", ls=":", lw=1)
            ax.annotate(f"{label} @ {m[key]}", (m[key], 5), rotation=90, fontsize=8, color="tab:red",
                        xytext=(3, 0), textcoords="offset points")
    ax.set(xlabel="tick", ylabel="coverage (%)", ylim=(0, 102),
           title=f"coverage: {run.label}, target {target:.0%}")
    ax.grid(alpha=0.3)
    fig.savefig(path)


def connectivity_plot(run: Run, path: Path) -> None:
    """Like Benavides et al. Figs. 6-8: connected or not, links, and the mean signal, per tick."""
    s = run.fold.series
    fig, (a1, a2, a3) = _figure(3, 1.6)
    t, conn = s.arrays("connected")
    a1.fill_between(t, conn, step="post", color="tab:green", alpha=0.5)
    a1.set(ylabel="connected", ylim=(-0.05, 1.05), yticks=[0, 1], yticklabels=["no", "yes"],
           title=f"connectivity: {run.label}, connected {fmt(run.metrics['connected_fraction'], True)}")
    t, links = s.arrays("links")
    n = len(run.fold.robots)
    a2.step(t, links, where="post", color="tab:blue")
    a2.set(ylabel="links", ylim=(-0.2, max(1, n * (n - 1) / 2) + 0.2))
    t, db = s.arrays("strength")
    a3.plot(t, db, color="tab:purple", lw=1)
    a3.axhline(float(run.fold.scenario.get("radio", {}).get("threshold", 0.0)), color="grey", ls="--", lw=1)
    a3.set(ylabel="mean P (dB)", xlabel="tick")
    for a in (a1, a2, a3):
        a.grid(alpha=0.3)
    fig.savefig(path)


def map_plot(run: Run, path: Path) -> None:
    """The team's final map (what the robots sensed, true values) with each robot's trajectory."""
    f = run.fold
    fig, ax = _figure(height=5.5)
    if f.team is not None:
        g = f.team.value.reshape(f.team.shape)
        img = np.full((*f.team.shape, 3), 0.72)
        img[g == 0] = 1.0
        img[g > 0] = 0.1
        ax.imshow(img, interpolation="nearest")
    failed = set(run.metrics.get("failed") or [])
    for r, traj in f.trajectory.items():
        if not traj:
            continue
        rows = [c[0] for _, c in traj]
        cols = [c[1] for _, c in traj]
        color = robot_rgb(r, f.robots)
        ax.plot(cols, rows, color=color, lw=1.5, label=f"{r} ({run.metrics['path']['per_robot'][r]} cells)")
        ax.plot(cols[0], rows[0], "o", color=color, ms=6)
        ax.plot(cols[-1], rows[-1], "x" if r in failed else "s", color=color, ms=7)
    ax.set(title=f"final map and trajectories: {run.label}", xlabel="column", ylabel="row")
    ax.legend(fontsize=7, loc="upper right")
    fig.savefig(path)


def messages_plot(run: Run, path: Path) -> None:
    s = run.fold.series
    fig, ax = _figure()
    t, tx = s.arrays("tx_msgs")
    ax.plot(t, tx, color="tab:blue", lw=1, label="sent (radio messages)")
    t, rx = s.arrays("rx_msgs")
    ax.plot(t, rx, color="tab:green", lw=1, label="delivered (per receiver)")
    ax.set(xlabel="tick", ylabel="messages per tick", title=f"radio traffic: {run.label}")
    ax2 = ax.twinx()
    t, b = s.arrays("tx_bytes")
    ax2.plot(t, b / 1024, color="tab:orange", lw=0.8, alpha=0.7, label="tx bundles (KiB)")
    ax2.set_ylabel("KiB per tick")
    lines = ax.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + lines2[0], lines[1] + lines2[1], fontsize=8, loc="upper right")
    ax.grid(alpha=0.3)
    fig.savefig(path)


def base_plot(run: Run, path: Path) -> None:
    """A run with a base station: the share of live robots with a path of links to the base,
    per tick, and each robot's connected ticks."""
    f = run.fold
    frac = run.metrics.get("base_connected_fraction") or {}
    fig, (a1, a2) = _figure(2, 2.0)
    curve = f.monitor.base_curve
    t = np.array([c[0] for c in curve], dtype=int)
    a1.step(t, np.array([c[1] for c in curve], dtype=float), where="post", color="tab:green", lw=1.2)
    if frac.get("overall") is not None:
        a1.axhline(frac["overall"], color="grey", ls="--", lw=1, label=f"mean {fmt(frac['overall'], True)}")
        a1.legend(fontsize=8, loc="lower left")
    a1.set(ylabel="connected to base", ylim=(-0.05, 1.05),
           title=f"base connectivity: {run.label}, all connected {fmt(frac.get('all_ticks'), True)} of ticks")
    per_robot = frac.get("per_robot") or {}
    for i, r in enumerate(f.robots):
        ticks = [tick for tick, flags in f.series.base.items() if flags.get(r)]
        a2.broken_barh([(tick, 1) for tick in ticks], (i - 0.3, 0.6), color=robot_rgb(r, f.robots))
    a2.set(yticks=range(len(f.robots)), xlabel="tick",
           yticklabels=[f"{r} {fmt(per_robot.get(r), True)}" for r in f.robots], ylim=(-0.7, len(f.robots) - 0.3))
    for a in (a1, a2):
        a.grid(alpha=0.3)
    fig.savefig(path)


def compare_plot(runs: list[Run], path: Path) -> None:
    fig, ax = _figure(height=4.2)
    for run in runs:
        t, c = run.coverage_curve()
        ax.plot(t, 100 * c, lw=1.8, label=run.label)
    ax.axhline(90, color="grey", ls=":", lw=1)
    ax.axhline(99, color="grey", ls="--", lw=1)
    ax.set(xlabel="tick", ylabel="coverage (%)", ylim=(0, 102), title="coverage")
    ax.legend(fontsize=8, loc="lower right")
    ax.grid(alpha=0.3)
    fig.savefig(path)


def panels_plot(panels: Mapping[tuple[str, str], Mapping[str, Sequence[float]]], path: Path, *, xlabel: str,
                ylabel: str, title: str) -> None:
    """Small multiples: one panel per ``(row, column)`` key (rows and columns in the keys' first-seen order),
    one line per named series in each (the value at each tick 0, 1, ...), the x axis shared by all, the y axis
    along a row. ``benchmarks/paper_setting.py`` draws Mukhija et al.'s Fig. 7 (cells seen against ticks, a
    line per fleet size) with it, a column per allocator and a row per map."""
    rows = list(dict.fromkeys(r for r, _ in panels))
    cols = list(dict.fromkeys(c for _, c in panels))
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4.2 * len(cols), 3.4 * len(rows)), dpi=110, layout="constrained")
    axes = np.atleast_2d(fig.subplots(len(rows), len(cols), sharex=True, sharey="row", squeeze=False))
    for i, row in enumerate(rows):
        for j, col in enumerate(cols):
            ax = axes[i, j]
            for label, ys in (panels.get((row, col)) or {}).items():
                ax.plot(np.arange(len(ys)), np.asarray(ys, dtype=float), lw=1.5, label=label)
            ax.set(title=f"{col}: {row}", xlabel=xlabel if i == len(rows) - 1 else "",
                   ylabel=ylabel if j == 0 else "")
            ax.grid(alpha=0.3)
            if ax.lines:
                ax.legend(fontsize=8, loc="lower right")
    fig.suptitle(title, fontsize=10)
    fig.savefig(path)


PLOTS: dict[str, Callable[[Run, Path], None]] = {
    "coverage": coverage_plot, "connectivity": connectivity_plot, "map": map_plot, "messages": messages_plot,
}
