"""A study's claims (sweep/claims.py): each kind of criterion judged with its interval over replicates on made-up
rows (reproduced, not reproduced, inconclusive, too few runs), a bad claim in one line, ``beside`` on any grid key,
and ``fleet sweep report`` printing the verdicts and writing ``claims.json``."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from fleet_emu.core.errors import ConfigError
from fleet_emu.sweep.claims import evaluate, judge, parse
from fleet_emu.sweep.figures import Runs
from fleet_emu.sweep.intervals import Verdict

R, NR, INC, FEW, ND, NJ = (Verdict.REPRODUCED, Verdict.NOT_REPRODUCED, Verdict.INCONCLUSIVE, Verdict.TOO_FEW,
                           Verdict.NO_DATA, Verdict.NOT_JUDGED)
#: Mean ticks by (allocator, robots, loss); every seed adds the same noise to every allocator (paired), and a
#: little of its own.
MEANS = {("trade", 2, 0.0): 105.0, ("trade", 3, 0.0): 130.0, ("trade", 2, 0.5): 140.0, ("hungarian", 2, 0.0): 100.0,
         ("hungarian", 3, 0.0): 100.0, ("greedy", 2, 0.0): 200.0, ("trade", 2, 0.1): 110.0,
         ("trade", 2, 0.3): 120.0}


def rows(seeds: int, own: float = 0.5, shared: float = 20.0, seed: int = 1) -> list[dict[str, Any]]:
    rng = np.random.default_rng(seed)
    common = rng.normal(0, shared, seeds)
    out = []
    for (alloc, robots, loss), mean in MEANS.items():
        for s in range(seeds):
            ticks = mean + common[s] + rng.normal(0, own)
            out.append({"param.allocator": alloc, "robots": robots, "loss_applied": loss, "param.seed": s,
                        "map": "office", "comm": "full", "bandwidth": 0.0, "map_sync": True, "ticks": ticks,
                        "completed": True, "status": "ok", "coverage": 0.99, "connected_fraction": 0.5})
    return out


def one(**c: Any) -> Any:
    return parse({"claims": [{"text": "a claim", "metric": "ticks"} | c]})[0]


@pytest.mark.parametrize(("claim", "verdict"), [
    ({"allocator": "trade", "robots": 3, "loss": 0.0, "above": {"allocator": "hungarian"}}, R),
    ({"allocator": "trade", "robots": 3, "loss": 0.0, "below": {"allocator": "hungarian"}}, NR),
    ({"allocator": "greedy", "robots": 2, "loss": 0.0, "at_most": {"allocator": "hungarian", "times": 2.5}}, R),
    ({"allocator": "greedy", "robots": 2, "loss": 0.0, "at_most": {"allocator": "hungarian", "times": 1.5}}, NR),
    ({"allocator": "hungarian", "robots": 2, "loss": 0.0, "below": [{"allocator": "greedy"}, {"allocator": "trade"}]},
     R),
    ({"allocator": "trade", "robots": [2, 3], "loss": 0.0, "each": "robots", "above": {"allocator": "hungarian"}},
     R),
    ({"allocator": "trade", "robots": 2, "loss": [0.1, 0.3, 0.5], "increasing": "loss"}, R),
    ({"allocator": "trade", "robots": 2, "loss": [0.5, 0.3], "increasing": "loss"}, NR),
    ({"allocator": "trade", "robots": 2, "loss": [0.5, 0.3], "decreasing": "loss"}, R),
    ({"allocator": "trade", "robots": 4, "loss": 0.0, "above": 0}, ND),
])
def test_paired_comparisons_are_decided_on_their_intervals(claim: dict[str, Any], verdict: Verdict) -> None:
    """The seeds' shared noise (sd 20 ticks) is far larger than the differences (5 to 100 ticks): only a
    comparison paired by seed decides them at 10 seeds."""
    assert judge(one(**claim), Runs(rows(10), "hungarian")).verdict == verdict


def test_a_bound_on_a_mean_straddled_is_inconclusive_with_the_replicates_it_needs() -> None:
    runs = Runs(rows(10, own=0.0), "hungarian")
    j = judge(one(allocator="trade", robots=2, loss=0.0, at_least=100), runs)  # 105 +- ~15 around 100
    assert j.verdict == INC and j.main is not None and j.main.needed is not None and j.main.needed > 10
    assert j.main.interval.low < 100 < j.main.interval.high and j.main.interval.n == 10
    assert judge(one(allocator="trade", robots=2, loss=0.0, at_least=100), Runs(rows(2), "hungarian")).verdict == FEW
    far = judge(one(allocator="trade", robots=2, loss=0.0, at_least=0), runs)
    assert far.verdict == R and far.main is not None and far.main.needed is None


def test_a_pooled_figure_resamples_seeds_not_runs() -> None:
    """Over 3 robot counts x 10 seeds the interval rests on 10 replicates, not 30."""
    runs = Runs(rows(10), "hungarian")
    j = judge(one(allocator="trade", robots=[2, 3], loss=0.0, metric="vs_baseline_pct", within=[-100, 100]), runs)
    assert j.main is not None and j.main.interval.n == 10


def test_the_same_rows_give_the_same_interval_and_the_point_estimate_is_the_plain_mean() -> None:
    data = rows(8)
    a = judge(one(allocator="trade", robots=2, loss=0.0, above=0), Runs(data, "hungarian"))
    b = judge(one(allocator="trade", robots=2, loss=0.0, above=0), Runs(data, "hungarian"))
    assert a == b and a.main is not None
    mine = [r["ticks"] for r in data if (r["param.allocator"], r["robots"], r["loss_applied"]) == ("trade", 2, 0.0)]
    assert a.main.interval.value == pytest.approx(np.mean(mine))


def test_a_string_claim_is_not_judged_and_beside_adds_a_selection() -> None:
    plain, = parse({"claims": ["the paper says so"]})
    assert judge(plain, Runs(rows(3), "hungarian")).verdict == NJ and plain.criterion() == "-"


def test_beside_on_any_grid_key_judges_each_value_apart() -> None:
    """``beside = "threshold"``: MinPos's figure differs per threshold (it was once pooled over all four)."""
    data = [{"param.allocator": "minpos", "param.threshold": th, "param.seed": s, "robots": 2, "map": "m",
             "comm": "wall", "loss_applied": 0.0, "bandwidth": 0.0, "map_sync": True, "status": "ok",
             "completed": True, "ticks": 100.0, "connected_fraction": (50 + th + s) / 100}
            for th in (-10, -20, -30) for s in range(4)]
    study = {"study": {"name": "t"}, "grid": {"allocator": ["minpos"], "threshold": [-10, -20, -30]},
             "paper": {"beside": "threshold", "claims": [{"text": "t", "metric": "connected_pct",
                                                          "allocator": "minpos", "above": 0}]}}
    judged = evaluate(study, data, "minpos")
    values = [j.main.interval.value for j in judged if j.main is not None]
    assert [j.where for j in judged] == [{"threshold": -10}, {"threshold": -20}, {"threshold": -30}]
    assert values == pytest.approx([41.5, 31.5, 21.5])


