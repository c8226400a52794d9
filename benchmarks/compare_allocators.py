"""Mean ticks to 99 % coverage per allocator, fleet size and map, over several seeds (the real fleet).

    python -m benchmarks.compare_allocators [--allocators nearest greedy utility minpos hungarian]
        [--robots 2 4 8] [--seeds 5] [--maps office hospital_section]
        [--loss 0] [--start random] [--jobs 2] [--in-process | --engine memory]

Each cell runs ``fleet run`` as a subprocess (``--no-record --quiet``; ``--engine memory`` for the memory engine:
the same results for a seed at a fraction of the CPU) and reads its ``result.json``. A run that
does not reach the target counts as its last tick and is flagged with ``*`` (and the count of such runs); a run
that failed (an exit code other than 0 or 3: bad input, or a process of the fleet, a robot too, failed) is left
out and counted as ``E``. One line per finished run goes to stderr; the exit code is 1 when any run failed.
With ``--start random`` (the default) each seed also draws the fleet's start cell, so that seeds differ even
at loss 0 on a fixed map; ``--start map`` keeps the map's own start.
"""

from __future__ import annotations

import statistics
import sys
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from benchmarks._common import HOSPITAL, engine_arguments, engine_flags, fleet_run, parser


def run_one(allocator: str, robots: int, seed: int, map_name: str, loss: float, extra: list[str]) -> dict[str, Any]:
    """One ``fleet run`` (``_common.fleet_run``): its result.json, or ``{"error": ..., "code": ...}`` when it did
    not end normally."""
    return fleet_run(["--map", map_name, "--robots", str(robots), "--allocator", allocator, "--seed", str(seed),
                      "--loss", str(loss), *extra])


def describe(result: dict[str, Any]) -> str:
    """A finished run in a few words, for the progress line."""
    if "error" in result:
        return f"FAILED (exit {result['code']}): {result['error']}"
    return f"t99 {result['t99']}, coverage {result['coverage']:.1%} at tick {result['ticks']}"


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.compare_allocators", __doc__)
    p.add_argument("--allocators", nargs="+", default=["nearest", "greedy", "utility", "minpos", "hungarian"])
    p.add_argument("--robots", type=int, nargs="+", default=[2, 4, 8])
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--maps", nargs="+", default=["office", HOSPITAL])
    p.add_argument("--loss", type=float, default=0.0)
    p.add_argument("--start", default="random", help="'random' (drawn per seed), 'map', or ROW,COL")
    p.add_argument("--jobs", type=int, default=2)
    engine_arguments(p)
    a = p.parse_args(argv)
    extra = engine_flags(a)
    if a.start != "map":
        extra += ["--start", a.start]
    jobs = [(al, n, s, m) for m in a.maps for n in a.robots for al in a.allocators for s in range(a.seeds)]
    results: list[dict[str, Any]] = [{}] * len(jobs)
    with ThreadPoolExecutor(a.jobs) as pool:
        futures = {pool.submit(run_one, al, n, s, m, a.loss, extra): i for i, (al, n, s, m) in enumerate(jobs)}
        for done, future in enumerate(as_completed(futures), start=1):
            i = futures[future]
            results[i] = future.result()
            al, n, s, m = jobs[i]
            print(f"[{done}/{len(jobs)}] {al} x{n} seed {s} on {Path(m).stem}: {describe(results[i])}",
                  file=sys.stderr, flush=True)
    table: dict[tuple[str, int, str], list[dict[str, Any]]] = {}
    for (al, n, _, m), r in zip(jobs, results, strict=True):
        table.setdefault((m, n, al), []).append(r)
    print(f"mean±sd ticks to 99% coverage (t99), loss {a.loss}, start {a.start}, seeds 0..{a.seeds - 1}; "
          f"'*k' = k runs that did not reach it (counted at their last tick)")
    for m in a.maps:
        print(f"\nmap {Path(m).stem}")
        print(f"{'robots':>6} " + " ".join(f"{al:>16}" for al in a.allocators))
        for n in a.robots:
            cells = []
            for al in a.allocators:
                rs = table[(m, n, al)]
                errors = [r for r in rs if "error" in r]
                ok = [r for r in rs if "error" not in r]
                ticks = [r["t99"] if r["t99"] is not None else r["ticks"] for r in ok]
                miss = sum(1 for r in ok if r["t99"] is None)
                text = f"{statistics.mean(ticks):.0f}±{statistics.pstdev(ticks):.0f}" if ticks else "-"
                text += f" *{miss}" if miss else ""
                text += f" E{len(errors)}" if errors else ""
                cells.append(f"{text:>16}")
            print(f"{n:>6} " + " ".join(cells))
    failed = sum(1 for r in results if "error" in r)
    if failed:
        print(f"compare_allocators: {failed} of {len(results)} runs failed (E in the table; see the lines above)",
              file=sys.stderr)
        raise SystemExit(1)


if __name__ == "__main__":
    main()
