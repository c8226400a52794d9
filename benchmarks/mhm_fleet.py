"""MHM in the whole fleet: the base plans, its orders cross the lossy radio hop by hop, the
robots obey. Memory engine (the same objects as the processes, one process, no Zenoh), disk radio.

    python -m benchmarks.mhm_fleet [--map office] [--robots 10 20] [--loss 0 0.1 0.3] [--seeds 0]
                                   [--comm-range 5] [--sensor-range 2] [--max-ticks 1500] [--hinges 0]

Prints one row per (robots, loss, seed): ticks, why the run ended, coverage, the base-connected fraction
(``overall``: the mean share of robots with a path to the base; ``worst``: the lowest share in any tick;
``all``: the share of ticks with every robot connected), the orders' delivery ratio and mean latency (ticks,
over the relay hops), the most node robots the plan held at once, the planner's stall count, and the run's
wall seconds (noisy under load: a count, not a timing, is the result).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import fleet_emu as fe
from benchmarks._common import parser
from fleet_emu.agents.allocators.mhm.planner import MhmPlanner
from fleet_emu.agents.allocators.mhm.station import MhmStation
from fleet_emu.launch.memory import Fleet


def _planner(fleet: Fleet) -> MhmPlanner | None:
    """The base's MHM planner (None before the base made it)."""
    station = fleet.base.planner if fleet.base is not None else None
    return station.planner if isinstance(station, MhmStation) else None


def run(scenario: fe.Scenario) -> dict[str, Any]:
    fleet = Fleet(scenario)
    fleet.reset()
    nodes = 0
    t0 = time.perf_counter()
    while not fleet.done:
        fleet.step()
        planner = _planner(fleet)
        if planner is not None:
            nodes = max(nodes, len(planner.node_of))
    res = fleet.result()
    series = fleet.monitor.base_reach.series
    frac = res["base_connected_fraction"]
    orders = res["relay"]["kinds"].get("mhm", {})
    planner = _planner(fleet)
    return {"ticks": res["ticks"], "reason": res["reason"], "coverage": res["coverage"],
            "overall": frac["overall"], "worst": min(series, default=float("nan")), "all": frac["all_ticks"],
            "orders": orders.get("delivery_ratio", 0.0), "latency": orders.get("latency_ticks", {}).get("mean"),
            "nodes": nodes, "stalls": planner.stalls if planner else 0, "done": bool(planner and planner.done),
            "wall": time.perf_counter() - t0}


def main(argv: list[str] | None = None) -> None:
    ap = parser("benchmarks.mhm_fleet", __doc__, full=False)
    ap.add_argument("--map", default="office")
    ap.add_argument("--robots", type=int, nargs="+", default=[10, 20])
    ap.add_argument("--loss", type=float, nargs="+", default=[0.0, 0.1, 0.3])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--comm", default="disk")
    ap.add_argument("--comm-range", type=float, default=5.0)
    ap.add_argument("--sensor-range", type=float, default=2.0)
    ap.add_argument("--max-ticks", type=int, default=1500)
    ap.add_argument("--hinges", type=int, default=0)
    a = ap.parse_args(argv)
    print(f"map {a.map}, {a.comm} radio {a.comm_range} m, sensor {a.sensor_range} m, max {a.max_ticks} ticks, "
          f"hinges {a.hinges}, memory engine")
    head = ("robots", "loss", "seed", "ticks", "end", "coverage", "overall", "worst", "all", "orders", "lat",
            "nodes", "stalls", "step18", "wall s")
    print(" | ".join(head))
    for n in a.robots:
        for loss in a.loss:
            for seed in a.seeds:
                s = fe.Scenario().override(map=a.map, robots=n, allocator="mhm", base=True, comm=a.comm,
                                           comm_range=a.comm_range, sensor_range=a.sensor_range, loss=loss,
                                           seed=seed, max_ticks=a.max_ticks)
                if a.hinges:
                    s = dataclasses.replace(s, allocator={"type": "mhm", "hinges": a.hinges}).validate()
                r = run(s)
                lat = r["latency"]
                print(f"{n} | {loss} | {seed} | {r['ticks']} | {r['reason']} | {r['coverage']:.3f} | "
                      f"{r['overall']:.4f} | {r['worst']:.3f} | {r['all']:.3f} | {r['orders']:.3f} | "
                      f"{lat if lat is None else round(lat, 2)} | {r['nodes']} | {r['stalls']} | {r['done']} | "
                      f"{r['wall']:.0f}", flush=True)


if __name__ == "__main__":
    main()
