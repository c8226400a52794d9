"""The pure parts of ``fleet run --hosts`` / ``fleet host``: placement, the lobby's keys, messages and access
control, and the one-line errors of bad host options (no router here)."""

from __future__ import annotations

from pathlib import Path

import pytest

from fleet_emu.core.access import acl_config, fleet_nodes, role_of, writes
from fleet_emu.core.codec import DecodeError, decode
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.keys import HostKeys, host_ids, robot_ids
from fleet_emu.core.messages import HostAssign, HostStatus
from fleet_emu.core.scenario import HostPlan
from fleet_emu.launch.host_client import check_hosts, check_reliable, host_credentials, placement, robot_argv
from fleet_emu.launch.host_server import host_login


def test_robots_are_dealt_round_robin_over_this_machine_and_the_hosts() -> None:
    robots = robot_ids(7)
    assert placement(robots, []) == {r: None for r in robots}
    assert placement(robots, ["host0", "host1"]) == {
        "r0": None, "r1": "host0", "r2": "host1", "r3": None, "r4": "host0", "r5": "host1", "r6": None}


def test_the_agent_command_line_is_the_one_the_launcher_uses_here() -> None:
    assert robot_argv("r3", "run1", "tcp/10.0.0.1:7447", Path("/w/scenario.json"), True) == [
        "--robot", "r3", "--run", "run1", "--connect", "tcp/10.0.0.1:7447", "--scenario", "/w/scenario.json",
        "--auth-stdin"]
    assert "--auth-stdin" not in robot_argv("r0", "run1", "tcp/x:1", Path("s.json"), False)


def test_lobby_keys_name_their_host_and_nothing_else() -> None:
    k = HostKeys("host2")
    assert (k.alive, k.spawn, k.status) == ("fleet-host/host2/alive", "fleet-host/host2/spawn",
                                            "fleet-host/host2/status")
    assert HostKeys.host_of(k.status) == "host2"
    for bad in ("fleet/host2/status", "fleet-host/r1/status", "fleet-host/host2/x/status"):
        assert HostKeys.host_of(bad) is None
    with pytest.raises(ValueError):
        HostKeys("r1")


def test_a_host_puts_nothing_in_a_run_and_only_its_own_lobby_keys() -> None:
    nodes = fleet_nodes(robot_ids(2)) + host_ids(2)
    assert role_of("host1") == "host" and role_of("r1") == "agent" and writes("host0") == []
    acl = acl_config("run1", nodes)
    rules = {r["id"]: r for r in acl["rules"]}
    policy = {p["subjects"][0]: p["rules"] for p in acl["policies"]}
    host0 = [rules[r] for r in policy["user host0"]]
    puts = [k for r in host0 if r["flows"] == ["ingress"] and "put" in r["messages"] for k in r["key_exprs"]]
    assert puts == ["fleet-host/host0/status"]
    receives = [k for r in host0 if "egress" in r["flows"] and "put" in r["messages"] for k in r["key_exprs"]]
    assert receives == ["fleet-host/host0/spawn"]  # the requests with its robots' credentials: its own only
    tokens = [k for r in host0 if "liveliness_token" in r["messages"] for k in r["key_exprs"]]
    assert tokens == ["fleet-host/host0/alive"]
    for node in ("world", "netem", "recorder", "r0", "r1", "host1"):  # nobody else receives host0's requests
        for rid in policy.get(f"user {node}", []) + policy["fleet"]:
            r = rules[rid]
            assert not ("egress" in r["flows"] and "put" in r["messages"]
                        and any(k in ("fleet-host/host0/spawn", "fleet-host/*/spawn", "fleet-host/**", "**")
                                for k in r["key_exprs"])), (node, rid)
    launcher_puts = [k for r in (rules[i] for i in policy["user launcher"]) if r["flows"] == ["ingress"]
                     and "put" in r["messages"] for k in r["key_exprs"]]
    assert "fleet-host/*/spawn" in launcher_puts and "fleet-host/*/status" not in launcher_puts


