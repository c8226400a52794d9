"""Which viewers can connect: the live server (foxglove-sdk's) speaks the Foxglove WebSocket protocol under the
``foxglove.sdk.v1`` subprotocol only; a client asking for the older ``foxglove.websocket.v1`` alone is refused
(HTTP 400), as docs/guides/watching.md says. Checked with the official ``@foxglove/ws-protocol`` client."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from fleet_emu.recording.clock import RunClock
from fleet_emu.recording.foxglove import live_topics
from fleet_emu.recording.live import LiveServer


@pytest.mark.parametrize("subprotocol, expect", [
    ("foxglove.sdk.v1", {"protocol": "foxglove.sdk.v1", "server": "fleet-emu"}),
    ("foxglove.websocket.v1", {"status": 400}),
])
def test_the_subprotocol_a_viewer_must_ask_for(js_clients: Path, subprotocol: str,
                                               expect: dict[str, object]) -> None:
    server = LiveServer("127.0.0.1", 0, RunClock.now(1.0), topics=live_topics(["r0"]))
    try:
        proc = subprocess.run(["node", "handshake.mjs", server.url, subprotocol], cwd=js_clients,
                              capture_output=True, text=True, timeout=60)
    finally:
        server.close()
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == expect
