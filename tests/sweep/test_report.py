"""The sweep report's numbers on hand-made rows: means, stds, % to the baseline, and the paper rows."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from fleet_emu.sweep.figures import Runs
from fleet_emu.sweep.plots import t_half
from fleet_emu.sweep.report import paired, paper_value, summary
from tests.harness.sweep import row

ROWS = [row("nearest", 1, t) for t in (100, 120, 140)] + [row("minpos", 1, t) for t in (80, 90, 100)] + \
       [row("nearest", 2, t) for t in (60, 60)] + [row("minpos", 2, t) for t in (45, 48, 51)] + \
       [row("minpos", 2, 5000, completed=False)] + \
       [row("minpos", 2, t, loss=0.5) for t in (90, 102)]


def test_summary_means_stds_and_percent_to_the_baseline() -> None:
    lines = {(ln["allocator"], ln["robots"], ln["loss_applied"]): ln for ln in summary(ROWS, "nearest")}
    one = lines[("minpos", 1, 0.0)]
    assert one["ticks"] == (90.0, 10.0, 3) and one["vs_baseline_pct"] == pytest.approx(-25.0)
    two = lines[("minpos", 2, 0.0)]
    assert two["runs"] == 4 and two["ticks"][2] == 3  # the run that did not reach the target has no time
    assert two["vs_baseline_pct"] == pytest.approx(-20.0)
    assert two["moves"][0] == pytest.approx((2 * (45 + 48 + 51) + 10000) / 4)
    assert math.isnan(lines[("minpos", 2, 0.5)]["vs_baseline_pct"])  # no nearest at loss 0.5


def test_paper_rows_pick_their_runs() -> None:
    runs = Runs(ROWS, "nearest")
    assert paper_value({"allocator": "minpos", "metric": "vs_baseline_pct"}, runs) == \
        pytest.approx(-22.5)
    assert paper_value({"allocator": "minpos", "robots": [1], "metric": "vs_baseline_pct"}, runs) == \
        pytest.approx(-25.0)
    assert paper_value({"allocator": "minpos", "loss": 0.5, "metric": "vs_loss0_pct"}, runs) == \
        pytest.approx(100.0 * (96 - 48) / 48)
    assert paper_value({"allocator": "nearest", "metric": "connected_pct"}, runs) == 50.0
    assert paper_value({"allocator": "nearest", "metric": "mean_std_ticks"}, runs) == \
        pytest.approx(20.0 / 2)


def test_the_paper_rows_keep_the_studys_baseline_under_another_baseline(tmp_path: Path,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:
    """``report --baseline minpos`` compares the table with minpos; the paper's "vs nearest" rows stay vs nearest."""
    from fleet_emu.sweep.execute import write_tables
    from fleet_emu.sweep.report import report

    write_tables([r | {"id": str(i)} for i, r in enumerate(ROWS)], tmp_path)
    (tmp_path / "study.toml").write_text('''[study]
name = "t"
baseline = "nearest"
[grid]
allocator = ["nearest", "minpos"]
[paper]
source = "a paper"
[[paper.rows]]
what = "minpos vs nearest"
allocator = "minpos"
metric = "vs_baseline_pct"
value = -13
''')
    report(tmp_path, baseline="minpos", plots=False)
    out = capsys.readouterr().out
    assert "vs minpos" in out and "(baseline nearest)" in out
    assert "│ minpos vs nearest │   -13 │ -22.5 │" in out


def test_another_grid_axis_splits_the_lines_and_a_replicate_axis_is_pooled_and_paired_on() -> None:
    """A grid key the table does not show (``threshold``) is a line of its own; one the study names in
    ``replicates`` (``start``: base cells, like seeds) is pooled, and the baseline is paired on it."""
    def point(alloc: str, threshold: float, start: str, ticks: int) -> dict:
        return row(alloc, 2, ticks) | {"param.threshold": threshold, "param.start": start, "param.seed": 0}

    rows = [point("minpos", thr, start, t) for thr, start, t in
            ((0.0, "[1, 2]", 100), (0.0, "[1, 9]", 120), (-10.0, "[1, 2]", 80), (-10.0, "[1, 9]", 90))]
    rows += [point("connectivity", -10.0, "[1, 2]", 90), point("connectivity", -10.0, "[1, 9]", 110)]
    lines = {(ln["allocator"], ln["param.threshold"]): ln for ln in summary(rows, "minpos", replicates=["start"])}
    assert set(lines) == {("minpos", 0.0), ("minpos", -10.0), ("connectivity", -10.0)}
    assert lines[("minpos", 0.0)]["ticks"][:2] == (110.0, pytest.approx(14.142, abs=1e-3))
    assert lines[("connectivity", -10.0)]["paired"] == pytest.approx((15.0, 5.0, 2))  # (+10, +20) by start
    every = summary(rows, "minpos")  # without replicates, each start is a line of its own
    assert len(every) == 6 and all(ln["runs"] == 1 for ln in every)


def test_t_half_is_students_t_half_width() -> None:
    v = np.array([1.0, 2.0, 3.0, 4.0])
    assert t_half(v, 0.95) == pytest.approx(3.182446 * v.std(ddof=1) / 2, rel=1e-5)
    assert math.isnan(t_half(np.array([1.0]), 0.95))


