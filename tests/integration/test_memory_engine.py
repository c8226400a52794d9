"""The memory engine gives the multi-process fleet's result: for every allocator, at loss 0 and 0.3, the
deterministic keys of ``result.json`` are equal (DESIGN.md "Engines": all engines agree for a seed)."""

from __future__ import annotations

from pathlib import Path

import pytest

import fleet_emu as fe
from fleet_emu.agents.allocators import allocator_names
from fleet_emu.core.scenario import BASE_PLANNERS
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import deterministic

from .conftest import fleet, result


@pytest.mark.parametrize("loss", [0.0, 0.3])
@pytest.mark.parametrize("allocator", allocator_names())
def test_memory_equals_processes(allocator: str, loss: float, small_map: Path) -> None:
    base = {"base": True} if allocator in BASE_PLANNERS else {}  # mhm: the base plans and sends its orders
    s = fe.Scenario().override(map=str(small_map), robots=3, allocator=allocator, loss=loss, seed=5, max_ticks=150,
                               **base)
    over_zenoh = fe.run(s)  # world, netem and one process per robot, over a Zenoh router
    in_memory = Fleet(s).run()
    assert over_zenoh["engine"] == "processes" and in_memory["engine"] == "memory"
    assert set(over_zenoh) == set(in_memory)
    assert deterministic(in_memory.data) == deterministic(over_zenoh.data)
    assert in_memory.curve == over_zenoh.curve
    assert over_zenoh["radio"]["sent"] > 0 and (over_zenoh["radio"]["dropped_loss"] > 0) == (loss > 0)


def test_fleet_run_engine_memory_writes_what_a_run_writes(tmp_path: Path, small_map: Path) -> None:
    """``fleet run --engine memory``: the same files and deterministic keys as the default engine, and a
    recording that ``fleet report`` reads back to the same result."""
    common = ["run", "--map", str(small_map), "--robots", "2", "--allocator", "minpos", "--loss", "0.2", "--seed",
              "1", "--quiet"]
    fleet(*common, "--engine", "memory", "--out", str(tmp_path / "m"))
    fleet(*common, "--no-record", "--out", str(tmp_path / "p"))
    mem, proc = result(tmp_path / "m"), result(tmp_path / "p")
    assert deterministic(mem) == deterministic(proc) and mem["engine"] == "memory"
    assert {p.name for p in (tmp_path / "m").iterdir()} >= {"result.json", "scenario.json", "map.npz", "run.mcap"}
    report = fleet("report", str(tmp_path / "m"), "--no-plots")
    assert "matches result.json" in report.stdout + report.stderr
    for flag in ("--in-process", "--fork-server", "--no-fork-server"):
        bad = fleet(*common, "--engine", "memory", flag, "--out", str(tmp_path / "x"), check=False)
        assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and not (tmp_path / "x").exists()
        assert f"takes no {flag if 'fork' not in flag else '--[no-]fork-server'}" in bad.stderr
