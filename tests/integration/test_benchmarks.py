"""The benchmark scripts, as smoke checks: each script's ``main(argv)`` in this process on a tiny input, its tables
read by their header names (never a column's position), a progress line per finished run on stderr, and a
non-zero exit when a run failed or an argument is bad (the scripts' fleets are real: ``fleet run`` subprocesses,
or the engines in this process)."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from tests.harness.bench import bench, fields, markdown


@pytest.mark.slow  # a benchmark script's smoke run over real fleets
def test_compare_allocators_reports_each_run_and_fails_when_one_fails(small_map: Path,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("compare_allocators", "--allocators", "nearest", "--robots", "2", "--seeds", "1",
                           "--maps", str(small_map), "/no/such/map.png", "--start", "map", "--engine", "memory",
                           capsys=capsys)
    assert code == 1
    lines = err.strip().splitlines()
    assert sorted(ln.split("]")[0] for ln in lines[:2]) == ["[1/2", "[2/2"], err
    done = {ln.split(" on ")[1].split(":")[0]: ln.split(": ", 1)[1] for ln in lines[:2]}
    assert done["two_rooms"].startswith("t99 ") and done["map"].startswith("FAILED (exit 2"), err
    assert lines[-1] == "compare_allocators: 1 of 2 runs failed (E in the table; see the lines above)"
    tables = {t.split("\n")[0]: t.split("\n")[1:] for t in out.split("\nmap ")[1:]}
    for name, cell in (("two_rooms", "^\\d+±\\d+$"), ("map", "^- E1$")):
        header, row = tables[name][:2]
        got = fields(header, row, ["robots", "nearest"])
        assert got["robots"] == "2" and re.match(cell, got["nearest"]), (name, got)


@pytest.mark.slow  # a benchmark script's smoke run over real fleets
def test_ticks_per_second_reports_each_run_and_fails_when_one_fails(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("ticks_per_second", "--robots", "1", "0", "--ticks", "5", "--in-process", capsys=capsys)
    assert code == 1
    lines = err.strip().splitlines()
    assert lines[0].startswith("[1/2] 1 robots: 5 ticks in "), err
    assert lines[1].startswith("[2/2] 0 robots: FAILED (exit 2: fleet: error:") and "--robots" in lines[1]
    assert lines[-1] == "ticks_per_second: 1 of 2 runs failed (see the lines above)"
    header, ok, failed = out.strip().splitlines()
    labels = ["robots", "ticks", "wall s", "ticks/s", "coverage", "agent RSS max MB", "mean MB", "decision ms"]
    got = fields(header, ok, labels)
    assert got["robots"] == "1" and got["ticks"] == "5" and float(got["wall s"]) > 0 and float(got["ticks/s"]) > 0
    assert fields(header, failed, labels) == {"robots": "0", "ticks": "failed"}


@pytest.mark.slow  # a benchmark script's smoke run over real fleets
def test_trade_idle_reports_each_run_and_the_idle_ticks(small_map: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("trade_idle", "--allocators", "hungarian", "trade:explore_in_round=false", "--seeds", "1",
                           "--maps", str(small_map), "--start", "map", "--comm", "full", "--engine", "memory",
                           capsys=capsys)
    assert code == 0, err[-2000:]
    lines = err.strip().splitlines()
    assert len(lines) == 2 and all(" idle " in ln for ln in lines), err
    table = out.strip().splitlines()
    header = next(ln for ln in table if ln.startswith("map "))
    labels = ["map", "loss", "allocator", "ticks", "vs hungarian", "path", "idle", ("idle share", "idle %"),
              "waiting"]
    rows = [fields(header, ln, labels) for ln in table if ln.startswith(small_map.stem)]
    assert [r["allocator"] for r in rows] == ["hungarian", "trade:explore_in_round=false"]
    assert int(rows[1]["idle"]) > 0  # robots standing still through their rounds: idle robot-ticks
    assert int(rows[1]["waiting"]) > 0  # ... spent WAITING


def test_trade_idle_bad_allocator_spec_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = bench("trade_idle", "--allocators", "trade:explore_in_round", capsys=capsys)
    assert code == 2 and err.strip().splitlines()[-1].endswith(
        "'trade:explore_in_round' is not NAME or NAME:PARAM=VALUE,...")


@pytest.mark.slow  # a benchmark script's smoke run
def test_engine_speed_compares_the_engines_on_equal_runs(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("engine_speed", "--quick", "--seeds", "1", "--max-ticks", "15", capsys=capsys)
    assert code == 0, err[-2000:]
    header, *rows = out.strip().splitlines()
    labels = ["scenario", "memory s/run", "in-process s/run", "in-process/memory"]
    assert len(rows) == 3 and rows[-1].startswith("all (sum)")
    total = fields(header, rows[-1].replace("all (sum)", "all_(sum)"), labels)
    assert total["scenario"] == "all_(sum)" and float(total["in-process/memory"]) > 0
    assert all(float(total[k]) > 0 for k in labels[1:3])
    assert "differs" not in err


@pytest.mark.slow  # a benchmark script's smoke run over real fleets
def test_scale_reports_a_row_per_fleet(capsys: pytest.CaptureFixture[str]) -> None:
    """A row per robot count, positive figures; a ``start`` row for a fleet larger than the map's free
    area (161 cells here), a ``cap`` row above the robot cap. (A map file, fitted by the same functions:
    ``test_brain_step_reports_a_row_per_map``.)"""
    code, out, err = bench("scale", "--robots", "2", "250", "300", "--cells", "20", "--ticks", "40", "--sensor-cells",
                           "2", "--maps", "maze", capsys=capsys)
    assert code == 0, err[-2000:]
    lines = out.strip().splitlines()
    assert lines[0].startswith("# benchmarks/scale.py: ") and " cores " in lines[0]
    groups, header = lines[2], lines[3]
    cpu, pss, first = groups.index("| CPU ms per robot-tick"), groups.index("| PSS MB"), header.index("world")
    assert cpu <= first < pss <= header.index("world", first + 1)  # world's CPU, then its PSS
    labels = ["map", "cells", "robots", "start s", "ticks", "ticks/s", "world", "netem", "decide", "brain", "a.py",
              "a.zen", "outside", "router", "launch", "total", "cores", "a.mean", "a.max", ("pss world", "world"),
              ("pss netem", "netem"), ("pss router", "router"), ("pss launch", "launch"), "dec wall", "load1"]
    stage_at = next(i for i, ln in enumerate(lines) if ln.startswith("# brain by stage"))
    measured, start, cap = lines[4:stage_at]
    r = fields(header, measured, labels)
    assert set(r) == {k if isinstance(k, str) else k[0] for k in labels}, r
    assert (r["map"], r["robots"], r["ticks"]) == ("maze", "2", "40") and r["cells"].startswith(("19x", "20x", "21x"))
    assert all(float(r[k]) > 0 for k in ("start s", "ticks/s", "total", "cores")), r
    # PSS of agents, world, netem, the router and the launcher
    assert all(float(r[k]) > 0 for k in ("a.mean", "a.max", "pss world", "pss netem", "pss router", "pss launch")), r
    # decide, brain, a.py and a.zen come from the agents' own clocks over the same steps, so none is negative
    # (a.bus was, from the /proc window under load); outside is the three besides the allocator
    decide, brain, apy, azen, outside = (float(r[k]) for k in ("decide", "brain", "a.py", "a.zen", "outside"))
    assert decide > 0 and brain > 0 and apy >= 0 and azen >= 0, r
    assert abs(brain + apy + azen - outside) < 0.02, r
    assert float(r["router"]) >= 0, r  # the router's own process: sampled (its PSS above)
    for row, note in ((start, "start: "), (cap, "cap: ")):
        got = fields(header, row, ["map", "cells", "robots"])
        assert got["map"] == "maze" and got["rest"].startswith(note), row
    assert [fields(header, ln, ["map", "cells", "robots"])["robots"] for ln in (start, cap)] == ["250", "300"]
    # the second table splits brain by stage; the stages add up to it
    stage_header, stage_row = lines[stage_at + 1:]
    names = ["map", "robots", "merge", "clusters", "decode", "navigation", "news", "other", "tick0"]
    st = fields(stage_header, stage_row, names)
    assert (st["map"], st["robots"]) == ("maze", "2")
    stages = [float(st[n]) for n in names[2:-1]]
    assert all(v >= 0 for v in stages[:-1]) and abs(sum(stages) - brain) < 0.02, (r, st)
    assert float(st["tick0"]) > 0, st  # the first step, left out of the agent columns
    assert len(err.strip().splitlines()) == 4  # the map line, three progress lines


def test_scale_bad_argument_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = bench("scale", "--robots", "0", capsys=capsys)
    assert code == 2
    assert err.strip().splitlines() == ["scale: error: --robots must be at least 1 (got 0)"]


@pytest.mark.slow  # a benchmark script's smoke run over real fleets
def test_agent_memory_reports_each_run(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("agent_memory", "--robots", "2", "--ticks", "40", "--period", "0.2", capsys=capsys)
    assert code == 0, err[-2000:]
    assert err.strip().splitlines()[0] == "[1/1] 2 robots: 40 ticks"
    header, row = out.strip().splitlines()
    labels = ["robots", "ticks", "agent PSS mean MB", "max MB", "agent RSS mean MB", "fork server PSS MB",
              "agents+server PSS MB"]
    got = fields(header, row, labels)
    assert got["robots"] == "2" and got["ticks"] == "40"
    assert all(float(got[k]) > 0 for k in labels[2:]), got  # the fork server's share too


def test_brain_step_reports_a_row_per_map(small_bitmap: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A row per map of thread CPU per robot-tick by stage; the stages add up to the step."""
    code, out, err = bench("brain_step", "--robots", "2", "--ticks", "5", "--cells", "40", "--maps", "maze",
                           str(small_bitmap), capsys=capsys)
    assert code == 0, err[-2000:]
    lines = out.strip().splitlines()
    assert lines[0].startswith("# benchmarks/brain_step.py: ") and " cores " in lines[0]
    labels = ["map", "decide", "clusters", "merge", "decode", "nav", "news", "other", "outside", "step", "rx codec",
              "load1"]
    rows = [fields(lines[2], ln, labels) for ln in lines[3:]]
    assert [r["map"] for r in rows] == ["maze", "two_rooms"]
    for r in rows:
        decide, step, outside, rx = (float(r[k]) for k in ("decide", "step", "outside", "rx codec"))
        stages = [float(r[k]) for k in ("clusters", "merge", "decode", "nav", "news", "other")]
        assert step > 0 and rx > 0 and all(v >= 0 for v in stages), r
        assert abs(decide + sum(stages) - step) < 0.01 and abs(step - decide - outside) < 0.01, r
    progress = err.strip().splitlines()  # per map: its fitted size, then its progress
    assert [ln.split(":")[0] for ln in progress if ln.startswith("map ")] == ["map maze", f"map {small_bitmap}"]
    assert sum("robot-ticks in" in ln for ln in progress) == 2 and len(progress) == 4


