"""Real time: does an allocator's computing time cost exploration time?

    python -m benchmarks.realtime_study [--hz 10] [--robots 8 32 64] [--max-ticks 6000] [--maps maze PATH ...]

For every map and robot count, two real-time runs (``fleet run --realtime HZ``: the world ticks HZ times a
second on the wall clock, whether or not every robot has answered; a robot whose decision is not ready keeps
stepping along its last plan, and a decision that ends after its tick is applied a tick late): ``greedy``
(MinPos paper Alg. 2: every robot computes the whole cost matrix, one BFS per frontier cluster, then the greedy
assignment, O(n²m)) against ``minpos`` with parallel wavefronts (section 4.3: paused and resynchronised
wavefronts, no cost matrix). Same map, start, seed and radio as ``benchmarks/scale.py``: a map fitted to about
``--cells`` cells across (the built-in ``maze`` by default, or a map such as the
registry's ``cave``), sensor and comm ranges fixed in cells (8 and 20), the fleet around the map's
most open start cell, the default radio (wall model, 10 % loss), no recording, target coverage 0.99.

The world's stall rules count ticks, and a real-time tick may be shorter than one decision: a fleet whose first
decisions take seconds stands still meanwhile. So the stall window is given in seconds here (``--stall-seconds``,
default 60: ``stall_ticks`` = that times HZ); ``coverage_stall_ticks`` stays the scenario's (500). Real-time runs
are not deterministic: the same seed gives different runs.

One row per map, robot count and allocator (stdout):

- ``t99``: the first tick at 99 % coverage (``-`` when the run ended without it), and ``t99 s`` the world's wall
  seconds at that tick (from tick 0's scheduled time: more than ``t99`` / HZ when the world overran);
  ``ticks`` and ``reason``: where and why the run ended; ``cov``: the final coverage;
- ``tps``: ticks per second the world achieved, and ``ovr`` its overruns (ticks it started late);
- ``late``: late decisions per robot (mean over the robots; applied a tick late), ``lstep``: late steps along
  the last plan (the robot's process itself slow to answer), ``miss``: ticks without any command, per robot;
  ``dec``: decisions per robot, ``plan``: ticks a robot stepped along its last plan while deciding, per robot;
- decision wall time in ms (the brain's whole step in the robot's worker thread): ``p50`` and ``p90`` the median
  over the robots of each robot's percentile, ``p99`` and ``max`` the largest over the robots.

``--lockstep`` runs the same scenarios in lockstep instead, on the memory engine (deterministic: every robot
decides every tick, however long it takes): the reference that says how much of a real-time run's ``t99`` is
the allocator's choices rather than its computing time. Its rows have ``t99 s`` the run's wall seconds, ``tps``
its ticks per second, ``p50`` and ``p90`` the mean and p95 of ``result.json``'s ``decision_ms``; the
real-time columns are empty.

A fleet larger than the world's start area is a ``start`` row, not run. ``--max-ticks`` caps every run (a short
cap makes a quick look: ``t99`` is then ``-``). Exit 0 when every run finished, 1 when one failed, 2 on a bad
argument (one line).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from typing import Any

from benchmarks._common import REAL_MAP, FittedMap, fail, fitted_maps, fitted_scenario, machine, parser

PROG = "realtime_study"
ALLOCATORS = {"greedy": {"type": "greedy"}, "minpos-par": {"type": "minpos", "wavefront": "parallel"}}


def parse(argv: list[str] | None) -> argparse.Namespace:
    p = parser("benchmarks.realtime_study", __doc__)
    p.add_argument("--hz", type=float, default=10.0, help="world ticks per second")
    p.add_argument("--robots", type=int, nargs="+", default=[8, 32, 64], help="fleet sizes")
    p.add_argument("--allocators", nargs="+", default=list(ALLOCATORS), choices=list(ALLOCATORS))
    p.add_argument("--max-ticks", type=int, default=6000, help="the cap of every run")
    p.add_argument("--stall-seconds", type=float, default=60.0, help="no move and nothing sensed this long: a stall")
    p.add_argument("--cells", type=int, default=512, help="cells across the maps (their larger side)")
    p.add_argument("--maps", nargs="+", default=["maze"],
                   help=f"built-in map names or map files (default: maze; or the registry's {REAL_MAP})")
    p.add_argument("--sensor-cells", type=float, default=8.0, help="sensor range in cells")
    p.add_argument("--comm-cells", type=float, default=20.0, help="comm range c in cells")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--lockstep", action="store_true", help="the lockstep reference on the memory engine instead")
    a = p.parse_args(argv)
    if not 0 < a.hz <= 1000:
        fail(PROG, f"--hz must be > 0 and <= 1000 (got {a.hz})")
    if min(a.robots) < 1 or a.max_ticks < 1 or a.stall_seconds <= 0 or a.cells < 8:
        fail(PROG, "--robots and --max-ticks must be at least 1, --stall-seconds positive, --cells at least 8")
    return a


def scenario_for(m: FittedMap, robots: int, allocator: dict[str, Any], a: argparse.Namespace) -> Any:
    """``benchmarks.scale``'s scenario with ``allocator``, to 99 %, the stall window in seconds at ``a.hz``."""
    return fitted_scenario(m, robots, a.seed, a.sensor_cells, a.comm_cells, allocator, max_ticks=a.max_ticks,
                           target_coverage=0.99, stall_ticks=max(1, round(a.stall_seconds * a.hz)))


