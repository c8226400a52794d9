"""The sweep figures: a coverage panel per robot count in percent, intervals that say their seeds and stay
above 0, titles that fit."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import pytest

from fleet_emu.sweep import plots
from tests.sweep.test_report import row

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
    assert sorted(ax.get_title() for ax in axes) == ["1 robot", "10 robots", "4 robots"]
    for ax in axes:
        assert len(ax.get_lines()) == 2  # one curve per allocator in each panel
        top = max(line.get_ydata().max() for line in ax.get_lines())
        assert 50 < top <= 100  # percent, as fleet report's plots


def test_intervals_say_their_seeds_and_stay_above_zero(figures: dict[str, Any]) -> None:
    ax = figures["time_vs_robots"].axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels and all("CI of 2 seeds" in label for label in labels)
    lows = [seg[:, 1].min() for coll in ax.collections for seg in getattr(coll, "get_segments", list)()]
    assert lows and min(lows) >= 0  # n = 2: a wide interval, cut at 0 ticks


def test_titles_fit_their_figure(figures: dict[str, Any]) -> None:
    for name, fig in figures.items():
        width = fig.bbox.width
        titles = [ax.title for ax in fig.axes if ax.get_visible()] + ([fig._suptitle] if fig._suptitle else [])
        for title in titles:
            box = title.get_window_extent()
            assert box.x0 >= 0 and box.x1 <= width, f"{name}: {title.get_text()!r} is cut"
