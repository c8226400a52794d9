"""Verdicts on a study whose effect is known by construction, and ``fleet sweep --until-decided``: a plugin
allocator that waits a drawn number of ticks (0 to 20, 10 on average) before it explores as nearest frontier does,
judged against a bound 3 ticks below its true mean: too few runs under 3 replicates, never "not reproduced", and
reproduced once the interval has narrowed. Then the sequential sweep itself, resumed."""

from __future__ import annotations

import json
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fleet_emu.agents.allocators.interface import Allocation, Allocator, Problem
from fleet_emu.agents.allocators.nearest import Nearest
from fleet_emu.core.messages import RadioMsg
from fleet_emu.sweep.claims import judge, parse
from fleet_emu.sweep.execute import run_point
from fleet_emu.sweep.figures import Runs
from fleet_emu.sweep.intervals import Verdict
from fleet_emu.sweep.study import Study
from tests.harness.cli import fleet, run_cli


class Waster(Nearest):
    """Nearest frontier after standing still for W ticks, W uniform on 0..20 from the run's seed (read off the
    generator's state, so that no draw changes what the robot does afterwards)."""

    DESCRIPTION = "a test allocator: waits 0-20 ticks (from the seed), then nearest frontier"

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self.left = int(rng.bit_generator.state["state"]["state"] % 21)

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        if self.left > 0:
            self.left -= 1
            return Allocation.hold()
        return super().allocate(problem, inbox)


def _study(study_dir: Path, seeds: int) -> Study:
    return Study.from_dict({
        "study": {"name": "waste", "seeds": seeds, "baseline": "nearest"},
        "grid": {"allocator": ["nearest", "test-waster"]},
        "fleet": {"map": str(study_dir / "rooms.png"), "robots": 1, "comm": "ideal", "cell_size": 0.5,
                  "sensor_range": 1.5, "start": [1, 1], "max_ticks": 300}}, study_dir / "waste.toml")


@pytest.fixture(scope="module")
def waste_rows(tmp_path_factory: pytest.TempPathFactory) -> Iterator[list[dict[str, Any]]]:
    """The study's 80 runs, the allocator registered only while they run (the registry is the process's: a test
    that runs every registered allocator must not find it)."""
    from tests.harness.files import ROOMS, draw_map

    folder = tmp_path_factory.mktemp("waste")
    draw_map(ROOMS, folder / "rooms.png")
    Waster.register("test-waster")
    try:
        rows = [run_point(p) for p in _study(folder, 40).points()]
    finally:
        Allocator.registry.pop("test-waster", None)
    yield rows


@pytest.mark.slow  # 80 runs for the decision's statistics
def test_verdicts_are_right_at_every_number_of_replicates(waste_rows: list[dict[str, Any]]) -> None:
    nearest = {r["ticks"] for r in waste_rows if r["param.allocator"] == "nearest"}
    assert len(nearest) == 1 and all(r["status"] == "ok" and r["completed"] for r in waste_rows)
    t0 = nearest.pop()  # the same start every seed: nearest frontier's time is one number
    waits = [r["ticks"] - t0 for r in waste_rows if r["param.allocator"] == "test-waster"]
    assert min(waits) >= 0 and max(waits) <= 20 and len(set(waits)) > 5  # the drawn waits, as built
    claim, = parse({"claims": [{"text": "the waster takes at least 7 ticks more than nearest's time",
                                "metric": "ticks", "allocator": "test-waster", "at_least": t0 + 7}]})
    seen = {}
    for n in (1, 2, 3, 4, 6, 10, 20, 40):
        rows = [r for r in waste_rows if r["param.seed"] < n]
        seen[n] = judge(claim, Runs(rows, "nearest")).verdict
    assert seen[1] == seen[2] == Verdict.TOO_FEW
    assert all(seen[n] in (Verdict.INCONCLUSIVE, Verdict.REPRODUCED) for n in seen if n >= 3)
    assert Verdict.INCONCLUSIVE in seen.values() and seen[40] == Verdict.REPRODUCED, seen


