"""``fleet sweep``: parallel runs into Parquet and CSV, resuming, failed rows and the exit code, the report,
and a study on a Dask cluster."""

from __future__ import annotations

import json
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet
from fleet_emu.sweep.cli import sweep
from fleet_emu.sweep.execute import read_rows
from fleet_emu.sweep.study import Study
from tests.harness.cli import ROOT, fleet, run_cli


@pytest.mark.slow
def test_a_sweep_writes_one_row_per_run_and_resumes(study_dir: Path) -> None:
    out = study_dir / "out"
    first = fleet("sweep", str(study_dir / "tiny.toml"), "--out", str(out), "--jobs", "2", "--limit", "5", check=False)
    assert first.returncode == 0, first.stderr
    assert "5 to run" in first.stderr and len(read_rows(out)) == 5
    again = fleet("sweep", str(study_dir / "tiny.toml"), "--out", str(out), "--jobs", "2", check=False)
    assert again.returncode == 0, again.stderr
    assert "5 done, 3 to run" in again.stderr
    table = pq.read_table(out / "results.parquet").to_pylist()
    csv_lines = (out / "results.csv").read_text().strip().splitlines()
    assert len(table) == 8 and len(csv_lines) == 9
    row = next(r for r in table if r["param.allocator"] == "minpos" and r["param.robots"] == 3
               and r["param.seed"] == 1)
    assert row["status"] == "ok" and row["error"] is None and row["engine"] == "memory"
    assert {"radio.sent", "decision_ms.mean", "scenario.radio.comm", "t99", "loss_applied", "curve"} <= set(row)
    # the row is the run: the same scenario in memory gives the same numbers
    study = Study.load(study_dir / "tiny.toml")
    point = next(p for p in study.points() if p.id == row["id"])
    res = Fleet(Scenario.from_dict(point.scenario)).run()
    assert (row["ticks"], row["radio.sent"], json.loads(row["path_length"])) == \
        (res["ticks"], res["radio"]["sent"], res["path_length"])
    curve = json.loads(row["curve"])
    assert curve[-1] <= res["coverage"] and len(curve) == res.ticks // row["curve_every"] + 1
    done = fleet("sweep", str(study_dir / "tiny.toml"), "--out", str(out), check=False)
    assert done.returncode == 0 and "0 to run" in done.stderr

    report = fleet("sweep", "report", str(out), check=False)
    assert report.returncode == 0, report.stderr
    assert "baseline nearest" in report.stdout and "minpos" in report.stdout
    assert {p.name for p in out.glob("*.png")} == {"time_vs_robots.png", "coverage_vs_tick.png"}
    first = fleet("sweep", "report", str(out), "--seeds", "1", "--no-plots", check=False)
    assert "4 runs, 0 failed; baseline nearest; the first 1 seeds" in first.stdout


def test_seeds_runs_the_first_seeds_and_a_later_call_completes(study_dir: Path) -> None:
    out = study_dir / "out"
    assert sweep(str(study_dir / "tiny.toml"), out, jobs=1, seeds=1, quiet=True) == 0
    assert sorted(r["param.seed"] for r in read_rows(out)) == [0] * 4
    assert sweep(str(study_dir / "tiny.toml"), out, jobs=1, quiet=True) == 0
    assert sorted(r["param.seed"] for r in read_rows(out)) == [0] * 4 + [1] * 4


@pytest.mark.slow
def test_a_grown_grid_keeps_the_finished_runs_and_runs_only_the_new_points(study_dir: Path) -> None:
    out = study_dir / "out"
    assert sweep(str(study_dir / "tiny.toml"), out, jobs=1, quiet=True) == 0
    before = {r["id"]: r["ticks"] for r in read_rows(out)}
    text = (study_dir / "tiny.toml").read_text()
    (study_dir / "tiny.toml").write_text(text.replace('["nearest", "minpos"]', '["nearest", "greedy", "minpos"]'))
    grown = fleet("sweep", str(study_dir / "tiny.toml"), "--out", str(out), "--jobs", "1", check=False)
    assert grown.returncode == 0, grown.stderr
    assert "8 done, 4 to run" in grown.stderr
    rows = read_rows(out)
    assert len(rows) == 12 and {r["id"]: r["ticks"] for r in rows if r["id"] in before} == before
    assert sorted(r["param.allocator"] for r in rows if r["id"] not in before) == ["greedy"] * 4
    assert "greedy" in (out / "study.toml").read_text()
    # a grid that lost a value is another study
    (study_dir / "tiny.toml").write_text(text.replace('["nearest", "minpos"]', '["nearest"]'))
    shrunk = fleet("sweep", str(study_dir / "tiny.toml"), "--out", str(out), check=False)
    assert shrunk.returncode == 2 and "another study" in shrunk.stderr


def test_failed_runs_are_rows_and_set_the_exit_code(study_dir: Path) -> None:
    """Sixty robots do not fit the small map (59 free cells): those runs fail, the others go on."""
    text = (study_dir / "tiny.toml").read_text().replace("robots = [2, 3]", "robots = [2, 60]")
    (study_dir / "fail.toml").write_text(text.replace('name = "tiny"', 'name = "fail"'))
    out = study_dir / "out"
    assert sweep(str(study_dir / "fail.toml"), out, jobs=1, quiet=True) == 200 + 4
    rows = read_rows(out)
    bad = [r for r in rows if r["status"] == "failed"]
    assert len(rows) == 8 and len(bad) == 4 and all(r["param.robots"] == 60 for r in bad)
    assert all("60 robots do not fit the free area reachable from the start cell" in r["error"] for r in bad)
    code, _, err = run_cli(["sweep", str(study_dir / "tiny.toml"), "--out", str(out)])  # another study's directory
    assert code == 2 and err.count("\n") == 1 and "another study" in err


