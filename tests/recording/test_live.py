"""``fleet run --live``, checked with clients nobody here wrote: the official Foxglove WebSocket client
(``@foxglove/ws-protocol``) connected to a live run, and the official MCAP reader (``@mcap/core``) over a
recording, each JSON message checked against its schema. Both run under node with the versions pinned in
``tests/js/package-lock.json``, installed once (``npm ci``) into a cache folder outside the repository keyed by
that lock file; without node, npm or the registry these tests are skipped with the reason."""

from __future__ import annotations

import itertools
import json
import queue
import subprocess
import threading
from pathlib import Path
from typing import Any

import msgspec
import pytest
from mcap.writer import Writer

from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.live import LiveOptions
from fleet_emu.launch.memory import run_memory
from fleet_emu.launch.result import deterministic
from fleet_emu.launch.runner import RunOptions, run_fleet
from fleet_emu.recording.foxglove import schema_text
from fleet_emu.recording.stats import SCHEMA_STATS
from tests.harness.cli import result, run_cli


def _node(folder: Path, *args: str, timeout: float = 120) -> dict[str, Any]:
    proc = subprocess.run(["node", *args], cwd=folder, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _watch(js_clients: Path, run: Any) -> tuple[Any, dict[str, Any]]:
    """``run(on_url)`` in a thread (a run with a live server that tells ``on_url`` its URL) watched by the
    official client, which the test lets in before the run's first tick (the run itself never waits for one):
    the run's result and what the client saw."""
    urls: queue.Queue[str] = queue.Queue()
    connected = threading.Event()

    def on_url(url: str) -> None:
        urls.put(url)
        connected.wait(60)

    got: dict[str, Any] = {}
    runner = threading.Thread(target=lambda: got.update(result=run(on_url)))
    runner.start()
    try:
        url = urls.get(timeout=60)
        assert url.startswith("ws://127.0.0.1:") and not url.endswith(":0")  # the port the OS picked
        with subprocess.Popen(["node", "live_client.mjs", url, "90"], cwd=js_clients, stdout=subprocess.PIPE,
                              text=True) as client:
            assert client.stdout is not None
            assert client.stdout.readline().strip() == "connected"
            connected.set()
            out, _ = client.communicate(timeout=120)
        assert client.returncode == 0
    finally:
        connected.set()
        runner.join(120)
    return got["result"], json.loads(out.strip().splitlines()[-1])


def test_the_official_client_sees_every_channel_of_a_live_run(js_clients: Path, small_map: Path) -> None:
    s = Scenario().override(map=str(small_map), robots=4, seed=3, max_ticks=60)
    live, seen = _watch(js_clients, lambda on_url: run_memory(s, record=False, live=LiveOptions(
        "127.0.0.1", 0, hz=8.0, on_url=on_url)))
    plain = run_memory(s, record=False)
    assert deterministic(live.data) == deterministic(plain.data)  # a viewer changed nothing

    assert seen["why"].startswith("closed")  # the run ended: its server closed the connection
    schemas = {c["topic"]: (c["schemaName"], c["encoding"]) for c in seen["channels"]}
    assert schemas["/viz/scene"] == ("foxglove.SceneUpdate", "protobuf")
    assert schemas["/viz/map/truth"] == schemas["/viz/map/coverage"] == ("foxglove.Grid", "protobuf")
    assert schemas["/viz/belief/r0"] == ("foxglove.Grid", "protobuf")
    assert schemas["/viz/log"] == ("foxglove.Log", "protobuf")
    assert schemas["/viz/stats"] == (SCHEMA_STATS, "json")
    topics = seen["topics"]
    ticks = plain.data["ticks"]
    truth = topics["/viz/map/truth"]
    assert truth["count"] == 1 and truth["first"]["column_count"] == 24  # latched: sent on subscribing
    assert truth["first"]["bytes"] == 12 * 24 * truth["first"]["cell_stride"]
    stats = topics["/viz/stats"]
    assert stats["first"]["tick"] < stats["last"]["tick"] == ticks and stats["count"] >= 2  # during the run
    assert stats["last"]["robots"] == ["r0", "r1", "r2", "r3"] and stats["last"]["coverage"] == plain["coverage"]
    assert topics["/viz/map/coverage"]["count"] >= 2 and topics["/viz/scene"]["count"] >= 2
    assert {"robot/r0", "links"} <= set(topics["/viz/scene"]["last"]["entities"])
    assert "run ended" in topics["/viz/log"]["last"]["message"]
    assert stats["last"]["sec"] - truth["first"]["sec"] == ticks  # one second a tick, from the run's start


def test_the_official_mcap_reader_validates_every_json_message(js_clients: Path, small_run: Path,
                                                               tmp_path: Path) -> None:
    res = result(small_run)
    read = _node(js_clients, "read_mcap.mjs", str(small_run / "run.mcap"))
    assert read["invalid"] == []
    topics = read["topics"]
    viz = {t: v for t, v in topics.items() if t.startswith("/viz/")}
    assert {v["schema"] for v in viz.values()} == {"foxglove.Grid (jsonschema)", "foxglove.SceneUpdate (jsonschema)",
                                                   "foxglove.Log (jsonschema)", f"{SCHEMA_STATS} (jsonschema)"}
    assert viz["/viz/stats"]["count"] == viz["/viz/scene"]["count"] == res["ticks"] + 1
    assert viz["/viz/map/truth"]["count"] == 1  # written once
    start, tick_ns = int(read["metadata"]["start_ns"]), round(float(read["metadata"]["tick_s"]) * 1e9)
    assert viz["/viz/stats"]["first"] == start and viz["/viz/stats"]["last"] == start + res["ticks"] * tick_ns
    assert start > 1_600_000_000 * 10**9  # the run's real start, not 1970

    bad = tmp_path / "bad.mcap"  # the reader's check bites: a stats message its schema refuses
    with bad.open("wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema(SCHEMA_STATS, "jsonschema", schema_text(SCHEMA_STATS))
        ch = w.register_channel("/viz/stats", "json", sid)
        w.add_message(ch, 1, json.dumps({"tick": -1}).encode(), 1)
        w.add_metadata("scenario", {"start_ns": "0"})
        w.finish()
    assert [i["topic"] for i in _node(js_clients, "read_mcap.mjs", str(bad))["invalid"]] == ["/viz/stats"]


def test_a_processes_run_serves_what_its_launcher_folds(js_clients: Path, small_run: Path, tmp_path: Path) -> None:
    """The suite's plain processes run again, live and paced (the world's ``--pace``), not recording: the launcher
    serves what it folds from the bus, up to the last tick, and the result is the run's without a viewer."""
    scenario = Scenario.from_json(small_run / "scenario.json")
    res, seen = _watch(js_clients, lambda on_url: run_fleet(scenario, RunOptions(
        out_dir=tmp_path / "live", record=False, live=LiveOptions("127.0.0.1", 0, hz=50.0, on_url=on_url))))
    assert deterministic(res.data) == deterministic(result(small_run))
    topics, ticks = seen["topics"], res["ticks"]
    assert topics["/viz/stats"]["last"]["tick"] == ticks  # the last tick's, flushed before the server closed
    assert topics["/viz/map/truth"]["count"] == 1 and topics["/viz/belief/r2"]["count"] >= 1
    assert "run ended" in topics["/viz/log"]["last"]["message"]


@pytest.mark.parametrize(("argv", "says"), [
    (["--live", "nope"], "--live wants [HOST:]PORT"),
    (["--live", "127.0.0.1:70000"], "--live wants [HOST:]PORT"),
    (["--live-hz", "5"], "--live-hz needs --live"),
    (["--live", "0", "--live-hz", "5", "--in-process", "--realtime", "5"], "--live-hz paces a lockstep run"),
])
def test_bad_live_flags_are_one_line(argv: list[str], says: str) -> None:
    code, _, err = run_cli(["run", "--robots", "2", *argv])
    assert code == 2 and says in err and len(err.strip().splitlines()) == 1


def test_a_taken_port_is_one_line(tmp_path: Path) -> None:
    with socket_bound() as port:
        code, _, err = run_cli(["run", "--engine", "memory", "--robots", "2", "--max-ticks", "3", "--live",
                                str(port), "--out", str(tmp_path / "r")])
    assert code == 2 and f"--live 127.0.0.1:{port}: cannot serve there" in err, err


class socket_bound:
    """A loopback port held open for the block."""

    def __enter__(self) -> int:
        import socket

        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen()
        return int(self.sock.getsockname()[1])

    def __exit__(self, *_: object) -> None:
        self.sock.close()


def _panels(node: dict[str, Any]) -> list[dict[str, Any]]:
    if node.get("type") == "panel":
        return [node]
    return [p for item in node.get("items", []) for p in _panels(item["content"])]


def test_fleet_report_writes_the_layout(tmp_path: Path) -> None:
    code, out, _ = run_cli(["report", "--layout", str(tmp_path / "fleet.json"), "--robots", "3"])
    assert code == 0 and out.strip() == str(tmp_path / "fleet.json")
    layout = json.loads((tmp_path / "fleet.json").read_text())
    panels = {p["title"]: p for p in _panels(layout["content"])}
    assert {p["panelType"] for p in panels.values()} == {"ThreeDee", "Plot", "Log"}
    topics = panels["fleet"]["config"]["topics"]
    assert {"/viz/scene", "/viz/map/truth", "/viz/map/coverage", "/viz/belief/r2"} <= set(topics)
    assert topics["/viz/map/coverage"]["colorMode"] == "rgba-fields"  # the grids' RGBA fields
    paths = {s["value"] for p in panels.values() if p["panelType"] == "Plot" for s in p["config"]["paths"]}
    assert {"/viz/stats.coverage", "/viz/stats.connected_fraction", "/viz/stats.robots.r2.decision_ms"} <= paths
    assert "/viz/stats.base_connected_fraction" not in paths  # null without a base station: not plotted
    assert panels["log"]["config"]["topicToRender"] == "/viz/log"
    code, _, err = run_cli(["report", "--layout", str(tmp_path / "x.json"), "--robots", "0"])
    assert code == 2 and "--robots must be from 1 to 1024" in err


@pytest.mark.slow  # a second live run; Foxglove once by default
def test_the_layout_plots_the_base_connected_fraction_only_for_a_run_with_a_base(tmp_path: Path) -> None:
    import fleet_emu as fe

    def plotted(argv: list[str]) -> set[str]:
        code, _, err = run_cli(["report", "--layout", str(tmp_path / "l.json"), *argv])
        assert code == 0, err
        layout = json.loads((tmp_path / "l.json").read_text())
        plots = [p for p in _panels(layout["content"]) if p["panelType"] == "Plot"]
        return {s["value"] for p in plots for s in p["config"]["paths"]}

    small = fe.Scenario().override(map="office", robots=2, seed=1, max_ticks=5)
    fe.run(small, engine="memory", out=tmp_path / "plain")
    fe.run(small.override(base=True), engine="memory", out=tmp_path / "based")
    key = "/viz/stats.base_connected_fraction"
    assert key not in plotted([str(tmp_path / "plain")]) and key in plotted([str(tmp_path / "based")])
    assert key in plotted(["--base"])  # a live run with a base: said by hand


def test_every_fold_message_becomes_the_sdks_typed_message() -> None:
    """Without a client: each of the fold's messages (grids, scene with a base, logs, stats) is logged through
    the SDK's typed channels with no error, and ``[HOST:]PORT`` parses as documented."""
    import numpy as np

    from fleet_emu.core.grid import from_ascii
    from fleet_emu.core.messages import BeliefSnapshot, Stop
    from fleet_emu.recording.clock import RunClock
    from fleet_emu.recording.foxglove import FoxgloveFold
    from fleet_emu.recording.live import LiveServer, parse_live
    from tests.harness.foxglove import ART, cmd, links, obs, scenario, state

    truth, _ = from_ascii(ART)
    fold = FoxgloveFold(scenario(), truth, grid_every=1, run_id="t", base_cell=(3, 1))
    poses = {"r0": (1, 1), "r1": (3, 5)}
    lk = links(0, ("r0", "r1"), True)
    lk = msgspec.structs.replace(lk, **{"base_link": np.array([True, False]), "base_strength": np.array([8.0, -3.0])})
    out = fold.fold(obs("r0", 0, (1, 1), [8, 9], truth)) + fold.fold(state(0, poses, ("r0", "r1"), 0.3))
    out += fold.fold(lk) + fold.fold(cmd("r0", 0, (1, 5)))
    out += fold.fold(BeliefSnapshot(src="r0", tick=0, seq=0, grid=truth.copy()))
    out += fold.fold(state(1, poses, ("r0",), 0.6)) + fold.fold(Stop(src="world", tick=1, seq=0, reason="coverage"))
    out += fold.finish()
    server = LiveServer("127.0.0.1", 0, RunClock.now())
    try:
        server.publish(out)
        assert not server.failed and server.published == len(out)
        assert {d.schema for d in out} == {"foxglove.Grid", "foxglove.SceneUpdate", "foxglove.Log", SCHEMA_STATS}
    finally:
        server.close()
    assert parse_live("9000") == ("127.0.0.1", 9000) and parse_live("0.0.0.0:0") == ("0.0.0.0", 0)
    assert parse_live("[::1]:8765") == ("::1", 8765)


def test_the_recording_clock_counts_the_scenarios_tick_s(small_map: Path, tmp_path: Path) -> None:
    """A tick is logged ``tick_s`` seconds after the one before it, from the run's real start."""
    from mcap.reader import make_reader

    scenario = Scenario().override(map=str(small_map), robots=2, max_ticks=6, tick_s=0.25)
    res = run_memory(scenario, tmp_path / "run")
    with (tmp_path / "run" / "run.mcap").open("rb") as f:
        reader = make_reader(f)
        meta = next(m.metadata for m in reader.iter_metadata() if m.name == "scenario")
        times = [m.log_time for _, _, m in reader.iter_messages(topics=["/viz/stats"])]
    assert float(meta["tick_s"]) == 0.25 and res.data["scenario"]["tick_s"] == 0.25
    assert len(times) == res.data["ticks"] + 1 and {b - a for a, b in itertools.pairwise(times)} == {250_000_000}
    assert times[0] == int(meta["start_ns"])