@pytest.mark.slow
def test_until_decided_adds_seeds_until_the_claims_are_decided_and_resumes(study_dir: Path) -> None:
    (study_dir / "decide.toml").write_text('''
[study]
name = "decide"
engine = "memory"
seeds = 2
baseline = "nearest"
[grid]
allocator = ["nearest", "minpos"]
[fleet]
map = "rooms.png"
robots = 2
comm = "ideal"
cell_size = 0.5
sensor_range = 1.5
start = "random"
max_ticks = 300
[paper]
source = "a test"
[[paper.claims]]
text = "minpos takes at most twice nearest's time"
metric = "ticks"
allocator = "minpos"
at_most = {allocator = "nearest", times = 2}
''')
    out = study_dir / "out"
    first = fleet("sweep", str(study_dir / "decide.toml"), "--out", str(out), "--until-decided", "--max-seeds", "8",
                  "--jobs", "2", check=False)
    assert first.returncode == 0, first.stderr
    assert "batches of 2 → 4 → 8 replicates; 3 looks at 98.3 % each" in first.stderr
    assert "look 1 of 3: 2 replicates; 0 of 1 claims decided" in first.stderr  # 2 seeds: too few runs
    plan = json.loads((out / "decided.json").read_text())
    assert plan["counts"] == [2, 4, 8]
    assert plan["decided"] == {"minpos takes at most twice nearest's time": 1}  # at the second look, 4 seeds
    again = fleet("sweep", str(study_dir / "decide.toml"), "--out", str(out), "--until-decided", "--max-seeds", "8",
                  "--jobs", "2", "--quiet", check=False)
    assert again.returncode == 0 and again.stderr == ""  # resumed: nothing to run, and quiet
    shown = fleet("sweep", "report", str(out), "--no-plots", check=False)
    doc = json.loads((out / "claims.json").read_text())
    assert doc[0]["verdict"] == "reproduced" and doc[0]["n"] == 4 and doc[0]["look"] == 2
    assert "judged at the look that decided it" in shown.stdout


def test_a_cap_below_the_study_or_with_quick_is_one_line(study_dir: Path) -> None:
    for extra, msg in ((["--max-seeds", "1"], "--max-seeds must be at least the study's 2 replicates"),
                       (["--quick"], "--until-decided chooses the replicates itself")):
        code, _, err = run_cli(["sweep", str(study_dir / "tiny.toml"), "--out", str(study_dir / "o"),
                                "--until-decided", *extra])  # refused before anything starts: in this process
        assert code == 2 and msg in err and err.count("\n") == 1
        assert not (study_dir / "o").exists()
    code, _, err = run_cli(["sweep", str(study_dir / "tiny.toml"), "--out", str(study_dir / "o"), "--max-seeds", "5"])
    assert code == 2 and "--max-seeds goes with --until-decided" in err


def test_a_plan_over_start_cells_reads_them_as_the_rows_hold_them() -> None:
    """A row holds a start cell as JSON text (``"[11, 6]"``): a look's rows are found by value all the same."""
    from fleet_emu.sweep.decide import Plan

    plan = Plan("start", [[11, 6], [11, 14], [11, 22]], [1, 2, 3], 0.95)
    rows = [{"param.start": "[11, 6]"}, {"param.start": "[11, 14]"}, {"param.start": [11, 22]}]
    assert plan.rows_of(rows, 0) == rows[:1] and plan.rows_of(rows, 1) == rows[:2] and plan.rows_of(rows, 2) == rows


def test_yan_loss_quick_is_too_few_runs_for_every_claim() -> None:
    """``fleet sweep yan-loss --quick`` runs each grid point once (its first seed): the study's own claims are
    judged on rows of that shape (every point, seed 0, made-up times) and none gets a verdict."""
    from fleet_emu.sweep.claims import evaluate
    from fleet_emu.sweep.study import Study

    study = Study.load("yan-loss")
    rng = np.random.default_rng(0)
    rows = [{"param.allocator": p.params["allocator"], "param.seed": p.params["seed"], "robots": p.params["robots"],
             "loss_applied": p.params["loss"], "map_sync": p.params["map_sync"], "map": "office", "comm": "full",
             "status": "ok", "completed": True, "ticks": float(rng.integers(100, 300))}
            for p in study.points() if p.params["seed"] == study.seeds[0]]
    judged = evaluate({"study": {"name": study.name}, "grid": study.grid, "paper": study.paper}, rows,
                      study.baseline)
    assert judged and {str(j.verdict) for j in judged if j.claim.kind} == {"too few runs"}
