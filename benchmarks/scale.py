"""How the multi-process fleet scales with robots on a 512 x 512-cell map.

    python -m benchmarks.scale [--robots 16 32 64 100] [--ticks 30] [--cells 512] [--maps maze PATH ...]

For every map and robot count, one run of the default engine (one OS process per node over Zenoh, lockstep),
allocator ``minpos`` with parallel wavefronts, the default radio (wall model, 10 % loss), no recording, for a
fixed number of ticks (``max_ticks``, target coverage 1.0 so that no run ends early). Each map is fitted to
about ``--cells`` cells across through its cell size: a built-in generator (``maze`` by default) and a real map
(the registry's ``cave``: ``fleet maps fetch cave``) resampled. The sensor and comm ranges are fixed in cells
(``--sensor-cells``, ``--comm-cells``: 8 and 20, the default scenario's 4 m and 10 m at 0.5 m cells) so that
only the map grows.
The fleet starts, for every robot count, around the same cell of each map: the most open one (most free cells
within the world's start radius) of the map's main free component, nearest the map's own start. Each run is a
child process of its own (``--one``), so that the launcher's memory is that run's alone.

One table row per map and robot count (stdout):

- ``start s``: wall time from calling the launcher to the world's first state (tick 0);
- ``ticks/s``: lockstep speed from the first state to the last (``result.json``'s ``ticks_per_second``);
- CPU in ms per robot-tick, from ``/proc/PID/stat`` (utime + stime) of every process, sampled when the state
  of a tick reaches the launcher, from the first sampled tick to the last one before the stop (start-up and
  teardown excluded): ``world``, ``netem``, and each agent's split with the agents' own thread-CPU clocks
  (their ``ctl/report``): ``decide`` (the allocator's ``allocate``), ``brain`` (the rest of ``Brain.step``:
  belief merge, frontier clusters, radio payload decode, navigation), ``a.py`` (the rest of the agent's event
  loop thread: message encode and decode, asyncio, publishing) and ``a.zen`` (the agent process's other
  threads: Zenoh's runtime, with its calls into Python that copy each sample out); all are averaged over every
  decision of the run but each robot's first (tick 0: it merges every teammate's first map and clusters the
  whole belief, a start-up cost shown apart, see below), from the agents' own clocks (thread CPU of the step
  and of the loop, process CPU, from the end of the first step to the report: the same ticks, so none is
  negative, which a /proc window is not: its ticks under load are not the agents'); ``outside`` is the
  agent's CPU outside the allocator (``brain + a.py + a.zen``); ``router`` the
  run's Zenoh router process (``pids.router``) and ``launch`` the launcher process (its fold and
  subscriptions); ``total`` their sum, and ``cores`` the CPU seconds per wall second over the window (at
  most the machine's cores);
- PSS in MB (``/proc/PID/smaps_rollup``, shared pages divided among the processes mapping them), sampled a
  couple of ticks before the end while every process is alive: agents' mean and max, world, netem, the
  router and the launcher;
- ``dec wall``: ``result.json``'s ``decision_ms.mean`` (perf_counter around ``allocate``: the wall time, which
  counts the waits for a core when the agents outnumber them);
- ``load1``: the 1-minute load average at the end of the run (the fleet's own processes, and other jobs on
  the machine).

A second table splits each run's ``brain`` by stage (``Brain.cpu_ms``: merge, clusters, decode, navigation,
news, and the rest as ``other``; they add up to ``brain``) and gives ``tick0``, an agent's mean process CPU in
its first step.

A robot count above ``fleet_emu.core.scenario.MAX_ROBOTS`` is a ``cap`` row, not run; a fleet larger than the
free area reachable from the start a ``start`` row, and one the launcher's memory check refuses
(``launch/budget.py``) a ``memory`` row, not run either. Numba compiles the kernels into their cache on a fresh
checkout: the first run's start-up then includes it. Progress goes to stderr. Exit 0 when every run finished, 1
when one failed (a ``failed`` row), 2 on a bad argument (one line).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from benchmarks._common import (
    REAL_MAP,
    ROOT,
    FittedMap,
    fail,
    fitted_maps,
    fitted_scenario,
    machine,
    parser,
    smaps_rollup,
)

CLK_TCK = os.sysconf("SC_CLK_TCK")
PROG = "scale"


def cpu_seconds(pid: int) -> float | None:
    """utime + stime of a process (every thread, live or ended), None when it is gone."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    fields = stat.rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # fields 14 and 15 of proc(5), after pid and comm


