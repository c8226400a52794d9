"""A sweep keeps the runs a user digs into (``[study] record``) and re-creates any point as a run folder
(``fleet sweep rerun``), checked against its row; all on the memory engine and the small rooms map."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fleet_emu.core.errors import ConfigError
from fleet_emu.launch.result import deterministic
from fleet_emu.sweep.cli import sweep
from fleet_emu.sweep.execute import ROWS, read_rows
from fleet_emu.sweep.study import Study
from tests.harness.cli import result, run_cli


def two_points(study_dir: Path, record: str | None = None) -> Path:
    """A study of two points: one that ends at tick 4 without the target, one that reaches it."""
    text = (study_dir / "tiny.toml").read_text()
    text = text.replace('allocator = ["nearest", "minpos"]', 'allocator = ["nearest"]') \
        .replace("robots = [2, 3]", "robots = [2]\nmax_ticks = [4, 300]").replace("max_ticks = 300\n", "") \
        .replace("seeds = 2", "seeds = 1" + (f'\nrecord = "{record}"' if record else ""))
    path = study_dir / f"two-{record}.toml"
    path.write_text(text.replace('name = "tiny"', f'name = "two-{record}"'))
    return path


def test_a_sweep_keeps_the_missed_run_and_rerun_recreates_it(study_dir: Path) -> None:
    out = study_dir / "out"
    assert sweep(str(two_points(study_dir)), out, jobs=1, quiet=True) == 0
    rows = {r["param.max_ticks"]: r for r in read_rows(out)}
    missed, reached = rows[4], rows[300]
    assert not missed["completed"] and reached["completed"]
    assert missed["run_dir"] == f"runs/{missed['id']}" and reached["run_dir"] is None
    assert [p.name for p in (out / "runs").iterdir()] == [missed["id"]]
    kept = result(out / missed["run_dir"])
    code, report, _ = run_cli(["sweep", "report", str(out), "--no-plots"])
    assert code == 0 and "1 runs failed or missed the target" in report
    assert f"{missed['id']}  allocator=nearest, robots=2, max_ticks=4" in report and f"(kept: {out / 'runs'}" in report
    assert kept["ticks"] == missed["ticks"] == 4 and (out / missed["run_dir"] / "run.mcap").stat().st_size > 0

    run = study_dir / "rerun"
    code, _, err = run_cli(["sweep", "rerun", str(out), missed["id"][:6], "--out", str(run)])
    assert code == 0, err
    assert "the run equals its row" in err and f"fleet report {run}" in err
    assert deterministic(result(run)) == deterministic(kept)  # the kept run and the re-created one agree
    code, report, err = run_cli(["report", str(run), "--no-plots"])
    assert code == 0 and "matches result.json" in report, err

    code, _, err = run_cli(["sweep", "rerun", str(out), missed["id"], "--out", str(run)])
    assert code == 2 and err == (f"fleet: error: --out {run} holds a run (result.json, run.mcap, scenario.json): "
                                 "pass --overwrite to replace it, or choose another folder\n")
    lines = (out / ROWS).read_text().replace(f'"ticks": {missed["ticks"]},', '"ticks": 5,')
    (out / ROWS).write_text(lines)  # a row that its run does not give
    code, _, err = run_cli(["sweep", "rerun", str(out), missed["id"], "--out", str(run), "--overwrite",
                             "--quiet"])
    assert code == 1 and err.count("\n") == 1
    assert f"the rerun of {missed['id']} differs from its row in 1 value: ticks (row 5, rerun 4)" in err


@pytest.mark.parametrize(("record", "kept"), [("all", {4, 300}), ("none", set())])
def test_record_all_keeps_every_run_and_none_keeps_none(study_dir: Path, record: str, kept: set[int]) -> None:
    out = study_dir / record
    assert sweep(str(two_points(study_dir, record)), out, jobs=1, quiet=True) == 0
    rows = read_rows(out)
    assert {r["param.max_ticks"] for r in rows if r["run_dir"]} == kept
    for r in rows:
        assert (out / "runs" / r["id"] / "run.mcap").exists() is bool(r["run_dir"])


def test_a_failed_point_is_kept_reported_and_rerun_fails_again(study_dir: Path) -> None:
    """Sixty robots do not fit the rooms: the row holds the error and the report still shows the point."""
    text = (study_dir / "tiny.toml").read_text().replace("robots = [2, 3]", "robots = [60]") \
        .replace('allocator = ["nearest", "minpos"]', 'allocator = ["nearest"]')
    (study_dir / "fail.toml").write_text(text)
    out = study_dir / "out"
    assert sweep(str(study_dir / "fail.toml"), out, jobs=1, quiet=True) == 200 + 2
    bad = read_rows(out)[0]
    assert bad["robots"] == 60 and bad["comm"] == "ideal" and bad["run_dir"] is None
    code, report, _ = run_cli(["sweep", "report", str(out), "--no-plots"])
    assert code == 0 and "2 runs, 2 failed" in report
    assert "│ rooms │ ideal, loss 0 │     60 │ nearest   │   0 / 2 │      2 │" in report
    code, _, err = run_cli(["sweep", "rerun", str(out), bad["id"], "--out", str(study_dir / "again"), "--quiet"])
    assert code == 1 and err.count("\n") == 1 and "failed again, as its row says: StartAreaError: 60 robots" in err, err


@pytest.mark.parametrize(("args", "message"), [
    (["report", "R", "--jobs", "2", "--dask", "tcp://x:1", "--limit", "1"],
     "fleet sweep report does not take --jobs, --dask, --limit"),
    (["report", "R", "--out", "x"], "fleet sweep report does not take --out"),
    (["rerun", "R", "abc", "--seeds", "1"], "fleet sweep rerun does not take --seeds"),
    (["tiny.toml", "--out", "x", "--overwrite"], "fleet sweep STUDY does not take --overwrite"),
    (["tiny.toml", "--out", "x", "--no-plots"], "fleet sweep STUDY does not take --no-plots"),
    (["rerun", "R"], "usage: fleet sweep rerun RESULTS ID"),
    (["rerun", "nowhere", "abc"], "no sweep results at nowhere"),
])
def test_options_an_action_does_not_use_are_refused(args: list[str], message: str, study_dir: Path) -> None:
    code, _, err = run_cli(["sweep", *args], cwd=study_dir)
    assert code == 2 and err.count("\n") == 1 and message in err, err
    assert not (study_dir / "x").exists()


def test_rerun_names_a_row_by_its_id_or_a_unique_start(tmp_path: Path) -> None:
    rows = [{"id": "ab12", "status": "ok"}, {"id": "ab34", "status": "ok"}]
    (tmp_path / ROWS).write_text("".join(json.dumps(r) + "\n" for r in rows))
    for wanted, message in (("ab", "2 rows have the id ab"), ("cd", "no row has the id cd")):
        code, _, err = run_cli(["sweep", "rerun", str(tmp_path), wanted])
        assert code == 2 and message in err, err
    code, _, err = run_cli(["sweep", "rerun", str(tmp_path), "ab1"])
    assert code == 2 and "has no study.toml" in err


def test_a_record_mode_is_one_of_three() -> None:
    with pytest.raises(ConfigError, match="record must be one of failed, all, none"):
        Study.from_dict({"study": {"record": "some"}, "grid": {"robots": [2]}})
    assert Study.from_dict({"grid": {"robots": [2]}}).record == "failed"


def test_a_point_that_runs_again_replaces_its_kept_folder(study_dir: Path) -> None:
    """Resuming runs a failed point again: the folder its earlier attempt left is the sweep's, and goes."""
    from fleet_emu.sweep.execute import run_point
    from fleet_emu.sweep.record import Keep

    point = next(p for p in Study.load(two_points(study_dir, "all")).points() if p.params["max_ticks"] == 4)
    stale = study_dir / "runs" / point.id / "robot-r9.log"
    stale.parent.mkdir(parents=True)
    stale.write_text("an earlier attempt")
    row = run_point(point, Keep("all", str(study_dir)))
    assert row["run_dir"] == f"runs/{point.id}" and row["ticks"] == 4
    assert sorted(p.name for p in stale.parent.iterdir()) == ["map.npz", "result.json", "run.mcap", "scenario.json"]