def test_hearing_splits_each_kinds_decode_by_stage(capsys: pytest.CaptureFixture[str]) -> None:
    """A row per payload kind of the stages of its batch decode, then ``hear``'s line; only a kind with arrays
    builds records; a bad argument is one line."""
    code, out, err = bench("hearing", "--robots", "3", "--ticks", "8", "--cells", "40", "--sample", "0.5",
                           "--repeat", "1", capsys=capsys)
    assert code == 0, err[-2000:]
    lines = out.strip().splitlines()
    assert lines[0].startswith("# benchmarks/hearing.py: ") and "inboxes kept" in lines[1]
    labels = ["kind", "payloads", "concatenate", "bounds", "msgspec", "records", "checks", "decode_many"]
    rows = {r["kind"]: r for r in (fields(lines[2], ln, labels) for ln in lines[3:5])}
    assert set(rows) == {"pose", "map"}
    assert all(float(v) >= 0 for r in rows.values() for k, v in r.items() if k != "kind"), rows
    assert float(rows["pose"]["payloads"]) > 0 and float(rows["pose"]["records"]) == 0.0
    assert float(rows["map"]["payloads"]) > 0 and float(rows["map"]["records"]) > 0
    assert re.match(r"hear: [0-9.]+ µs per inbox, of which -?[0-9.]+ outside the rows above", lines[5]), lines[5]
    code, _, err = bench("hearing", "--sample", "0", capsys=capsys)
    assert code == 2 and err.count("\n") == 1 and "--sample" in err