# --- one run ---------------------------------------------------------------------------------------------

@dataclasses.dataclass
class Sampler:
    """Samples the fleet's processes from the launcher's progress callback: CPU times at the first
    tick seen and at every later tick before the stop; PSS at the first tick seen, then near the end, sampled
    again at each later tick until one sample finds every process (a short run may end, and a process exit,
    between two progress calls: the first sample then stands)."""

    ticks: int
    pids: dict[str, Any] = dataclasses.field(default_factory=dict)
    first: tuple[int, float, dict[str, float]] | None = None  # (tick, monotonic time, CPU seconds by process)
    last: tuple[int, float, dict[str, float]] | None = None
    pss: dict[str, int] = dataclasses.field(default_factory=dict)
    late: bool = False  # whether ``pss`` is a late sample that found every process
    monitor: Any = None

    def spawned(self, pids: dict[str, Any]) -> None:
        agents = pids["robots"]
        self.pids = {"world": pids["world"], "netem": pids["netem"], "launcher": os.getpid(),
                     **({"router": pids["router"]} if "router" in pids else {}),
                     **{f"r{i}": p for i, p in enumerate(agents)}}

    def _cpu(self) -> dict[str, float]:
        return {k: c for k, p in self.pids.items() if (c := cpu_seconds(p)) is not None}

    def progress(self, monitor: Any) -> None:
        self.monitor = monitor
        if not self.pids or monitor.state is None:
            return
        tick = monitor.state.tick
        if monitor.stop is None and (self.last is None or tick > self.last[0]):
            cpu = self._cpu()
            if len(cpu) == len(self.pids):  # not once a process has exited: its CPU would drop out of ``cores``
                self.last = (tick, time.monotonic(), cpu)
                self.first = self.first or self.last
        late = tick >= self.ticks - 2 or monitor.stop is not None
        if not self.pss or (late and not self.late):
            pss = {k: v for k, p in self.pids.items() if (v := (smaps_rollup(p) or {}).get("Pss")) is not None}
            if len(pss) >= len(self.pss):  # a process that has exited has no PSS left to read
                self.pss = pss
                self.late = late and len(pss) == len(self.pids)


def scenario_for(m: FittedMap, robots: int, a: argparse.Namespace) -> Any:
    """The default scenario on this map and fleet for ``a.ticks`` ticks, minpos with parallel wavefronts."""
    return fitted_scenario(m, robots, a.seed, a.sensor_cells, a.comm_cells, {"type": "minpos", "wavefront": "parallel"},
                           max_ticks=a.ticks, target_coverage=1.0)


def _stage_ms(stage: str, report: Any) -> float:
    return float(report.stage_cpu_ms.get(stage, 0.0))


