"""Robots on other machines (``fleet run --hosts N`` and ``fleet host``), with real routers and real processes: on
this machine over loopback, and across two network namespaces joined by a veth pair."""

from __future__ import annotations

import collections
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import zenoh
from mcap.reader import make_reader

from fleet_emu.core.access import Credential, read_dictionary
from fleet_emu.core.bus import client_config, publisher, router_locators
from fleet_emu.core.keys import HostKeys
from fleet_emu.core.messages import HostAssign
from fleet_emu.core.scenario import HostPlan, Scenario
from fleet_emu.launch.result import deterministic
from fleet_emu.launch.router_config import router_config_text
from tests.harness.cli import ROOT, result, run_cli
from tests.harness.files import make_certs
from tests.harness.procs import children_of, free_port, pid_alive, wait_for

FLEET = [sys.executable, "-m", "fleet_emu.launch"]
WAIT = ["--connect-timeout", "120"]  # a host may start before the launcher's router


@pytest.fixture
def users(tmp_path: Path) -> tuple[Path, Path]:
    """A users file with two hosts (``router-config --hosts 2``) and host0's own one-line file."""
    users = tmp_path / "users.txt"
    router_config_text(4, users, listen="tcp/127.0.0.1:0", hosts=2)
    return users, _own(users, "host0")


def _own(users: Path, host: str) -> Path:
    own = users.with_name(f"{host}.txt")
    own.write_text(next(ln for ln in users.read_text().splitlines() if ln.startswith(f"{host}:")) + "\n")
    own.chmod(0o600)
    return own


def _start(args: list[str], prefix: list[str] | None = None) -> subprocess.Popen[str]:
    return subprocess.Popen([*(prefix or []), *FLEET, *args], cwd=ROOT, text=True, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, start_new_session=True)


def _finish(proc: subprocess.Popen[str], timeout: float = 240) -> tuple[int, str]:
    try:
        _, err = proc.communicate(timeout=timeout)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
    return proc.returncode, err


def _one_machine(small_map: Path, out: Path) -> dict:
    """The split runs' scenario with every robot here, on the memory engine (every engine's result for a seed:
    ``test_memory_engine.py``)."""
    code, _, err = run_cli(["run", "--map", str(small_map), "--robots", "4", "--max-ticks", "50", "--seed", "5",
                            "--quiet", "--engine", "memory", "--no-record", "--out", str(out)])
    assert code in (0, 3), err
    return result(out)


RUN = ["run", "--robots", "4", "--max-ticks", "50", "--seed", "5", "--quiet", "--hosts", "1"]


def test_a_host_with_wrong_credentials_is_refused_and_spawn_requests_reach_only_their_host(
        users: tuple[Path, Path], tmp_path: Path) -> None:
    all_users, _ = users
    text = router_config_text(4, all_users, listen="tcp/127.0.0.1:0", hosts=2)
    conf = zenoh.Config.from_json5(text)
    conf.insert_json5("adminspace/enabled", "true")
    with zenoh.open(conf) as router:
        endpoint = router_locators(router)[0]
        bad = tmp_path / "bad.txt"
        bad.write_text("host0:guessed\n")
        bad.chmod(0o600)
        code, _, err = run_cli(["host", "--connect", endpoint, "--credentials", str(bad), "--once"])
        assert code == 2
        assert err.strip().splitlines()[-1] == \
            f"fleet: error: --connect {endpoint}: no Zenoh router answered or it refused host0's credentials " \
            f"(gave up after 5 s)"
        assert "Traceback" not in err
        pw = read_dictionary(all_users.read_text())
        sessions = {u: zenoh.open(client_config(endpoint, Credential(u, pw[u])))
                    for u in ("launcher", "host0", "host1", "r0", "recorder")}
        try:
            got: dict[str, list[bytes]] = {u: [] for u in sessions}
            subs = [s.declare_subscriber(k, lambda x, u=u: got[u].append(x.payload.to_bytes()))
                    for u, s in sessions.items() if u != "launcher"
                    for k in ("**", "fleet-host/**", "fleet-host/host0/spawn")]
            subs.append(sessions["launcher"].declare_subscriber(
                HostKeys("host0").status, lambda x: got["launcher"].append(x.payload.to_bytes())))
            time.sleep(1.0)
            request = HostAssign(src="launcher", tick=0, seq=0, host="host0", run="acl", robots=("r1",),
                                 secrets={"r1": '{"user": "r1", "password": "secret"}'}).encode()
            publisher(sessions["launcher"], HostKeys("host0").spawn).put(request)
            sessions["r0"].put(HostKeys("host0").spawn, b"forged")  # not the launcher's key to write
            sessions["host1"].put(HostKeys("host0").status, b"spoofed")
            wait_for(lambda: len(got["host0"]) >= 1, 10)
            time.sleep(0.5)
            assert set(got["host0"]) == {request}  # its own request (on two of its subscriptions), nothing forged
            assert got["recorder"] == [] and got["launcher"] == []  # host1 may not speak for host0
            assert set(got["r0"]) == {b"forged"} and set(got["host1"]) == {b"spoofed"}  # their own, in-session
            for s in subs:
                s.undeclare()
        finally:
            for s in sessions.values():
                s.close()