def test_host_messages_round_trip_and_bad_ones_are_dropped() -> None:
    msg = HostAssign(src="launcher", tick=0, seq=0, host="host0", run="run1", robots=("r1", "r3"), scenario="{}",
                     secrets={"r1": '{"user": "r1", "password": "p"}'})
    assert decode(msg.encode(), expected=HostAssign) == msg
    status = HostStatus(src="host0", tick=0, seq=3, run="run1", event="exited", robot="r1", code=-9)
    assert decode(status.encode(), expected=HostStatus) == status
    for bad in (HostAssign(src="launcher", tick=0, seq=0, host="hostX", run="run1"),
                HostAssign(src="launcher", tick=0, seq=0, host="host0", run="run/1"),
                HostAssign(src="launcher", tick=0, seq=0, host="host0", run="run1", robots=("r1", "r1")),
                HostAssign(src="launcher", tick=0, seq=0, host="host0", run="run1", robots=("world",)),
                HostAssign(src="launcher", tick=0, seq=0, host="host0", run="run1", robots=("r1",),
                           secrets={"r2": '{"user": "r2", "password": "p"}'}),
                HostStatus(src="host0", tick=0, seq=0, run="run1", event="rebooted")):
        with pytest.raises(DecodeError):
            decode(bad.encode())


def test_bad_host_options_are_one_line(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="takes no --in-process"):
        check_hosts(1, True, None, "tcp/127.0.0.1:7447")
    with pytest.raises(ConfigError, match="needs a router the hosts can reach"):
        check_hosts(1, False, None, None)
    with pytest.raises(ConfigError, match="takes no --connect"):
        check_hosts(0, False, "tcp/127.0.0.1:7447", "tcp/127.0.0.1:7448")
    check_hosts(2, False, "tcp/127.0.0.1:7447", None)
    users = tmp_path / "users.txt"
    users.write_text("world:a\nhost0:b\nhost1:c\n")
    users.chmod(0o600)
    assert set(host_credentials(users)) == {"host0", "host1"}
    with pytest.raises(ConfigError, match="needs --credentials"):
        host_credentials(None)
    none = tmp_path / "none.txt"
    none.write_text("world:a\n")
    none.chmod(0o600)
    with pytest.raises(ConfigError, match="has no host user"):
        host_credentials(none)
    with pytest.raises(ConfigError, match=r"has 2 host user\(s\) for 3 hosts: make them with `fleet router-config "
                                          r"--hosts 3`"):
        host_credentials(users, HostPlan(3))
    with pytest.raises(ConfigError, match="has no user 'host5' of the scenario's \\[hosts\\] names"):
        host_credentials(users, HostPlan(1, ("host5",)))
    assert set(host_credentials(users, HostPlan(1, ("host1",)))) == {"host0", "host1"}
    with pytest.raises(ConfigError, match="holds 2 host users"):
        host_login(users, None, None)
    assert host_login(users, "host1", None)[1].password == "c"  # type: ignore[union-attr]
    with pytest.raises(ConfigError, match="--name must be"):
        host_login(users, "world", None)
    one = tmp_path / "host0.txt"
    one.write_text("host0:b\n")
    one.chmod(0o600)
    name, cred = host_login(one, None, None)
    assert name == "host0" and cred is not None and cred.user == "host0"
    assert host_login(None, None, None) == ("host0", None)


def test_a_spawn_request_whose_credential_is_not_its_robots_is_dropped() -> None:
    good = HostAssign(src="launcher", tick=0, seq=0, host="host0", run="run1", robots=("r1",),
                      secrets={"r1": '{"user": "r1", "password": "p"}'})
    assert decode(good.encode()) == good
    for secret in ('{"user": "r2", "password": "p"}', "not json", '{"user": "r1"}'):
        bad = HostAssign(src="launcher", tick=0, seq=0, host="host0", run="run1", robots=("r1",),
                         secrets={"r1": secret})
        with pytest.raises(DecodeError):
            decode(bad.encode())


