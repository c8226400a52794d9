"""Mukhija et al.'s setting for the base-station constraint: their Fig. 7 and Table I.

    python -m benchmarks.paper_setting [--maps grid PATH ...] [--robots 10 20] [--allocators mhm minpos connectivity]
        [--cells 512] [--r-comm 40] [--sensor 15] [--max-ticks 2000] [--at 250 500 1000 2000] [--cell-size 1]
        [--loss 0] [--seed 0] [--out fig7.png] [--json runs.json]
    python -m benchmarks.paper_setting --from runs.json more.json [--max-ticks 3000 | --at ...] [--out fig7.png]

The paper (section IV): 512 x 512-pixel bounded maps, one grid cell = one pixel, r_comm = 40 pixels, a sensor
range of 15 pixels, 10 to 50 robots; Fig. 7 plots MHM's total visibility (grid cells seen) against ticks, a
curve per fleet size, and Table I gives MHM's computation time per run (1-7 minutes for 10-17 robots on an
AMD Turion of 2009).

- **Maps.** Each map is drawn at the cell size that makes it about ``--cells`` cells across
  (``scale.fit_cell_size``), then cut (centred) or padded with walls to exactly ``--cells`` x ``--cells``, its
  border walled: a bounded map. Default: the built-in ``grid`` (30 x 30 m of 4 m blocks and 2 m streets: 514
  cells at 0.0627 m, one cell cut off each side) and Stage's ``cave`` (the registry's: ``fleet maps
  fetch cave``; 512 x 512 at 0.0314 m).
- **Units.** One cell is one pixel and the unit of distance, as in the paper: every run uses ``--cell-size``
  metres per cell (1 by default) whatever resolution the map was drawn at, so the radio and sensor ranges are
  ``--r-comm`` and ``--sensor`` cells. The only rule that sees metres is ``connectivity``'s eq. 9 (its path
  cost is in metres, its connectivity term in dB of distance ratios): the paper leaves the scale open, so it
  is this explicit parameter (``--cell-size 0.15`` puts r_comm at Benavides et al.'s 6 m).
- **Start.** The base station stands on the map's start cell (``world.maps.choose_start``); the robots start
  on the free cells nearest it by path (``mhm.sim.start_cells``), the same cells for every allocator.
- **MHM** is the pure base-station planner (``agents/allocators/mhm/``) in its kinematic sim
  (``mhm/sim.py``), not the processes: the team map at the base is the union of what the robots sensed
  (loss-free and instant) and links are ``d < r_comm``. It runs until the planner's step 18 or
  ``--max-ticks``. The planner's time is this thread's CPU (``time.thread_time``) around each
  ``MhmPlanner.step``: one step per tick, the base's whole decision for the fleet.
- **The others** (``minpos``, ``connectivity``, any built-in allocator) run on the memory engine
  (``fleet_emu.launch.memory.Fleet``: the same World, Channel and Brain objects as ``fleet run``) with the disk
  radio of range ``--r-comm`` cells (linked when ``d <= r_comm``, the paper's "never more than r_comm"),
  loss ``--loss`` (0: the paper's radio loses nothing) and a base station at the same cell (``base = [row,
  col]``): it listens, these allocators ignore it, and ``base_connected_fraction`` says how far they leave it.
  A run ends at 99 % coverage, a stall, or ``--max-ticks``. Their time is the allocator's thread CPU per
  robot decision (every robot decides for itself every tick), from the robots' reports.

One row per map, allocator and fleet size (stdout), as each run ends: ``ticks`` run, ``end`` (``step18``,
``max_ticks``, ``coverage``, ``stall``), ``coverage`` (the share of the free cells reachable from the start
that some robot sensed), ``seen@T`` the cells (free or occupied) some robot sensed by tick T (Fig. 7's
ordinate; the last value after a run that ended, ``-`` past ``--max-ticks``), ``base`` (``overall``: the
mean over ticks of the share of robots with a path of links to the base; ``all``: the share of ticks every
robot had one; ``worst``: the lowest share of any tick), ``ms mean / p95 / max`` (planner CPU per MHM tick;
allocator CPU per decision, mean only, for the others), ``plan s`` (that CPU summed over the run: all robots
for the others) and ``run s`` (this thread's CPU for the whole run). ``--out`` draws Fig. 7
(``recording.plots.panels_plot``: cells seen against ticks, a line per fleet size, a panel per allocator and
map); ``--json`` writes the rows and the curves (after every run), and ``--from`` runs nothing but prints the
table and draws ``--out`` from such files, joined and sorted by map, allocator and fleet size (runs split
over several invocations, e.g. one per map; ``--at`` or ``--max-ticks`` pick the columns). Progress goes to
stderr. Exit 0 when every run finished, 1 when one failed (an ``error`` row), 2 on a bad argument (one line).
"""

