"""``fleet run --ros2`` on a real bus, watched by clients nobody here wrote: ``zenoh-ros2-sdk`` subscribes to
``/<robot>/map`` and ``/<robot>/pose`` (with the read-only viewer's login) and decodes them; a liveliness query on
``@ros2_lv/<domain>/**`` lists the node and its publishers in rmw_zenoh's token format; the viewer cannot write
a topic; and the run's result is the same with and without the bridge, in both engines that have a bus."""

from __future__ import annotations

import contextlib
import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

pytest.importorskip("rosbags")
pytest.importorskip("zenoh_ros2_sdk")

import zenoh

from fleet_emu.core.access import Credential
from fleet_emu.core.bus import client_config
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.result import deterministic
from fleet_emu.launch.runner import BusAccess, RunOptions, run_fleet
from fleet_emu.ros2 import rmw
from fleet_emu.ros2.bridge import VIEWER, Ros2Options, grants
from fleet_emu.ros2.fold import topics
from fleet_emu.ros2.types import GRID, POSE, decode, type_hash
from tests.harness.cli import run_cli

DOMAIN = 5


class Probe:
    """A companion entered after the bridge, before the nodes start: the SDK's subscribers, a liveliness
    query, and a viewer's attempt to write a topic."""

    def __init__(self, password: str, messages: Path, monkeypatch: pytest.MonkeyPatch) -> None:
        self.password, self.messages, self.monkeypatch = password, messages, monkeypatch
        self.got: dict[str, list[Any]] = {}
        self.tokens: list[str] = []
        self.heard: list[bytes] = []  # what a second viewer session got on /r0/pose: the bridge's, no spoof
        self.late: dict[str, list[bytes]] = {}  # what a subscriber that came after the run got of the latched grids

    @contextlib.contextmanager
    def __call__(self, access: BusAccess) -> Iterator[None]:
        from zenoh_ros2_sdk import ROS2Subscriber, ZenohSession, get_registry, message_registry

        from docs.ros2.listen import write_msg_files

        host, port = access.endpoint.removeprefix("tcp/").rsplit(":", 1)
        self.monkeypatch.setenv("ZENOH_CONFIG_OVERRIDE", ";".join([
            'mode="client"', f"transport/auth/usrpwd/user={json.dumps(VIEWER)}",
            f"transport/auth/usrpwd/password={json.dumps(self.password)}"]))
        write_msg_files(self.messages, [GRID, POSE])
        message_registry._registry = None
        get_registry(str(self.messages))
        subs = [ROS2Subscriber(f"/r{i}/{what}", kind, lambda m, t=f"/r{i}/{what}": self.got.setdefault(t, []).append(m),
                               domain_id=DOMAIN, router_ip=host, router_port=int(port))
                for i in range(2) for what, kind in (("map", GRID), ("pose", POSE))]
        login = Credential(VIEWER, self.password)
        viewer, other = (zenoh.open(client_config(access.endpoint, login)) for _ in range(2))
        try:
            self.tokens = [str(r.ok.key_expr) for r in viewer.liveliness().get(f"@ros2_lv/{DOMAIN}/**", timeout=5)
                           if r.ok is not None]
            key = rmw.topic_key(DOMAIN, "/r0/pose", POSE, type_hash(POSE))
            other.declare_subscriber(key, lambda s: self.heard.append(s.payload.to_bytes()))
            time.sleep(0.5)
            viewer.put(key, b"spoof")  # the ACL lets the viewer subscribe, never write
            yield
            time.sleep(1.0)  # the last publications on their way
            for topic in ("/map", "/r1/map"):  # transient local as rmw_zenoh does it: a late advanced subscriber
                zenoh.ext.declare_advanced_subscriber(  # with history gets each latched publisher's cache
                    viewer, rmw.topic_key(DOMAIN, topic, GRID, type_hash(GRID)),
                    lambda s, t=topic: self.late.setdefault(t, []).append(s.payload.to_bytes()),
                    history=zenoh.ext.HistoryConfig(detect_late_publishers=True))
            time.sleep(1.0)
        finally:
            for s in subs:
                s.close()
            viewer.close()
            other.close()
            ZenohSession.get_instance().close()


def _scenario(small_map: Path) -> Scenario:
    return Scenario().override(map=str(small_map), robots=2, seed=6, max_ticks=60)


