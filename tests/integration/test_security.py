"""The bus only its own fleet can write: Zenoh's user/password authentication and access control, tried by an
attacker with real sessions against real routers and real fleets."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import msgpack
import numpy as np
import pytest
import zenoh
from mcap.reader import make_reader

from fleet_emu.agents.protocol import MapDelta
from fleet_emu.core.access import Credential, read_dictionary
from fleet_emu.core.bus import client_config, router_locators
from fleet_emu.core.messages import Command, Failed, Links, RadioMsg, RxBundle, Stop, TxBundle, WorldState, seal
from fleet_emu.launch.result import deterministic
from fleet_emu.launch.router_config import router_config_text
from tests.harness.cli import ENDLESS, ROOT, result, run_cli
from tests.harness.files import make_certs
from tests.harness.procs import all_pids, pid_alive, wait_for

RUN = "sec"


def _open_router(text: str) -> zenoh.Session:
    conf = zenoh.Config.from_json5(text)
    conf.insert_json5("adminspace/enabled", "true")  # to read back the port the OS chose
    return zenoh.open(conf)


def _login(users: Path, user: str, endpoint: str, ca: Path | None = None) -> zenoh.Session:
    cred = Credential(user, read_dictionary(users.read_text())[user], str(ca) if ca else None)
    return zenoh.open(client_config(endpoint, cred))


@pytest.fixture
def router(tmp_path: Path):  # type: ignore[no-untyped-def]
    users = tmp_path / "users.txt"
    text = router_config_text(3, users, listen="tcp/127.0.0.1:0")
    assert oct(users.stat().st_mode & 0o777) == "0o600"
    with _open_router(text) as r:
        yield router_locators(r)[0], users


def test_outsiders_cannot_connect_and_a_robot_puts_only_on_its_own_keys(router) -> None:  # type: ignore[no-untyped-def]
    endpoint, users = router
    with pytest.raises(zenoh.ZError):
        zenoh.open(client_config(endpoint))  # no credentials
    with pytest.raises(zenoh.ZError):
        zenoh.open(client_config(endpoint, Credential("r1", "guessed")))
    got: list[str] = []
    with _login(users, "recorder", endpoint) as rec, _login(users, "r1", endpoint) as r1, \
            _login(users, "world", endpoint) as world:
        sub = rec.declare_subscriber(f"fleet/{RUN}/**", lambda s: got.append(str(s.key_expr)))
        alive: list[str] = []
        lsub = rec.liveliness().declare_subscriber(  # declared tokens (an undeclare is a DELETE sample)
            f"fleet/{RUN}/alive/**",
            lambda s: alive.append(str(s.key_expr)) if s.kind == zenoh.SampleKind.PUT else None)
        time.sleep(0.5)
        denied = ["robot/r2/cmd", "robot/r2/belief", "radio/tx/r2", "world/state", "world/obs/r1", "radio/rx/r1",
                  "netem/links", "ctl/stop", "ctl/failed/r1", "ctl/hello", "ctl/report/r2", "ctl/ready/world"]
        for k in denied:
            r1.put(f"fleet/{RUN}/{k}", b"x")
        rec.put(f"fleet/{RUN}/ctl/stop", b"x")  # the recorder puts nothing (it only hears itself)
        allowed = ["robot/r1/cmd", "radio/tx/r1", "ctl/report/r1", "ctl/ready/r1"]
        for k in allowed:
            r1.put(f"fleet/{RUN}/{k}", b"x")
        world.put(f"fleet/{RUN}/world/state", b"x")
        world.put(f"fleet/{RUN}/radio/rx/r1", b"x")  # not the world's
        tokens = [r1.liveliness().declare_token(f"fleet/{RUN}/alive/agent/r1"),
                  r1.liveliness().declare_token(f"fleet/{RUN}/alive/world/world")]
        deadline = time.monotonic() + 10
        while len(got) < len(allowed) + 2 and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(0.5)
        for t in tokens:
            t.undeclare()
        sub.undeclare()
        lsub.undeclare()
    heard = sorted(k.split("/", 2)[2] for k in got)
    assert heard == sorted([*allowed, "world/state", "ctl/stop"])  # ctl/stop: the recorder's own, local
    assert got.count(f"fleet/{RUN}/ctl/stop") == 1
    assert alive == [f"fleet/{RUN}/alive/agent/r1"]


def _attack(endpoint: str, users: Path, run: str, until: threading.Event) -> dict[str, int]:
    """Every attack of the security tests, with robot r1's credentials, against everything that is not r1's."""
    sent = {"puts": 0}
    started = threading.Event()
    tick = [0]

    def on_state(s: zenoh.Sample) -> None:
        tick[0] = _tick_of(s.payload.to_bytes(), tick[0])
        started.set()

    with _login(users, "r1", endpoint) as s:
        watch = s.declare_subscriber(f"fleet/{run}/world/state", on_state)
        started.wait(180)

        def put(key: str, data: bytes) -> None:
            s.put(f"fleet/{run}/{key}", data)
            sent["puts"] += 1

        while not until.is_set():
            t = tick[0]
            put("ctl/stop", Stop(src="outsider", tick=t, seq=1, reason="pwned").encode())
            put("ctl/stop", Stop(src="launcher", tick=t, seq=1, reason="interrupted").encode())
            put("ctl/failed/r0", Failed(src="launcher", tick=t, seq=1, robot="r0", reason="spoof").encode())
            walls = MapDelta(cells=np.arange(200, dtype=np.int64), values=np.full(200, 100, dtype=np.int8))
            put("radio/tx/r0", TxBundle(src="r0", tick=t, seq=7, msgs=(seal(RadioMsg(walls), "r0", t, 7),)).encode())
            for r in ("r0", "r2"):
                put(f"robot/{r}/cmd", Command(src=r, tick=t, seq=9, move=(0, 0)).encode())
                put(f"radio/rx/{r}", RxBundle(src="netem", tick=t + 1, seq=9, dst=r, msgs=()).encode())
            put("world/state", WorldState(src="world", tick=t + 5000, seq=99, poses={}, live=(), coverage=1.0,
                                          path_length={}, done=True, reason="coverage").encode())
            put("netem/links", Links(src="netem", tick=t, seq=99, robots=(), strength=np.zeros((0, 0), np.float32),
                                     link=np.zeros((0, 0), bool), connected=True, sent=0, delivered=0,
                                     dropped_loss=0, dropped_signal=0, bytes_sent=0).encode())
            tok = s.liveliness().declare_token(f"fleet/{run}/alive/agent/r0")  # a fake r0 that then "dies"
            tok.undeclare()
            time.sleep(0.02)
        watch.undeclare()
    return sent


def _tick_of(data: bytes, default: int) -> int:
    obj = msgpack.unpackb(data)
    return obj.get("tick", default) if isinstance(obj, dict) else default


def _comparable(res: dict) -> dict:
    return deterministic(res)


def test_every_attack_leaves_the_seeded_result_unchanged(router, small_map: Path, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """The attacked run's seeded result is the run's without an attacker: the same scenario on the memory
    engine (which gives every engine's result for a seed: ``test_memory_engine.py``)."""
    endpoint, users = router
    scenario = ["--map", str(small_map), "--robots", "3", "--seed", "3", "--loss", "0.2", "--quiet"]
    base = tmp_path / "base"
    code, _, err = run_cli(["run", *scenario, "--engine", "memory", "--no-record", "--out", str(base)])
    assert code in (0, 3), err
    attacked = tmp_path / "attacked"
    stop = threading.Event()
    counts: dict[str, int] = {}
    attacker = threading.Thread(target=lambda: counts.update(_attack(endpoint, users, RUN, stop)), daemon=True)
    attacker.start()
    _, _, err = run_cli(["run", *scenario, "--connect", endpoint, "--credentials", str(users), "--run-id", RUN,
                         "--out", str(attacked)], check=True)
    stop.set()
    attacker.join(30)
    assert counts["puts"] > 100
    rb, ra = result(base), result(attacked)
    assert ra["authenticated"] is True and ra["malformed_dropped"] == 0  # the router stopped all of it
    assert _comparable(ra) == _comparable(rb), err[-2000:]


@pytest.mark.slow  # 2nd router's outsiders; default: the external one
def test_the_embedded_router_refuses_outsiders_and_sigterm_keeps_the_files(small_map: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = subprocess.Popen(
        [sys.executable, "-m", "fleet_emu.launch", "run", *ENDLESS.args(robots=1), "--out", str(out), "--quiet",
         "--no-fork-server"],  # nodes started afresh: a command line that ps shows (a forked one has the server's)
        cwd=ROOT, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    cmdline: list[str] = []
    while time.monotonic() < deadline and not (out / "run.mcap").exists():
        time.sleep(0.2)
    while time.monotonic() < deadline and not cmdline:
        for d in Path("/proc").iterdir():
            if d.name.isdigit():
                try:
                    args = (d / "cmdline").read_bytes().split(b"\0")
                except OSError:
                    continue
                if b"fleet_emu.world" in args and str(out).encode() in b" ".join(args):
                    cmdline = [a.decode() for a in args]
        time.sleep(0.2)
    endpoint = cmdline[cmdline.index("--connect") + 1]  # what any local process can read from ps
    assert "--auth-stdin" in cmdline  # the password is on no command line
    with pytest.raises(zenoh.ZError):
        zenoh.open(client_config(endpoint))
    with pytest.raises(zenoh.ZError):
        zenoh.open(client_config(endpoint, Credential("world", "")))
    wait_for(lambda: (out / "run.mcap").stat().st_size > 20000, 90)  # the run is going
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=90)
    assert proc.returncode == 143, err[-2000:]
    assert "Traceback" not in err
    res = result(out)
    assert res["reason"] == "interrupted" and res["signal"] == "SIGTERM" and res["authenticated"] is True
    with open(out / "run.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    assert sum(summary.statistics.channel_message_counts.values()) == res["recording"]["messages"]
    deadline = time.monotonic() + 10
    while any(pid_alive(p) for p in all_pids(res)) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(pid_alive(p) for p in all_pids(res))


def test_a_fleet_runs_over_tls_with_router_config(small_map: Path, tmp_path: Path) -> None:
    ca, cert, key = make_certs(tmp_path)
    users = tmp_path / "users.txt"
    code, config, err = run_cli(["router-config", "--robots", "2", "--users", str(users), "--listen",
                                 "tls/localhost:0", "--tls-cert", str(cert), "--tls-key", str(key)])
    assert code == 0, err
    with _open_router(config) as r:
        endpoint = router_locators(r)[0]
        assert endpoint.startswith("tls/")
        with pytest.raises(zenoh.ZError):  # right password, but no trust in the router's certificate
            _login(users, "launcher", endpoint)
        out = tmp_path / "run"
        code, _, err = run_cli(["run", "--map", str(small_map), "--robots", "2", "--max-ticks", "15", "--quiet",
                                "--out", str(out), "--connect", endpoint, "--credentials", str(users), "--tls-ca",
                                str(ca)])
        assert code == 3, err[-2000:]
    res = result(out)
    assert res["ticks"] == 15 and res["failed"] == [] and res["authenticated"] is True


def test_auth_flags_without_connect_are_one_line() -> None:
    code, _, err = run_cli(["run", "--credentials", "users.txt"])
    assert code == 2 and err.strip() == "fleet: error: --credentials and --tls-ca go with --connect (the embedded " \
        "router makes its own)"


def test_an_authenticated_router_without_credentials_is_one_line_naming_them(router, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    endpoint, _ = router
    out = tmp_path / "run"
    code, _, err = run_cli(["run", "--connect", endpoint, "--out", str(out), "--quiet"])
    assert code == 2 and not out.exists()
    assert err.strip().splitlines() == [
        f"fleet: error: --connect {endpoint}: no Zenoh router answered (gave up after 5 s); a router with "
        "authentication needs --credentials"]