from __future__ import annotations

import json
import statistics
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._common import REAL_MAP, Cell, fail, fit_cell_size, machine, parser

PROG = "paper_setting"
AT = (250, 500, 1000, 1500, 2000, 3000, 4000)


# --- maps ------------------------------------------------------------------------------------------------

def square(grid: np.ndarray, start: Cell, cells: int) -> tuple[np.ndarray, Cell]:
    """``grid`` cut (centred) or padded with walls to ``cells`` x ``cells``, its border walled; ``start``
    moved with it (the map's chosen start again when it fell off or onto a wall)."""
    from fleet_emu.core.grid import FREE, OCCUPIED
    from fleet_emu.world.maps import choose_start

    out = np.full((cells, cells), OCCUPIED, dtype=np.int8)
    shift = []
    for axis in (0, 1):
        n = grid.shape[axis]
        shift.append((n - cells) // 2 if n > cells else -((cells - n) // 2))
    src = grid[max(0, shift[0]):max(0, shift[0]) + cells, max(0, shift[1]):max(0, shift[1]) + cells]
    r0, c0 = max(0, -shift[0]), max(0, -shift[1])
    out[r0:r0 + src.shape[0], c0:c0 + src.shape[1]] = src
    out[[0, -1], :] = OCCUPIED
    out[:, [0, -1]] = OCCUPIED
    s = (start[0] - shift[0], start[1] - shift[1])
    if not (0 <= s[0] < cells and 0 <= s[1] < cells and out[s] == FREE):
        s = choose_start(out)
    return out, (int(s[0]), int(s[1]))


def paper_map(name: str, cells: int, seed: int) -> tuple[np.ndarray, Cell, float]:
    """The map ``name`` as a ``cells`` x ``cells`` bounded grid, its start cell, and the resolution (m/cell)
    it was drawn at."""
    from fleet_emu.world.maps import load_map

    cs, _ = fit_cell_size(name, cells, seed)
    m = load_map(name, cs, seed)
    grid, start = square(m.grid, m.start, cells)
    return grid, start, cs


# --- one run ---------------------------------------------------------------------------------------------

def run_mhm(grid: np.ndarray, base: Cell, robots: int, a: Any) -> dict[str, Any]:
    """MHM's pure planner in its kinematic sim; the row's numbers and the cells-seen curve."""
    from fleet_emu.agents.allocators.mhm.planner import MhmConfig
    from fleet_emu.agents.allocators.mhm.sim import simulate

    config = MhmConfig(r_comm=a.r_comm, sensor_range=a.sensor)
    t0 = time.thread_time()
    # ticks 0 .. max_ticks, as the memory engine's runs (the sim's loop stops before its max_ticks)
    out = simulate(grid, base, robots, config, a.seed, a.max_ticks + 1, clock=time.thread_time)
    run_s = time.thread_time() - t0
    ms = sorted(out.step_ms)
    return {
        "ticks": out.ticks, "end": "step18" if out.done else "max_ticks", "coverage": out.coverage,
        "seen": out.seen, "overall": statistics.fmean(out.connected),
        "all": sum(c >= 1.0 for c in out.connected) / len(out.connected), "worst": min(out.connected),
        "ms_mean": statistics.fmean(ms), "ms_p95": ms[min(len(ms) - 1, int(0.95 * len(ms)))], "ms_max": ms[-1],
        "plan_s": sum(ms) / 1000.0, "run_s": run_s, "stalls": out.planner.stalls,
    }


def run_fleet(grid: np.ndarray, base: Cell, robots: int, allocator: str, a: Any) -> dict[str, Any]:
    """One fleet on the memory engine with a base station at ``base``; the row's numbers and the curve."""
    from fleet_emu.agents.allocators.mhm.sim import start_cells
    from fleet_emu.core.grid import FREE, MapData
    from fleet_emu.core.scenario import Scenario
    from fleet_emu.launch.memory import Fleet

    cs = a.cell_size
    s = Scenario().override(map=a.map_name, robots=robots, allocator=allocator, comm="disk", comm_range=a.r_comm * cs,
                            sensor_range=a.sensor * cs, cell_size=cs, loss=a.loss, seed=a.seed,
                            max_ticks=a.max_ticks, base=list(base), target_coverage=0.99)
    fleet = Fleet(s, map_data=MapData(a.label, grid, cs, base), starts=start_cells(grid == FREE, base, robots))
    t0 = time.thread_time()
    fleet.reset()
    seen = [fleet.world.sensed_cells]
    while not fleet.done:
        fleet.step()
        seen.append(fleet.world.sensed_cells)
    run_s = time.thread_time() - t0
    r = fleet.result().data
    frac = r["base_connected_fraction"]
    reports = list(fleet.monitor.reports.values())
    decisions = sum(rep.decisions for rep in reports) or 1
    plan_ms = sum(rep.decision_cpu_ms for rep in reports)
    return {
        "ticks": r["ticks"], "end": r["reason"], "coverage": r["coverage"], "seen": seen,
        "overall": frac["overall"], "all": frac["all_ticks"],
        "worst": min((c for _, c in fleet.monitor.base_curve), default=float("nan")),
        "ms_mean": plan_ms / decisions, "ms_p95": None, "ms_max": None, "plan_s": plan_ms / 1000.0,
        "run_s": run_s, "stalls": None,
    }


# --- the table -------------------------------------------------------------------------------------------

def seen_at(row: dict[str, Any], tick: int) -> str:
    """Cells seen by ``tick``: the last value after a run that ended (nothing more to see), ``-`` past a run
    cut at ``--max-ticks``."""
    seen = row["seen"]
    if tick >= len(seen) and row["end"] == "max_ticks":
        return "-"
    return str(seen[min(tick, len(seen) - 1)])


def header(at: list[int]) -> str:
    return (f"{'map':>10} {'allocator':>12} {'robots':>6} {'ticks':>5} {'end':>9} {'coverage':>8} "
            + " ".join(f"{'seen@' + str(t):>10}" for t in at)
            + f" {'overall':>7} {'all':>5} {'worst':>5} {'ms mean':>8} {'ms p95':>7} {'ms max':>7} {'plan s':>7}"
            f" {'run s':>7}")


def line(map_name: str, allocator: str, robots: int, row: dict[str, Any], at: list[int]) -> str:
    def num(v: float | None, width: int, f: str) -> str:
        return f"{'-':>{width}}" if v is None else f"{v:>{width}{f}}"

    return (f"{map_name:>10} {allocator:>12} {robots:>6} {row['ticks']:>5} {row['end']:>9} {row['coverage']:>8.3f} "
            + " ".join(f"{seen_at(row, t):>10}" for t in at)
            + f" {row['overall']:>7.3f} {row['all']:>5.3f} {row['worst']:>5.3f} {num(row['ms_mean'], 8, '.3f')}"
            f" {num(row['ms_p95'], 7, '.2f')} {num(row['ms_max'], 7, '.1f')} {row['plan_s']:>7.1f}"
            f" {row['run_s']:>7.1f}")


def parse(argv: list[str] | None) -> Any:
    p = parser("benchmarks.paper_setting", __doc__, full=False)
    p.add_argument("--maps", nargs="+", default=["grid", REAL_MAP],
                   help="built-in map names or map files (default: grid and the registry's cave)")
    p.add_argument("--robots", type=int, nargs="+", default=[10, 20])
    p.add_argument("--allocators", nargs="+", default=["mhm", "minpos", "connectivity"])
    p.add_argument("--cells", type=int, default=512, help="the maps' side in cells (the paper: 512)")
    p.add_argument("--r-comm", type=float, default=40.0, help="radio range in cells (the paper: 40)")
    p.add_argument("--sensor", type=float, default=15.0, help="sensor range in cells (the paper: 15)")
    p.add_argument("--max-ticks", type=int, default=2000)
    p.add_argument("--at", type=int, nargs="+", default=None, help="ticks of the seen@ columns")
    p.add_argument("--cell-size", type=float, default=1.0, help="metres per cell in the runs (eq. 9's scale)")
    p.add_argument("--loss", type=float, default=0.0)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", type=Path, default=None, help="write Fig. 7 (PNG) here")
    p.add_argument("--json", type=Path, default=None, help="write the rows and curves (JSON) here")
    p.add_argument("--from", dest="from_json", type=Path, nargs="+", default=None, metavar="JSON",
                   help="run nothing: the table and --out of these --json files' rows, joined")
    a = p.parse_args(argv)
    if min(a.robots) < 1:
        fail(PROG, f"--robots must be at least 1 (got {min(a.robots)})")
    if a.cells < 8:
        fail(PROG, f"--cells must be at least 8 (got {a.cells})")
    for flag, v in (("--r-comm", a.r_comm), ("--sensor", a.sensor), ("--cell-size", a.cell_size)):
        if not (np.isfinite(v) and v > 0):
            fail(PROG, f"{flag} must be a positive number (got {v})")
    if a.max_ticks < 1:
        fail(PROG, f"--max-ticks must be at least 1 (got {a.max_ticks})")
    if not 0.0 <= a.loss <= 1.0:
        fail(PROG, f"--loss must be in [0, 1] (got {a.loss})")
    from fleet_emu.agents.allocators import allocator_names

    known = set(allocator_names()) | {"mhm"}
    for name in a.allocators:
        if name not in known:
            fail(PROG, f"unknown allocator {name!r} (one of {', '.join(sorted(known))})")
    a.at = sorted({t for t in (a.at or AT) if t <= a.max_ticks} | ({a.max_ticks} if a.at is None else set()))
    for path in (a.out, a.json):
        if path is not None and not path.parent.is_dir():
            fail(PROG, f"no such directory for {path}: {path.parent}")
    for path in a.from_json or ():
        if not path.is_file():
            fail(PROG, f"no such file: {path}")
    return a


def save(rows: list[dict[str, Any]], a: Any) -> None:
    """Write ``--json`` (after every run, so that an interrupted invocation keeps the runs it finished)."""
    if a.json is not None:
        setting = {k: (str(v) if isinstance(v, Path) else [str(p) for p in v] if k == "from_json" and v else v)
                   for k, v in vars(a).items()}
        tmp = a.json.with_name(a.json.name + ".tmp")
        tmp.write_text(json.dumps({"setting": setting, "rows": rows}))
        tmp.replace(a.json)


def saved_rows(paths: list[Path], a: Any) -> list[dict[str, Any]]:
    """The rows of earlier ``--json`` files, in order (a bad file is a one-line error); the first file's
    setting (cells, r_comm, sensor) goes into ``a`` for the figure's title."""
    rows: list[dict[str, Any]] = []
    for path in paths:
        try:
            saved = json.loads(path.read_text())
            rows += saved["rows"]
            setting = saved["setting"]
        except (OSError, ValueError, KeyError, TypeError) as exc:
            fail(PROG, f"{path} is not a --json file of this script: {exc}")
        if path == paths[0]:
            a.cells, a.r_comm, a.sensor = setting["cells"], setting["r_comm"], setting["sensor"]
    return rows


def draw(rows: list[dict[str, Any]], a: Any) -> None:
    """Fig. 7 from the rows: cells seen against ticks, a line per fleet size, a panel per allocator and map."""
    from fleet_emu.recording.plots import panels_plot

    panels: dict[tuple[str, str], dict[str, list[int]]] = {}
    for r in sorted((r for r in rows if "seen" in r), key=lambda r: r["robots"]):
        panels.setdefault((r["map"], r["allocator"]), {})[f"{r['robots']} robots"] = r["seen"]
    panels_plot(panels, a.out, xlabel="tick", ylabel="cells seen",
                title=f"Mukhija et al. Fig. 7 setting: {a.cells}x{a.cells} cells, r_comm {a.r_comm:g}, "
                      f"sensor {a.sensor:g}, base at the start")


def replay(a: Any) -> None:
    """``--from``: the table and ``--out`` of earlier ``--json`` files, sorted by map, allocator and fleet size."""
    rows = saved_rows(a.from_json, a)
    maps = {m: i for i, m in enumerate(dict.fromkeys(r["map"] for r in rows))}
    allocators = {x: i for i, x in enumerate(dict.fromkeys(r["allocator"] for r in rows))}
    rows.sort(key=lambda r: (maps[r["map"]], allocators[r["allocator"]], r["robots"]))
    print(header(a.at))
    for r in rows:
        if "seen" in r:
            print(line(r["map"], r["allocator"], r["robots"], r, a.at))
    if a.out is not None:
        draw(rows, a)


def main(argv: list[str] | None = None) -> None:
    a = parse(argv)
    if a.from_json:
        replay(a)
        return
    from fleet_emu.core.errors import MapError
    from fleet_emu.core.grid import FREE
    from fleet_emu.core.kernels import warm_up

    maps: dict[str, tuple[np.ndarray, Cell, float]] = {}
    for name in a.maps:
        try:
            maps[name] = paper_map(name, a.cells, a.seed)
        except MapError as exc:
            fail(PROG, f"map {name}: {exc}")
    warm_up()
    print(f"# benchmarks/paper_setting.py: {machine()}")
    print(f"# {a.cells} x {a.cells} cells, r_comm {a.r_comm:g} cells, sensor {a.sensor:g} cells, "
          f"{a.cell_size:g} m/cell in the runs, loss {a.loss:g}, seed {a.seed}, {a.max_ticks} ticks at most; "
          "mhm: pure planner, kinematic sim; others: memory engine, disk radio, base listening")
    for name, (grid, start, cs) in maps.items():
        print(f"# map {Path(name).stem}: drawn at {cs:.4f} m/cell, {int((grid == FREE).sum())} free cells, "
              f"base at {start}")
    print(header(a.at), flush=True)
    rows: list[dict[str, Any]] = []
    failed = 0
    total = len(maps) * len(a.allocators) * len(a.robots)
    for name, (grid, start, _cs) in maps.items():
        label = Path(name).stem
        a.label, a.map_name = label, name
        for allocator in a.allocators:
            for n in a.robots:
                k = len(rows) + 1
                wall = time.perf_counter()
                try:
                    row = run_mhm(grid, start, n, a) if allocator == "mhm" else run_fleet(grid, start, n, allocator, a)
                except Exception as exc:  # a failed run is a row, and exit 1, not the end of the table
                    failed += 1
                    print(f"[{k}/{total}] {label} {allocator} {n}: FAILED: {type(exc).__name__}: {exc}",
                          file=sys.stderr, flush=True)
                    print(f"{label:>10} {allocator:>12} {n:>6} error: {type(exc).__name__}", flush=True)
                    rows.append({"map": label, "allocator": allocator, "robots": n, "error": str(exc)})
                    save(rows, a)
                    continue
                print(line(label, allocator, n, row, a.at), flush=True)
                print(f"[{k}/{total}] {label} {allocator} {n}: {row['ticks']} ticks, {row['end']}, "
                      f"{time.perf_counter() - wall:.0f} s wall", file=sys.stderr, flush=True)
                rows.append({"map": label, "allocator": allocator, "robots": n} | row)
                save(rows, a)
    if a.out is not None:
        draw(rows, a)
    if failed:
        print(f"paper_setting: {failed} of {total} runs failed (see the lines above)", file=sys.stderr)
        raise SystemExit(1)


if __name__ == "__main__":
    main()
