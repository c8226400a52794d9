"""What each allocator puts on the radio: bytes per robot-tick by kind, on the memory engine.

    python -m benchmarks.radio [--map office] [--robots 4] [--seeds 2] [--bandwidth 0] [--comm wall]
        [--loss 0.1] [--allocators nearest greedy ...] [--max-ticks 3000]

Per allocator, the mean over the seeds of one run each: the ticks it took, and the bytes its robots handed to
the radio per robot-tick (each message once, its whole envelope: what a bandwidth-limited medium charges) split
by kind: map data (``map`` deltas and ``mapfill`` recoveries), beacons (``pose``) and protocol messages (the
allocator's own: auctions, assignments, orders). ``compact`` is the map data's size in its compact form (cells
delta-coded, then deflated: ``fleet_emu.core.messages.compact``, as a limited radio sends it) as a share of its
plain size: what the compact form saves, or on an unlimited radio (which sends plain payloads) would save. With
``--bandwidth`` the radio is limited (kbit/s), map data goes compact, and the last columns give the run's delay
(ticks, mean and max) and its queue drops.
"""

from __future__ import annotations

import statistics
import sys
from collections import Counter

from benchmarks._common import fail, machine, parser
from fleet_emu.agents.allocators import allocator_names
from fleet_emu.core.errors import FleetError
from fleet_emu.core.messages import Message, TxBundle, compact, expand
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.checks import check
from fleet_emu.launch.memory import Fleet

ALLOCATORS = ("nearest", "greedy", "minpos", "trade", "hungarian", "connectivity")
MAP_KINDS = frozenset({"map", "mapfill"})


def kind_of(payload_kind: str) -> str:
    """The column a payload kind counts in: ``map``, ``beacons`` or ``protocol``."""
    return "map" if payload_kind in MAP_KINDS else "beacons" if payload_kind == "pose" else "protocol"


def measure(scenario: Scenario) -> dict[str, float]:
    """One run: its ticks, the bytes per robot-tick by kind, the deflated map bytes, and the radio's delay."""
    sizes: Counter[str] = Counter()
    robot_ticks = 0

    def tap(_key: str, msg: Message, _ns: int) -> None:
        nonlocal robot_ticks
        if isinstance(msg, TxBundle):
            robot_ticks += 1
            for env in msg.msgs:
                kind = kind_of(env.payload_kind)
                sizes[kind] += len(env.encode())
                if kind == "map":
                    head = len(env.encode()) - len(env.payload)
                    plain = expand(env.payload)
                    sizes["plain"] += head + len(plain)
                    sizes["compact"] += head + len(compact(plain))

    res = Fleet(scenario, tap=tap).run()
    per = max(robot_ticks, 1)
    radio = res["radio"]
    return {"ticks": res["ticks"], "completed": float(res["completed"]),
            **{k: sizes[k] / per for k in ("map", "beacons", "protocol", "plain", "compact")},
            "delay_mean": radio["delay_ticks"]["mean"] or 0.0, "delay_max": radio["delay_ticks"]["max"] or 0,
            "dropped_queue": radio["dropped_queue"]}


def main(argv: list[str] | None = None) -> int:
    p = parser("benchmarks.radio", __doc__)
    p.add_argument("--map", default="office")
    p.add_argument("--robots", type=int, default=4)
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--bandwidth", type=float, default=0.0, help="kbit/s (0: unlimited)")
    p.add_argument("--comm", default="wall")
    p.add_argument("--loss", type=float, default=0.1)
    p.add_argument("--max-ticks", type=int, default=3000)
    p.add_argument("--allocators", nargs="+", default=list(ALLOCATORS))
    a = p.parse_args(argv)
    if a.seeds < 1:
        fail("radio", f"--seeds must be at least 1 (got {a.seeds})")
    unknown = sorted(set(a.allocators) - set(allocator_names()))
    if unknown:
        fail("radio", f"unknown allocator(s) {', '.join(unknown)} (one of {', '.join(allocator_names())})")
    try:
        base = Scenario().override(map=a.map, robots=a.robots, comm=a.comm, loss=a.loss, bandwidth=a.bandwidth,
                                   max_ticks=a.max_ticks, start="random")
        check(base)
    except FleetError as exc:
        fail("radio", str(exc))
    rate = f"{a.bandwidth:g} kbit/s" if a.bandwidth else "unlimited"
    print(f"# {machine()}")
    print(f"# {a.map}, {a.robots} robots, {a.comm} radio, loss {a.loss:g}, {rate}; mean of {a.seeds} seed(s); "
          "bytes per robot-tick")
    print(f"{'allocator':<13} {'ticks':>6} {'map':>8} {'beacons':>8} {'protocol':>9} {'total':>8} {'compact':>8} "
          f"{'delay':>6} {'max':>5} {'qdrop':>6}")
    for alloc in a.allocators:
        runs = []
        for seed in range(a.seeds):
            print(f"{alloc} seed {seed}", file=sys.stderr)
            runs.append(measure(base.override(allocator=alloc, seed=seed)))
        m = {k: statistics.fmean(r[k] for r in runs) for k in runs[0]}
        total = m["map"] + m["beacons"] + m["protocol"]
        z = f"{m['compact'] / m['plain']:.0%}" if m["plain"] else "-"
        print(f"{alloc:<13} {m['ticks']:>6.0f} {m['map']:>8.0f} {m['beacons']:>8.0f} {m['protocol']:>9.0f} "
              f"{total:>8.0f} {z:>8} {m['delay_mean']:>6.2f} {m['delay_max']:>5.0f} {m['dropped_queue']:>6.0f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
