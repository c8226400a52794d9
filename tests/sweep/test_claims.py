"""A study's claims (sweep/claims.py): each kind of criterion reproduced and not on made-up numbers, a bad claim
in one line, the selection of runs (failed ones, map sync), and ``fleet sweep report`` printing the verdicts."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from fleet_emu.core.errors import ConfigError
from fleet_emu.sweep import claims
from fleet_emu.sweep.claims import NO_DATA, NOT_JUDGED, NOT_REPRODUCED, REPRODUCED, judge, parse


def value_of(table: dict[tuple[Any, ...], float]) -> claims.Value:
    """Our numbers by (allocator, robots, loss): a selection with a list is the mean of what it lists."""
    def value(sel: dict[str, Any], _metric: str) -> float | None:
        keys = [k for k in table if all(_in(k[i], sel.get(n)) for i, n in enumerate(("allocator", "robots", "loss")))]
        return sum(table[k] for k in keys) / len(keys) if keys else None
    return value


def _in(got: Any, want: Any) -> bool:
    return want is None or (got in want if isinstance(want, list) else got == want)


NUMBERS = value_of({("trade", 2, 0.0): 5.0, ("trade", 3, 0.0): 30.0, ("trade", 2, 0.5): 40.0,
                    ("hungarian", 2, 0.0): 10.0, ("hungarian", 3, 0.0): 10.0, ("greedy", 2, 0.0): 20.0,
                    ("trade", 2, 0.1): 3.0, ("trade", 2, 0.3): 9.0})


def one(**c: Any) -> claims.Claim:
    return parse({"claims": [{"text": "a claim", "metric": "ticks"} | c]})[0]


@pytest.mark.parametrize(("claim", "verdict", "ours"), [
    ({"allocator": "trade", "robots": 2, "loss": 0.0, "within": [0, 25]}, REPRODUCED, "5"),
    ({"allocator": "trade", "robots": 3, "loss": 0.0, "within": [0, 25]}, NOT_REPRODUCED, "30"),
    ({"allocator": "trade", "robots": [2, 3], "loss": 0.0, "each": "robots", "within": [0, 25]}, NOT_REPRODUCED,
     "2: 5; 3: 30"),
    ({"allocator": "trade", "robots": [2, 3], "loss": 0.0, "each": "robots", "at_least": 5}, REPRODUCED,
     "2: 5; 3: 30"),
    ({"allocator": "trade", "robots": [2, 3], "loss": 0.0, "at_most": 17}, NOT_REPRODUCED, "17.5"),
    ({"allocator": "trade", "loss": 0.5, "above": 39.5}, REPRODUCED, "40"),
    ({"allocator": "trade", "loss": 0.5, "below": 40}, NOT_REPRODUCED, "40"),
    ({"allocator": "hungarian", "robots": 2, "loss": 0.0, "below": {"allocator": "greedy"}}, REPRODUCED,
     "10 vs allocator=greedy 20"),
    ({"allocator": "greedy", "robots": 2, "loss": 0.0, "below": {"allocator": "hungarian"}}, NOT_REPRODUCED,
     "20 vs allocator=hungarian 10"),
    ({"allocator": "greedy", "robots": 2, "loss": 0.0, "at_most": {"allocator": "hungarian", "times": 2}},
     REPRODUCED, "20 vs 2 x allocator=hungarian 10"),
    ({"allocator": "greedy", "robots": 2, "loss": 0.0, "at_most": {"allocator": "hungarian", "times": 1.5}},
     NOT_REPRODUCED, "20 vs 1.5 x allocator=hungarian 10"),
    ({"allocator": "hungarian", "robots": 2, "loss": 0.0, "below": [{"allocator": "greedy"}, {"allocator": "trade"}]},
     NOT_REPRODUCED, "10 vs allocator=greedy 20, allocator=trade 5"),
    ({"allocator": "trade", "robots": 2, "loss": 0.0, "near": 4.0, "tolerance": 1}, REPRODUCED, "5"),
    ({"allocator": "trade", "robots": 2, "loss": 0.0, "near": 7.0, "tolerance": 1}, NOT_REPRODUCED, "5"),
    ({"allocator": "trade", "robots": 2, "loss": [0.1, 0.3, 0.5], "increasing": "loss"}, REPRODUCED,
     "0.1: 3 → 0.3: 9 → 0.5: 40"),
    ({"allocator": "trade", "robots": 2, "loss": [0.0, 0.1, 0.3], "increasing": "loss"}, NOT_REPRODUCED,
     "0: 5 → 0.1: 3 → 0.3: 9"),
    ({"allocator": "trade", "robots": 2, "loss": [0.5, 0.3], "decreasing": "loss"}, REPRODUCED, "0.5: 40 → 0.3: 9"),
    ({"allocator": "trade", "robots": 4, "loss": 0.0, "within": [0, 25]}, NO_DATA, "-"),
    ({"allocator": "trade", "robots": [2, 4], "loss": 0.0, "each": "robots", "within": [0, 25]}, NO_DATA,
     "2: 5; 4: -"),
    ({"allocator": "trade", "robots": [3, 4], "loss": 0.0, "each": "robots", "within": [0, 25]}, NOT_REPRODUCED,
     "3: 30; 4: -"),
    ({"allocator": "trade", "robots": 2, "loss": [0.1, 0.2], "increasing": "loss"}, NO_DATA, "0.1: 3 → 0.2: -"),
])
def test_each_criterion_is_judged_on_our_numbers(claim: dict[str, Any], verdict: str, ours: str) -> None:
    v = judge(one(**claim), NUMBERS)
    assert (v.verdict, v.ours) == (verdict, ours)


def test_a_string_claim_is_the_papers_words_not_judged_and_beside_adds_a_selection() -> None:
    plain, with_criterion = parse({"claims": ["the paper says so", {"text": "t", "metric": "ticks", "above": 0}]})
    assert judge(plain, NUMBERS).verdict == NOT_JUDGED and plain.criterion() == "-"
    seen: list[dict[str, Any]] = []
    judge(with_criterion, lambda sel, _m: seen.append(sel) or 1.0, {"map_sync": False})
    assert seen == [{"map_sync": False}]
    own = one(map_sync=True, above=0)
    judge(own, lambda sel, _m: seen.append(sel) or 1.0, {"map_sync": False})
    assert seen[-1] == {"map_sync": True}  # the claim's own selection wins


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


def _row(alloc: str, ticks: int, sync: bool = True, status: str = "ok", completed: bool = True) -> dict[str, Any]:
    return {"param.allocator": alloc, "robots": 2, "map": "office", "comm": "full", "loss_applied": 0.3,
            "bandwidth": 0.0, "map_sync": sync, "ticks": ticks, "completed": completed, "coverage": 0.99,
            "connected_fraction": 0.5, "path_length": json.dumps([ticks]), "status": status}


ROWS = [_row("trade", 100), _row("trade", 120), _row("trade", 200, sync=False), _row("trade", 220, sync=False),
        _row("hungarian", 100), _row("hungarian", 100, sync=False), _row("hungarian", 0, status="failed"),
        _row("hungarian", 300, sync=False, completed=False)]


def test_row_value_selects_by_map_sync_and_counts_failed_runs_as_not_reached() -> None:
    from fleet_emu.sweep.report import summary

    value = claims.row_value(ROWS, summary(ROWS, "hungarian"), "hungarian")
    assert value({"allocator": "trade", "map_sync": True}, "ticks") == 110.0
    assert value({"allocator": "trade", "map_sync": False}, "ticks") == 210.0
    assert value({"allocator": "trade", "map_sync": False}, "vs_baseline_pct") == pytest.approx(110.0)
    assert value({"allocator": "hungarian", "map_sync": True}, "reached_pct") == 50.0  # one of two failed
    assert value({"allocator": "hungarian", "map_sync": False}, "reached_pct") == 50.0  # one of two missed
    assert value({"allocator": "trade"}, "reached_pct") == 100.0
    assert value({"allocator": "greedy"}, "reached_pct") is None


def test_the_report_prints_the_verdicts_beside_each_other_and_writes_them(tmp_path: Path,
                                                                         capsys: pytest.CaptureFixture[str]) -> None:
    from fleet_emu.sweep.execute import write_tables
    from fleet_emu.sweep.report import report

    write_tables([r | {"id": str(i), "scenario.map_sync": False if not r.pop("map_sync") else None}
                  for i, r in enumerate(json.loads(json.dumps(ROWS)))], tmp_path)
    (tmp_path / "study.toml").write_text('''[study]
name = "t"
baseline = "hungarian"
[grid]
allocator = ["trade", "hungarian"]
map_sync = [false, true]
[paper]
source = "a paper"
beside = "map_sync"
[[paper.claims]]
text = "trade is at most 50 % slower than Hungarian"
metric = "vs_baseline_pct"
allocator = "trade"
within = [0, 50]
''')
    report(tmp_path, plots=False)
    out = capsys.readouterr().out
    assert "ours, map_sync = false" in out and "verdict, map_sync = true" in out
    line = next(ln for ln in out.splitlines() if "trade is at most" in ln)
    cells = [c.strip() for c in line.split("│")]
    assert cells[3:7] == ["110", "not reproduced", "10", "reproduced"]  # trade +110 % without sync, +10 % with
    assert "full, loss 0.3, no map sync" in out  # the summary's groups keep the settings apart
    doc = json.loads((tmp_path / "claims.json").read_text())
    assert [j["verdict"] for j in doc[0]["judged"]] == [NOT_REPRODUCED, REPRODUCED]
    assert [j["where"] for j in doc[0]["judged"]] == [{"map_sync": False}, {"map_sync": True}]