def run_one(m: FittedMap, robots: int, a: argparse.Namespace) -> dict[str, Any]:
    """One fleet run, in this process; the row's numbers (raises FleetError when the run failed)."""
    from fleet_emu.agents.brain import STAGES
    from fleet_emu.launch.runner import RunOptions, run_fleet

    sampler = Sampler(a.ticks)
    t0 = time.time_ns()
    result = run_fleet(scenario_for(m, robots, a),
                       RunOptions(record=False, on_progress=sampler.progress, on_spawn=sampler.spawned))
    mon = sampler.monitor
    first, last = sampler.first, sampler.last
    if mon is None or first is None or last is None or last[0] <= first[0]:
        raise RuntimeError(f"too few ticks sampled ({result['ticks']} ticks run): raise --ticks")
    window_ticks, wall = last[0] - first[0], last[1] - first[1]
    per = window_ticks * robots / 1000.0  # ms per robot-tick from CPU seconds
    cpu = {k: last[2][k] - first[2].get(k, 0.0) for k in last[2]}
    # the agents' own clocks over the same steps, their first (tick 0: a start-up cost, reported apart) left out:
    # the process CPU from the end of the first step to the report (the /proc window of the other processes is
    # not the agents' ticks under load: a.bus came out negative)
    reports = [r for r in mon.reports.values() if r.first_cpu_ms]
    steps = sum(r.decisions - 1 for r in reports)
    if steps <= 0:
        raise RuntimeError(f"no agent reported a step after its first ({result['ticks']} ticks run)")

    def later(total: Callable[[Any], float], key: str) -> float:
        """ms per robot-tick of an agent clock after the first step."""
        return sum(total(r) - r.first_cpu_ms.get(key, 0.0) for r in reports) / steps

    decide = later(lambda r: r.decision_cpu_ms, "decision")
    step = later(lambda r: r.step_cpu_ms, "step")
    agent_ms = later(lambda r: r.process_cpu_ms, "process")
    loop_ms = later(lambda r: r.loop_cpu_ms, "loop")
    stages = {k: later(functools.partial(_stage_ms, k), k) for k in STAGES if k != "decision"}
    agent_pss = [sampler.pss[k] / 1024 for k in sampler.pss if k.startswith("r")] or [0.0]
    row = {
        "start": ((mon.first_state_ns or t0) - t0) / 1e9,
        "ticks": result["ticks"],
        "tps": result["ticks_per_second"] or 0.0,
        "world": cpu.get("world", 0.0) / per,
        "netem": cpu.get("netem", 0.0) / per,
        "decide": decide,
        "brain": step - decide,
        "apy": loop_ms - step,
        "azen": agent_ms - loop_ms,
        "outside": agent_ms - decide,
        "router": cpu.get("router", 0.0) / per,
        "launch": cpu.get("launcher", 0.0) / per,
        "cores": sum(cpu.values()) / wall if wall > 0 else 0.0,
        "pss_mean": sum(agent_pss) / len(agent_pss),
        "pss_max": max(agent_pss),
        "pss_world": sampler.pss.get("world", 0) / 1024,
        "pss_netem": sampler.pss.get("netem", 0) / 1024,
        "pss_router": sampler.pss.get("router", 0) / 1024,
        "pss_launcher": sampler.pss.get("launcher", 0) / 1024,
        "dec_wall": result["decision_ms"]["mean"],
    }
    row["stages"] = stages | {"other": step - sum(stages.values()) - decide,
                              "tick0": sum(r.first_cpu_ms["process"] for r in reports) / len(reports)}
    row["total"] = row["world"] + row["netem"] + agent_ms + row["router"] + row["launch"]
    return row


# --- the table -------------------------------------------------------------------------------------------

COLUMNS = [("map", 10, "s"), ("cells", 9, "s"), ("robots", 6, "d"), ("start s", 7, ".1f"), ("ticks", 5, "d"),
           ("ticks/s", 7, ".2f"), ("world", 6, ".2f"), ("netem", 6, ".2f"), ("decide", 6, ".2f"),
           ("brain", 6, ".2f"), ("a.py", 6, ".2f"), ("a.zen", 6, ".2f"), ("outside", 7, ".2f"),
           ("router", 6, ".2f"), ("launch", 6, ".2f"), ("total", 6, ".2f"),
           ("cores", 5, ".2f"), ("a.mean", 6, ".0f"), ("a.max", 6, ".0f"), ("world", 6, ".0f"),
           ("netem", 6, ".0f"), ("router", 6, ".0f"), ("launch", 6, ".0f"), ("dec wall", 8, ".2f"), ("load1", 5, ".2f")]
