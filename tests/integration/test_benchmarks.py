"""The benchmark scripts: a progress line per finished run on stderr, and a non-zero exit when a run failed."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from tests.conftest import ROOT


def _bench(script: str, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(ROOT / "benchmarks" / script), *args], capture_output=True,
                          text=True, timeout=240, cwd=ROOT)


def test_compare_allocators_reports_each_run(small_map: Path) -> None:
    proc = _bench("compare_allocators.py", "--allocators", "nearest", "--robots", "2", "--seeds", "2",
                  "--maps", str(small_map), "--start", "map")
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 2 and all(" t99 " in ln for ln in lines), proc.stderr
    assert sorted(ln.split("]")[0] for ln in lines) == ["[1/2", "[2/2"]
    assert "E" not in proc.stdout.splitlines()[-1]


def test_compare_allocators_fails_when_a_run_fails() -> None:
    proc = _bench("compare_allocators.py", "--allocators", "nearest", "--robots", "2", "--seeds", "2",
                  "--maps", "/no/such/map.png")
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert [ln.split(": ", 1)[1].split(")")[0] for ln in lines[:2]] == ["FAILED (exit 2"] * 2, proc.stderr
    assert lines[-1] == "compare_allocators: 2 of 2 runs failed (E in the table; see the lines above)"
    assert "E2" in proc.stdout


def test_ticks_per_second_reports_each_run() -> None:
    proc = _bench("ticks_per_second.py", "--robots", "1", "--ticks", "5")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stderr.strip().splitlines()[0].startswith("[1/1] 1 robots: 5 ticks in ")


def test_ticks_per_second_fails_when_a_run_fails() -> None:
    proc = _bench("ticks_per_second.py", "--robots", "1", "2", "--ticks", "5", "--allocator", "telepathy")
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert lines[0].startswith("[1/2] 1 robots: FAILED (exit 2: fleet: error:") and "telepathy" in lines[0]
    assert lines[-1] == "ticks_per_second: 2 of 2 runs failed (see the lines above)"


def test_trade_idle_reports_each_run_and_the_idle_ticks(small_map: Path) -> None:
    proc = _bench("trade_idle.py", "--allocators", "hungarian", "trade:explore_in_round=false", "--seeds", "1",
                  "--maps", str(small_map), "--start", "map", "--comm", "full")
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 2 and all(" idle " in ln for ln in lines), proc.stderr
    rows = [ln.split() for ln in proc.stdout.splitlines() if ln.startswith(small_map.stem)]
    assert [r[2] for r in rows] == ["hungarian", "trade:explore_in_round=false"]
    assert int(rows[1][-3]) > 0  # robots standing still through their rounds: idle robot-ticks
    assert int(rows[1][-1]) > 0  # ... spent WAITING


def test_trade_idle_bad_allocator_spec_is_one_line() -> None:
    proc = _bench("trade_idle.py", "--allocators", "trade:explore_in_round")
    assert proc.returncode == 2 and proc.stderr.strip().splitlines()[-1].endswith(
        "'trade:explore_in_round' is not NAME or NAME:PARAM=VALUE,...")


def test_engine_speed_compares_the_engines_on_equal_runs() -> None:
    proc = _bench("engine_speed.py", "--quick", "--seeds", "1", "--max-ticks", "15")
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.strip().splitlines()
    assert lines[0].split()[:4] == ["scenario", "memory", "s/run", "in-process"] and "in-process/memory" in lines[0]
    assert len(lines) == 4 and lines[-1].startswith("all (sum)") and float(lines[-1].split()[-1]) > 0
    assert "differs" not in proc.stderr


def test_scale_reports_a_row_per_map_and_fleet(small_map: Path) -> None:
    """Issue 11: a row per map and robot count, positive figures; a ``start`` row for a fleet larger than the
    map's free area (161 and 199 cells here), a ``cap`` row above the robot cap."""
    proc = _bench("scale.py", "--robots", "2", "250", "300", "--cells", "20", "--ticks", "6", "--sensor-cells", "2",
                  "--maps", "maze", str(small_map))
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.strip().splitlines()
    assert lines[0].startswith("# benchmarks/scale.py (issue 11): ") and " cores " in lines[0]
    assert lines[3].split()[:6] == ["map", "cells", "robots", "start", "s", "ticks"]
    stage_at = next(i for i, ln in enumerate(lines) if ln.startswith("# brain by stage"))
    rows = [ln.split() for ln in lines[4:stage_at]]
    assert [(r[0], r[2]) for r in rows] == [(m, n) for m in ("maze", "two_rooms") for n in ("2", "250", "300")]
    stage_rows = [ln.split() for ln in lines[stage_at + 2:]]
    assert lines[stage_at + 1].split() == ["map", "robots", "merge", "clusters", "decode", "navigation", "news",
                                           "other", "tick0"]
    assert [(r[0], r[1]) for r in stage_rows] == [("maze", "2"), ("two_rooms", "2")]
    for r, st in zip((rows[0], rows[3]), stage_rows, strict=True):
        assert len(r) == 25 and int(r[4]) == 6, r
        start, tps, total, cores = float(r[3]), float(r[5]), float(r[15]), float(r[16])
        assert start > 0 and tps > 0 and total > 0 and cores > 0, r
        assert all(float(v) > 0 for v in r[17:23]), r  # PSS of agents, world, netem, the router and the launcher
        # decide, brain, a.py and a.zen come from the agents' own clocks over the same steps, so none is negative
        # (a.bus was, from the /proc window under load); outside is the three besides the allocator
        decide, brain, apy, azen, outside = map(float, r[8:13])
        assert decide > 0 and brain > 0 and apy >= 0 and azen >= 0, r
        assert abs(brain + apy + azen - outside) < 0.02, r
        assert float(r[13]) >= 0 and float(r[21]) > 0, r  # the router's own process: sampled (its PSS)
        # the second table splits brain by stage; the stages add up to it
        *stages, tick0 = map(float, st[2:])
        assert all(v >= 0 for v in stages[:-1]) and abs(sum(stages) - brain) < 0.02, (r, st)
        assert tick0 > 0, st  # the first step, left out of the agent columns
    assert rows[0][1].startswith(("19x", "20x", "21x"))  # the maze fitted to about 20 cells across
    assert len(proc.stderr.strip().splitlines()) == 8  # two map lines, six progress lines