def run_one(scenario: Any, hz: float) -> dict[str, Any]:
    """One real-time run in this process; its row."""
    from fleet_emu.launch.runner import RunOptions, run_fleet

    res = run_fleet(scenario, RunOptions(record=False, realtime_hz=hz)).data
    rt = res.get("realtime") or {}
    robots = [r for r in (rt.get("robots") or {}).values() if r.get("decisions") is not None]
    if not robots:
        raise RuntimeError(f"no real-time summary (reason {res['reason']})")

    def mean(key: str) -> float:
        return statistics.fmean(r[key] for r in robots)

    return {
        "t99": res["t99"], "t99s": rt.get("t99_s"), "ticks": res["ticks"],
        "reason": res["reason"], "cov": res["coverage"], "tps": rt.get("ticks_per_second") or 0.0,
        "ovr": rt.get("world_overruns", 0), "late": mean("late_commands"),
        "lstep": mean("late_steps"), "miss": mean("missed_ticks"),
        "dec": mean("decisions"), "plan": mean("plan_steps"),
        "p50": statistics.median(r["decision_ms"]["p50"] for r in robots),
        "p90": statistics.median(r["decision_ms"]["p90"] for r in robots),
        "p99": max(r["decision_ms"]["p99"] for r in robots), "max": max(r["decision_ms"]["max"] for r in robots),
        "failed": len(res["failed"]),
    }


def run_lockstep(scenario: Any) -> dict[str, Any]:
    """One lockstep run of the same scenario on the memory engine; its row (real-time columns empty)."""
    from fleet_emu.launch.memory import run_memory

    res = run_memory(scenario, record=False).data
    return {"t99": res["t99"], "t99s": res["wall_seconds"] if res["t99"] is not None else None,
            "ticks": res["ticks"], "reason": res["reason"], "cov": res["coverage"],
            "tps": res.get("ticks_per_second") or res["ticks"] / res["wall_seconds"],
            "p50": res["decision_ms"]["mean"], "p90": res["decision_ms"]["p95"], "failed": len(res["failed"])}


COLUMNS = [("map", 8, "s"), ("cells", 9, "s"), ("robots", 6, "d"), ("allocator", 10, "s"), ("t99", 5, "s"),
           ("t99 s", 6, "s"), ("ticks", 5, "d"), ("reason", 9, "s"), ("cov", 5, ".3f"), ("tps", 5, ".2f"),
           ("ovr", 4, "d"), ("late", 6, ".1f"), ("lstep", 6, ".1f"), ("miss", 5, ".1f"), ("dec", 6, ".1f"),
           ("plan", 6, ".1f"),
           ("p50", 7, ".1f"), ("p90", 7, ".1f"), ("p99", 7, ".1f"), ("max", 7, ".1f"), ("load1", 5, ".2f")]
KEYS = ["map", "cells", "robots", "allocator", "t99", "t99s", "ticks", "reason", "cov", "tps", "ovr", "late", "lstep",
        "miss", "dec", "plan", "p50", "p90", "p99", "max", "load1"]


def line(row: dict[str, Any]) -> str:
    cells = []
    for key, (_, w, fmt) in zip(KEYS, COLUMNS, strict=True):
        value = row.get(key)
        if key in ("t99", "t99s"):
            value = "-" if value is None else (f"{value:.1f}" if key == "t99s" else str(value))
            cells.append(f"{value:>{w}}")
        else:
            cells.append(f"{value:>{w}{fmt}}" if value is not None else f"{'':>{w}}")
    text = " ".join(cells)
    if "note" in row:
        text = text[:sum(w + 1 for _, w, _ in COLUMNS[:4])] + row["note"]
    return text


def main(argv: list[str] | None = None) -> None:
    a = parse(argv)
    from fleet_emu.core.errors import FleetError
    from fleet_emu.world.sim import StartAreaError

    maps = fitted_maps(PROG, a.maps, a.cells, a.seed)
    print(f"# benchmarks/realtime_study.py: {machine()}")
    mode = "lockstep, memory engine" if a.lockstep else f"real time at {a.hz:g} Hz, processes engine"
    print(f"# {mode}, wall radio, loss 0.1, target 0.99, cap {a.max_ticks} ticks, "
          f"stall {a.stall_seconds:g} s, sensor {a.sensor_cells:g} cells, comm {a.comm_cells:g} cells, seed {a.seed}")
    print("# decision ms: result.json's decision_ms, p50 its mean and p90 its p95" if a.lockstep else
          "# decision ms: the brain's whole step in the robot's worker thread (wall clock)")
    print(" ".join(f"{name:>{w}}" for name, w, _ in COLUMNS), flush=True)
    failed = 0
    for m in maps:
        label = m.label
        for n in a.robots:
            for alloc in a.allocators:
                row: dict[str, Any] = {"map": label[:8], "cells": m.cells, "robots": n, "allocator": alloc}
                t = time.monotonic()
                try:
                    sc = scenario_for(m, n, ALLOCATORS[alloc], a)
                    row |= run_lockstep(sc) if a.lockstep else run_one(sc, a.hz)
                    row["load1"] = os.getloadavg()[0]
                    failed += bool(row["failed"])
                    print(f"{label} {n} {alloc}: {row['ticks']} ticks ({row['reason']}), "
                          f"{time.monotonic() - t:.0f} s", file=sys.stderr, flush=True)
                except StartAreaError as exc:
                    row["note"] = "start: the map's free area holds fewer robots"
                    print(f"{label} {n} {alloc}: not run ({exc})", file=sys.stderr, flush=True)
                except (FleetError, RuntimeError) as exc:
                    failed += 1
                    row["note"] = f"failed: {str(exc).splitlines()[0][:80]}"
                    print(f"{label} {n} {alloc}: FAILED ({exc})", file=sys.stderr, flush=True)
                print(line(row), flush=True)
    if failed:
        print(f"realtime_study: {failed} runs failed or lost robots (see above)", file=sys.stderr)
        raise SystemExit(1)


if __name__ == "__main__":
    main()