def test_the_paired_difference_matches_seeds_and_leaves_out_runs_that_did_not_finish() -> None:
    def seeded(alloc: str, seed: int, ticks: int, completed: bool = True) -> dict:
        return row(alloc, 2, ticks, completed=completed) | {"param.seed": seed}

    base = [seeded("utility", s, t) for s, t in enumerate((100, 110, 130, 90))]
    runs = [seeded("minpos", 0, 104), seeded("minpos", 1, 110), seeded("minpos", 2, 140),
            seeded("minpos", 3, 5000, completed=False), seeded("minpos", 7, 10)]  # seed 7: no utility run
    mean, se, n = paired(runs, base)
    d = np.array([4.0, 0.0, 10.0])
    assert n == 3 and mean == pytest.approx(d.mean()) and se == pytest.approx(d.std(ddof=1) / math.sqrt(3))
    lines = {ln["allocator"]: ln for ln in summary(base + runs, "utility")}
    assert lines["minpos"]["paired"] == pytest.approx((mean, se, n))
    assert math.isnan(lines["utility"]["paired"][0])


def test_a_base_connected_column_only_for_studies_with_a_base_station(tmp_path: Path,
                                                                        capsys: pytest.CaptureFixture[str]) -> None:
    from fleet_emu.sweep.execute import write_tables
    from fleet_emu.sweep.report import report, stats

    with_base = [r | {"id": str(i), "base_connected_fraction.overall": f}
                 for i, (r, f) in enumerate(zip(ROWS[:6], (0.5, 0.25, 0.75, 1.0, 0.5, 0.0), strict=True))]
    assert stats(with_base[:3], "base_connected_pct") == (50.0, 25.0, 3)
    for rows, shown in ((with_base, True), ([r | {"id": str(i)} for i, r in enumerate(ROWS)], False)):
        out = tmp_path / str(shown)
        out.mkdir()
        write_tables(rows, out)
        report(out, baseline="nearest", plots=False)
        text = capsys.readouterr().out
        assert ("base connected %" in text) is shown
        assert ("50.0 ± 25.0" in text) is shown  # nearest, 1 robot: 0.5, 0.25, 0.75


MISSED = [row("greedy", 1, 300, completed=False) | {"coverage": c} for c in (0.5, 0.7)] + \
         [{"param.allocator": "greedy", "robots": 1, "map": "office", "comm": "full", "loss_applied": 0.0,
           "status": "failed", "error": "RunError: r1 died"}]


def test_every_point_shows_its_runs_that_reached_the_target_and_the_coverage_of_those_that_missed(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from fleet_emu.sweep.execute import write_tables
    from fleet_emu.sweep.report import report

    lines = {(ln["allocator"], ln["robots"], ln["loss_applied"]): ln for ln in summary(ROWS + MISSED, "nearest")}
    greedy = lines[("greedy", 1, 0.0)]  # no run reached the target, one failed
    assert (greedy["runs"], greedy["reached"], greedy["failed"], greedy["ticks"][2]) == (3, 0, 1, 0)
    assert greedy["missed_coverage_pct"] == pytest.approx((60.0, math.sqrt(200.0), 2))
    minpos = lines[("minpos", 2, 0.0)]
    assert (minpos["runs"], minpos["reached"], minpos["missed_coverage_pct"]) == (4, 3, (99.0, 0.0, 1))
    write_tables([r | {"id": str(i)} for i, r in enumerate(ROWS + MISSED)], tmp_path)
    report(tmp_path, baseline="nearest", plots=False)
    out = capsys.readouterr().out
    assert "17 runs, 1 failed" in out
    cells = {tuple(c.strip() for c in ln.split("│")[1:6]): [c.strip() for c in ln.split("│")[6:-1]]
             for ln in out.splitlines() if ln.startswith("│")}
    assert cells[("office", "full, loss 0", "1", "greedy", "0 / 3")][:5] == ["1", "-", "-", "-", "60.0 ± 14.1"]
    assert cells[("office", "full, loss 0", "2", "minpos", "3 / 4")][4] == "99.0, n = 1"


def test_the_figures_have_titles_and_one_robot_count_a_narrow_axis(tmp_path: Path,
                                                                   monkeypatch: pytest.MonkeyPatch) -> None:
    from fleet_emu.sweep import plots

    figures = {}
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.setdefault(path.name, fig) and path)
    one = [r | {"curve": json.dumps([0.1, 0.5]), "curve_every": 5} for r in ROWS if r["robots"] == 2]
    plots.draw(one, tmp_path)
    fig = figures["time_vs_robots.png"]
    ax = fig.axes[0]
    assert fig._suptitle.get_text() == "Time to the target against the robot count"
    assert [a.get_title() for a in fig.axes] == ["loss 0", "loss 0.5"]  # a panel per loss, never pooled
    assert ax.get_xlim() == (1.0, 3.0) and [t.get_text() for t in ax.get_xticklabels()] == ["2"]
    assert figures["time_vs_loss.png"]._suptitle.get_text() == "Time to the target against the loss"
    assert len(figures["time_vs_loss.png"].axes) == 1  # the loss is its axis: one panel
    assert [a.get_title() for a in figures["coverage_vs_tick.png"].axes] == ["loss 0", "loss 0.5"]
