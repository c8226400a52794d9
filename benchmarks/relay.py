"""Multi-hop relaying: what each policy and hop limit delivers, and at what radio cost.

    python -m benchmarks.relay [--map office] [--robots 4] [--seeds 3] [--comm disk] [--comm-range 8]
        [--loss 0.1] [--max-ticks 300] [--allocator minpos] [--ttls 0 2 4]

Runs on the memory engine (``fleet_emu.Fleet``: the same objects and result as ``fleet run``). Rows: no
relaying, then ``flood`` and ``tree`` for each ``relay_ttl``; ``tree`` has no routes until the base-station
allocator fills them (docs/guides/radio.md, "Relaying"), so it forwards nothing and shows what a ttl costs
alone. Per row,
over the seeds (mean ± sd): the pose beacons' delivery ratio and transmissions per delivery, the share of
beacon deliveries that took 2+ hops, the radio's (message, receiver) pairs sent, coverage and ticks.
Counts, not timings: the numbers do not depend on the machine's load.
"""

from __future__ import annotations

import statistics
import sys

from benchmarks._common import mean_sd, parser
from fleet_emu.core.errors import FleetError
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet


def main(argv: list[str] | None = None) -> None:
    try:
        table(argv)
    except FleetError as exc:  # bad input: one line, exit 2
        print(f"relay: error: {exc}", file=sys.stderr)
        raise SystemExit(2) from None


def table(argv: list[str] | None) -> None:
    """Parse the arguments and print the table."""
    p = parser("benchmarks.relay", __doc__, full=False)
    p.add_argument("--map", default="office")
    p.add_argument("--robots", type=int, default=4)
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--comm", default="disk")
    p.add_argument("--comm-range", type=float, default=8.0)
    p.add_argument("--loss", type=float, default=0.1)
    p.add_argument("--max-ticks", type=int, default=300)
    p.add_argument("--allocator", default="minpos")
    p.add_argument("--ttls", type=int, nargs="+", default=[0, 2, 4])
    a = p.parse_args(argv)
    print(f"# benchmarks/relay.py: {a.map}, {a.robots} robots, {a.allocator}, {a.comm} radio, "
          f"range {a.comm_range} m, loss {a.loss}, {a.max_ticks} ticks at most, seeds 0..{a.seeds - 1}")
    print("| relay | ttl | pose delivery | pose tx/delivered | pose 2+ hops | radio pairs sent | coverage | ticks |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    rows = [("none", 0)] + [(pol, ttl) for ttl in a.ttls for pol in ("flood", "tree")]
    for policy, ttl in rows:
        runs = []
        for seed in range(a.seeds):
            s = Scenario().override(map=a.map, robots=a.robots, allocator=a.allocator, comm=a.comm,
                                    comm_range=a.comm_range, loss=a.loss, seed=seed, max_ticks=a.max_ticks,
                                    relay=policy, relay_ttl=ttl)
            runs.append(Fleet(s).run().data)
        pose = [r["relay"]["kinds"]["pose"] for r in runs if "pose" in r.get("relay", {}).get("kinds", {})]
        if pose and len(pose) == len(runs):
            ratio = mean_sd([k["delivery_ratio"] for k in pose])
            tpd = mean_sd([k["tx_per_delivered"] for k in pose], 2)
            multi = mean_sd([sum(v for h, v in k["hops"].items() if int(h) > 1) / max(1, k["delivered"])
                             for k in pose])
        else:
            ratio = tpd = multi = "-"
        sent = mean_sd([r["radio"]["sent"] for r in runs], 0)
        print(f"| {policy} | {ttl} | {ratio} | {tpd} | {multi} | {sent} | {mean_sd([r['coverage'] for r in runs])} | "
              f"{statistics.mean(r['ticks'] for r in runs):.0f} |", flush=True)


if __name__ == "__main__":
    main()
