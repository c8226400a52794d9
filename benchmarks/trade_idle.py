"""Trade against Hungarian: ticks, total path and idle robot-ticks per map and loss (the real fleet).

    python -m benchmarks.trade_idle [--allocators hungarian trade trade:explore_in_round=false] [--robots 4]
        [--seeds 5] [--maps office hospital_section autolab]
        [--loss 0 0.1 0.3 0.5] [--comm wall] [--start random] [--jobs 2] [--in-process | --engine memory]

Yan et al. 2011 compare their trade-based allocation with a Hungarian-method central planner (section 5,
Tables 1-2: +3.9 % and +7.4 % runtime with 4 robots) and run it under 10/30/50 % message loss (Tables 3-4).
Per (map, loss, allocator) the table gives the mean ± sd of the ticks to 99 % coverage (a run that does not
reach it counts at its last tick, flagged ``*k``), the mean total path (cells), the mean idle robot-ticks
(result.json's ``idle_robot_ticks``: a robot with something to do that stays on its cell) with the share of
the run's robot-ticks they are and how many of them the robots spent ``WAITING`` (in a protocol round), and,
for every allocator after the first, the mean paired difference in ticks to the first one (same map, loss
and seed). An allocator is ``NAME`` or ``NAME:PARAM=VALUE,...`` (its parameters, given through a scenario
file: ``trade:explore_in_round=false`` is the first version, robots standing still during a round). Each run
is ``fleet run --no-record --quiet`` in a subprocess (with ``--in-process``, every node of a run in that one
process; with ``--engine memory``, the memory engine, no Zenoh: the same results at a fraction of the CPU).
One line per finished run goes to stderr; the exit code is 1 when a run failed (exit other than 0 or 3; left
out of the table, counted as ``E``).
"""

from __future__ import annotations

import statistics
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from benchmarks._common import HOSPITAL, engine_arguments, engine_flags, parser
from benchmarks.compare_allocators import run_one as fleet_run

MAPS = ["office", HOSPITAL, "autolab"]  # the latter two from the registry (`fleet maps fetch NAME`)


def run_one(spec: str, robots: int, seed: int, map_name: str, loss: float,
            extra: list[str]) -> dict[str, Any]:
    """One ``fleet run`` (``compare_allocators.run_one``) with the spec's parameters in a scenario file."""
    allocator, params = _spec(spec)
    with tempfile.TemporaryDirectory() as tmp:
        if params:
            scenario = Path(tmp) / "scenario.toml"
            lines = [f'type = "{allocator}"', *(f"{k} = {v}" for k, v in params.items())]
            scenario.write_text("[allocator]\n" + "\n".join(lines) + "\n")
            extra = [*extra, "--scenario", str(scenario)]
        return fleet_run(allocator, robots, seed, map_name, loss, extra)


def ticks(result: dict[str, Any]) -> int:
    return int(result["t99"] if result["t99"] is not None else result["ticks"])


def describe(result: dict[str, Any]) -> str:
    if "error" in result:
        return f"FAILED (exit {result['code']}): {result['error']}"
    return (f"t99 {result['t99']}, ticks {result['ticks']}, path {sum(result['path_length'])}, "
            f"idle {result['idle_robot_ticks']} {result['idle_by_status']}")


def _spec(spec: str) -> tuple[str, dict[str, str]]:
    """``NAME:PARAM=VALUE,...`` -> (NAME, {PARAM: VALUE}); the values as TOML (``false``, ``3``, ``"x"``)."""
    name, _, rest = spec.partition(":")
    params = {}
    for item in filter(None, rest.split(",")):
        key, _, value = item.partition("=")
        if not key or not value:
            raise ValueError(f"{spec!r} is not NAME or NAME:PARAM=VALUE,...")
        params[key] = value
    return name, params


