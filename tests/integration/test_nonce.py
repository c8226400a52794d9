"""A run is bound to its own traffic: every message carries the run's nonce, and a replayed recording (on an open
router, with its keys rewritten to the live run's id) changes nothing but the counts of what was dropped."""

from __future__ import annotations

import subprocess
import threading
from pathlib import Path

import pytest
import zenoh
from mcap.records import Channel
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader

from fleet_emu.core.bus import client_config, router_config, router_locators
from fleet_emu.launch.result import deterministic
from fleet_emu.launch.router_config import router_config_text
from tests.harness.cli import fleet, result, run_cli

RUN = "replayed"


def _recorded(mcap: Path, run: str) -> list[tuple[str, bytes]]:
    """Every bus message of a recording, in order, its key moved to run ``run``."""
    topics: dict[int, str] = {}
    out = []
    with mcap.open("rb") as f:
        for rec in StreamReader(f).records:
            if isinstance(rec, Channel):
                topics[rec.id] = rec.topic
            elif isinstance(rec, McapMessage) and topics[rec.channel_id].startswith("fleet/"):
                parts = topics[rec.channel_id].split("/")
                out.append(("/".join(["fleet", run, *parts[2:]]), rec.data))
    return out


def _replay(endpoint: str, messages: list[tuple[str, bytes]], until: threading.Event, sent: list[int]) -> None:
    """Once the live run's first state is on the bus, put the recording again and again (every other message
    with another run's nonce attached, the rest with none) until ``until``."""
    started = threading.Event()
    with zenoh.open(client_config(endpoint)) as s:
        watch = s.declare_subscriber(f"fleet/{RUN}/world/state", lambda _: started.set())
        started.wait(300)
        while not until.is_set():
            for i, (key, data) in enumerate(messages):
                s.put(key, data, attachment=b"\x00" * 8 if i % 2 else None)
                sent[0] += 1
                if until.is_set():
                    break
        watch.undeclare()


def test_a_replayed_recording_changes_nothing_and_its_drops_are_counted(small_run: Path, tmp_path: Path) -> None:
    """The suite's recorded run replayed into the same scenario running live on an open router: the live run's
    seeded result is the recorded one's, and every receiver counted the replayed messages it dropped."""
    messages = _recorded(small_run / "run.mcap", RUN)
    assert any(k.endswith("/ctl/stop") for k, _ in messages)  # a replayed stop would have ended the run
    out = tmp_path / "live"
    until, sent = threading.Event(), [0]
    with zenoh.open(router_config()) as router:
        endpoint = router_locators(router)[0]
        attacker = threading.Thread(target=_replay, args=(endpoint, messages, until, sent), daemon=True)
        attacker.start()
        try:
            _, _, err = run_cli(["run", str(small_run / "scenario.json"), "--quiet", "--in-process", "--no-record",
                                 "--connect", endpoint, "--run-id", RUN, "--out", str(out)], check=True)
        finally:
            until.set()
            attacker.join(30)
    live, recorded = result(out), result(small_run)
    assert sent[0] > len(messages) // 2
    assert deterministic(live) == deterministic(recorded), err[-2000:]
    by = live["bus"]["foreign_dropped_by"]
    assert all(by[n] > 0 for n in ("launcher", "world", "netem", "r0", "r1", "r2")), by
    assert live["bus"]["foreign_dropped"] == sum(by.values()) and live["bus"]["nonce"] != recorded["bus"]["nonce"]


@pytest.mark.slow  # two live fleets; attacks once by default
def test_a_second_run_with_a_live_run_id_is_refused_and_the_first_goes_on(small_map: Path, tmp_path: Path) -> None:
    """Two runs with one --run-id on one authenticated router (``fleet router-config``'s users file): the second,
    started while the first is live, is refused in one line with exit 2 and leaves no folder; the first ends as
    its seed decides (the memory engine's result)."""
    users = tmp_path / "users.txt"
    scenario = ["--map", str(small_map), "--robots", "3", "--seed", "5", "--quiet", "--no-record"]
    code, _, err = run_cli(["run", *scenario, "--engine", "memory", "--out", str(tmp_path / "memory")])
    assert code in (0, 3), err
    first: dict[str, subprocess.CompletedProcess[str]] = {}
    started = threading.Event()
    with _open_router(router_config_text(3, users, listen="tcp/127.0.0.1:0")) as router:
        endpoint = router_locators(router)[0]
        login = ["--connect", endpoint, "--credentials", str(users), "--run-id", "twice"]
        watch = router.declare_subscriber("fleet/twice/world/state", lambda _: started.set())
        runner = threading.Thread(target=lambda: first.update(run=fleet(
            "run", *scenario, "--in-process", *login, "--out", str(tmp_path / "first"), check=False)), daemon=True)
        runner.start()
        assert started.wait(300)
        code, out, err = run_cli(["run", *scenario, *login, "--out", str(tmp_path / "second")])
        runner.join(300)
        watch.undeclare()
    assert code == 2 and err.count("\n") == 1 and not out, err
    assert "run id 'twice' is already live" in err and not (tmp_path / "second").exists()
    assert first["run"].returncode in (0, 3), first["run"].stderr[-2000:]
    assert deterministic(result(tmp_path / "first")) == deterministic(result(tmp_path / "memory"))


def _open_router(text: str) -> zenoh.Session:
    """A router from ``fleet router-config``'s text, its admin space on (to read back the port the OS chose)."""
    conf = zenoh.Config.from_json5(text)
    conf.insert_json5("adminspace/enabled", "true")
    return zenoh.open(conf)
