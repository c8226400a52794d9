"""The sweep figures: a coverage panel per grid point in percent, intervals over one point's runs that say n and
stay above 0, none at n = 1, legends outside the data, titles that fit."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import pytest

from fleet_emu.sweep import plots
from tests.harness.sweep import row

matplotlib.use("Agg")


def _rows() -> list[dict[str, Any]]:
    out = []
    for alloc in ("nearest", "minpos"):
        for robots in (1, 4, 10):
            for seed, ticks in ((0, 100 * robots), (1, 900 // robots + 600)):  # two seeds far apart
                curve = list(np.linspace(0.05, 0.99, 6) ** (robots / 4))
                out.append(row(alloc, robots, ticks) | {"param.seed": seed, "curve": json.dumps(curve),
                                                        "curve_every": 10})
    return out


@pytest.fixture(scope="module")
def figures(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    got: dict[str, Any] = {}

    def keep(fig: Any, path: Path) -> Path:
        fig.tight_layout()
        fig.canvas.draw()
        got[path.stem] = fig
        return path

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(plots, "_save", keep)
        plots.draw(_rows(), tmp_path_factory.mktemp("plots"))
    yield got
    import matplotlib.pyplot as plt

    plt.close("all")


def test_coverage_has_a_panel_per_robot_count_in_percent(figures: dict[str, Any]) -> None:
    fig = figures["coverage_vs_tick"]
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert sorted(ax.get_title() for ax in axes) == ["robots 1", "robots 10", "robots 4"]
    for ax in axes:
        assert len(ax.get_lines()) == 2  # one curve per allocator in each panel
        top = max(line.get_ydata().max() for line in ax.get_lines())
        assert 50 < top <= 100  # percent, as fleet report's plots


def test_intervals_say_their_n_and_level_stay_above_zero_and_the_legend_is_outside(figures: dict[str, Any]) -> None:
    fig = figures["time_vs_robots"]
    ax = fig.axes[0]
    legend = fig.legends[0]
    labels = [t.get_text() for t in legend.get_texts()]
    assert labels and all("(n = 2)" in label for label in labels) and "95 % CI" in legend.get_title().get_text()
    lows = [seg[:, 1].min() for coll in ax.collections for seg in getattr(coll, "get_segments", list)()]
    assert lows and min(lows) >= 0  # n = 2: a wide interval, cut at 0 ticks
    fig.canvas.draw()
    assert legend.get_window_extent().x0 >= ax.get_window_extent().x1  # beside the data, not over it


def test_one_run_per_point_draws_no_interval(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    got: dict[str, Any] = {}
    monkeypatch.setattr(plots, "_save", lambda fig, path: got.setdefault(path.stem, fig) and path)
    plots.draw([r for r in _rows() if r["param.seed"] == 0], tmp_path)
    fig = got["time_vs_robots"]
    assert all("n = 1, no interval" in t.get_text() for t in fig.legends[0].get_texts())
    bars = [seg for coll in fig.axes[0].collections for seg in getattr(coll, "get_segments", list)()]
    assert all(np.ptp(seg[:, 1]) == 0 for seg in bars)  # error bars of zero length: no interval drawn


def test_titles_fit_their_figure(figures: dict[str, Any]) -> None:
    for name, fig in figures.items():
        width = fig.bbox.width
        titles = [ax.title for ax in fig.axes if ax.get_visible()] + ([fig._suptitle] if fig._suptitle else [])
        for title in titles:
            box = title.get_window_extent()
            assert box.x0 >= 0 and box.x1 <= width, f"{name}: {title.get_text()!r} is cut"