def test_a_run_seen_over_rmw_zenoh(small_map: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    ros2 = Ros2Options.new(DOMAIN, authenticated=True)
    assert ros2.viewer_password is not None
    lines: list[str] = []
    ros2 = Ros2Options(DOMAIN, ros2.viewer_password, lines.append)
    probe = Probe(ros2.viewer_password, tmp_path / "msg", monkeypatch)
    seen = run_fleet(_scenario(small_map), RunOptions(
        out_dir=tmp_path / "ros2", companions=(ros2.companion(), probe), grants=grants(DOMAIN),
        grant_users={VIEWER: ros2.viewer_password}))
    plain = run_fleet(_scenario(small_map), RunOptions(out_dir=tmp_path / "plain"))
    assert deterministic(seen.data) == deterministic(plain.data) and plain["ticks"] > 10

    (line,) = lines
    assert line.startswith("ros2: tcp/127.0.0.1:") and line.endswith(f"domain {DOMAIN} credentials "
                                                                      f"{tmp_path / 'ros2' / 'ros2.users'}")
    assert (tmp_path / "ros2" / "ros2.users").read_text() == f"{VIEWER}:{ros2.viewer_password}\n"
    poses, maps = probe.got["/r0/pose"], probe.got["/r1/map"]
    assert len(poses) >= plain["ticks"] - 1  # every world state (the one after the stop may not come)
    assert maps and maps[-1].info.width == 24 and maps[-1].info.height == 12 and (maps[-1].data >= 0).any()
    assert poses[-1].header.frame_id == "map" and poses[0].pose.orientation.w == 1.0
    assert len(probe.heard) == len(poses) and b"spoof" not in probe.heard
    (truth,), (belief,) = probe.late["/map"], probe.late["/r1/map"]  # the cache holds one, the last
    assert decode(belief, GRID).data.tolist() == maps[-1].data.tolist()
    assert (decode(truth, GRID).data == 100).any()

    ours = [t.split("/") for t in probe.tokens if t.split("/")[8] == "fleet_emu"]
    assert [t[3:] for t in ours if t[5] == "NN"] == [["0", "0", "NN", "%", "%", "fleet_emu"]]
    assert {t[2] for t in ours} == {next(t for t in ours if t[5] == "NN")[2]}  # one session, the bridge's
    assert any(t[5] == "MS" for t in (t.split("/") for t in probe.tokens))  # the SDK's subscribers, listed too
    published = {t[9] for t in ours if t[5] == "MP"}
    assert published == {rmw.mangle(topic) for topic in topics(2)}
    grid = next(t for t in probe.tokens if "/%r1%map/" in t and "/MP/" in t)
    assert grid.endswith(f"/nav_msgs::msg::dds_::OccupancyGrid_/{type_hash(GRID)}/{rmw.qos(True)}")


@pytest.mark.slow  # ROS 2 in-process; over processes by default
def test_in_process_the_same_run(small_map: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    """``fe.run(..., ros2=N)`` in the in-process engine, bridged (nobody watching), ends as the plain run does;
    the memory engine, which has no bus, refuses it."""
    import fleet_emu as fe

    seen = fe.run(_scenario(small_map), tmp_path / "a", in_process=True, ros2=DOMAIN)
    assert f"domain {DOMAIN} credentials {tmp_path / 'a' / 'ros2.users'}" in capfd.readouterr().err
    plain = fe.run(_scenario(small_map), tmp_path / "b", in_process=True)
    assert deterministic(seen.data) == deterministic(plain.data)
    with pytest.raises(fe.ConfigError, match="ros2"):
        fe.run(_scenario(small_map), engine="memory", ros2=DOMAIN)


@pytest.mark.slow  # ROS 2 over processes proven once by default (rmw_zenoh)
def test_the_cli_says_where_under_quiet(small_map: Path, tmp_path: Path) -> None:
    from tests.harness.cli import fleet

    out = tmp_path / "run"
    done = fleet("run", "--ros2", "3", "--quiet", "--map", str(small_map), "--robots", "2", "--max-ticks", "15",
                 "--out", str(out))
    (line,) = [x for x in done.stderr.splitlines() if x.startswith("ros2: ")]
    assert line.startswith("ros2: tcp/127.0.0.1:") and line.endswith(f" domain 3 credentials {out / 'ros2.users'}")
    assert (out / "ros2.users").stat().st_mode & 0o077 == 0


@pytest.mark.parametrize(("args", "says"), [
    (["--engine", "memory", "--ros2"], "--engine memory runs without Zenoh nor processes: it takes no --ros2"),
    (["--ros2-listen", "tcp/127.0.0.1:7447"], "--ros2-listen goes with --ros2"),
    (["--ros2", "999"], "ROS domain id"),
    (["--ros2", "--listen", "tcp/127.0.0.1:7000", "--ros2-listen", "tcp/127.0.0.1:7447"], "two endpoints"),
])
def test_bad_ros2_flags_are_one_line(args: list[str], says: str, tmp_path: Path) -> None:
    code, _, err = run_cli(["run", *args, "--out", str(tmp_path / "x")])  # refused before anything starts
    assert code == 2 and err.count("\n") == 1 and says in err, err
    assert not (tmp_path / "x").exists()
