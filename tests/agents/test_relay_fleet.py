"""Relaying in the robots: real brains, the real world and netem channel, stepped by the memory
engine on a drawn corridor where a disk radio links only neighbours, every robot held on its cell.

    r0 - r1 - r2 - r3 - r4      (4 cells apart, range 2.5 m = 5 cells: only neighbours are linked)
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from fleet_emu.core.grid import STAY, MapData, from_ascii
from fleet_emu.core.messages import Envelope, Message, RxBundle, TxBundle
from fleet_emu.core.radio import RadioConfig
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet

CORRIDOR = """
##############################
#0...1...2...3...4...........#
##############################
"""

#: Decides whether one envelope in a tx bundle is lost before netem: (tick, sender, envelope) -> lost.
Drop = Callable[[int, str, Envelope], bool]


class Chain:
    """The fleet, its rx log ``(tick, receiver, envelope)`` and tx log ``(tick, sender, envelope)``."""

    def __init__(self, relay: str = "flood", ttl: int = 3, drop: Drop | None = None, ticks: int = 8,
                 routes: dict[str, str] | None = None) -> None:
        grid, marks = from_ascii(CORRIDOR)
        self.scenario = Scenario(name="chain", map="drawn", cell_size=0.5, robots=len(marks), sensor_range=0.5,
                                 allocator={"type": "nearest"}, radio=RadioConfig(comm="disk", comm_range=2.5,
                                                                                  loss=0.0),
                                 target_coverage=1.0, max_ticks=100, relay=relay, relay_ttl=ttl)
        self.rx: list[tuple[int, str, Envelope]] = []
        self.tx: list[tuple[int, str, Envelope]] = []
        self.fleet = Fleet(self.scenario, tap=self._tap, map_data=MapData("drawn", grid, 0.5, marks["r0"]),
                           starts=marks)
        self.fleet.reset()
        if routes is not None:
            for b in self.fleet.brains.values():
                assert b.relay is not None
                b.relay.set_routes(routes)
        if drop is not None:
            transmit = self.fleet.channel.transmit

            def lossy(tick: int, robots: tuple[str, ...], link: np.ndarray,
                      bundles: dict[str, tuple[Envelope, ...]]) -> None:
                kept = {r: tuple(e for e in msgs if not drop(tick, r, e)) for r, msgs in bundles.items()}
                transmit(tick, robots, link, kept)
            self.fleet.channel.transmit = lossy  # type: ignore[method-assign]
        for _ in range(ticks):
            self.fleet.step(dict.fromkeys(self.fleet.agents, STAY))

    def _tap(self, _key: str, msg: Message, _ns: int) -> None:
        if isinstance(msg, RxBundle):
            self.rx += [(msg.tick, msg.dst, e) for e in msg.msgs]
        elif isinstance(msg, TxBundle):
            self.tx += [(msg.tick, msg.src, e) for e in msg.msgs]

    def arrivals(self, origin: str, seq: int, robot: str) -> list[tuple[int, Envelope]]:
        return [(t, e) for t, r, e in self.rx if r == robot and e.origin == origin and e.seq == seq]

    def beacon(self, origin: str, tick: int = 0) -> int:
        """The seq of the pose beacon ``origin`` made at ``tick`` (the first envelope it sends)."""
        return next(e.seq for t, r, e in self.tx if t == tick and r == origin and e.origin == origin
                    and e.payload_kind == "pose")


def test_a_broadcast_crosses_a_chain_of_three_relays() -> None:
    run = Chain()
    seq = run.beacon("r0")
    (tick, env), = run.arrivals("r0", seq, "r4")[:1]
    assert tick == 4 and env.src == "r3" and env.ttl == 0  # four links, one tick each, the last by r3
    assert [e.src for _, e in run.arrivals("r0", seq, "r4")] == ["r3"]  # r4 hears only its neighbour
    assert run.fleet.brains["r0"].teammates["r4"].cell == (1, 17)  # and r4's came the other way
    assert run.fleet.brains["r4"].teammates["r0"].cell == (1, 1)  # the relayed beacon reached r4's brain


def test_an_addressed_message_crosses_the_chain_and_only_its_dst_delivers_it() -> None:
    run = Chain(ticks=12)
    # r0 hears r4's first beacon at tick 4 and answers it with its whole map, addressed to r4
    to_r4 = [e for t, r, e in run.tx if r == "r0" and e.origin == "r0" and e.dst == "r4"]
    assert to_r4, "r0 sent nothing addressed to r4"
    first = to_r4[0]
    got = run.arrivals("r0", first.seq, "r4")
    assert got and got[0][1].src == "r3"
    kinds = run.fleet.result().data["relay"]["kinds"]
    assert kinds["map"]["delivered"] >= 1


def test_duplicates_are_dropped_each_robot_forwards_a_message_once() -> None:
    run = Chain()
    seq = run.beacon("r2")
    forwards = [r for _, r, e in run.tx if e.origin == "r2" and e.seq == seq and r != "r2"]
    assert sorted(forwards) == ["r0", "r1", "r3", "r4"]  # each once, though r1 and r3 hear it back from r0, r4
    heard = [r for _, r, e in run.rx if e.origin == "r2" and e.seq == seq]
    assert heard.count("r1") == 2 and heard.count("r2") == 2  # the copies that came back were not sent on again


def test_the_hop_limit_holds() -> None:
    run = Chain(ttl=2)  # three links: r0 -> r3, not r4
    seq = run.beacon("r0")
    assert run.arrivals("r0", seq, "r3")
    assert not run.arrivals("r0", seq, "r4")
    assert not [r for _, r, e in run.tx if e.origin == "r0" and e.seq == seq and r == "r3"]  # r3 sent it no further


def test_a_lost_hop_loses_the_message() -> None:
    state: dict[str, int] = {}

    def drop(tick: int, r: str, env: Envelope) -> bool:  # r2's forward of r0's first beacon: no other way on
        return r == "r2" and env.origin == "r0" and env.seq == state.setdefault("seq", 1)

    run = Chain(drop=drop)
    seq = run.beacon("r0")
    assert seq == 1
    assert run.arrivals("r0", seq, "r2")
    assert not run.arrivals("r0", seq, "r3") and not run.arrivals("r0", seq, "r4")


def test_tree_forwards_only_on_the_routes_and_nothing_without_them() -> None:
    chain = {"r4": "r3", "r3": "r2", "r2": "r1", "r1": "r0"}
    run = Chain(relay="tree", routes=chain)
    seq = run.beacon("r0")
    assert run.arrivals("r0", seq, "r4")  # broadcast: every robot with a child forwards
    bare = Chain(relay="tree")
    assert not [e for _, r, e in bare.tx if e.origin != r]  # no routes: nothing forwarded


def test_result_relay_block_counts_from_headers() -> None:
    run = Chain()
    relay = run.fleet.result().data["relay"]
    assert relay["policy"] == "flood" and relay["ttl"] == 3
    b = relay["kinds"]["pose"]
    assert set(b["hops"]) == {"1", "2", "3", "4"}
    assert 0 < b["delivery_ratio"] <= 1 and b["tx_per_delivered"] >= 1
    assert b["latency_ticks"]["max"] == 4 and b["latency_ticks"]["mean"] >= 1


def test_relay_none_keeps_the_scenario_and_result_as_before() -> None:
    assert "relay" not in Scenario().to_dict() and "relay_ttl" not in Scenario().to_dict()
    run = Chain(relay="none", ttl=0, ticks=3)
    assert "relay" not in run.fleet.result().data
    assert all(e.ttl == 0 and e.origin == r for _, r, e in run.tx)


@pytest.mark.parametrize("bad", [{"relay": "mesh"}, {"relay_ttl": -1}, {"relay_ttl": 99}])
def test_a_bad_relay_setting_is_a_config_error(bad: dict) -> None:
    from fleet_emu.core.errors import ConfigError
    with pytest.raises(ConfigError, match="relay"):
        Scenario(**bad).validate()