def test_brain_step_bad_input_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = bench("brain_step", "--maps", "/no/such/map.png", capsys=capsys)
    assert code == 2 and err.count("\n") == 1 and "map /no/such/map.png" in err
    code, _, err = bench("brain_step", "--ticks", "x", capsys=capsys)
    assert code == 2 and err.startswith("brain_step: error: ") and err.count("\n") == 1


@pytest.mark.slow  # a benchmark script's smoke run over real fleets
def test_realtime_study_reports_a_row_per_fleet_and_allocator(small_bitmap: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    """A fleet in real time, its row with the real-time columns; a ``start`` row for a fleet
    larger than the map's free area (199 cells here); a row per allocator (here greedy, in lockstep too)."""
    code, out, err = bench("realtime_study", "--robots", "2", "250", "--cells", "24", "--max-ticks", "20", "--hz",
                           "20", "--maps", str(small_bitmap), "--allocators", "greedy", capsys=capsys)
    assert code == 0, err[-2000:]
    lines = out.strip().splitlines()
    assert lines[0].startswith("# benchmarks/realtime_study.py: ")
    labels = ["map", "cells", "robots", "allocator", "t99", "t99 s", "ticks", "reason", "cov", "tps", "ovr", "late",
              "lstep", "miss", "dec", "plan", "p50", "p90", "p99", "max", "load1"]
    header = lines[3]
    r = fields(header, lines[4], labels)
    assert (r["robots"], r["allocator"]) == ("2", "greedy")
    assert set(r) == set(labels), r  # every real-time column filled
    assert int(r["ticks"]) <= 20 and float(r["tps"]) > 0, r  # ticks, achieved ticks/s
    assert float(r["dec"]) > 0 and float(r["plan"]) > 0, r  # decisions and plan steps per robot
    start = fields(header, lines[5], ["map", "cells", "robots", "allocator"])
    assert (start["robots"], start["allocator"]) == ("250", "greedy") and start["rest"].startswith("start: ")
    assert len(lines) == 6
    code, out, err = bench("realtime_study", "--lockstep", "--robots", "2", "--cells", "24", "--max-ticks", "20",
                           "--maps", str(small_bitmap), capsys=capsys)
    assert code == 0, err[-2000:]
    rows = [fields(header, ln, labels[:10]) for ln in out.strip().splitlines()[4:]]
    assert [r["allocator"] for r in rows] == ["greedy", "minpos-par"] and all(int(r["ticks"]) > 0 for r in rows)


def test_realtime_study_bad_argument_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = bench("realtime_study", "--hz", "0", capsys=capsys)
    assert code == 2
    assert err.strip().splitlines() == ["realtime_study: error: --hz must be > 0 and <= 1000 (got 0.0)"]


def test_map_sync_reports_the_gaps_and_the_recovery(small_map: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("map_sync", "--map", str(small_map), "--robots", "2", "--seeds", "1", "--start", "map",
                           "--loss", "0.3", capsys=capsys)
    assert code == 0, err[-2000:]
    header, row = out.splitlines()[:2]
    cells = dict(zip(header.split(), row.split(), strict=True))  # one word a column, labels included
    assert int(cells["asks"]) > 0 and int(cells["resent"]) > 0 and int(cells["rec.bytes"]) > 0  # loss recovered
    assert int(cells["conflict"]) == 0


def test_map_sync_switch_prints_a_row_per_loss_on_against_off(small_map: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("map_sync", "--map", str(small_map), "--robots", "2", "--seeds", "1", "--start", "map",
                           "--switch", "0,0.3", capsys=capsys)
    assert code == 0, err[-2000:]
    lines = out.strip().splitlines()
    assert len(lines) == 4 and lines[2].startswith("| 0 |") and lines[3].startswith("| 0.3 |")
    zero, lossy = ([c.strip() for c in ln.strip("|").split("|")] for ln in lines[2:])
    assert zero[1] == zero[2] and zero[5] == zero[6]  # nothing lost at loss 0: one run, on or off
    assert lossy[5] != lossy[6]  # at loss 0.3 the two send different bytes


def test_map_sync_bad_map_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = bench("map_sync", "--map", "/no/such/map.png", "--seeds", "1", capsys=capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert err.startswith("map_sync: error: ")
    code, _, err = bench("map_sync", "--switch", "0,2", capsys=capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1 and "each loss must be in [0, 1]" in err, err


def test_base_connectivity_prints_a_row_per_allocator(small_map: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("base_connectivity", "--map", str(small_map), "--robots", "2", "--seeds", "2", "--comm",
                           "disk", "--comm-range", "2", "--max-ticks", "40", "--allocators", "nearest", "minpos",
                           capsys=capsys)
    assert code == 0, err[-2000:]
    rows = markdown(out)
    assert [r["allocator"] for r in rows] == ["nearest", "minpos"]
    overall = float(rows[0]["base connected (overall)"].split("±")[0])
    assert 0.0 <= overall < 1.0  # a 2 m disk radio leaves the base behind on this map


def test_relay_prints_a_row_per_policy_and_ttl(small_map: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("relay", "--map", str(small_map), "--robots", "3", "--seeds", "1", "--comm-range", "2",
                           "--max-ticks", "40", "--ttls", "2", capsys=capsys)
    assert code == 0, err[-2000:]
    rows = {(r["relay"], r["ttl"]): r for r in markdown(out)}
    assert set(rows) == {("none", "0"), ("flood", "2"), ("tree", "2")}
    assert float(rows[("flood", "2")]["pose 2+ hops"].split("±")[0]) > 0  # some beacons crossed a relay
    code, _, err = bench("relay", "--map", "/no/such/map.png", "--seeds", "1", capsys=capsys)
    assert code == 2 and err.startswith("relay: error: ") and err.count("\n") == 1


@pytest.mark.slow  # a benchmark script's smoke run
def test_paper_setting_prints_fig7_rows_and_draws_them(small_bitmap: Path, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    """A row per allocator and fleet size; MHM keeps every robot connected to the base (its
    constraint), the cells seen grow, and the PNG and the JSON are written; ``--from`` redraws from the JSON."""
    png, data = tmp_path / "fig7.png", tmp_path / "fig7.json"
    code, out, err = bench("paper_setting", "--maps", str(small_bitmap), "--cells", "24", "--r-comm", "6", "--sensor",
                           "3", "--robots", "2", "3", "--allocators", "mhm", "minpos", "--max-ticks", "30", "--at",
                           "10", "30", "--out", str(png), "--json", str(data), capsys=capsys)
    assert code == 0, err[-2000:]
    lines = out.strip().splitlines()
    assert lines[0].startswith("# benchmarks/paper_setting.py: ")
    assert "# map two_rooms: drawn at " in lines[2] and lines[2].endswith("base at (11, 12)")  # padded
    labels = ["map", "allocator", "robots", "ticks", "end", "coverage", "seen@10", "seen@30", "overall", "all",
              "worst", "ms mean", "ms p95", "ms max", "plan s", "run s"]
    rows = [fields(lines[3], ln, labels) for ln in lines[4:]]
    assert [(r["allocator"], r["robots"]) for r in rows] == [("mhm", "2"), ("mhm", "3"), ("minpos", "2"),
                                                             ("minpos", "3")]
    for r in rows:
        assert 0 < int(r["seen@10"]) <= int(r["seen@30"]) <= 24 * 24, r  # cells seen: grow, within the map
        assert 0.0 <= float(r["worst"]) <= float(r["overall"]) <= 1.0, r  # worst tick <= overall share connected
    assert all(float(r["worst"]) == 1.0 for r in rows[:2])  # MHM: every robot linked to the base at every tick
    assert all((r["ms p95"], r["ms max"]) == ("-", "-") for r in rows[2:])  # p95 / max only for MHM's planner
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    saved = json.loads(data.read_text())["rows"]
    assert [len(r["seen"]) for r in saved] == [r["ticks"] + 1 for r in saved]  # ticks 0..T
    assert [(r["end"], r["ticks"]) for r in saved[:2]] == [("step18", 27), ("max_ticks", 30)]  # MHM: up to tick 30
    code, again, err = bench("paper_setting", "--from", str(data), "--at", "10", "30", "--max-ticks", "30",
                             capsys=capsys)
    assert code == 0 and again.strip().splitlines()[1:] == lines[4:], err[-2000:]


def test_paper_setting_bad_input_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = bench("paper_setting", "--allocators", "telepathy", capsys=capsys)
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith("paper_setting: error: unknown allocator 'telepathy'")
    code, _, err = bench("paper_setting", "--maps", "/no/such/map.png", capsys=capsys)
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith("paper_setting: error: map /no/such/map.png: ")


def test_trade_lock_counts_runs_that_drag_on(small_map: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("trade_lock", "--map", str(small_map), "--robots", "2", "--seeds", "2", "--loss", "0",
                           "--long", "1", capsys=capsys)
    assert code == 0, err
    lines = out.strip().splitlines()
    labels = ["loss", "blocked_after", "past 1", "ticks", "longest"]
    rows = [fields(lines[1], ln, labels) for ln in lines[2:]]
    assert [(r["loss"], r["blocked_after"]) for r in rows] == [("0.0", "4"), ("0.0", "0")]
    for r in rows:
        assert r["past 1"] == "2" and re.match(r"^\d+±\d+$", r["ticks"]) and int(r["longest"]) > 1, r
    code, _, err = bench("trade_lock", "--map", "/no/such/map.png", capsys=capsys)
    assert code == 2 and err == "trade_lock: error: map file not found: /no/such/map.png\n"


@pytest.mark.slow  # a benchmark script's smoke run
def test_yan_regions_counts_trade_rounds_and_segmentations(small_map: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("yan_regions", "--map", str(small_map), "--allocators", "trade:tasks=regions", "trade",
                           "--seeds", "1", "--loss", "0", "--max-ticks", "300", capsys=capsys)
    assert code == 0, err[-2000:]
    regions, frontiers = markdown(out)
    assert (regions["allocator"], frontiers["allocator"]) == ("trade:tasks=regions", "trade")
    assert 0 < float(regions["calls/robot-tick"]) <= 1.0 and float(regions["segmentation ms/call"]) > 0
    assert frontiers["segmentation ms/call"] == "-" and float(frontiers["rounds /100 ticks"]) > 0
    assert len(err.strip().splitlines()) == 2  # a line per run


def test_yan_regions_and_regions_picture_bad_input_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = bench("yan_regions", "--allocators", "trade:tasks=rooms", capsys=capsys)
    assert code == 2 and err.count("\n") == 1 and "tasks must be one of" in err, err
    code, _, err = bench("regions_picture", "--maps", "/no/such/map.png", capsys=capsys)
    assert code == 2 and err.count("\n") == 1 and err.startswith("regions_picture: error: "), err


@pytest.mark.slow  # a benchmark script's smoke run
def test_regions_picture_draws_a_png_per_map(small_map: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("regions_picture", "--maps", str(small_map), "--tick", "5", "--out", str(tmp_path),
                           capsys=capsys)
    assert code == 0, err[-2000:]
    (row,) = markdown(out)
    assert row["map"] == small_map.stem and int(row["regions (whole map)"]) >= 1
    assert (tmp_path / f"regions-{small_map.stem}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("script", ["fault_trials", "attacks", "bad_inputs", "connectivity_table", "decision_time",
                                    "mhm_fleet", "mhm_planner", "minpos_vs_utility", "ros2_cost"])
def test_the_other_scripts_import_and_describe_themselves(script: str, capsys: pytest.CaptureFixture[str]) -> None:
    """The scripts the suite does not run (minutes each): they import, and ``--help`` describes them."""
    code, out, _ = bench(script, "--help", capsys=capsys)
    assert code == 0 and out.startswith("usage: ") and "--" in out


def test_flips_prints_a_row_per_allocator_and_size(small_map: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("flips", "--maps", str(small_map), "--robots", "2", "--seeds", "1", "--max-ticks", "40",
                           "--allocators", "nearest", "hungarian:replan=tick", capsys=capsys)
    assert code == 0, err[-2000:]
    rows = markdown(out)
    assert [r["allocator"] for r in rows] == ["nearest", "hungarian:replan=tick"]
    for r in rows:
        assert r["robots"] == "2" and r["runs"] == "1" and 0.0 <= float(r["flips / 100 robot-ticks"]) <= 100.0
    assert err.count(" robot-ticks\n") == 2  # a progress line per run
    code, _, err = bench("flips", "--allocators", "hungarian:replan", "--seeds", "1", capsys=capsys)
    assert code == 2 and err.startswith("flips: error: ") and err.count("\n") == 1


@pytest.mark.slow  # a benchmark script's smoke run
def test_mhm_reach_runs_to_the_method_end_and_compares_with_the_disc(tmp_path: Path,
                                                                    capsys: pytest.CaptureFixture[str]) -> None:
    data = tmp_path / "reach.json"
    code, out, err = bench("mhm_reach", "--cells", "70", "--robots", "3", "--r-comm", "8", "--sensor", "3",
                           "--json", str(data), capsys=capsys)
    assert code == 0, err[-2000:]
    (row,) = json.loads(data.read_text())
    assert row["end"] == "step18" and row["stop"].startswith("stop: ") and row["worst"] == 1.0
    assert row["reach"] == int(out.strip().splitlines()[-1].split()[4].replace(",", ""))
    assert abs(row["disc"] - 3.141592653589793 * (2 * 8 + 3) ** 2) < 1e-6 and row["table2"] is None
    assert 0.5 < row["vs_disc"] < 1.5 and not row["bounded"]
    code, out, err = bench("mhm_reach", "--cells", "30", "--robots", "3", "--r-comm", "8", "--sensor", "3",
                           "--max-ticks", "5", capsys=capsys)
    assert code == 0 and " max_ticks " in out.splitlines()[-1] and "max ticks" in out.splitlines()[-1]
    code, out, err = bench("mhm_reach", "--cells", "24", "--robots", "3", "--r-comm", "8", "--sensor", "3",
                           "--json", str(data), capsys=capsys)
    assert code == 0 and json.loads(data.read_text())[0]["bounded"], err[-2000:]  # the walls were in reach


def test_mhm_reach_bad_argument_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = bench("mhm_reach", "--robots", "1", capsys=capsys)
    assert code == 2 and err.count("\n") == 1 and err.startswith("mhm_reach: error: --robots"), err


def test_crash_maze_prints_a_row_per_run_with_its_blind_twin(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("crash_maze", "--seeds", "2", "--max-ticks", "40", capsys=capsys)
    assert code == 0, err[-2000:]
    rows = markdown(out)
    assert [(r["seed"], r["crashed"]) for r in rows] == [("0", "r0"), ("1", "r1")]
    for r in rows:
        assert int(r["ticks"]) <= 40 and r["reached"] in ("yes", "no") and 0.0 <= float(r["coverage"]) <= 1.0
    assert err.count(" ticks (") == 2  # a progress line per run
    code, _, err = bench("crash_maze", "--crash-tick", "5000", capsys=capsys)
    assert code == 2 and err.startswith("crash_maze: error: ") and err.count("\n") == 1


def test_live_viewers_bad_argument_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = bench("live_viewers", "--viewers", "0", capsys=capsys)
    assert code == 2
    assert err.strip().splitlines() == ["live_viewers: error: --viewers, --waves, --ticks and --seeds must be at "
                                        "least 1, --delay from 0 to 600"]


def test_suite_cost_tables_the_tests_and_the_modules_by_cpu(capsys: pytest.CaptureFixture[str]) -> None:
    from benchmarks.suite_cost import table

    rows = [{"nodeid": f"tests/{m}.py::t{i}", "cpu": c, "wall": 2 * c, "outcome": o}
            for m, i, c, o in (("a", 0, 1.0, "passed"), ("a", 1, 3.0, "failed"), ("b", 0, 2.5, "skipped"))]
    lines = table(9.0, 20.0, rows, top=2).splitlines()
    assert lines[0] == ("suite: 3 tests (1 failed, 1 passed, 1 skipped), 9 CPU s user+sys in all (6 in the tests, "
                        "the rest collection and start-up), 20 s wall")
    tests = [ln for ln in lines if ln.startswith("| `tests/") and "::" in ln]
    assert tests == ["| `tests/a.py::t1` | 3.0 | 6.0 |", "| `tests/b.py::t0` | 2.5 | 5.0 |"]  # the top 2
    assert [ln for ln in lines if ln.startswith("| `tests/") and "::" not in ln] == [
        "| `tests/a.py` | 4.0 | 2 |", "| `tests/b.py` | 2.5 | 1 |"]
    code, _, err = bench("suite_cost", "--top", "0", capsys=capsys)
    assert code == 2 and err == "suite_cost: error: --top must be at least 1, not 0\n"


@pytest.mark.slow  # a pytest in a child process (a few CPU s)
def test_suite_cost_measures_a_pytest_run(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("suite_cost", "--top", "3", "--", "tests/core/test_keys.py", "-q", "-p", "no:cacheprovider",
                           capsys=capsys)
    assert code == 0, err[-2000:]
    assert re.search(r"^suite: \d+ tests \(\d+ passed\), \d+ CPU s user\+sys in all", out, re.M), out
    assert "| `tests/core/test_keys.py` |" in out