@pytest.mark.slow  # hosts over processes proven once by default
def test_too_few_hosts_is_one_line_and_a_result(users: tuple[Path, Path], small_map: Path, tmp_path: Path) -> None:
    all_users, _ = users
    out = tmp_path / "out"
    listen = f"tcp/127.0.0.1:{free_port()}"
    code, _, err = run_cli([*RUN, "--map", str(small_map), "--listen", listen,
                            "--credentials", str(all_users), "--host-timeout", "2", "--out", str(out)])
    assert code == 1  # the endpoint the hosts were to reach is named, with the command that reaches it
    assert err.strip().splitlines()[-1] == f"fleet: error: --hosts 1: waited 2 s at {listen} for 1 host(s) " \
                                           f"(`fleet host --connect {listen} --credentials hostK.txt`), 0 came (none)"
    failed = result(out)
    assert failed["reason"] == "error" and failed["error"].startswith("--hosts 1")
    assert failed["scenario"]["hosts"] == {"count": 1}
    code, _, err = run_cli([*RUN, "--map", str(small_map), "--out", str(tmp_path / "x")])
    assert code == 2 and "--hosts (or a scenario's [hosts]) with the embedded router needs " \
        "--credentials USERS" in err
    code, _, err = run_cli([*RUN, "--map", str(small_map), "--credentials", str(all_users), "--out",
                            str(tmp_path / "x")])
    assert code == 2 and "--hosts (or a scenario's [hosts]) needs a router the hosts can reach" in err
    assert not (tmp_path / "x").exists()