def _ms(values: list[float]) -> str:
    return f"{statistics.mean(values):.0f}±{statistics.pstdev(values):.0f}" if values else "-"


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.trade_idle", __doc__)
    p.add_argument("--allocators", nargs="+", default=["hungarian", "trade", "trade:explore_in_round=false"])
    p.add_argument("--robots", type=int, default=4)
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--maps", nargs="+", default=MAPS)
    p.add_argument("--loss", type=float, nargs="+", default=[0.0])
    p.add_argument("--comm", default="wall")
    p.add_argument("--start", default="random", help="'random' (drawn per seed), 'map', or ROW,COL")
    p.add_argument("--jobs", type=int, default=2)
    engine_arguments(p)
    a = p.parse_args(argv)
    extra = ["--comm", a.comm] + (["--start", a.start] if a.start != "map" else [])
    extra += engine_flags(a)
    for al in a.allocators:
        try:
            _spec(al)  # a malformed spec stops here (one line, exit 2), before any run
        except ValueError as exc:
            p.error(str(exc))
    jobs = [(m, loss, al, s) for m in a.maps for loss in a.loss for al in a.allocators for s in range(a.seeds)]
    results: dict[tuple[str, float, str, int], dict[str, Any]] = {}
    with ThreadPoolExecutor(a.jobs) as pool:
        futures = {pool.submit(run_one, al, a.robots, s, m, loss, extra): (m, loss, al, s)
                   for m, loss, al, s in jobs}
        for done, future in enumerate(as_completed(futures), start=1):
            m, loss, al, s = futures[future]
            results[(m, loss, al, s)] = future.result()
            print(f"[{done}/{len(jobs)}] {al} seed {s} loss {loss} on {Path(m).stem}: "
                  f"{describe(results[(m, loss, al, s)])}", file=sys.stderr, flush=True)
    print(f"{a.robots} robots, comm {a.comm}, start {a.start}, seeds 0..{a.seeds - 1}"
          + "; ticks to 99 % (*k: k runs short of it, at their last tick); idle = robot-ticks a robot with "
            "something to do stayed on its cell (% of robot-ticks, of which waiting in a protocol round)")
    head = f"{'map':<18} {'loss':>4} {'allocator':<28} {'ticks':>10} {'vs ' + a.allocators[0]:>14} " \
           f"{'path':>6} {'idle':>6} {'idle %':>7} {'waiting':>8}"
    print(head)
    for m in a.maps:
        for loss in a.loss:
            for al in a.allocators:
                rs = [results[(m, loss, al, s)] for s in range(a.seeds)]
                ok = [r for r in rs if "error" not in r]
                miss = sum(1 for r in ok if r["t99"] is None)
                errors = len(rs) - len(ok)
                text = _ms([ticks(r) for r in ok]) + (f" *{miss}" if miss else "") + (f" E{errors}" if errors else "")
                diff = "-"
                if al != a.allocators[0]:
                    pairs = [(ticks(r), ticks(results[(m, loss, a.allocators[0], s)])) for s, r in enumerate(rs)
                             if "error" not in r and "error" not in results[(m, loss, a.allocators[0], s)]]
                    if pairs:
                        d = [x - y for x, y in pairs]
                        base = statistics.mean(y for _, y in pairs)
                        diff = f"{statistics.mean(d):+.0f} ({statistics.mean(d) / base:+.0%})"
                path = statistics.mean(sum(r["path_length"]) for r in ok) if ok else float("nan")
                idle = [r["idle_robot_ticks"] for r in ok]
                share = [r["idle_robot_ticks"] / max(1, r["ticks"] * r["robots"]) for r in ok]
                waiting = [r["idle_by_status"].get("WAITING", 0) for r in ok]
                print(f"{Path(m).stem:<18} {loss:>4} {al:<28} {text:>10} {diff:>14} {path:>6.0f} "
                      f"{statistics.mean(idle) if ok else float('nan'):>6.0f} "
                      f"{statistics.mean(share) if ok else float('nan'):>7.1%} "
                      f"{statistics.mean(waiting) if ok else float('nan'):>8.0f}")
    failed = sum(1 for r in results.values() if "error" in r)
    if failed:
        print(f"trade_idle: {failed} of {len(results)} runs failed (E in the table; see the lines above)",
              file=sys.stderr)
        raise SystemExit(1)


if __name__ == "__main__":
    main()
