"""The bandwidth-limited medium (netem/medium.py): capacity per tick and per medium, queues, airtime over several
ticks, the order of service, delay; and on the memory engine, a limited run's per-tick links."""

from __future__ import annotations

import numpy as np
import pytest

from fleet_emu.agents.protocol import MapDelta, PoseBeacon
from fleet_emu.core.messages import Envelope, Links, Message, RadioMsg, TxBundle, expand, seal
from fleet_emu.core.radio import RadioConfig
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet
from fleet_emu.netem.channel import make_channel
from fleet_emu.netem.medium import components

ROBOTS = ("r0", "r1", "r2")
FULL = ~np.eye(3, dtype=bool)


def _beacon(src: str, tick: int = 0, seq: int = 1) -> Envelope:
    return seal(RadioMsg(PoseBeacon(cell=(0, 0))), src, tick, seq)


def _delta(src: str, cells: int, tick: int = 0, seq: int = 1) -> Envelope:
    body = MapDelta(cells=np.arange(cells, dtype=np.int32), values=np.zeros(cells, dtype=np.int8))
    return seal(RadioMsg(body), src, tick, seq)


def _channel(bandwidth: float, queue_bytes: int = 1_000_000, latency: int = 1, jitter: int = 0, seed: int = 0):
    radio = RadioConfig(comm="full", loss=0.0, bandwidth=bandwidth, queue_bytes=queue_bytes, latency=latency,
                        jitter=jitter)
    return make_channel(seed, radio, 1.0)


def test_media_are_the_link_graphs_components() -> None:
    link = np.zeros((5, 5), dtype=bool)
    for i, j in ((0, 2), (2, 4), (1, 3)):
        link[i, j] = link[j, i] = True
    assert components(link) == [[0, 2, 4], [1, 3]]
    assert components(np.zeros((2, 2), dtype=bool)) == [[0], [1]]


def test_a_medium_never_carries_more_than_its_capacity_and_queues_the_rest() -> None:
    ch = _channel(bandwidth=8.0)  # 1000 bytes a tick
    beacon = len(_beacon("r0").encode())
    per_tick = 1000 // beacon
    for t in range(6):
        ch.transmit(t, ROBOTS, FULL, {r: tuple(_beacon(r, t, s) for s in range(10)) for r in ROBOTS})
        m = ch.medium
        assert m is not None and sum(m.load) <= 1000 and m.load[0] == per_tick * beacon
    assert ch.counters.bytes_sent == m.airtime_bytes == 6 * per_tick * beacon
    assert m.queued_max_bytes > 10 * beacon  # the queues grew: 30 beacons offered a tick, fewer carried


def test_two_media_each_have_the_capacity() -> None:
    ch = _channel(bandwidth=8.0)
    link = np.zeros((3, 3), dtype=bool)  # three media: nobody hears anybody
    ch.transmit(0, ROBOTS, link, {r: tuple(_beacon(r, 0, s) for s in range(40)) for r in ROBOTS})
    m = ch.medium
    assert m is not None and len(m.load) == 3 and all(0 < x <= 1000 for x in m.load)
    assert m.medium_of == {"r0": 0, "r1": 1, "r2": 2}


def test_a_message_longer_than_a_tick_takes_several_ticks_of_airtime() -> None:
    ch = _channel(bandwidth=8.0)  # 1000 bytes a tick
    big = _delta("r0", 500)  # about 2.5 kB
    size = len(big.encode())
    assert 2000 < size < 3000
    ch.transmit(0, ROBOTS, FULL, {"r0": (big,)})
    ticks = 1
    while not ch.counters.sent:
        ch.transmit(ticks, ROBOTS, FULL, {})
        ticks += 1
    assert ticks == 3  # on the air at ticks 0, 1 and 2
    assert ch.deliver(3)["r1"] == [big] and ch.counters.delay == {3: 1}  # handed at 0, delivered at 3