@pytest.mark.slow  # hosts over processes proven once by default (another machine)
def test_a_scenario_s_hosts_over_quic_run_their_robots_in_real_time(
        users: tuple[Path, Path], small_map: Path, tmp_path: Path) -> None:
    """A scenario's ``[hosts]`` place its robots (three on host1), over QUIC with TLS, and the robots on the host
    decide and step in real time (started in lockstep, a robot would report no decision). That a split lockstep
    run is the one-machine run: the test over two network namespaces, below."""
    all_users, _ = users
    ca, cert, key = make_certs(tmp_path)  # for localhost and 127.0.0.1
    scenario = tmp_path / "lab.toml"  # the default scenario, and three robots on host1 (of host0 and host1)
    scenario.write_text((ROOT / "launch/scenarios/default.toml").read_text()
                        + '\n[hosts]\nnames = ["host1"]\nrobots = [3]\n')
    endpoint = f"quic/127.0.0.1:{free_port()}"
    launcher = _start(["run", "--scenario", str(scenario), "--map", str(small_map), "--robots", "4", "--max-ticks",
                       "60", "--seed", "5", "--realtime", "20", "--quiet", "--listen", endpoint, "--tls-cert",
                       str(cert), "--tls-key", str(key), "--credentials", str(all_users), "--out",
                       str(tmp_path / "split")])
    host = _start(["host", "--connect", endpoint, "--credentials", str(_own(all_users, "host1")), "--tls-ca",
                   str(ca), "--once", "--out", str(tmp_path / "h"), *WAIT])
    code, err = _finish(launcher)
    host_code, host_err = _finish(host, 30)
    assert code in (0, 3), err
    assert host_code == 0, host_err
    split = result(tmp_path / "split")
    assert split["pids"]["hosts"] == {"host1": ["r1", "r2", "r3"]} and split["failed"] == []
    assert split["scenario"]["hosts"] == {"count": 1, "names": ["host1"], "robots": [3]}
    assert Scenario.load(tmp_path / "split" / "scenario.json").hosts == HostPlan(1, ("host1",), (3,))
    assert split["realtime_hz"] == 20.0 and set(robots := split["realtime"]["robots"]) == {"r0", "r1", "r2", "r3"}
    for r in ("r1", "r2", "r3"):  # on the host
        assert robots[r]["decisions"] >= 1 and robots[r]["plan_steps"] + robots[r]["waits"] >= 1, (r, robots[r])
    bad = [run_cli(["run", "--scenario", str(scenario), "--engine", "memory"]),
           run_cli(["run", "--scenario", str(scenario), "--hosts", "0", "--listen", "udp/127.0.0.1:7447"])]
    assert [(code, err.strip().splitlines()) for code, _, err in bad] == [
        (2, ["fleet: error: --engine memory runs without Zenoh nor processes: it takes no [hosts] (the "
             "scenario's; --hosts 0 runs every robot here)"]),
        (2, ["fleet: error: --listen udp/127.0.0.1:7447: Zenoh does not retransmit over udp/, and a lockstep run "
             "may lose no message: use tcp/, tls/ or quic/"])]


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_a_host_killed_mid_run_fails_its_robots_and_the_run_ends_with_a_result(
        sig: signal.Signals, users: tuple[Path, Path], tmp_path: Path) -> None:
    all_users, own = users
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    out = tmp_path / "out"
    # a run of 1,500 ticks (4 robots see 59 % of this maze in 400): well over 10 s even at 100 ticks/s, so the
    # kill, a second after the host's last robot started, lands mid-run
    launcher = _start(["run", "--robots", "4", "--max-ticks", "1500", "--seed", "2", "--quiet", "--hosts", "1",
                       "--map", "maze", "--sensor-range", "2", "--target-coverage", "1.0",
                       "--listen", endpoint, "--credentials", str(all_users), "--out", str(out)])
    host = _start(["host", "--connect", endpoint, "--credentials", str(own), "--out", str(tmp_path / "h"), *WAIT])
    try:
        wait_for(lambda: len(list((tmp_path / "h").glob("*/host0/r3.log"))) == 1, 120)
        time.sleep(1.0)  # the run is going
        robots = [p for c in children_of(host.pid) for p in [c, *children_of(c)]]
        if sig == signal.SIGKILL:
            os.killpg(host.pid, sig)  # the host and its fork server; its robots are in their own groups
        else:
            host.send_signal(sig)  # the host alone: it tears its robots down and exits 143
        host.communicate(timeout=60)
        assert host.returncode == (-9 if sig == signal.SIGKILL else 143)
        code, err = _finish(launcher)
    finally:
        for p in (launcher, host):
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGKILL)
    res = result(out)
    assert code == 1, err
    # the run went on with r0 and r2 to its own end (a stall too: the maze's target of 1.0 may be out of reach,
    # and a failed robot's body stays on its cell, where it may wall a survivor in for good in the maze's
    # corridors: how far the survivors get is not this test's)
    assert res["failed"] == ["r1", "r3"] and res["reason"] in ("max_ticks", "coverage", "stall") and res["ticks"] > 0
    with open(out / "run.mcap", "rb") as f:  # the survivors decided on ticks after the host's robots stopped
        cmds = collections.Counter(ch.topic.split("/")[-2] for _, ch, _ in make_reader(f).iter_messages()
                                   if ch.topic.endswith("/cmd"))
    assert min(cmds["r0"], cmds["r2"]) > max(cmds["r1"], cmds["r3"]) > 0, cmds
    wait_for(lambda: not any(pid_alive(p) for p in robots), 10)  # the host's robots did not outlive it


# --- two machines: network namespaces joined by a veth pair ----------------------------------------------------

def _netns(pid: int) -> int:
    return os.stat(f"/proc/{pid}/ns/net").st_ino


def _ip(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30)


@pytest.fixture
def namespaces():  # type: ignore[no-untyped-def]
    """Two namespaces, ``A`` (10.231.<k>.1, the launcher's) and ``B`` (10.231.<k>.2, the host's), joined by a veth
    pair; removed on every path. None where they cannot be made (no iproute2, no privilege)."""
    if shutil.which("ip") is None:
        yield None
        return
    tag = f"{os.getpid() % 100000}"
    a, b = f"fleetA{tag}", f"fleetB{tag}"
    if _ip("netns", "add", a).returncode != 0:
        yield None
        return
    k = os.getpid() % 250 + 1
    try:
        made = True
        for cmd in (["netns", "add", b], ["link", "add", f"va{tag}", "netns", a, "type", "veth", "peer", "name",
                                         f"vb{tag}", "netns", b],
                    ["-n", a, "addr", "add", f"10.231.{k}.1/24", "dev", f"va{tag}"],
                    ["-n", b, "addr", "add", f"10.231.{k}.2/24", "dev", f"vb{tag}"],
                    ["-n", a, "link", "set", f"va{tag}", "up"], ["-n", b, "link", "set", f"vb{tag}", "up"],
                    ["-n", a, "link", "set", "lo", "up"], ["-n", b, "link", "set", "lo", "up"]):
            made = made and _ip(*cmd).returncode == 0
        yield ((a, f"10.231.{k}.1"), (b, f"10.231.{k}.2")) if made else None
    finally:
        for ns in (a, b):
            _ip("netns", "del", ns)  # also removes the veth pair
        assert all(ns not in _ip("netns", "list").stdout for ns in (a, b))