KEYS = ["map", "cells", "robots", "start", "ticks", "tps", "world", "netem", "decide", "brain", "apy", "azen",
        "outside", "router", "launch", "total", "cores", "pss_mean", "pss_max", "pss_world", "pss_netem",
        "pss_router", "pss_launcher", "dec_wall", "load1"]


def stage_table(rows: list[dict[str, Any]]) -> str:
    """The second table: each run's ``brain`` column split by stage (ms of thread CPU per robot-tick), in the
    order :func:`run_one` gives them (``Brain.step``'s stages besides the allocator, ``other``, ``tick0``)."""
    names = list(rows[0]["stages"])
    lines = ["# brain by stage (Brain.cpu_ms), ms of thread CPU per robot-tick; tick0: an agent's process CPU in "
             "its first step (mean), left out of every agent column",
             f"{'map':>10} {'robots':>6} " + " ".join(f"{n:>10}" for n in names)]
    for row in rows:
        cells = " ".join(f"{row['stages'][n]:>10.3f}" for n in names)
        lines.append(f"{row['map']:>10} {row['robots']:>6} {cells}")
    return "\n".join(lines)


def header() -> str:
    groups = " " * 51 + "| CPU ms per robot-tick" + " " * 60 + "| PSS MB" + " " * 35 + "|"
    return groups + "\n" + " ".join(f"{name:>{w}}" for name, w, _ in COLUMNS)


def line(row: dict[str, Any]) -> str:
    cells = []
    for key, (_, w, fmt) in zip(KEYS, COLUMNS, strict=True):
        cells.append(f"{row[key]:>{w}{fmt}}" if key in row else f"{'':>{w}}")
    text = " ".join(cells)
    if "note" in row:
        text = text[:sum(w + 1 for _, w, _ in COLUMNS[:3])] + row["note"]
    return text


def parse(argv: list[str] | None) -> argparse.Namespace:
    p = parser("benchmarks.scale", __doc__)
    p.add_argument("--robots", type=int, nargs="+", default=[16, 32, 64, 100], help="fleet sizes")
    p.add_argument("--ticks", type=int, default=30, help="ticks per run (the scenario's max_ticks)")
    p.add_argument("--cells", type=int, default=512, help="cells across the maps (their larger side)")
    p.add_argument("--maps", nargs="+", default=["maze", REAL_MAP],
                   help=f"built-in map names or map files (default: maze and {REAL_MAP})")
    p.add_argument("--sensor-cells", type=float, default=8.0, help="sensor range in cells")
    p.add_argument("--comm-cells", type=float, default=20.0, help="comm range c in cells")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--one", nargs=5, metavar=("MAP", "CELL_SIZE", "ROBOTS", "ROW", "COL"),
                   help=argparse.SUPPRESS)  # one run in this process: its row as one JSON line on stdout
    a = p.parse_args(argv)
    if min(a.robots) < 1:
        fail(PROG, f"--robots must be at least 1 (got {min(a.robots)})")
    if a.ticks < 4:
        fail(PROG, f"--ticks must be at least 4 (got {a.ticks})")
    if a.cells < 8:
        fail(PROG, f"--cells must be at least 8 (got {a.cells})")
    if a.sensor_cells < 1 or a.comm_cells <= 0:
        fail(PROG, "--sensor-cells must be at least 1 and --comm-cells positive")
    return a


