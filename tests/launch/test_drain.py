"""The launcher's listener: a subscriber drained from Zenoh's FIFO channel into the consumer's queue, over a real
router and two real sessions (no Python runs on Zenoh's threads)."""

from __future__ import annotations

import queue

import zenoh

from fleet_emu.core.bus import client_config, router_config, router_locators
from fleet_emu.core.keys import Keys
from fleet_emu.launch.watch import Drain


def test_every_sample_reaches_the_queue_in_order_and_undeclaring_ends_the_thread() -> None:
    keys = Keys("drain")
    samples: queue.Queue = queue.Queue()
    with zenoh.open(router_config()) as router:
        endpoint = router_locators(router)[0]
        with zenoh.open(client_config(endpoint)) as listener, zenoh.open(client_config(endpoint)) as robot:
            drain = Drain(listener, keys.all, samples)
            other = Drain(listener, f"{keys.all}/nothing", samples)  # matches nothing: ends empty
            pub = robot.declare_publisher(keys.cmd("r0"), congestion_control=zenoh.CongestionControl.BLOCK)
            got: list[tuple[str, bytes, int]] = []
            for _ in range(200):  # until the subscriber's declaration has reached the router
                pub.put(b"hello")
                try:
                    got.append(samples.get(timeout=0.05))
                    break
                except queue.Empty:
                    continue
            assert got, "the subscriber was never matched"
            payloads = [i.to_bytes(4, "big") + bytes(i % 7) * 1000 for i in range(3000)]
            for p in payloads:
                pub.put(p)
            pub.put(b"last")
            while got[-1][1] != b"last":
                got.append(samples.get(timeout=10))
            drain.undeclare()
            other.undeclare()
            pub.undeclare()
    assert not drain.is_alive() and not other.is_alive()
    data = [d for _, d, _ in got if d not in (b"hello", b"last")]
    assert data == payloads  # none lost, none reordered, bytes intact
    assert {k for k, _, _ in got} == {keys.cmd("r0")}
    stamps = [t for _, _, t in got]
    assert stamps == sorted(stamps)