def test_scale_bad_argument_is_one_line() -> None:
    proc = _bench("scale.py", "--robots", "0")
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == ["scale: error: --robots must be at least 1 (got 0)"]


def test_agent_memory_reports_each_run() -> None:
    proc = _bench("agent_memory.py", "--robots", "2", "--ticks", "40", "--period", "0.2")
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stderr.strip().splitlines()[0] == "[1/1] 2 robots: 40 ticks"
    row = proc.stdout.strip().splitlines()[-1].split()
    assert row[:2] == ["2", "40"] and all(float(x) > 0 for x in row[2:])  # the fork server's share too


def test_brain_step_reports_a_row_per_map(small_map: Path) -> None:
    """Issue 11, part 3: a row per map of thread CPU per robot-tick by stage; the stages add up to the step."""
    proc = _bench("brain_step.py", "--robots", "2", "--ticks", "5", "--cells", "40", "--maps", "maze", str(small_map))
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.strip().splitlines()
    assert lines[0].startswith("# benchmarks/brain_step.py (issue 11, part 3): ") and " cores " in lines[0]
    assert lines[2].split()[:3] == ["map", "decide", "clusters"]
    rows = [ln.split() for ln in lines[3:]]
    assert [r[0] for r in rows] == ["maze", "two_rooms"]
    for r in rows:
        decide, *stages, outside, step, rx = map(float, r[1:11])
        assert step > 0 and rx > 0 and all(v >= 0 for v in stages), r
        assert abs(decide + sum(stages) - step) < 0.01 and abs(step - decide - outside) < 0.01, r
    assert len(proc.stderr.strip().splitlines()) == 2  # a progress line per map


def test_brain_step_bad_input_is_one_line() -> None:
    proc = _bench("brain_step.py", "--maps", "/no/such/map.png")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "map /no/such/map.png" in proc.stderr
    proc = _bench("brain_step.py", "--ticks", "x")
    assert proc.returncode == 2 and proc.stderr.startswith("brain_step: error: ") and proc.stderr.count("\n") == 1


def test_realtime_study_reports_a_row_per_fleet_and_allocator(small_map: Path) -> None:
    """Issue 11, part 5: greedy and minpos in real time, a row each with the real-time columns; a ``start`` row
    for a fleet larger than the map's free area (199 cells here)."""
    proc = _bench("realtime_study.py", "--robots", "2", "250", "--cells", "24", "--max-ticks", "20", "--hz", "20",
                  "--maps", str(small_map))
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.strip().splitlines()
    assert lines[0].startswith("# benchmarks/realtime_study.py (issue 11, part 5): ")
    assert lines[3].split()[:5] == ["map", "cells", "robots", "allocator", "t99"]
    rows = [ln.split() for ln in lines[4:]]
    assert [(r[2], r[3]) for r in rows] == [("2", "greedy"), ("2", "minpos-par"), ("250", "greedy"),
                                           ("250", "minpos-par")]
    for r in rows[:2]:
        assert len(r) == 21 and int(r[6]) <= 20 and float(r[9]) > 0, r  # ticks, achieved ticks/s
        assert float(r[15]) > 0, r  # decisions per robot
    assert [r[4] for r in rows[2:]] == ["start:", "start:"]


def test_realtime_study_bad_argument_is_one_line() -> None:
    proc = _bench("realtime_study.py", "--hz", "0")
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == ["realtime_study: error: --hz must be > 0 and <= 1000 (got 0.0)"]