def child(a: argparse.Namespace) -> None:
    """``--one``: one run in this process, its row (or ``error``, ``start_area`` when the fleet does not fit
    the map's free area, ``memory`` when the machine does not hold it) as one JSON line on stdout."""
    from fleet_emu.core.errors import FleetError
    from fleet_emu.launch.budget import BudgetError
    from fleet_emu.world.sim import StartAreaError

    name, cs, robots, row, col = a.one
    m = FittedMap(name, Path(name).stem, float(cs), (0, 0), (int(row), int(col)))  # the shape is the parent's
    try:
        out: dict[str, Any] = run_one(m, int(robots), a)
    except StartAreaError as exc:
        out = {"start_area": str(exc)}
    except BudgetError as exc:
        out = {"memory": str(exc)}
    except (FleetError, RuntimeError) as exc:
        out = {"error": str(exc).splitlines()[0][:300]}
    print(json.dumps(out), flush=True)


def spawn_one(m: FittedMap, robots: int, a: argparse.Namespace) -> dict[str, Any]:
    """One run in a child process (``--one``): its JSON line, or an ``error``."""
    cmd = [sys.executable, "-m", "benchmarks.scale", "--one", m.name, repr(m.cell_size), str(robots),
           *map(str, m.start), "--ticks", str(a.ticks), "--sensor-cells", str(a.sensor_cells),
           "--comm-cells", str(a.comm_cells), "--seed", str(a.seed)]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    lines = proc.stdout.strip().splitlines()
    try:
        return dict(json.loads(lines[-1]))
    except (IndexError, ValueError):
        err = proc.stderr.strip().splitlines()
        return {"error": f"exit {proc.returncode}: {err[-1][:300] if err else 'no output'}"}


def main(argv: list[str] | None = None) -> None:
    a = parse(argv)
    if a.one:
        child(a)
        return
    from fleet_emu.core.scenario import MAX_ROBOTS

    maps = fitted_maps(PROG, a.maps, a.cells, a.seed)
    print(f"# benchmarks/scale.py: {machine()}")
    print(f"# minpos (parallel wavefronts), processes engine, wall radio, loss 0.1, {a.ticks} ticks, sensor "
          f"{a.sensor_cells:g} cells, comm {a.comm_cells:g} cells, seed {a.seed}, robot cap {MAX_ROBOTS}")
    print(header(), flush=True)
    total, failed, done = len(maps) * len(a.robots), 0, 0
    measured: list[dict[str, Any]] = []
    for m in maps:
        label = m.label
        for n in a.robots:
            done += 1
            row: dict[str, Any] = {"map": label[:10], "cells": m.cells, "robots": n}
            if n > MAX_ROBOTS:
                row["note"] = f"cap: more than {MAX_ROBOTS} robots is refused (core/scenario.py)"
                print(f"[{done}/{total}] {label} {n} robots: over the cap of {MAX_ROBOTS}, not run",
                      file=sys.stderr, flush=True)
            else:
                t = time.monotonic()
                got = spawn_one(m, n, a)
                if "start_area" in got or "memory" in got:
                    why = "start" if "start_area" in got else "memory"
                    row["note"] = ("start: the map's free area holds fewer robots" if why == "start" else
                                   "memory: the launcher's memory check refused the run")
                    print(f"[{done}/{total}] {label} {n} robots: not run ({got.get('start_area') or got['memory']})",
                          file=sys.stderr, flush=True)
                elif "error" in got:
                    failed += 1
                    row["note"] = "failed"
                    print(f"[{done}/{total}] {label} {n} robots: FAILED ({got['error']})", file=sys.stderr,
                          flush=True)
                else:
                    row |= got
                    measured.append(row)
                    row["load1"] = os.getloadavg()[0]
                    print(f"[{done}/{total}] {label} {n} robots: {row['ticks']} ticks, {row['tps']:.2f} ticks/s, "
                          f"start-up {row['start']:.1f} s, {time.monotonic() - t:.0f} s in all",
                          file=sys.stderr, flush=True)
            print(line(row), flush=True)
    if measured:
        print(stage_table(measured), flush=True)
    if failed:
        print(f"scale: {failed} of {total} runs failed (see the lines above)", file=sys.stderr)
        raise SystemExit(1)


if __name__ == "__main__":
    main()
