"""What a credential holder can do to a run on a router that serves any run (``fleet router-config``'s default
``--run-id '*'``), tried with real sessions against a real fleet: it reads the run's nonce off the bus, as
anyone allowed to subscribe can. Its messages in its own robot's name are checked like any other: a second one
for a tick is dropped and counted (first wins), never a silent replacement (docs/design/security.md)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest
import zenoh

from fleet_emu.agents.protocol import MapDelta
from fleet_emu.core.access import Credential, read_dictionary
from fleet_emu.core.bus import client_config, router_locators
from fleet_emu.core.codec import decode
from fleet_emu.core.grid import MapData
from fleet_emu.core.messages import RadioMsg, TxBundle, WorldState, seal
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.result import deterministic
from fleet_emu.launch.router_config import router_config_text
from fleet_emu.netem.node import NetemNode
from tests.harness.cli import result, run_cli
from tests.harness.procs import wait_for

RUN = "insider"


def _second_bundles(endpoint: str, users: Path, until: threading.Event, sent: list[int], last: int) -> None:
    """As r0's credential holder: a second tx bundle of r0 for each tick (walls where r0 saw floor), carrying
    the nonce read off the bus, put once the world's state two ticks later shows that netem has sent that tick
    (a bundle of a tick still open may come first or second: first wins, ``test_netem_keeps_the_first``).
    None is put on a state after tick ``last``, so that every put reaches netem before the run ends, however
    late this thread runs on a loaded machine."""
    cred = Credential("r0", read_dictionary(users.read_text())["r0"])
    walls = MapDelta(cells=np.arange(300, dtype=np.int64), values=np.full(300, 100, dtype=np.int8))
    with zenoh.open(client_config(endpoint, cred)) as s:
        def on_state(sample: zenoh.Sample) -> None:
            st = decode(sample.payload.to_bytes(), expected=WorldState)
            att, t = sample.attachment, st.tick - 2
            if t < 0 or st.done or st.tick > last:
                return
            fake = TxBundle(src="r0", tick=t, seq=10**6 + t, msgs=(seal(RadioMsg(walls), "r0", t, 10**6 + t),))
            s.put(f"fleet/{RUN}/radio/tx/r0", fake.encode(), attachment=att.to_bytes() if att is not None else None)
            sent.append(t)

        sub = s.declare_subscriber(f"fleet/{RUN}/world/state", on_state)
        until.wait(300)
        sub.undeclare()


@pytest.mark.slow  # an insider over processes; an attack by default
def test_a_second_bundle_in_a_robots_name_is_dropped_and_counted(small_map: Path, tmp_path: Path) -> None:
    users = tmp_path / "users.txt"
    scenario = ["--map", str(small_map), "--robots", "2", "--seed", "3", "--loss", "0.2", "--quiet"]
    code, _, err = run_cli(["run", *scenario, "--engine", "memory", "--no-record", "--out", str(tmp_path / "base")])
    assert code in (0, 3), err
    last = result(tmp_path / "base")["ticks"] - 8  # the attacked run is the same run (asserted below)
    conf = zenoh.Config.from_json5(router_config_text(3, users, listen="tcp/127.0.0.1:0"))
    conf.insert_json5("adminspace/enabled", "true")  # to read back the port the OS chose
    with zenoh.open(conf) as router:
        conf_endpoint = router_locators(router)[0]
        until, sent = threading.Event(), list[int]()
        attacker = threading.Thread(target=_second_bundles, args=(conf_endpoint, users, until, sent, last),
                                    daemon=True)
        attacker.start()
        _, _, err = run_cli(["run", *scenario, "--connect", conf_endpoint, "--credentials", str(users),
                             "--run-id", RUN, "--out", str(tmp_path / "attacked")], check=True)
        until.set()
        attacker.join(30)
    base, attacked = result(tmp_path / "base"), result(tmp_path / "attacked")
    assert len(sent) > 10
    # every second bundle was dropped and counted, by netem alone
    assert attacked["malformed_dropped"] == attacked["malformed_dropped_by"]["netem"] == len(sent), \
        (attacked["malformed_dropped_by"], len(sent))
    same = {k: v for k, v in deterministic(attacked).items() if not k.startswith("malformed_dropped")}
    assert same == {k: v for k, v in deterministic(base).items() if not k.startswith("malformed_dropped")}, \
        err[-2000:]  # r0's own bundle (the first) was the one sent


def test_netem_keeps_the_first_bundle_of_a_sender_and_tick() -> None:
    node = NetemNode(Scenario().override(robots=2), "x", MapData("open", np.zeros((6, 6), dtype=np.int8), 0.5,
                                                                  (1, 1)))
    first, second = (TxBundle(src="r0", tick=3, seq=s, msgs=()) for s in (1, 2))
    node._keep_tx("fleet/x/radio/tx/r0", first)
    node._keep_tx("fleet/x/radio/tx/r0", second)
    assert node.tx[3]["r0"] is first and node.dropped == 1
    node.sent_tick = 3
    node._keep_tx("fleet/x/radio/tx/r0", TxBundle(src="r0", tick=2, seq=3, msgs=()))
    assert 2 not in node.tx and node.dropped == 2


def _heard_puts(run_id: str, tmp_path: Path, user: str, keys: list[str]) -> list[str]:
    """The keys of ``keys`` (under ``fleet/``) that a session of ``user`` got past a router made by
    ``fleet router-config --run-id run_id``, as heard by the router itself."""
    users = tmp_path / f"users-{run_id.strip('*') or 'any'}.txt"
    conf = zenoh.Config.from_json5(router_config_text(2, users, listen="tcp/127.0.0.1:0", run_id=run_id))
    conf.insert_json5("adminspace/enabled", "true")
    got: list[str] = []
    with zenoh.open(conf) as router:
        endpoint = router_locators(router)[0]
        sub = router.declare_subscriber("fleet/**", lambda s: got.append(str(s.key_expr)))
        cred = Credential(user, read_dictionary(users.read_text())[user])
        with zenoh.open(client_config(endpoint, cred)) as s:
            for k in keys:
                s.put(f"fleet/{k}", b"x")
            wait_for(lambda: len(got) >= 1, 10)
            time.sleep(0.5)
        sub.undeclare()
    return sorted(k.removeprefix("fleet/") for k in got)


def test_a_credential_reaches_every_run_on_an_any_run_router_and_one_run_on_a_per_run_one(tmp_path: Path) -> None:
    keys = ["a/radio/tx/r0", "b/radio/tx/r0", "a/radio/tx/r1", "a/ctl/stop", "b/ctl/stop"]
    assert _heard_puts("*", tmp_path, "r0", keys) == ["a/radio/tx/r0", "b/radio/tx/r0"]
    assert _heard_puts("a", tmp_path, "r0", keys) == ["a/radio/tx/r0"]
    assert _heard_puts("*", tmp_path, "world", keys) == ["a/ctl/stop", "b/ctl/stop"]
    assert _heard_puts("a", tmp_path, "world", keys) == ["a/ctl/stop"]


def test_per_run_logins_act_on_their_own_run_only_and_run_a_fleet(small_map: Path, tmp_path: Path) -> None:
    """``fleet router-config --run-id a --run-id b``: run ``a``'s users file holds only run ``a``'s logins;
    its world can stop run ``a``, not run ``b``; a fleet runs with it as run ``a``, and not as run ``b``."""
    users = tmp_path / "users.txt"
    conf = zenoh.Config.from_json5(router_config_text(2, users, listen="tcp/127.0.0.1:0", run_id=["a", "b"]))
    conf.insert_json5("adminspace/enabled", "true")
    mine = tmp_path / "users-a.txt"
    assert oct(mine.stat().st_mode & 0o777) == "0o600"
    logins = read_dictionary(mine.read_text())
    assert logins and all(u.startswith("a.") for u in logins) and "a.world" in logins
    assert set(logins) < set(read_dictionary(users.read_text()))
    got: list[str] = []
    with zenoh.open(conf) as router:
        endpoint = router_locators(router)[0]
        sub = router.declare_subscriber("fleet/**", lambda s: got.append(str(s.key_expr)))
        with zenoh.open(client_config(endpoint, Credential("a.world", logins["a.world"]))) as s:
            for k in ("a/ctl/stop", "b/ctl/stop"):
                s.put(f"fleet/{k}", b"x")
            wait_for(lambda: got, 10)
            time.sleep(0.5)
        sub.undeclare()
        assert got == ["fleet/a/ctl/stop"]
        scenario = ["--map", str(small_map), "--robots", "2", "--seed", "3", "--quiet", "--in-process",
                    "--connect", endpoint, "--credentials", str(mine)]
        code, _, err = run_cli(["run", *scenario, "--run-id", "b", "--out", str(tmp_path / "b")])
        assert code == 2 and "holds the logins of run id a: add --run-id a" in err, err
        run_cli(["run", *scenario, "--run-id", "a", "--out", str(tmp_path / "a")], check=True)
    res = result(tmp_path / "a")
    assert res["authenticated"] is True and res["ticks"] > 0
