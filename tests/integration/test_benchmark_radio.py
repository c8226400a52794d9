"""``benchmarks/radio.py``: bytes per robot-tick by kind, per allocator, on the memory engine."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.harness.bench import bench, fields


def test_radio_splits_each_allocators_bytes_by_kind(small_map: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("radio", "--map", str(small_map), "--robots", "2", "--seeds", "1", "--max-ticks", "40",
                           "--allocators", "nearest", "hungarian", "--bandwidth", "4", capsys=capsys)
    assert code == 0, err[-2000:]
    lines = [ln for ln in out.splitlines() if not ln.startswith("#")]
    header, rows = lines[0], lines[1:]
    labels = ["allocator", "ticks", "map", "beacons", "protocol", "total", "compact", "delay", "max", "qdrop"]
    got = {r["allocator"]: r for r in (fields(header, ln, labels) for ln in rows)}
    assert set(got) == {"nearest", "hungarian"}
    for r in got.values():
        assert float(r["map"]) > 0 and float(r["beacons"]) > 0
        assert float(r["total"]) == pytest.approx(float(r["map"]) + float(r["beacons"]) + float(r["protocol"]), abs=2)
        assert 0 < float(r["compact"].rstrip("%")) < 100  # the limited radio sends map data compact, smaller
    assert float(got["nearest"]["protocol"]) == 0 < float(got["hungarian"]["protocol"])  # assignments


def test_radio_bad_allocator_is_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = bench("radio", "--allocators", "nope", capsys=capsys)
    assert code == 2 and err.strip().startswith("radio: error: unknown allocator(s) nope")


def test_radio_cost_times_the_limited_radio_s_own_code(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("radio_cost", "--seeds", "1", "--max-ticks", "12", "--bandwidths", "16", capsys=capsys)
    assert code == 0, err[-2000:]
    lines = [ln for ln in out.splitlines() if not ln.startswith("#")]
    labels = ["kbit/s", "ticks", "calls", "radio s", "rest s", "share"]
    r = fields(lines[0], lines[1], labels)
    assert r["kbit/s"] == "16" and int(r["ticks"]) == 24 and int(r["calls"]) > 48  # enqueue and serve each tick
    assert 0 < float(r["radio s"]) < float(r["rest s"])
    code, _, err = bench("radio_cost", "--bandwidths", "0", capsys=capsys)
    assert code == 2 and err.strip().startswith("radio_cost: error:")


def test_radio_cost_times_the_shadowing_s_own_code(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = bench("radio_cost", "--shadowing", "--robots", "3", "--seeds", "1", "--max-ticks", "15",
                           capsys=capsys)
    assert code == 0, err[-2000:]
    lines = [ln for ln in out.splitlines() if not ln.startswith("#")]
    labels = ["shadowing", "robot-ticks", "delivered", "ms/robot-tick", "vs off", "calls", "shadow s", "rest s",
              "share"]
    off, only, on = (fields(lines[0], ln, labels) for ln in lines[1:4])
    assert [ln[:9].strip() for ln in lines[1:4]] == ["off", "code only", "8 dB"]
    assert off["calls"] == "1" and float(off["shadow s"]) < 0.01  # off draws no field: one call that returns
    assert int(only["calls"]) == int(on["calls"]) > 16  # the field once, then the terms and the count each tick
    assert (only["robot-ticks"], only["delivered"]) == (off["robot-ticks"], off["delivered"])  # the run of off
    assert 0 < float(only["shadow s"]) < float(only["rest s"])
    code, _, err = bench("radio_cost", "--shadowing", "--shadowing-db", "0", capsys=capsys)
    assert code == 2 and err.strip().startswith("radio_cost: error:")
