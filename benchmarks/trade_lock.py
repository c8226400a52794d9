"""Trade with and without giving a task up when a teammate stands in the way: runs that drag on, mean ticks.

    python -m benchmarks.trade_lock [--map autolab] [--robots 4] [--seeds 30] [--loss 0 0.3] [--comm full]
        [--blocked-after 4 0] [--long 250]

Two trade robots can meet head-on in a one-cell door and, each keeping its task, stay there until
``task_timeout`` (300 ticks). ``blocked_after`` (``agents/allocators/blocking.py``) is how many ticks a teammate
may hold the robot's way without it coming nearer before the robot gives its task up; 0 keeps the task (the
behaviour before it). Per loss and ``blocked_after``: the runs past ``--long`` ticks, the mean ± sd of the
ticks to 99 % coverage (a run short of it counts at its last tick, flagged ``*k``) and the longest run. Each
run is the memory engine in this process (random start cell per seed, as ``fleet run --start random``):
30 seeds at two losses and two settings on autolab take about 15 s.
"""

from __future__ import annotations

import statistics
import sys
from typing import Any

from benchmarks._common import parser
from fleet_emu.core.errors import FleetError
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet


def scenario(map_name: str, robots: int, seed: int, loss: float, comm: str, blocked_after: int) -> Scenario:
    """One run's scenario (a bad map, loss or fleet size is a FleetError here)."""
    return Scenario().override(map=map_name, robots=robots, seed=seed, loss=loss, comm=comm, start="random",
                               allocator={"type": "trade", "blocked_after": blocked_after})


def run_one(s: Scenario) -> dict[str, Any]:
    """One memory-engine run's ``result.json``."""
    return Fleet(s).run().data


def ticks(result: dict[str, Any]) -> int:
    return int(result["t99"] if result["t99"] is not None else result["ticks"])


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.trade_lock", __doc__)
    p.add_argument("--map", default="autolab")
    p.add_argument("--robots", type=int, default=4)
    p.add_argument("--seeds", type=int, default=30)
    p.add_argument("--loss", type=float, nargs="+", default=[0.0, 0.3])
    p.add_argument("--comm", default="full", choices=("wall", "disk", "full", "ideal"))
    p.add_argument("--blocked-after", type=int, nargs="+", default=[4, 0])
    p.add_argument("--long", type=int, default=250, help="a run past this many ticks counts as dragging on")
    a = p.parse_args(argv)
    if a.seeds < 1 or any(k < 0 for k in a.blocked_after):
        p.error("--seeds must be >= 1, --blocked-after >= 0")
    try:
        for loss in a.loss:
            scenario(a.map, a.robots, 0, loss, a.comm, a.blocked_after[0])
    except FleetError as exc:
        p.error(str(exc))
    print(f"trade on {a.map}, {a.robots} robots, comm {a.comm}, random start, seeds 0..{a.seeds - 1}; "
          f"ticks to 99 % (*k: k runs short of it, at their last tick)")
    print(f"{'loss':>5} {'blocked_after':>13} {'past ' + str(a.long):>9} {'ticks':>11} {'longest':>8}")
    for loss in a.loss:
        for k in a.blocked_after:
            rs = [run_one(scenario(a.map, a.robots, s, loss, a.comm, k)) for s in range(a.seeds)]
            long = sum(1 for r in rs if r["ticks"] > a.long)
            miss = sum(1 for r in rs if r["t99"] is None)
            t = [ticks(r) for r in rs]
            cell = f"{statistics.mean(t):.0f}±{statistics.pstdev(t):.0f}" + (f" *{miss}" if miss else "")
            print(f"{loss:>5} {k:>13} {long:>9} {cell:>11} {max(r['ticks'] for r in rs):>8}", flush=True)
            print(f"  loss {loss}, blocked_after {k}: runs past {a.long}: "
                  f"{[s for s, r in enumerate(rs) if r['ticks'] > a.long]}", file=sys.stderr)


if __name__ == "__main__":
    main()
