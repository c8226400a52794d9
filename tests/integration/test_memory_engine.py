"""The memory engine gives the multi-process fleet's result (docs/design/architecture.md, "Engines": every engine gives
the same result for a seed): the deterministic keys of ``result.json`` are equal. Over processes once per transport
concern (here the radio at its hardest: a protocol allocator, whose auction crosses the bus each round, at loss, on a
bandwidth-limited shared medium with queues and jitter, on a short disk radio that robots flood-relay over; a plain
fleet at loss in ``test_fleet_run.py``, a base in ``test_base.py``, a planning base relaying over its tree in
``test_engine_messages.py``), and for every allocator across interpreters, as a robot's own process would show:
another hash seed (state that one fleet leaves behind for the next is ``seed_test``'s, in
``tests/launch/test_memory.py``)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

import fleet_emu as fe
from fleet_emu.agents.allocators import allocator_names
from fleet_emu.core.scenario import BASE_PLANNERS
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import deterministic
from tests.harness.cli import ROOT, result, run_cli


def _scenario(small_map: Path, allocator: str, loss: float) -> fe.Scenario:
    base = {"base": True} if allocator in BASE_PLANNERS else {}  # mhm: the base plans and sends its orders
    return fe.Scenario().override(map=str(small_map), robots=3, allocator=allocator, loss=loss, seed=5,
                                  max_ticks=150, **base)


@pytest.mark.slow  # engines agree once by default
def test_memory_equals_processes_for_a_protocol_allocator_on_a_shared_relayed_radio(small_map: Path,
                                                                                    tmp_path: Path) -> None:
    s = fe.Scenario().override(map=str(small_map), robots=3, allocator="trade", loss=0.2, seed=4, max_ticks=120,
                               bandwidth=4.0, jitter=1,  # 500 bytes a tick: queues, airtime and jitter all matter
                               comm="disk", comm_range=2.0, relay="flood", relay_ttl=2)
    over_zenoh = fe.run(s, tmp_path / "p")  # world, netem and one process per robot, over a Zenoh router
    in_memory = Fleet(s).run()
    assert over_zenoh["engine"] == "processes" and in_memory["engine"] == "memory"
    assert set(over_zenoh) == set(in_memory) | {"bus"}  # the memory engine has no bus, no nonce to drop by
    assert over_zenoh["bus"]["foreign_dropped"] == 0
    assert deterministic(in_memory.data) == deterministic(over_zenoh.data)
    assert in_memory.curve == over_zenoh.curve
    radio = over_zenoh["radio"]
    assert radio["sent"] > 0 and radio["dropped_loss"] > 0
    assert radio["queued_max_bytes"] > 0 and radio["delay_ticks"]["max"] > 2  # the medium queued and delayed
    relay = over_zenoh["relay"]
    assert relay["policy"] == "flood" and relay["ttl"] == 2
    pose = relay["kinds"]["pose"]
    assert pose["delivered"] > 0 and 0 < pose["delivery_ratio"] <= 1
    assert pose["hops"].get("2", 0) > 0  # some beacons crossed a relay
    assert pose["transmissions"] > pose["sent"]  # the forwarded copies were transmitted
    code, out, err = run_cli(["report", str(tmp_path / "p"), "--no-plots"])  # recomputed from the recording
    assert code == 0 and "matches result.json" in out + err and "relay flood ttl 2" in out + err


# Runs every allocator's fleets of this module in a fresh interpreter, and prints their deterministic keys.
_ELSEWHERE = """
import json, sys
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import deterministic
runs = {k: deterministic(Fleet(Scenario.from_dict(s)).run().data) for k, s in json.loads(sys.argv[1]).items()}
print(json.dumps(runs))
"""


@pytest.mark.slow  # every allocator twice more; engines agree once by default
def test_every_allocator_gives_the_same_result_in_another_interpreter(small_map: Path) -> None:
    """What a processes run would show if an allocator's result hung on its interpreter: an order of dicts or
    sets that changes with the hash seed (``PYTHONHASHSEED``), at loss 0 and 0.3."""
    scenarios = {f"{a}@{loss}": _scenario(small_map, a, loss) for a in allocator_names() for loss in (0.0, 0.3)}
    here = {k: json.loads(json.dumps(deterministic(Fleet(s).run().data))) for k, s in scenarios.items()}
    other = "1" if os.environ.get("PYTHONHASHSEED") != "1" else "2"
    proc = subprocess.run([sys.executable, "-c", _ELSEWHERE, json.dumps({k: s.to_dict() for k, s in
                                                                          scenarios.items()})],
                          capture_output=True, text=True, timeout=240, cwd=ROOT,
                          env={**os.environ, "PYTHONHASHSEED": other})
    assert proc.returncode == 0, proc.stderr[-3000:]
    elsewhere = json.loads(proc.stdout)
    assert set(elsewhere) == set(here) and all(r["ticks"] > 0 for r in here.values())
    for key in here:
        assert elsewhere[key] == here[key], key


def test_fleet_run_engine_memory_writes_what_a_run_writes(small_run: Path, tmp_path: Path) -> None:
    """``fleet run --engine memory``: the same files and deterministic keys as the default engine (the suite's
    plain run over processes, from its ``scenario.json``), and a recording that ``fleet report`` reads back to
    the same result."""
    common = ["run", str(small_run / "scenario.json"), "--quiet"]
    code, _, err = run_cli([*common, "--engine", "memory", "--out", str(tmp_path / "m")])
    assert code == 0, err
    mem, proc = result(tmp_path / "m"), result(small_run)
    assert deterministic(mem) == deterministic(proc) and mem["engine"] == "memory" and proc["engine"] == "processes"
    assert {p.name for p in (tmp_path / "m").iterdir()} >= {"result.json", "scenario.json", "map.npz", "run.mcap"}
    code, out, err = run_cli(["report", str(tmp_path / "m"), "--no-plots"])
    assert code == 0 and "matches result.json" in out + err
    for flag in ("--in-process", "--fork-server", "--no-fork-server"):
        code, _, err = run_cli([*common, "--engine", "memory", flag, "--out", str(tmp_path / "x")])
        assert code == 2 and err.count("\n") == 1 and not (tmp_path / "x").exists()
        assert f"takes no {flag if 'fork' not in flag else '--[no-]fork-server'}" in err