@pytest.mark.parametrize(("claim", "message"), [
    ({"metric": "ticks", "above": 0}, "text must be the paper's words"),
    ({"text": "t", "metric": "speed", "above": 0}, "metric must be one of"),
    ({"text": "t", "metric": "ticks"}, "give one criterion"),
    ({"text": "t", "metric": "ticks", "above": 0, "below": 5}, "give one criterion"),
    ({"text": "t", "metric": "ticks", "within": [5, 0]}, "within must be [LOW, HIGH]"),
    ({"text": "t", "metric": "ticks", "within": 5}, "within must be [LOW, HIGH]"),
    ({"text": "t", "metric": "ticks", "near": 5, "tolerance": -1}, "tolerance must be a number >= 0"),
    ({"text": "t", "metric": "ticks", "above": 0, "tolerance": 1}, "tolerance goes with near"),
    ({"text": "t", "metric": "ticks", "near": "five"}, "near must be a number"),
    ({"text": "t", "metric": "ticks", "below": {"allocater": "x"}}, "below must be a number or a selection"),
    ({"text": "t", "metric": "ticks", "below": {"allocator": "x", "times": 0}}, "times must be a number > 0"),
    ({"text": "t", "metric": "ticks", "loss": 0.1, "increasing": "loss"}, "increasing must name a selection key"),
    ({"text": "t", "metric": "ticks", "robots": [2], "each": "seed", "above": 0}, "each must name a selection key"),
    ({"text": "t", "metric": "ticks", "above": 0, "colour": "red"}, "unknown key(s) colour"),
    (7, "a claim is a string or a table"),
])
def test_a_bad_claim_is_one_line_naming_it(claim: Any, message: str) -> None:
    with pytest.raises(ConfigError) as exc:
        parse({"claims": ["first", claim]}, "study s")
    assert str(exc.value).startswith("study s: claim 2: ") and message in str(exc.value)
    assert "\n" not in str(exc.value)