def test_map_sync_reports_the_gaps_and_the_recovery(small_map: Path) -> None:
    proc = _bench("map_sync.py", "--map", str(small_map), "--robots", "2", "--seeds", "1", "--start", "map",
                  "--loss", "0.3")
    assert proc.returncode == 0, proc.stderr[-2000:]
    header, row = proc.stdout.splitlines()[:2]
    cells = dict(zip(header.split(), row.split(), strict=True))
    assert int(cells["asks"]) > 0 and int(cells["resent"]) > 0 and int(cells["rec.bytes"]) > 0  # loss recovered
    assert int(cells["conflict"]) == 0


def test_map_sync_bad_map_is_one_line() -> None:
    proc = _bench("map_sync.py", "--map", "/no/such/map.png", "--seeds", "1")
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert proc.stderr.startswith("map_sync: error: ")


def test_base_connectivity_prints_a_row_per_allocator(small_map: Path) -> None:
    proc = _bench("base_connectivity.py", "--map", str(small_map), "--robots", "2", "--seeds", "2",
                  "--comm", "disk", "--comm-range", "2", "--max-ticks", "40", "--allocators", "nearest", "minpos")
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = [ln for ln in proc.stdout.splitlines() if ln.startswith("| nearest") or ln.startswith("| minpos")]
    assert len(rows) == 2
    overall = float(rows[0].split("|")[2].split("±")[0])
    assert 0.0 <= overall < 1.0  # a 2 m disk radio leaves the base behind on this map


def test_relay_prints_a_row_per_policy_and_ttl(small_map: Path) -> None:
    proc = _bench("relay.py", "--map", str(small_map), "--robots", "3", "--seeds", "1", "--comm-range", "2",
                  "--max-ticks", "40", "--ttls", "2")
    assert proc.returncode == 0, proc.stderr[-2000:]
    rows = {tuple(c.strip() for c in ln.split("|")[1:3]): ln for ln in proc.stdout.splitlines()
            if ln.startswith("| ") and not ln.startswith("| relay") and not ln.startswith("| ---")}
    assert set(rows) == {("none", "0"), ("flood", "2"), ("tree", "2")}
    assert float(rows[("flood", "2")].split("|")[5].split("±")[0]) > 0  # some beacons crossed a relay
    bad = _bench("relay.py", "--map", "/no/such/map.png", "--seeds", "1")
    assert bad.returncode == 2 and bad.stderr.startswith("relay: error: ") and bad.stderr.count("\n") == 1


def test_paper_setting_prints_fig7_rows_and_draws_them(small_map: Path, tmp_path: Path) -> None:
    """Issue 10, part 6: a row per allocator and fleet size; MHM keeps every robot connected to the base (its
    constraint), the cells seen grow, and the PNG and the JSON are written; ``--from`` redraws from the JSON."""
    png, data = tmp_path / "fig7.png", tmp_path / "fig7.json"
    proc = _bench("paper_setting.py", "--maps", str(small_map), "--cells", "24", "--r-comm", "6", "--sensor", "3",
                  "--robots", "2", "3", "--allocators", "mhm", "minpos", "--max-ticks", "30", "--at", "10", "30",
                  "--out", str(png), "--json", str(data))
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = proc.stdout.strip().splitlines()
    assert lines[0].startswith("# benchmarks/paper_setting.py (issue 10, part 6): ")
    assert "# map two_rooms: drawn at " in lines[2] and lines[2].endswith("base at (11, 12)")  # padded
    assert lines[3].split()[:8] == ["map", "allocator", "robots", "ticks", "end", "coverage", "seen@10", "seen@30"]
    rows = [ln.split() for ln in lines[4:]]
    assert [(r[1], r[2]) for r in rows] == [("mhm", "2"), ("mhm", "3"), ("minpos", "2"), ("minpos", "3")]
    for r in rows:
        assert 0 < int(r[6]) <= int(r[7]) <= 24 * 24, r  # cells seen by ticks 10 and 30: grow, within the map
        assert 0.0 <= float(r[10]) <= float(r[8]) <= 1.0, r  # worst tick <= overall share connected
    assert all(float(r[10]) == 1.0 for r in rows[:2])  # MHM: every robot linked to the base at every tick
    assert all(r[12:14] == ["-", "-"] for r in rows[2:])  # p95 / max only for MHM's planner
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    saved = json.loads(data.read_text())["rows"]
    assert [len(r["seen"]) for r in saved] == [r["ticks"] + 1 for r in saved]  # ticks 0..T
    assert [(r["end"], r["ticks"]) for r in saved[:2]] == [("step18", 27), ("max_ticks", 30)]  # MHM: up to tick 30
    again = _bench("paper_setting.py", "--from", str(data), "--at", "10", "30", "--max-ticks", "30")
    assert again.returncode == 0 and again.stdout.strip().splitlines()[1:] == lines[4:], again.stderr[-2000:]


def test_paper_setting_bad_input_is_one_line() -> None:
    proc = _bench("paper_setting.py", "--allocators", "telepathy")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert proc.stderr.startswith("paper_setting: error: unknown allocator 'telepathy'")
    proc = _bench("paper_setting.py", "--maps", "/no/such/map.png")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert proc.stderr.startswith("paper_setting: error: map /no/such/map.png: ")
