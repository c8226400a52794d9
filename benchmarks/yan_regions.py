"""Trade and Hungarian on Yan's regions against frontier clusters: ticks, trade rounds, segmentation cost.

    python -m benchmarks.yan_regions [--allocators trade:tasks=regions trade hungarian:tasks=regions hungarian]
        [--robots 2] [--loss 0 0.5] [--seeds 3] [--map office] [--max-ticks 3000]

Yan et al. 2011 (section 4.2) bid on regions found by topologizing the map; ``tasks = "regions"``
(``agents/regions.py``) gives trade and hungarian those tasks instead of frontier clusters. Per (loss,
allocator) over the seeds, in the memory engine, ``full`` radio, to 99 % coverage: the ticks (mean ± sd; a run
that misses it counts at its last tick, flagged ``*k``), trade's rounds per 100 ticks (``TradeAllocation``
broadcasts: one per closed round or self-allocation), its tasks given up or done per 100 ticks
(``TradeDone``), the decision's CPU per robot-tick (ms) and, with regions, the segmentation's CPU per call (ms)
and calls per robot-tick (at most one: a belief is segmented once). A smaller sample of the ``yan-regions``
study (``fleet sweep yan-regions``), with the round counts the study does not keep.
"""

from __future__ import annotations

import statistics
import sys
from collections import Counter
from typing import Any

from benchmarks._common import fail, parser
from fleet_emu.agents.allocators import make_allocator
from fleet_emu.core.errors import ConfigError, MapError
from fleet_emu.core.messages import Message, TxBundle
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet


def spec(text: str) -> dict[str, Any]:
    """``NAME`` or ``NAME:tasks=regions`` -> an allocator table."""
    name, _, rest = text.partition(":")
    table: dict[str, Any] = {"type": name}
    for item in filter(None, rest.split(",")):
        key, _, value = item.partition("=")
        table[key] = value
    return table


def run_one(allocator: dict[str, Any], robots: int, loss: float, seed: int, map_name: str, max_ticks: int
            ) -> dict[str, float]:
    kinds: Counter[str] = Counter()

    def tap(_key: str, msg: Message, _ns: int) -> None:
        if isinstance(msg, TxBundle):
            kinds.update(env.payload_kind for env in msg.msgs)

    scenario = Scenario().override(map=map_name, robots=robots, loss=loss, comm="full", seed=seed,
                                   target_coverage=0.99, max_ticks=max_ticks, allocator=allocator)
    fleet = Fleet(scenario, tap=tap)
    res = fleet.run()
    ticks = int(res["t99"] if res["t99"] is not None else res["ticks"])
    regions = [getattr(b.allocator, "regions", None) for b in fleet.brains.values()]
    calls = sum(r.segmentations for r in regions if r is not None)
    seg_ms = sum(r.cpu_ms for r in regions if r is not None)
    robot_ticks = robots * int(res["ticks"])
    return {"ticks": ticks, "missed": float(res["t99"] is None),
            "rounds": 100.0 * kinds["trade_alloc"] / ticks, "done": 100.0 * kinds["trade_done"] / ticks,
            "decision": sum(b.decision_cpu_ms for b in fleet.brains.values()) / robot_ticks,
            "seg_ms": seg_ms / calls if calls else float("nan"), "calls": calls / robot_ticks}


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.yan_regions", __doc__)
    p.add_argument("--allocators", nargs="+",
                   default=["trade:tasks=regions", "trade", "hungarian:tasks=regions", "hungarian"])
    p.add_argument("--robots", type=int, default=2)
    p.add_argument("--loss", type=float, nargs="+", default=[0.0, 0.5])
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--map", default="office")
    p.add_argument("--max-ticks", type=int, default=3000)
    a = p.parse_args(argv)
    try:
        for text in a.allocators:
            make_allocator(spec(text))
        Scenario().override(map=a.map)
    except (ConfigError, MapError) as exc:
        fail("yan_regions", str(exc))
    print(f"{a.map}, {a.robots} robots, full radio, seeds 0..{a.seeds - 1}, memory engine, to 99 %")
    print("| loss | allocator | ticks | rounds /100 ticks | TradeDone /100 ticks | decision ms/robot-tick "
          "| segmentation ms/call | calls/robot-tick |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for loss in a.loss:
        for text in a.allocators:
            runs = []
            for seed in range(a.seeds):
                runs.append(run_one(spec(text), a.robots, loss, seed, a.map, a.max_ticks))
                print(f"loss {loss:g} {text} seed {seed}: {runs[-1]['ticks']} ticks", file=sys.stderr, flush=True)
            t = [r["ticks"] for r in runs]
            missed = int(sum(r["missed"] for r in runs))
            flag = f" *{missed}" if missed else ""

            def mean(key: str, runs: list[dict[str, float]] = runs) -> float:
                return statistics.mean(r[key] for r in runs)

            trade = spec(text)["type"] == "trade"
            rounds = f"{mean('rounds'):.1f} | {mean('done'):.1f}" if trade else "- | -"
            seg = f"{mean('seg_ms'):.2f} | {mean('calls'):.2f}" if "tasks=regions" in text else "- | -"
            print(f"| {loss:g} | {text} | {statistics.mean(t):.0f} ± {statistics.pstdev(t):.0f}{flag} "
                  f"| {rounds} | {mean('decision'):.2f} | {seg} |", flush=True)


if __name__ == "__main__":
    main()
