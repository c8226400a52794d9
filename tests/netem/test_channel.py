"""The channel's delivery, loss and counting rules, with a seeded generator."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import msgspec
import numpy as np
import pytest

from fleet_emu.agents.protocol import PoseBeacon
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.grid import MapData
from fleet_emu.core.messages import Envelope, RadioMsg, WorldState, seal
from fleet_emu.core.radio import RadioConfig
from fleet_emu.core.scenario import Scenario
from fleet_emu.netem.channel import Channel, radio_tick
from fleet_emu.netem.node import NetemNode

ROBOTS = ("r0", "r1", "r2")


def _beacon(src: str, dst: str = "*", tick: int = 0) -> Envelope:
    return seal(RadioMsg(PoseBeacon(cell=(0, 0)), dst=dst), src, tick, 1)


def test_broadcast_follows_links_and_arrives_next_tick() -> None:
    link = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], dtype=bool)
    ch = Channel(loss=0.0, rng=np.random.default_rng(0))
    ch.transmit(0, ROBOTS, link, {"r0": (_beacon("r0"),), "r1": (_beacon("r1", dst="r2"),)})
    assert ch.deliver(0) == {}
    got = ch.deliver(1)
    assert [m.src for m in got["r1"]] == ["r0"]
    assert [m.src for m in got["r2"]] == ["r1"]  # unicast reaches only its destination
    assert "r0" not in got
    c = ch.counters
    assert (c.sent, c.delivered, c.dropped_signal, c.dropped_loss) == (3, 2, 1, 0)
    assert c.sent == c.delivered + c.dropped_loss + c.dropped_signal
    assert c.bytes_sent > 0
    assert ch.deliver(1) == {}  # delivered once


def test_loss_is_seeded_and_close_to_its_probability() -> None:
    link = ~np.eye(3, dtype=bool)

    def run(seed: int) -> tuple[int, int]:
        ch = Channel(loss=0.3, rng=np.random.default_rng(seed), latency=2)
        for t in range(500):
            ch.transmit(t, ROBOTS, link, {r: (_beacon(r, tick=t),) for r in ROBOTS})
        assert ch.deliver(1) == {} and ch.deliver(2)  # latency 2
        return ch.counters.delivered, ch.counters.dropped_loss

    a, b = run(1), run(1)
    assert a == b != run(2)
    delivered, lost = a
    assert abs(lost / (delivered + lost) - 0.3) < 0.03


def test_all_or_nothing_loss() -> None:
    link = ~np.eye(3, dtype=bool)
    for loss, expect in ((0.0, 6), (1.0, 0)):
        ch = Channel(loss=loss, rng=np.random.default_rng(0))
        ch.transmit(0, ROBOTS, link, {r: (_beacon(r),) for r in ROBOTS})
        assert ch.counters.delivered == expect


def test_payloads_are_opaque_to_the_channel() -> None:
    """netem routes by the envelope alone: a payload of a kind it never heard of, not even msgpack, arrives
    byte for byte."""
    odd = Envelope(src="r0", tick=0, seq=3, origin="r0", dst="r2", ttl=0, payload_kind="plugin_msg",
                   payload=b"\xc1 not msgpack")
    ch = Channel(loss=0.0, rng=np.random.default_rng(0))
    ch.transmit(0, ROBOTS, np.ones((3, 3), dtype=bool), {"r0": (odd,)})
    assert ch.deliver(1) == {"r2": [odd]}
    assert ch.counters.bytes_sent == len(odd.encode())


def test_netem_imports_no_robot_protocol() -> None:
    code = ("import sys, fleet_emu.netem.node; "
            "print(sorted(m for m in sys.modules if m.startswith('fleet_emu.agents')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_the_base_station_hears_broadcasts_and_leaves_the_robots_deliveries_as_they_were() -> None:
    """The base is a receiver like a robot (linked: it hears a broadcast; a unicast to a robot is not for it),
    and its draws come from a generator of its own: the robots get the same messages with or without it."""
    robots_link = np.array([[0, 1, 1], [1, 0, 1], [1, 1, 0]], dtype=bool)
    with_base = np.zeros((4, 4), dtype=bool)
    with_base[:3, :3] = robots_link
    with_base[0, 3] = with_base[3, 0] = True  # only r0 reaches the base
    nodes = (*ROBOTS, "base")

    def bundles(t: int) -> dict[str, tuple[Envelope, ...]]:
        return {"r0": (_beacon("r0", tick=t),), "r1": (_beacon("r1", tick=t), _beacon("r1", "r2", t)),
                "r2": (_beacon("r2", tick=t),)}

    plain = Channel(loss=0.3, rng=np.random.default_rng(5))
    based = Channel(loss=0.3, rng=np.random.default_rng(5), base_rng=np.random.default_rng(6))
    heard = 0
    for t in range(40):
        plain.transmit(t, ROBOTS, robots_link, bundles(t))
        based.transmit(t, nodes, with_base, bundles(t))
        a, b = plain.deliver(t + 1), based.deliver(t + 1)
        assert {r: [(m.src, m.seq, m.dst) for m in a.get(r, [])] for r in ROBOTS} == \
            {r: [(m.src, m.seq, m.dst) for m in b.get(r, [])] for r in ROBOTS}
        assert all(m.src == "r0" and m.dst == "*" for m in b.get("base", []))
        heard += len(b.get("base", []))
    assert 15 < heard < 40  # r0's 40 broadcasts, about 30 % lost
    assert based.counters.sent == plain.counters.sent + 3 * 40  # the base is an intended receiver of 3 broadcasts


def test_a_radio_tick_publishes_the_links_then_each_endpoint_s_rx_bundle() -> None:
    """netem's messages of a tick (both engines build them with ``radio_tick``): the links of the live robots in
    robot order and the base, drawn first from netem's counter, then one rx bundle per endpoint with what is due;
    none once the run is over."""
    occupied = np.zeros((6, 6), dtype=bool)
    ch = Channel(loss=0.0, rng=np.random.default_rng(0), base_rng=np.random.default_rng(1))
    ch.transmit(0, ("r0", "r2", "base"), np.ones((3, 3), dtype=bool), {"r0": (_beacon("r0"),)})
    counter = iter(range(1, 100))
    state = WorldState(src="world", tick=1, seq=0, poses={"r0": (0, 0), "r1": (5, 5), "r2": (1, 1)},
                       live=("r2", "r0"), coverage=0.1, path_length={})
    tick = radio_tick(ch, occupied, ROBOTS, (2, 2), 0.5, RadioConfig(comm="full"), state, lambda: next(counter), 4)
    assert tick.nodes == ("r0", "r2", "base") and tick.link.shape == (3, 3)
    assert (tick.links.tick, tick.links.seq, tick.links.robots, tick.links.dropped) == (1, 1, ("r0", "r2"), 4)
    assert tick.links.base_link is not None and tick.links.sent == 2
    assert [(b.dst, b.seq, b.tick, [m.src for m in b.msgs]) for b in tick.rx] == \
        [("r0", 2, 1, []), ("r2", 3, 1, ["r0"]), ("base", 4, 1, ["r0"])]
    over = radio_tick(ch, occupied, ROBOTS, None, 0.5, RadioConfig(comm="full"),
                      msgspec.structs.replace(state, tick=2, done=True), lambda: next(counter), 0)
    assert over.rx == () and over.nodes == ("r0", "r2") and over.links.seq == 5


def test_netem_takes_the_base_cell_exactly_when_the_scenario_has_a_base(tmp_path: Path) -> None:
    """The launcher resolves the base station's cell and passes it on (``--base-cell``): a netem given none for
    a scenario with a base, or one for a scenario without, refuses to start, in one line."""
    md = MapData("open", np.zeros((6, 6), dtype=np.int8), 0.5, (1, 1))
    with_base = Scenario().override(robots=1, base=True)
    with pytest.raises(ConfigError, match="--base-cell"):
        NetemNode(with_base, "run", md)
    with pytest.raises(ConfigError, match="--base-cell"):
        NetemNode(Scenario().override(robots=1), "run", md, base=(1, 1))
    (tmp_path / "s.json").write_text(json.dumps(with_base.to_dict()))
    md.save(tmp_path / "map.npz")
    proc = subprocess.run([sys.executable, "-m", "fleet_emu.netem", "--run", "x", "--connect", "tcp/127.0.0.1:9",
                           "--scenario", str(tmp_path / "s.json"), "--map-file", str(tmp_path / "map.npz")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "--base-cell" in proc.stderr