def test_beside_names_a_grid_key_and_a_study_with_a_bad_claim_does_not_load() -> None:
    from fleet_emu.sweep.study import Study

    with pytest.raises(ConfigError, match="beside must name a \\[grid\\] key"):
        parse({"beside": "map_sync", "claims": []}, "s", {"loss": [0.0]})
    raw = {"grid": {"allocator": ["nearest"]}, "paper": {"claims": [{"text": "t", "metric": "ticks"}]}}
    with pytest.raises(ConfigError, match="claim 1: give one criterion"):
        Study.from_dict(raw)


def test_a_claim_with_an_infinite_bound_or_a_value_absent_from_the_grid_is_refused() -> None:
    with pytest.raises(ConfigError, match="at_most must be a number"):
        parse({"claims": [{"text": "t", "metric": "ticks", "at_most": float("inf")}]}, "s")
    with pytest.raises(ConfigError, match="tolerance must be a number"):
        parse({"claims": [{"text": "t", "metric": "ticks", "near": 1, "tolerance": float("inf")}]}, "s")
    with pytest.raises(ConfigError, match=r"claim 1: loss = 0.2 is not in the \[grid\]'s loss"):
        parse({"claims": [{"text": "t", "metric": "ticks", "loss": 0.2, "above": 0}]}, "s", {"loss": [0.0, 0.1]})
    with pytest.raises(ConfigError, match="allocator = 'greedy' is not in"):
        parse({"claims": [{"text": "t", "metric": "ticks", "allocator": "minpos", "below": {"allocator": "greedy"}}]},
              "s", {"allocator": ["minpos", {"type": "nearest"}]})


def test_the_report_prints_value_interval_n_and_verdict_and_writes_them(tmp_path: Path,
                                                                       capsys: pytest.CaptureFixture[str]) -> None:
    from fleet_emu.sweep.execute import write_tables
    from fleet_emu.sweep.report import report

    write_tables([r | {"id": str(i)} for i, r in enumerate(rows(6))], tmp_path)
    (tmp_path / "study.toml").write_text('''[study]
name = "t"
baseline = "hungarian"
seeds = 6
[grid]
allocator = ["trade", "hungarian", "greedy"]
[paper]
source = "a paper"
[[paper.claims]]
text = "trade is slower than Hungarian with 3 robots"
metric = "ticks"
allocator = "trade"
robots = 3
loss = 0.0
above = {allocator = "hungarian"}
[[paper.claims]]
text = "trade takes at least 100 ticks"
metric = "ticks"
allocator = "trade"
robots = 2
loss = 0.0
at_least = 100
''')
    report(tmp_path, plots=False)
    out = capsys.readouterr().out
    assert "95 % CI" in out and "reproduced" in out and "inconclusive (needs ~" in out
    doc = json.loads((tmp_path / "claims.json").read_text())
    first, second = doc
    assert first["verdict"] == "reproduced" and first["n"] == 6 and first["level"] == 0.95
    assert first["ci"][0] > 0 and first["value"] == pytest.approx(30, abs=2)
    assert second["verdict"] == "inconclusive" and second["replicates_needed"] > 6
    assert first["bootstrap"] == {"method": first["bootstrap"]["method"], "resamples": 2000, "seed": 0}