def test_a_spawn_request_carries_the_real_time_rate_and_the_robots_get_it() -> None:
    msg = HostAssign(src="launcher", tick=0, seq=0, host="host0", run="run1", robots=("r1",), realtime_hz=10.0)
    assert decode(msg.encode(), expected=HostAssign).realtime_hz == 10.0
    assert decode(HostAssign(src="launcher", tick=0, seq=0, host="host0", run="run1").encode()).realtime_hz == 0.0
    for hz in (-1.0, 1001.0, float("nan"), float("inf")):
        with pytest.raises(DecodeError, match="realtime_hz"):
            decode(HostAssign(src="launcher", tick=0, seq=0, host="host0", run="run1", realtime_hz=hz).encode())
    argv = robot_argv("r0", "run1", "tcp/127.0.0.1:7447", Path("s.json"), True, 10.0)
    assert argv[argv.index("--realtime") + 1] == "10.0" and "--realtime" not in robot_argv(
        "r0", "run1", "tcp/127.0.0.1:7447", Path("s.json"), True)


def test_a_scenario_s_shares_place_the_robots_and_equal_shares_are_round_robin() -> None:
    robots = robot_ids(7)
    assert placement(robots, ["host5", "host2"], (4, 1)) == {  # dealt round the machines that have room
        "r0": None, "r1": "host5", "r2": "host2", "r3": None, "r4": "host5", "r5": "host5", "r6": "host5"}
    assert placement(robots, ["host0"], (7,)) == {r: "host0" for r in robots}
    assert placement(robots, ["host0", "host1"], (0, 0)) == {r: None for r in robots}
    assert placement(robot_ids(6), ["host0"], (3,)) == placement(robot_ids(6), ["host0"])


def test_the_embedded_router_listens_on_tcp_tls_or_quic(tmp_path: Path) -> None:
    from fleet_emu.launch.host_client import listen_endpoints

    pem = tmp_path / "x.pem"
    pem.write_text("")
    assert listen_endpoints(None, None, None) == ["tcp/127.0.0.1:0"]
    assert listen_endpoints("tcp/10.0.0.1:7447", None, None) == ["tcp/10.0.0.1:7447"]
    for proto in ("tls", "quic"):  # and a loopback tcp/ one for this machine's processes
        assert listen_endpoints(f"{proto}/10.0.0.1:7447", pem, pem) == [f"{proto}/10.0.0.1:7447", "tcp/127.0.0.1:0"]
    for listen, cert, match in [
            ("udp/10.0.0.1:7447", None, "Zenoh does not retransmit over udp/, and a lockstep run may lose no message: "
                                        "use tcp/, tls/ or quic/"),
            ("ws/10.0.0.1:7447", None, r"the embedded router listens on tcp/, tls/ or quic/ \(got ws/\)"),
            ("10.0.0.1:7447", None, "is not an endpoint"),
            ("tls/10.0.0.1:7447", None, "a tls/ router needs --tls-cert CERT.pem and --tls-key KEY.pem"),
            ("tcp/10.0.0.1:7447", pem, "--tls-cert and --tls-key go with a tls/ or quic/ --listen"),
            ("quic/10.0.0.1:7447", tmp_path / "none.pem", "--tls-cert .*none.pem: no such file")]:
        with pytest.raises(ConfigError, match=match):
            listen_endpoints(listen, cert, pem if cert is not None else None)
    with pytest.raises(ConfigError, match=r"--connect udp/10\.0\.0\.1:7447: Zenoh does not retransmit over udp/"):
        check_reliable("--connect", "udp/10.0.0.1:7447")  # fleet run --connect and fleet host --connect
    check_reliable("--connect", "quic/10.0.0.1:7447")