@pytest.mark.parametrize(("args", "message"), [
    (["no_such_study", "--out", "x"], "not found"),
    (["tiny.toml"], "--out"),
    (["tiny.toml", "--out", "x", "--jobs", "0"], "--jobs"),
    (["report"], "usage"),
    (["report", "nowhere"], "no sweep results"),
    (["tiny.toml", "--out", "x", "--dask", "tcp://127.0.0.1:1"], "no Dask scheduler answered"),
])
def test_bad_sweep_input_is_one_line(args: list[str], message: str, study_dir: Path) -> None:
    code, _, err = run_cli(["sweep", *args], cwd=study_dir)
    assert code == 2 and err.count("\n") == 1 and message in err, err
    assert not (study_dir / "x").exists()


def test_a_missing_map_is_one_line_exit_2(tmp_path: Path) -> None:
    (tmp_path / "s.toml").write_text('[study]\nname = "s"\n[grid]\nmap = ["stage/no_such_map.yaml"]\n')
    code, _, err = run_cli(["sweep", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")])
    assert code == 2 and err.count("\n") == 1 and "no_such_map" in err


def test_list_names_the_shipped_studies() -> None:
    code, out, _ = run_cli(["sweep", "--list"])
    assert code == 0
    from fleet_emu.sweep.study import STUDIES

    names = [ln.split()[0] for ln in out.strip().splitlines()]
    assert names == sorted(p.stem for p in STUDIES.glob("*.toml"))  # every shipped file, in order, once
    assert {"bautin-fig5", "benavides", "yan-loss", "shadowing", "mukhija-fig5"} <= set(names)


@pytest.mark.slow  # a scheduler and workers; sweep over processes once by default
def test_a_study_on_a_dask_cluster(study_dir: Path) -> None:
    """``--dask ADDRESS`` sends the points to the scheduler; its workers run whole fleets."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) \
            as cluster:
        out = study_dir / "out"
        assert sweep(str(study_dir / "tiny.toml"), out, dask=cluster.scheduler_address, limit=3, quiet=True) == 0
    rows = read_rows(out)
    assert len(rows) == 3 and all(r["status"] == "ok" and r["ticks"] > 0 for r in rows)


def test_a_processes_study_runs_real_fleets_with_the_memory_rows(study_dir: Path) -> None:
    text = (study_dir / "tiny.toml").read_text()
    (study_dir / "real.toml").write_text(text.replace('engine = "memory"', 'engine = "processes"')
                                         .replace('name = "tiny"', 'name = "real"'))
    assert sweep(str(study_dir / "real.toml"), study_dir / "real", jobs=1, limit=1, quiet=True) == 0
    assert sweep(str(study_dir / "tiny.toml"), study_dir / "mem", jobs=1, limit=1, quiet=True) == 0
    (real,), (mem,) = read_rows(study_dir / "real"), read_rows(study_dir / "mem")
    assert real["engine"] == "processes" and mem["engine"] == "memory" and real["id"] == mem["id"]
    assert real["pids.world"] != real["pids.netem"] and mem["pids.world"] == mem["pids.netem"]
    same = ("ticks", "coverage", "path_length", "radio.sent", "radio.bytes_sent", "curve")
    assert [real[k] for k in same] == [mem[k] for k in same]
    # a processes run records as it goes; with record = "failed" its folder stays only when it missed the target
    kept = study_dir / "real" / "runs" / real["id"]
    assert (kept / "run.mcap").exists() is bool(real["run_dir"]) is (not real["completed"])


@pytest.mark.slow  # sweep over processes proven once by default
def test_sigterm_stops_a_sweep_keeps_its_rows_and_leaves_no_worker(tmp_path: Path) -> None:
    import signal
    import subprocess
    import sys
    import time

    (tmp_path / "long.toml").write_text('[study]\nname = "long"\nengine = "memory"\nseeds = 40\n[grid]\n'
                                        'allocator = ["nearest"]\nrobots = [2]\nmap = ["office"]\n')
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "fleet_emu", "sweep", str(tmp_path / "long.toml"), "--out",
                             str(out), "--jobs", "2", "--quiet"], cwd=ROOT, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 240
    while not (out / "rows.jsonl").exists() or not read_rows(out):
        assert time.monotonic() < deadline and proc.poll() is None, "no row was written"
        time.sleep(0.2)
    workers = subprocess.run(["pgrep", "-P", str(proc.pid)], capture_output=True, text=True).stdout.split()
    assert workers  # the pool's processes
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err[-2000:]
    assert "Traceback" not in err and "interrupted" in err.strip().splitlines()[-1]
    rows = read_rows(out)
    assert 1 <= len(rows) < 40 and all(r["status"] == "ok" for r in rows)
    assert len(pq.read_table(out / "results.parquet")) == len(rows)
    deadline = time.monotonic() + 10
    while any(_alive(int(p)) for p in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [Path(f"/proc/{p}/cmdline").read_text() for p in workers if _alive(int(p))]


def _alive(pid: int) -> bool:
    import os

    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True
