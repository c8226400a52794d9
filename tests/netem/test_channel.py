"""The channel's delivery, loss and counting rules, with a seeded generator."""

from __future__ import annotations

import numpy as np

from fleet_emu.core.messages import PoseBeacon
from fleet_emu.netem.channel import Channel

ROBOTS = ("r0", "r1", "r2")


def _beacon(src: str, dst: str = "*", tick: int = 0) -> PoseBeacon:
    return PoseBeacon(src=src, tick=tick, seq=1, dst=dst, ttl=0, cell=(0, 0))


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
