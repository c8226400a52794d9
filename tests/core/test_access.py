"""Who may write what: the one table behind the router's access control and every receiver's src check."""

from __future__ import annotations

import json

import numpy as np
import pytest

from fleet_emu.core.access import (
    Credential,
    acl_config,
    allowed_src,
    dictionary_text,
    fleet_nodes,
    make_credentials,
    read_dictionary,
    writes,
)
from fleet_emu.core.keys import Keys, robot_ids
from fleet_emu.core.messages import Command, Stop, WorldState
from fleet_emu.core.node import NodeShell
from fleet_emu.recording.monitor import Monitor
from fleet_emu.recording.result import fold_keys

K = Keys("run1")


def _may_write(node: str, key_expr: str) -> bool:
    """Whether ``key_expr`` falls under one of ``node``'s own key expressions (``*`` one chunk, ``**`` any)."""
    tail = key_expr.split("/")[2:]
    for pattern in writes(node):
        parts = pattern.split("/")
        if parts[-1] == "**" and tail[:len(parts) - 1] == parts[:-1]:
            return True
        if len(parts) == len(tail) and all(p in ("*", t) for p, t in zip(parts, tail, strict=True)):
            return True
    return False


EVERY_KEY = [K.obs("r0"), K.state, K.cmd("r1"), K.belief("r1"), K.tx("r1"), K.rx("r1"), K.links, K.hello,
             K.ready("r1"), K.ready("world"), K.stop, K.failed("r1"), K.report("r1"), K.cmd("r2"), K.tx("r2"),
             K.clock, K.timing("r1"), K.timing("r2"),  # the real-time mode's keys too
             K.report("base"), K.ready("base"), K.rx("base")]  # a base station's


@pytest.mark.parametrize("node", ["world", "netem", "launcher", "recorder", "r1", "base"])
def test_the_router_table_and_the_receivers_table_agree(node: str) -> None:
    """A node may put on a key exactly when receivers accept that node as the key's sender."""
    for expr in EVERY_KEY:
        allowed = allowed_src(K.parse(expr))  # type: ignore[arg-type]
        assert allowed is not None
        assert _may_write(node, expr) == (node in allowed), (node, expr)


def test_a_robot_writes_only_its_own_keys() -> None:
    assert _may_write("r1", K.cmd("r1")) and _may_write("r1", K.tx("r1")) and _may_write("r1", K.report("r1"))
    assert _may_write("r1", K.timing("r1")) and _may_write("world", K.clock)
    for expr in (K.cmd("r2"), K.tx("r2"), K.belief("r11"), K.state, K.obs("r1"), K.rx("r1"), K.stop,
                 K.failed("r1"), K.ready("r2"), K.hello, K.links, K.clock, K.timing("r2")):
        assert not _may_write("r1", expr), expr
    assert writes("recorder") == []


def test_acl_config_is_default_deny_with_one_policy_per_user() -> None:
    nodes = fleet_nodes(robot_ids(2))
    acl = acl_config("run1", nodes)
    assert acl["enabled"] is True and acl["default_permission"] == "deny"
    json.dumps(acl)  # plain JSON: it goes into a zenohd config file as it is
    rules = {r["id"]: r for r in acl["rules"]}
    assert rules["put r1"]["key_exprs"] == ["fleet/run1/robot/r1/**", "fleet/run1/radio/tx/r1",
                                            "fleet/run1/ctl/report/r1", "fleet/run1/ctl/ready/r1"]
    assert rules["put r1"]["flows"] == ["ingress"] and rules["put r1"]["messages"] == ["put"]
    assert rules["token r1"]["key_exprs"] == ["fleet/run1/alive/agent/r1"]
    assert "put recorder" not in rules  # the recorder puts nothing
    assert "put" not in rules["subscribe"]["messages"]
    users = {s["id"]: s["usernames"] for s in acl["subjects"]}
    assert users["fleet"] == nodes and users["user r0"] == ["r0"]
    assert acl_config("*", nodes)["rules"][0]["key_exprs"] == ["fleet/*/**"]


