"""End to end: real Zenoh router, real world/netem/agent processes, real recording."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader

from fleet_emu.core.messages import decode
from fleet_emu.launch.result import deterministic
from tests.harness.cli import result, run_cli
from tests.harness.procs import all_pids, pid_alive

KEYS = ("run_id", "seed", "map", "allocator", "robots", "loss", "ticks", "completed", "coverage", "t90", "t99",
        "path_length", "connected_fraction", "radio", "decision_ms", "pids", "recording")


@pytest.mark.slow  # a plain fleet: the suite's small_run by default
def test_three_robot_processes_explore_a_small_map(small_run: Path) -> None:
    res = result(small_run)
    assert set(KEYS) <= set(res)
    assert res["completed"] is True and res["coverage"] >= 0.99
    assert res["t99"] is not None and res["t90"] <= res["t99"] <= res["ticks"]
    assert len(res["path_length"]) == 3 and all(p > 0 for p in res["path_length"])
    # world, netem, three agents, the fork server they were forked from and the router, each its own process
    assert len(set(all_pids(res))) == 7 and "fork_server" in res["pids"] and "router" in res["pids"]
    assert not any(pid_alive(p) for p in all_pids(res)), "a child outlived the run"
    radio = res["radio"]
    assert radio["sent"] == radio["delivered"] + radio["dropped_loss"] + radio["dropped_signal"] > 0
    assert radio["dropped_loss"] > 0 and radio["bytes_sent"] > 0  # the default 10 % loss is applied
    with open(small_run / "run.mcap", "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        count = sum(summary.statistics.channel_message_counts.values())
        topics = {c.topic for c in summary.channels.values()}
        encodings = {c.topic: c.message_encoding for c in summary.channels.values()}
        assert {e for t, e in encodings.items() if t.startswith("fleet/")} == {"msgpack"}  # the bus, as sent
        assert {e for t, e in encodings.items() if t.startswith("/viz/")} == {"json"}  # the Foxglove views
        meta = list(reader.iter_metadata())
    assert count == res["recording"]["messages"]
    run = res["run_id"]
    for key in ("world/state", "netem/links", "world/obs/r2", "robot/r0/cmd", "radio/tx/r1", "radio/rx/r2"):
        assert f"fleet/{run}/{key}" in topics
    assert meta and meta[0].name == "scenario" and '"robots": 3' in meta[0].metadata["scenario"]


def _tick_messages(path: Path) -> dict[str, list[bytes]]:
    """Per channel, the payloads of the lockstep traffic (the ready handshake's retries are timing)."""
    out: dict[str, list[bytes]] = {}
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            if "/ctl/" in channel.topic or channel.message_encoding != "msgpack":
                continue
            msg = decode(message.data)
            obj = msg.to_obj()
            obj.pop("decision_ms", None)  # wall-clock timing
            topic = channel.topic.split("/", 2)[2]
            out.setdefault(topic, []).append(repr(obj).encode())
    return out


@pytest.mark.slow  # 3 fleets; engines agree by default (test_engine_messages)
def test_same_seed_same_run_and_in_process_agrees(small_run: Path, tmp_path: Path) -> None:
    """The suite's plain run over processes (``a``, seed 0 at 10 % loss), run again from the ``scenario.json``
    it wrote (``b``: the file alone reproduces it), in one process (``c``) and on the memory engine (``d``):
    the same deterministic keys, and every message of every tick the same; another seed, another run."""
    a, b, c, d = small_run, tmp_path / "b", tmp_path / "c", tmp_path / "d"
    scenario = str(a / "scenario.json")
    run_cli(["run", scenario, "--quiet", "--out", str(b)], check=True)  # the file alone: as --scenario
    run_cli(["run", "--scenario", scenario, "--quiet", "--out", str(c), "--in-process"], check=True)
    code, _, err = run_cli(["run", scenario, "--quiet", "--out", str(d), "--engine", "memory"])
    assert code == 0, err
    ra, rb, rc, rd = result(a), result(b), result(c), result(d)
    assert (ra["engine"], rb["engine"], rc["engine"], rd["engine"]) == ("processes", "processes", "in-process",
                                                                        "memory")
    assert ra["radio"]["dropped_loss"] > 0
    assert deterministic(ra) == deterministic(rb) == deterministic(rc) == deterministic(rd)
    ma, mb, mc, md = (_tick_messages(p / "run.mcap") for p in (a, b, c, d))
    assert ma.keys() == mb.keys() == mc.keys() == md.keys()
    for topic in ma:  # every message of every tick, the memory engine's too
        assert ma[topic] == mb[topic] == mc[topic] == md[topic], f"{topic} differs between runs"
    code, _, err = run_cli(["run", scenario, "--seed", "5", "--quiet", "--out", str(tmp_path / "other"),
                            "--engine", "memory", "--no-record"])
    assert code in (0, 3), err
    assert deterministic(result(tmp_path / "other")) != deterministic(ra)  # the seed matters
