"""The relay metrics fold (recording/relaystats.py): from envelope headers only, in any arrival order."""

from __future__ import annotations

import itertools
from collections import Counter

import msgspec

from fleet_emu.core.messages import Envelope, RxBundle, TxBundle
from fleet_emu.recording.relaystats import RelayStats, relay_line


def env(origin: str, seq: int, dst: str, ttl: int, src: str | None = None, kind: str = "pose") -> Envelope:
    return Envelope(src=src or origin, tick=2, seq=seq, origin=origin, dst=dst, ttl=ttl, payload_kind=kind,
                    payload=b"x")


# r0 - r1 - r2: r0's broadcast (ttl 1) reaches r1 at tick 3 and, relayed by r1, r2 at tick 4; r0 hears r1's
# copy back (an echo, not a delivery); r0's message for r2 (ttl 1) is overheard by r1 and relayed, but lost.
B = env("r0", 1, "*", 1)
B1 = msgspec.structs.replace(B, src="r1", ttl=0)
A = env("r0", 2, "r2", 1, kind="map")
A1 = msgspec.structs.replace(A, src="r1", ttl=0)
SAMPLES = [
    TxBundle(src="r0", tick=2, seq=1, msgs=(B, A)),
    TxBundle(src="r1", tick=3, seq=1, msgs=(B1, A1)),
    RxBundle(src="netem", tick=3, seq=1, dst="r1", msgs=(B, A)),
    RxBundle(src="netem", tick=4, seq=2, dst="r2", msgs=(B1,)),
    RxBundle(src="netem", tick=4, seq=3, dst="r0", msgs=(B1,)),
]


def fold(order: tuple) -> dict:
    st = RelayStats(endpoints=3)
    for m in order:
        (st.fold_tx if isinstance(m, TxBundle) else st.fold_rx)(m)
    return st.result()


def test_broadcast_and_addressed_metrics_from_headers() -> None:
    res = fold(tuple(SAMPLES))
    pose, mp = res["pose"], res["map"]
    assert pose == {"sent": 1, "transmissions": 2, "delivered": 2, "delivery_ratio": 1.0, "hops": {"1": 1, "2": 1},
                    "latency_ticks": {"mean": 1.5, "p50": 1.5, "max": 2}, "tx_per_delivered": 1.0}
    assert mp["sent"] == 1 and mp["transmissions"] == 2 and mp["delivered"] == 0 and mp["delivery_ratio"] == 0.0
    assert mp["latency_ticks"] is None and mp["tx_per_delivered"] is None  # overheard by r1: not a delivery
    line = relay_line({"policy": "flood", "ttl": 1, "kinds": res})
    assert line.startswith("relay flood ttl 1: map 0.00") and "pose 1.00 (1.5 hops, 1.5 ticks, 1.00 tx/dlv)" in line


def test_the_fold_does_not_depend_on_arrival_order() -> None:
    want = fold(tuple(SAMPLES))
    assert all(fold(p) == want for p in itertools.permutations(SAMPLES))


def test_a_duplicate_arrival_counts_once_with_its_first_tick() -> None:
    late = RxBundle(src="netem", tick=6, seq=4, dst="r2", msgs=(msgspec.structs.replace(B, src="r1", ttl=0),))
    assert fold((*SAMPLES, late))["pose"] == fold(tuple(SAMPLES))["pose"]


def long_run(horizon: int, ticks: int = 300) -> tuple[RelayStats, dict]:
    """r0 broadcasts every tick (ttl 1); r1 hears it a tick later and relays it; r2 hears the relay at +2,
    except every fifth message, which r2 never gets."""
    st = RelayStats(endpoints=3, horizon=horizon)
    peak = 0
    for t in range(ticks):
        b = Envelope(src="r0", tick=t, seq=t, origin="r0", dst="*", ttl=1, payload_kind="pose", payload=b"x")
        st.fold_tx(TxBundle(src="r0", tick=t, seq=t, msgs=(b,)))
        if t >= 1:
            prev = msgspec.structs.replace(b, tick=t - 1, seq=t - 1)
            st.fold_rx(RxBundle(src="netem", tick=t, seq=2 * t, dst="r1", msgs=(prev,)))
            st.fold_tx(TxBundle(src="r1", tick=t, seq=t, msgs=(msgspec.structs.replace(prev, src="r1", ttl=0),)))
        if t >= 2 and (t - 2) % 5:
            two = msgspec.structs.replace(b, src="r1", tick=t - 2, seq=t - 2, ttl=0)
            st.fold_rx(RxBundle(src="netem", tick=t, seq=2 * t + 1, dst="r2", msgs=(two,)))
        peak = max(peak, len(st.made) + len(st.arrivals))
    return st, {"peak": peak, "result": st.result()}


def test_a_long_run_settles_old_messages_and_gives_the_unbounded_result() -> None:
    _, bounded = long_run(horizon=16)
    _, unbounded = long_run(horizon=10_000)
    assert bounded["result"] == unbounded["result"]
    assert bounded["peak"] <= 3 * 16 and unbounded["peak"] >= 290  # kept: only the last horizon's messages
    pose = bounded["result"]["pose"]
    assert pose["sent"] == 300 and pose["hops"] == {"1": 299, "2": 238}


def test_the_median_of_a_histogram_is_numpys() -> None:
    import numpy as np

    from fleet_emu.recording.relaystats import median

    rng = np.random.default_rng(3)
    for n in (1, 2, 5, 10, 101):
        values = rng.integers(0, 6, n)
        assert median(Counter(values.tolist())) == float(np.percentile(values, 50))