def test_a_host_on_another_machine_runs_its_robots_and_the_result_is_the_one_machine_run(
        namespaces, users: tuple[Path, Path], small_map: Path, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """The launcher and a host in two network namespaces joined by a veth pair (the host reaches the launcher's
    router only across it, and its robots, its children, are in its namespace too); where namespaces cannot be
    made, both on this machine over loopback."""
    all_users, own = users
    if namespaces is not None:
        (ns_a, addr_a), (ns_b, _) = namespaces
        endpoint = f"tcp/{addr_a}:7447"
        here, there = ["ip", "netns", "exec", ns_a], ["ip", "netns", "exec", ns_b]
    else:
        endpoint, here, there = f"tcp/127.0.0.1:{free_port()}", [], []
    launcher = _start([*RUN, "--map", str(small_map), "--listen", endpoint, "--credentials", str(all_users),
                       "--out", str(tmp_path / "split")], prefix=here)
    host = _start(["host", "--connect", endpoint, "--credentials", str(own), "--once", "--out", str(tmp_path / "h"),
                   *WAIT], prefix=there)
    if namespaces is not None:
        # `ip netns exec` execs the command: each pid is the fleet process, in its namespace
        time.sleep(1.0)
        assert _netns(launcher.pid) == os.stat(f"/run/netns/{ns_a}").st_ino
        assert _netns(host.pid) == os.stat(f"/run/netns/{ns_b}").st_ino
    code, err = _finish(launcher)
    host_code, host_err = _finish(host, 30)
    assert code in (0, 3), err
    assert host_code == 0, host_err
    split = result(tmp_path / "split")
    assert split["pids"]["hosts"] == {"host0": ["r1", "r3"]}  # round-robin: here, host0, here, host0
    assert split["failed"] == [] and split["authenticated"] is True
    logs = tmp_path / "h" / split["run_id"] / "host0"
    assert sorted(p.name for p in logs.glob("r*.log")) == ["r1.log", "r3.log"]
    said = [ln.removeprefix("fleet host host0: ") for ln in host_err.splitlines() if ln.startswith("fleet host")]
    assert said[0].startswith(f"connected to {endpoint}") and said[-2].startswith(  # the host's console: each run
        f"joined run {split['run_id']}: robots r1, r3 (logs in ") and said[-1].startswith(
        f"left run {split['run_id']} (exit codes: r1 "), host_err
    assert deterministic(split) == deterministic(_one_machine(small_map, tmp_path / "one"))
    for pid in split["pids"]["robots"]:
        assert not pid_alive(pid)


def test_the_launcher_says_what_it_waits_for_and_who_came() -> None:
    """Over a real (peer) Zenoh session: the launcher's console line before the wait, and after it either the
    hosts that came or the timeout's line naming the endpoint; a host's liveliness token is what counts."""
    import threading

    from fleet_emu.launch.host_client import Hosts, HostsError

    conf = zenoh.Config()
    conf.insert_json5("scouting/multicast/enabled", "false")
    said: list[str] = []
    with zenoh.open(conf) as session:
        with Hosts(session, HostPlan(1), timeout=0.3, endpoint="tcp/192.0.2.10:7447", say=said.append) as hosts, \
                pytest.raises(HostsError, match=r"waited 0.3 s at tcp/192.0.2.10:7447 for 1 host\(s\)"):
            hosts.gather(threading.Event())
        assert said == ["waiting up to 0.3 s at tcp/192.0.2.10:7447 for 1 host(s) (`fleet host --connect "
                        "tcp/192.0.2.10:7447 --credentials hostK.txt` on each)"]
        token = session.liveliness().declare_token(HostKeys("host0").alive)
        try:
            with Hosts(session, HostPlan(1), timeout=30, endpoint="tcp/192.0.2.10:7447", say=said.append) as hosts:
                assert hosts.gather(threading.Event()) == ["host0"]
        finally:
            token.undeclare()
    assert said[-1] == "host0 came; starting the run"