def test_beacons_go_before_queued_map_data() -> None:
    ch = _channel(bandwidth=8.0)
    deltas = tuple(_delta("r0", 100, 0, s) for s in range(5))  # about 600 bytes each
    ch.transmit(0, ROBOTS, FULL, {"r0": deltas})
    assert [m.seq for m in ch.deliver(1)["r1"]] == [0]  # one delta a tick fits
    ch.transmit(1, ROBOTS, FULL, {"r0": (_beacon("r0", 1, 9),)})
    got = ch.deliver(2)["r1"]  # the beacon, handed after the deltas, went first: behind them it would wait
    assert [m.seq for m in got if m.payload_kind == "pose"] == [9] and len(got) == 2  # ... and one delta
    later = []
    for t in range(2, 8):
        ch.transmit(t, ROBOTS, FULL, {})
        later += [m.seq for m in ch.deliver(t + 1).get("r1", [])]
    assert sorted([m.seq for m in got if m.payload_kind == "map"] + later) == [1, 2, 3, 4]


def test_a_full_queue_drops_the_tail() -> None:
    ch = _channel(bandwidth=8.0, queue_bytes=1500)
    deltas = tuple(_delta("r0", 100, 0, s) for s in range(5))
    ch.transmit(0, ROBOTS, FULL, {"r0": deltas})
    m = ch.medium
    assert m is not None and m.dropped_queue == 3 and m.queued_max_bytes <= 1500


def test_the_order_of_service_and_the_jitter_are_seeded() -> None:
    def run(seed: int) -> list[tuple[str, int]]:
        ch = _channel(bandwidth=2.0, jitter=3, seed=seed)  # 250 bytes: a few beacons a tick
        for t in range(20):
            ch.transmit(t, ROBOTS, FULL, {r: (_beacon(r, t),) for r in ROBOTS})
        return [(m.src, t) for t in range(40) for m in ch.deliver(t).get("r0", [])]

    a = run(1)
    assert a == run(1) != run(2)
    assert len({t for _, t in a}) > 1


def test_an_unlimited_radio_builds_no_medium() -> None:
    assert _channel(bandwidth=0.0).medium is None
    assert _channel(bandwidth=0.0, jitter=2).medium is not None


@pytest.fixture(scope="module")
def limited_links(small_map) -> tuple[list[Links], dict]:
    """A memory run at 16 kbit/s on the full radio (2000 bytes a tick), and every links message it published."""
    links: list[Links] = []
    maps: list[Envelope] = []

    def tap(_key: str, msg: Message, _ns: int) -> None:
        if isinstance(msg, Links):
            links.append(msg)
        elif isinstance(msg, TxBundle):
            maps.extend(e for e in msg.msgs if e.payload_kind == "map")

    s = Scenario().override(map=str(small_map), robots=3, comm="full", bandwidth=16.0, seed=1, max_ticks=120)
    res = Fleet(s, tap=tap).run().data
    assert len(maps) > 20 and all(expand(e.payload) != e.payload for e in maps)  # map data goes compact
    return links, res


def test_bytes_on_the_air_per_tick_never_exceed_a_medium_capacity(limited_links) -> None:
    links, res = limited_links
    loads = [lk.medium_load for lk in links if lk.medium_load]
    assert len(loads) > 10 and all(lk.medium_capacity == 2000 for lk in links[1:])
    assert all(len(load) == 1 and load[0] <= 2000 for load in loads)  # the full radio: one medium
    assert max(load[0] for load in loads) > 1000  # the limit was felt
    radio = res["radio"]
    assert radio["airtime_bytes"] >= radio["bytes_sent"] > 0 and radio["queued_max_bytes"] > 0
    assert radio["delay_ticks"]["max"] > 1 and res["scenario"]["radio"]["bandwidth"] == 16.0


def test_a_limit_that_never_binds_gives_the_unlimited_run(small_map) -> None:
    """Messages on the air in their own tick are sent in the unlimited radio's order (sender, then bundle): the
    same loss draws and deliveries, so only the queue's size and the bytes (map data deflated) tell the runs
    apart."""
    from fleet_emu.launch.result import deterministic

    s = Scenario().override(map=str(small_map), robots=3, allocator="trade", seed=2, max_ticks=80)
    free, wide = (deterministic(Fleet(x).run().data) for x in (s, s.override(bandwidth=1e6)))
    assert free["radio"].pop("queued_max_bytes") == 0 < wide["radio"].pop("queued_max_bytes")
    for key in ("bytes_sent", "airtime_bytes"):
        assert free["radio"].pop(key) > wide["radio"].pop(key) > 0
    assert free.pop("scenario") != wide.pop("scenario")  # the bandwidth
    assert free == wide and free["radio"]["dropped_loss"] > 0
