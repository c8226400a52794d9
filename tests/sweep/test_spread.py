"""``fleet sweep --limit N`` and ``--quick``: the first runs are spread over the grid, every allocator at the same
settings, far apart, so that a quick look already compares them."""

from __future__ import annotations

import dataclasses
import itertools
from pathlib import Path
from typing import Any

import pytest

from fleet_emu.core.errors import ConfigError
from fleet_emu.sweep.cli import sweep
from fleet_emu.sweep.execute import read_rows
from fleet_emu.sweep.spread import farthest_first, spread
from fleet_emu.sweep.study import Study


@dataclasses.dataclass(frozen=True)
class _P:
    params: dict[str, Any]


def _points(grid: dict[str, list[Any]], seeds: list[int]) -> list[_P]:
    keys = list(grid)
    return [_P(dict(zip(keys, v, strict=True)) | {"seed": s})
            for v in itertools.product(*(grid[k] for k in keys)) for s in seeds]


def test_a_papers_first_runs_compare_every_allocator_at_far_apart_fleets() -> None:
    study = Study.load("bautin-fig5")
    order = spread(_points(study.grid, study.seeds), study.grid, study.seeds)
    first8 = order[:8]
    assert {p.params["allocator"] for p in first8} == set(study.grid["allocator"])
    assert {p.params["robots"] for p in first8} == {1, 10}  # the smallest and the largest fleet
    for n in range(4, 41, 4):  # at every multiple of 4, each allocator at the robot counts the baseline has
        by = {a: sorted(p.params["robots"] for p in order[:n] if p.params["allocator"] == a)
              for a in study.grid["allocator"]}
        assert len({tuple(v) for v in by.values()}) == 1
    assert {p.params["seed"] for p in order[:40]} == {study.seeds[0]}
    assert len({(p.params["allocator"], p.params["robots"]) for p in order[:40]}) == 40


@pytest.mark.parametrize("name", ["mukhija-fig5", "benavides"])
def test_a_study_whose_replicate_is_a_start_cell_is_spread_too(name: str) -> None:
    """A grid value may be a list (a start cell ``[ROW, COL]``): the spread orders it like any other."""
    study = Study.load(name)
    order = spread(_points(study.grid, study.seeds), study.grid, study.seeds)
    assert len(order) == len(study.points())
    first = order[:len(study.grid["allocator"])]  # every allocator at the first setting, side by side
    assert {str(p.params["allocator"]) for p in first} == {str(a) for a in study.grid["allocator"]}
    assert len({str(p.params["start"]) for p in first}) == 1


def test_farthest_first_starts_at_the_ends() -> None:
    cells = [(i / 9,) for i in range(10)]
    assert farthest_first(cells)[:3] == [0, 9, 4]
    assert sorted(farthest_first(cells)) == list(range(10))


def test_quick_runs_every_point_once_and_a_limit_continues_spread(study_dir: Path) -> None:
    out = study_dir / "out"
    assert sweep(str(study_dir / "tiny.toml"), out, jobs=1, quick=True, quiet=True) == 0
    rows = read_rows(out)
    assert sorted((r["param.allocator"], r["param.robots"], r["param.seed"]) for r in rows) == [
        ("minpos", 2, 0), ("minpos", 3, 0), ("nearest", 2, 0), ("nearest", 3, 0)]
    with pytest.raises(ConfigError, match="--quick"):
        sweep(str(study_dir / "tiny.toml"), out, jobs=1, quick=True, limit=2, quiet=True)
