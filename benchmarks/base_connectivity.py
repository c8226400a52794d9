"""Base connectivity for every allocator: how often the robots have a path to a base station.

    python -m benchmarks.base_connectivity [--map office] [--robots 4] [--seeds 3] [--comm wall]
        [--comm-range 10] [--loss 0.1] [--max-ticks 400] [--allocators nearest minpos ...]

Each run has a base station at the start cell (``base = true``) and is stepped on the memory engine
(``fleet_emu.Fleet``: the same objects as ``fleet run``, the same result). The base only listens, so every
allocator explores as it does without one; the table says how far from the base each leaves the team.
Per allocator, over the seeds: ``base_connected_fraction.overall`` (the mean share of live robots with a
path of links to the base, per tick) and ``all_ticks`` (the share of ticks every robot had one), the base's
known fraction of the map's cells at the end, the coverage and the ticks.
"""

from __future__ import annotations

import statistics

from benchmarks._common import mean_sd, parser
from fleet_emu.agents.allocators import allocator_names
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.base_connectivity", __doc__, full=False)
    p.add_argument("--map", default="office")
    p.add_argument("--robots", type=int, default=4)
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--comm", default="wall")
    p.add_argument("--comm-range", type=float, default=10.0)
    p.add_argument("--loss", type=float, default=0.1)
    p.add_argument("--max-ticks", type=int, default=400)
    p.add_argument("--allocators", nargs="+", default=None)
    a = p.parse_args(argv)
    names = a.allocators or allocator_names()  # mhm too: every run here has its base
    print(f"# {a.map}, {a.robots} robots, {a.comm} radio, range {a.comm_range} m, loss {a.loss}, "
          f"{a.max_ticks} ticks at most, seeds 0..{a.seeds - 1}, base at the start cell")
    print("| allocator | base connected (overall) | all connected (ticks) | base knows | coverage | ticks |")
    print("| --- | --- | --- | --- | --- | --- |")
    for name in names:
        rows = []
        for seed in range(a.seeds):
            s = Scenario().override(map=a.map, robots=a.robots, allocator=name, comm=a.comm, comm_range=a.comm_range,
                                    loss=a.loss, seed=seed, max_ticks=a.max_ticks, base=True)
            rows.append(Fleet(s).run().data)
        frac = [r["base_connected_fraction"] for r in rows]
        print(f"| {name} | {mean_sd([f['overall'] for f in frac])} | {mean_sd([f['all_ticks'] for f in frac])} | "
              f"{mean_sd([r['base']['known_fraction'] for r in rows])} | {mean_sd([r['coverage'] for r in rows])} | "
              f"{statistics.mean(r['ticks'] for r in rows):.0f} |", flush=True)


if __name__ == "__main__":
    main()
