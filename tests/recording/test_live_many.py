"""Twenty official Foxglove clients (``@foxglove/ws-protocol``) started at the moment the ``live:`` URL is told
each get every channel of the run, and every tick from tick 0: the server advertises every channel from its
start, and the run's first tick comes a moment after the URL (the run holds here only until the clients have
connected, so that each connected before tick 0)."""

from __future__ import annotations

import json
import queue
import subprocess
import threading
from pathlib import Path
from typing import Any

import pytest

from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.live import LiveOptions
from fleet_emu.launch.memory import run_memory
from fleet_emu.recording.foxglove import live_topics

CLIENTS = 20


def _watch_many(js_clients: Path, scenario: Scenario) -> tuple[Any, list[dict[str, Any]]]:
    urls: queue.Queue[str] = queue.Queue()
    connected = threading.Event()

    def on_url(url: str) -> None:
        urls.put(url)
        connected.wait(120)  # every client connected before tick 0 (the server does not wait for them)

    got: dict[str, Any] = {}
    runner = threading.Thread(target=lambda: got.update(result=run_memory(scenario, record=False, live=LiveOptions(
        "127.0.0.1", 0, hz=20.0, on_url=on_url))))
    runner.start()
    clients: list[subprocess.Popen[str]] = []
    try:
        url = urls.get(timeout=60)
        clients = [subprocess.Popen(["node", "live_client.mjs", url, "120"], cwd=js_clients, stdout=subprocess.PIPE,
                                    text=True) for _ in range(CLIENTS)]
        for c in clients:
            assert c.stdout is not None and c.stdout.readline().strip() == "connected"
        connected.set()
        outs = [c.communicate(timeout=150)[0] for c in clients]
    finally:
        connected.set()
        for c in clients:
            if c.poll() is None:
                c.kill()
        runner.join(150)
    assert all(c.returncode == 0 for c in clients)
    return got["result"], [json.loads(o.strip().splitlines()[-1]) for o in outs]


@pytest.mark.slow
def test_twenty_clients_at_the_live_line_get_every_channel_from_tick_0(
        js_clients: Path, small_map: Path) -> None:
    s = Scenario().override(map=str(small_map), robots=3, seed=1, max_ticks=30)
    result, seen = _watch_many(js_clients, s)
    topics = {t for t, _ in live_topics(["r0", "r1", "r2"])}
    ticks = result["ticks"]
    for i, view in enumerate(seen):
        assert {c["topic"] for c in view["channels"]} == topics, f"client {i}"
        dead = sorted(t for t in topics if view["topics"].get(t, {}).get("count", 0) == 0)
        assert not dead, f"client {i} got nothing on {dead}"
        stats = view["topics"]["/viz/stats"]
        assert stats["first"]["tick"] == 0 and stats["last"]["tick"] == ticks, f"client {i}"
        assert stats["count"] == ticks + 1, f"client {i}: {stats['count']} stats for ticks 0..{ticks}"
