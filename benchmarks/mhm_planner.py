"""MHM's base-station planner on the paper's setting, without processes (Mukhija et al., section IV).

    python -m benchmarks.mhm_planner [--map office] [--cell-size 0.05] [--size 512] [--robots 10 20]
                                     [--r-comm 40] [--sensor 15] [--max-ticks 4000] [--seed 0] [--quick]

Crops a built-in map (or a PNG/PGM/ROS YAML map, resampled) to ``--size`` x ``--size`` cells (one cell = one
pixel, as in the paper), walls its border, places the base station at the map's start cell, and runs
:class:`fleet_emu.agents.allocators.mhm.planner.MhmPlanner` in the kinematic world of ``mhm.sim`` (robots step
one cell per tick, sense a disk, loss-free radio with links ``d < r_comm``). Prints, per fleet size: ticks
run, whether step 18 was reached, coverage, cells seen at fixed ticks (the paper's Fig. 7 is cells seen
against ticks), the worst per-tick base-connected fraction (1.0: the constraint held), the most node robots,
the planner's time per tick (mean, p95, max, in ms) and per run (s) (the paper's Table I reports minutes per
run for 10-17 robots on 2009 hardware), and the planner's stall count.
"""

from __future__ import annotations

import statistics
import sys
import time

import numpy as np

from benchmarks._common import parser
from fleet_emu.agents.allocators.mhm.planner import MhmConfig
from fleet_emu.agents.allocators.mhm.sim import fraction_at, simulate, worst
from fleet_emu.core.grid import FREE, OCCUPIED, Cell
from fleet_emu.core.kernels import warm_up
from fleet_emu.world.maps import load_map

AT = (250, 500, 1000, 2000, 4000)


def crop(grid: np.ndarray, start: Cell, size: int) -> tuple[np.ndarray, Cell]:
    """A size x size window of ``grid`` around ``start`` (clipped to the map), border walled."""
    r0 = min(max(0, start[0] - size // 2), max(0, grid.shape[0] - size))
    c0 = min(max(0, start[1] - size // 2), max(0, grid.shape[1] - size))
    out = grid[r0:r0 + size, c0:c0 + size].copy()
    out[[0, -1], :] = OCCUPIED
    out[:, [0, -1]] = OCCUPIED
    base = (start[0] - r0, start[1] - c0)
    if out[base] != FREE:
        raise SystemExit(f"the start cell {start} is not free after cropping")
    return out, base


def main(argv: list[str] | None = None) -> None:
    ap = parser("benchmarks.mhm_planner", __doc__, full=False)
    ap.add_argument("--map", default="office")
    ap.add_argument("--cell-size", type=float, default=0.05)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--robots", type=int, nargs="+", default=[10, 20])
    ap.add_argument("--r-comm", type=float, default=40.0)
    ap.add_argument("--sensor", type=float, default=15.0)
    ap.add_argument("--x-min", type=int, default=1)
    ap.add_argument("--hinges", type=int, default=0)
    ap.add_argument("--max-ticks", type=int, default=4000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--quick", action="store_true", help="128 x 128 cells, r_comm 16, sensor 6, 6 robots")
    a = ap.parse_args(argv)
    if a.quick:
        a.size, a.r_comm, a.sensor, a.robots, a.cell_size = 128, 16.0, 6.0, [6], 0.2
    m = load_map(a.map, a.cell_size, a.seed)
    grid, base = crop(m.grid, m.start, a.size)
    warm_up()
    config = MhmConfig(r_comm=a.r_comm, sensor_range=a.sensor, x_min=a.x_min, hinges=a.hinges)
    free = int((grid == FREE).sum())
    print(f"map {a.map} at {a.cell_size} m/cell cropped to {grid.shape[0]}x{grid.shape[1]}, {free} free cells, "
          f"base {base}, r_comm {a.r_comm}, sensor {a.sensor}, X_min {a.x_min}, hinges {a.hinges or 'any'}, "
          f"seed {a.seed}")
    head = (f"{'robots':>6} {'ticks':>6} {'step18':>6} {'coverage':>8} "
            + " ".join(f"{'seen@' + str(t):>9}" for t in AT)
            + f" {'worst':>6} {'nodes':>5} {'ms mean':>8} {'ms p95':>7} {'ms max':>7} {'run s':>7} {'stalls':>6}")
    print(head)
    for n in a.robots:
        t0 = time.perf_counter()
        out = simulate(grid, base, n, config, a.seed, a.max_ticks, clock=time.perf_counter)
        ms = sorted(out.step_ms)
        p95 = ms[min(len(ms) - 1, int(0.95 * len(ms)))]
        print(f"{n:>6} {out.ticks:>6} {out.done!s:>6} {out.coverage:>8.3f} "
              + " ".join(f"{v:>9}" for v in fraction_at(out.seen, list(AT)))
              + f" {worst(out.connected):>6.3f} {max(out.nodes):>5} {statistics.fmean(ms):>8.2f} {p95:>7.2f}"
              f" {ms[-1]:>7.1f} {sum(ms) / 1000:>7.1f} {out.planner.stalls:>6}", flush=True)
        print(f"       (wall {time.perf_counter() - t0:.0f} s; stop: "
              f"{next((e for _, e in out.planner.events if e.startswith('stop')), 'max ticks')})",
              file=sys.stderr, flush=True)


if __name__ == "__main__":
    main()