def test_credentials_round_trip_and_bad_files() -> None:
    pw = make_credentials(["world", "r0"])
    assert len(set(pw.values())) == 2 and all(len(p) >= 24 for p in pw.values())
    assert read_dictionary(dictionary_text(pw)) == pw
    with pytest.raises(ValueError, match="line 2"):
        read_dictionary("world:x\nnocolon\n")
    c = Credential("r0", "secret", "/ca.pem")
    assert Credential.from_json(c.to_json()) == c
    with pytest.raises(ValueError):
        Credential.from_json('{"user": 3}')


class _Node(NodeShell):
    role = "world"


def test_a_receiver_drops_and_counts_a_message_whose_src_may_not_write_its_key() -> None:
    node = _Node(K, "world")
    forged = Command(src="r2", tick=3, seq=1, move=(0, 1)).encode()  # r2's command on r1's key
    assert node.decode(K.cmd("r1"), forged, Command) is None
    assert node.dropped == 1
    assert node.decode(K.cmd("r2"), forged, Command) is not None
    outsider_stop = Stop(src="outsider", tick=0, seq=1, reason="x").encode()
    assert node.decode(K.stop, outsider_stop, Stop) is None
    assert node.decode(K.stop, Stop(src="launcher", tick=0, seq=1, reason="x").encode(), Stop) is not None
    assert node.dropped == 2


def test_the_monitor_never_folds_a_spoofed_state_and_counts_it() -> None:
    m = Monitor(("r0",))
    real = WorldState(src="world", tick=5, seq=1, poses={"r0": (1, 1)}, live=("r0",), coverage=0.2,
                      path_length={"r0": 5}, dropped=2)
    m.feed(K.state, real.encode())
    spoof = WorldState(src="r0", tick=5005, seq=9, poses={"r0": (1, 1)}, live=("r0",), coverage=1.0,
                       path_length={"r0": 5})
    m.feed(K.state, spoof.encode())
    m.feed(K.state, b"\x93garbage")
    assert m.tick == 5 and m.coverage == pytest.approx(0.2)
    res = fold_keys(m, {"seed": 0, "map": "m", "allocator": {"type": "nearest"}, "robots": 1,
                        "radio": {"loss": 0.0, "comm": "full"}}, "run1", 0.9)
    assert res["malformed_dropped_by"] == {"launcher": 2, "world": 2, "netem": 0}
    assert res["malformed_dropped"] == 4
    assert np.isfinite(res["coverage"])


def test_the_base_writes_only_its_own_keys_and_no_robot_writes_the_bases() -> None:
    assert writes("base") == ["radio/tx/base", "ctl/report/base", "ctl/ready/base"]  # tx: a planner's orders
    assert _may_write("base", K.tx("base")) and not _may_write("r0", K.tx("base"))
    for expr in (K.cmd("r0"), K.tx("r0"), K.report("r0"), K.ready("r0"), K.belief("r0"), K.rx("base"), K.state,
                 K.links, K.stop, K.failed("r0"), K.hello):
        assert not _may_write("base", expr), expr
    for robot in ("r0", "r1"):
        for expr in (K.report("base"), K.ready("base"), K.rx("base"), K.tx("base")):
            assert not _may_write(robot, expr), (robot, expr)
    acl = acl_config("run1", fleet_nodes(robot_ids(2), base=True))
    policy = next(p for p in acl["policies"] if p["subjects"] == ["user base"])
    rules = {r["id"]: r for r in acl["rules"]}
    assert rules["put base"]["key_exprs"] == ["fleet/run1/radio/tx/base", "fleet/run1/ctl/report/base",
                                              "fleet/run1/ctl/ready/base"]
    assert rules["token base"]["key_exprs"] == ["fleet/run1/alive/base/base"]
    assert sorted(policy["rules"]) == ["put base", "token base"]
    assert "base" not in fleet_nodes(robot_ids(2))  # a run without a base has no base user
