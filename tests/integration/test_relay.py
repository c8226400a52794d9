"""Relaying over real processes and Zenoh: a flooding fleet on a short disk radio relays
messages over more than one hop, ``result.json`` carries the relay block, ``fleet report`` recomputes it from
the recording, and the memory engine gives the same result for the seed."""

from __future__ import annotations

from pathlib import Path

import fleet_emu as fe
from fleet_emu.launch.memory import Fleet
from fleet_emu.launch.result import deterministic
from tests.conftest import result, run_cli


def test_flood_relays_over_zenoh_and_the_memory_engine_agrees(tmp_path: Path, small_map: Path) -> None:
    run_cli(["run", "--map", str(small_map), "--robots", "3", "--allocator", "nearest", "--seed", "5",
             "--max-ticks", "150", "--comm", "disk", "--comm-range", "2", "--relay", "flood", "--relay-ttl", "2",
             "--quiet", "--out", str(tmp_path / "p")], check=True)
    proc = result(tmp_path / "p")
    assert proc["engine"] == "processes"
    relay = proc["relay"]
    assert relay["policy"] == "flood" and relay["ttl"] == 2
    pose = relay["kinds"]["pose"]
    assert pose["delivered"] > 0 and 0 < pose["delivery_ratio"] <= 1
    assert pose["hops"].get("2", 0) > 0  # some beacons crossed a relay
    assert pose["transmissions"] > pose["sent"]  # the forwarded copies were transmitted
    mem = Fleet(fe.Scenario.load(tmp_path / "p" / "scenario.json")).run()
    assert deterministic(mem.data) == deterministic(proc)
    code, out, err = run_cli(["report", str(tmp_path / "p"), "--no-plots"])
    assert code == 0 and "matches result.json" in out + err and "relay flood ttl 2" in out + err
