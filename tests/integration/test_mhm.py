"""MHM end to end: ``fleet run --allocator mhm --base`` with 6 robots. The base plans and broadcasts its orders on
``radio/tx/base``; robots relay them over the tree and obey. Without loss every robot keeps a path of links to the
base on every tick, and the fleet reaches its target coverage. (Disk radio of 3 m on the two-room map: r_comm = 6
cells.) The run is the memory engine's, which runs the same world, channel, robots and base: over Zenoh, an MHM
run with its base in its own process publishes the memory engine's messages field by field
(``test_engine_messages.py``)."""

from __future__ import annotations

from pathlib import Path

from tests.harness.cli import result, run_cli


def test_mhm_keeps_every_robot_connected_to_the_base_and_completes(small_map: Path, tmp_path: Path) -> None:
    out = tmp_path / "mhm"
    run_cli(["run", "--map", str(small_map), "--robots", "6", "--allocator", "mhm", "--base", "--comm", "disk",
             "--comm-range", "3", "--sensor-range", "1.5", "--loss", "0", "--seed", "0", "--max-ticks", "300",
             "--engine", "memory", "--no-record", "--quiet", "--out", str(out)], check=True)
    res = result(out)
    assert res["failed"] == [] and res["malformed_dropped"] == 0
    assert res["completed"] is True and res["coverage"] >= 0.99, res["reason"]
    frac = res["base_connected_fraction"]
    assert frac["all_ticks"] == 1.0 and frac["overall"] == 1.0  # the constraint held on every tick
    assert res["scenario"]["relay"] == "tree" and res["scenario"]["relay_ttl"] == 16  # mhm's defaults
    orders = res["relay"]["kinds"]["mhm"]
    assert orders["sent"] >= res["ticks"] - 5 and orders["delivered"] > 0  # the base planned and was heard
    assert orders["hops"].get("2", 0) > 0  # and robots relayed its orders


def test_mhm_without_a_base_is_refused_in_one_line(small_map: Path, tmp_path: Path) -> None:
    code, _, err = run_cli(["run", "--map", str(small_map), "--allocator", "mhm", "--out", str(tmp_path / "x")])
    assert code == 2 and err.count("\n") == 1 and "needs --base" in err
    assert not (tmp_path / "x").exists()
