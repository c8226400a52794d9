"""MHM's final reach on an open map, against the paper's Table II (Mukhija et al., section IV).

    python -m benchmarks.mhm_reach [--cells 1200] [--robots 10 11 12] [--r-comm 40] [--sensor 15] [--x-min 1]
                                   [--max-ticks 400000] [--seed 0] [--method mhm] [--json reach.json]

Table II gives the *total final visibility* (grid cells seen) of 10, 11 and 12 robots "determined in an
unbounded map", with r_comm 40 and a sensor range of 15 (pixels = cells): MHM 423,421 / 489,689 / 590,780. A
base-connected chain of n robots sees at most about the disc of radius (n - 1) * r_comm + r_sense around the
base; Table II is 0.96 / 0.91 / 0.91 of that disc.

Here MHM is the pure base-station planner (``agents/allocators/mhm/``) in its kinematic simulation
(``mhm/sim.py``: a loss-free, instant team map at the base, links ``d < r_comm``), on an obstacle-free square of
``--cells`` x ``--cells`` cells with a walled border (an open map: the paper's "unbounded" maps were not
published), the base at its centre, the robots on the free cells nearest it. Each run goes on until the
planner's own end (section III-D, step 18); ``--max-ticks`` is only a cap, and a run that hits it says so.

One row per fleet size: ``ticks`` run, ``end`` (``step18`` or ``max_ticks``), ``reach`` (cells seen, free or
occupied: Table II's measure), Table II's MHM figure and the ratio, the disc and the ratio, ``radius`` (the
farthest cell seen from the base), ``bounded`` (whether a seen cell lies within ``--sensor`` cells of the
map's border: then the map bounded the run and it is too small), ``worst`` (the lowest per-tick share of
robots with a path of links to the base; 1.0: the constraint held), ``phase 2`` (the tick phase 2 began: the
cells seen by then), the phase-2 ``chains`` built, the planner's CPU (``plan s``) and the
whole run's (``run s``), and where the method stopped (the planner's last event: step 10's frontier that
needs as many nodes as there are robots, or no reachable frontier). ``--json`` keeps the rows; progress
(every 10,000 ticks) goes to stderr.
Exit 2 on a bad argument (one line).
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._common import fail, machine, parser
from fleet_emu.agents.allocators.mhm.planner import METHODS

PROG = "mhm_reach"
#: Table II, MHM's column: robots -> grid cells seen, in an unbounded map (r_comm 40, sensor 15).
TABLE_II = {10: 423_421, 11: 489_689, 12: 590_780}


def disc(robots: int, r_comm: float, sensor: float) -> float:
    """The reach disc of a base-connected chain of ``robots``: pi ((n - 1) r_comm + r_sense)^2 cells."""
    return math.pi * ((robots - 1) * r_comm + sensor) ** 2


def open_map(cells: int) -> tuple[np.ndarray, tuple[int, int]]:
    """An obstacle-free ``cells`` x ``cells`` grid, border walled, and its centre cell."""
    from fleet_emu.core.grid import FREE, OCCUPIED

    grid = np.full((cells, cells), FREE, dtype=np.int8)
    grid[[0, -1], :] = OCCUPIED
    grid[:, [0, -1]] = OCCUPIED
    return grid, (cells // 2, cells // 2)


def run(grid: np.ndarray, base: tuple[int, int], robots: int, a: Any) -> dict[str, Any]:
    """One fleet to the planner's end (or the cap); the row's numbers."""
    from fleet_emu.agents.allocators.mhm.planner import MhmConfig
    from fleet_emu.agents.allocators.mhm.sim import simulate, worst

    config = MhmConfig(r_comm=a.r_comm, sensor_range=a.sensor, x_min=a.x_min, method=a.method)
    t0 = time.process_time()
    def progress(tick: int, seen: int) -> None:
        print(f"  {robots} robots: tick {tick}, {seen} cells seen, {time.process_time() - t0:.0f} CPU s",
              file=sys.stderr, flush=True)

    out = simulate(grid, base, robots, config, a.seed, a.max_ticks, clock=time.thread_time, keep_belief=True,
                   progress=progress)
    run_s = time.process_time() - t0
    assert out.belief is not None
    seen = np.argwhere(out.belief >= 0)
    radius = float(np.hypot(seen[:, 0] - base[0], seen[:, 1] - base[1]).max())
    edge = int(a.sensor) + 1
    bounded = bool(((seen < edge) | (seen >= grid.shape[0] - edge)).any())
    reach = out.seen[-1]
    d = disc(robots, a.r_comm, a.sensor)
    table = TABLE_II.get(robots) if (a.r_comm, a.sensor) == (40.0, 15.0) else None
    stop = next((e for _, e in reversed(out.planner.events) if e.startswith("stop")), "max ticks")
    phase2 = next((t for t, e in out.planner.events if e == "phase 2"), None)
    return {
        "robots": robots, "cells": grid.shape[0], "ticks": out.ticks, "end": "step18" if out.done else "max_ticks",
        "reach": reach, "table2": table, "vs_table2": reach / table if table else None, "disc": d,
        "vs_disc": reach / d, "radius": radius, "bounded": bounded, "worst": worst(out.connected),
        "nodes": max(out.nodes), "plan_s": sum(out.step_ms) / 1000.0, "run_s": run_s, "stalls": out.planner.stalls,
        "chains": sum(e.startswith("chain to") for _, e in out.planner.events), "stop": stop,
        "phase2": phase2, "phase1_reach": out.seen[phase2] if phase2 is not None else None,
    }


HEAD = (f"{'robots':>6} {'map':>9} {'ticks':>7} {'end':>9} {'reach':>8} {'Table II':>8} {'ratio':>6} {'disc':>8}"
        f" {'ratio':>6} {'radius':>6} {'bounded':>7} {'worst':>5} {'phase 2':>14} {'chains':>6} {'plan s':>7}"
        f" {'run s':>7}  stop")


def line(r: dict[str, Any]) -> str:
    t2 = f"{r['table2']:>8,}" if r["table2"] else f"{'-':>8}"
    v2 = f"{r['vs_table2']:>6.3f}" if r["vs_table2"] else f"{'-':>6}"
    ph2 = f"{r['phase2']}: {r['phase1_reach']:,}" if r["phase2"] is not None else "-"
    return (f"{r['robots']:>6} {str(r['cells']) + '^2':>9} {r['ticks']:>7} {r['end']:>9} {r['reach']:>8,} {t2} {v2}"
            f" {r['disc']:>8,.0f} {r['vs_disc']:>6.3f} {r['radius']:>6.0f} {r['bounded']!s:>7} {r['worst']:>5.3f}"
            f" {ph2:>14} {r['chains']:>6} {r['plan_s']:>7.0f} {r['run_s']:>7.0f}  {r['stop']}")


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.mhm_reach", __doc__, full=False)
    p.add_argument("--cells", type=int, default=1200, help="the open map's side in cells (at least 1,200 for 10)")
    p.add_argument("--robots", type=int, nargs="+", default=[10])
    p.add_argument("--r-comm", type=float, default=40.0)
    p.add_argument("--sensor", type=float, default=15.0)
    p.add_argument("--x-min", type=int, default=1, help="eq. 1's X_min")
    p.add_argument("--max-ticks", type=int, default=400_000, help="a cap only: a run ends at step 18")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--method", choices=METHODS, default="mhm", help="mhm, or shm: the single hinged method")
    p.add_argument("--json", type=Path, default=None)
    a = p.parse_args(argv)
    if min(a.robots) < 2:
        fail(PROG, f"--robots must be at least 2 (got {min(a.robots)})")
    if a.cells < 16:
        fail(PROG, f"--cells must be at least 16 (got {a.cells})")
    for flag, v in (("--r-comm", a.r_comm), ("--sensor", a.sensor)):
        if not (math.isfinite(v) and v > 1):
            fail(PROG, f"{flag} must be a number above 1 (got {v})")
    if a.x_min < 1 or a.max_ticks < 1:
        fail(PROG, "--x-min and --max-ticks must be at least 1")
    if a.json is not None and not a.json.parent.is_dir():
        fail(PROG, f"no such directory for {a.json}: {a.json.parent}")
    from fleet_emu.core.kernels import warm_up

    warm_up()
    grid, base = open_map(a.cells)
    print(f"# benchmarks/mhm_reach.py: {machine()}")
    print(f"# open map {a.cells} x {a.cells} cells, base at {base}, r_comm {a.r_comm:g}, sensor {a.sensor:g}, "
          f"X_min {a.x_min}, seed {a.seed}, {a.max_ticks} ticks at most; {a.method.upper()}: pure planner, "
          "kinematic sim")
    print(HEAD, flush=True)
    rows = []
    for n in a.robots:
        rows.append(run(grid, base, n, a))
        print(line(rows[-1]), flush=True)
        if a.json is not None:
            a.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
