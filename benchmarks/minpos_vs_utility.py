"""Ticks to full coverage per allocator and fleet size on hospital_section with a perfect radio, and MinPos's
paired difference to utility (Bautin et al. 2012, Fig. 5(a), is the figure this approaches).

    python -m benchmarks.minpos_vs_utility [--robots 2 4] [--seeds 8] [--allocators nearest utility minpos]
        [--map hospital_section] [--jobs 2] [--in-process | --engine memory]

Every run is ``fleet run --comm ideal --loss 0 --start random --target-coverage 1.0`` (a subprocess, as in
compare_allocators.py), seeds ``0 .. seeds-1``; a seed draws the same start for every allocator, so the
difference minpos - utility is paired by seed: its mean and standard error (sd / sqrt(n)) are printed, and
the relative difference of the means. A run that does not reach full coverage counts at its last tick and is
flagged ``*``; a failed run is left out (``E``), and its seed leaves the paired difference.
"""

from __future__ import annotations

import math
import statistics
import sys
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

from benchmarks._common import HOSPITAL, engine_arguments, engine_flags, mean_sd, parser
from benchmarks.compare_allocators import describe, run_one


def paired(a: dict[int, float], b: dict[int, float]) -> str:
    """Mean ± standard error of a[s] - b[s] over the seeds both have, and the relative difference of means."""
    seeds = sorted(set(a) & set(b))
    if len(seeds) < 2:
        return "-"
    d = [a[s] - b[s] for s in seeds]
    se = statistics.stdev(d) / math.sqrt(len(d))
    rel = 100.0 * statistics.fmean(d) / statistics.fmean([b[s] for s in seeds])
    return f"{statistics.fmean(d):+.1f} ± {se:.1f} ({rel:+.1f} %)"


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.minpos_vs_utility", __doc__)
    p.add_argument("--allocators", nargs="+", default=["nearest", "utility", "minpos"])
    p.add_argument("--robots", type=int, nargs="+", default=[2, 4])
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument("--map", default=HOSPITAL)
    p.add_argument("--max-ticks", type=int, default=2000)
    p.add_argument("--jobs", type=int, default=2)
    engine_arguments(p)
    a = p.parse_args(argv)
    extra = ["--comm", "ideal", "--start", "random", "--target-coverage", "1.0", "--max-ticks", str(a.max_ticks)]
    extra += engine_flags(a)
    jobs = [(al, n, s) for n in a.robots for al in a.allocators for s in range(a.seeds)]
    ticks: dict[tuple[int, str], dict[int, float]] = {}
    short: dict[tuple[int, str], int] = {}
    errors: dict[tuple[int, str], int] = {}
    with ThreadPoolExecutor(a.jobs) as pool:
        futures = {pool.submit(run_one, al, n, s, a.map, 0.0, extra): (al, n, s) for al, n, s in jobs}
        for done, future in enumerate(as_completed(futures), start=1):
            al, n, s = futures[future]
            r = future.result()
            print(f"[{done}/{len(jobs)}] {al} x{n} seed {s}: {describe(r)}", file=sys.stderr, flush=True)
            if "error" in r:
                errors[(n, al)] = errors.get((n, al), 0) + 1
                continue
            ticks.setdefault((n, al), {})[s] = float(r["ticks"])
            short[(n, al)] = short.get((n, al), 0) + int(not r["completed"])
    print(f"ticks to full coverage, mean ± sd, {Path(a.map).stem}, --comm ideal --loss 0 --start random, "
          f"seeds 0..{a.seeds - 1}; '*k': k runs short of full coverage; 'Ek': k failed runs")
    cols = [*a.allocators, *(["minpos - utility (paired, ± se)"] if {"minpos", "utility"} <= set(a.allocators)
                             else [])]
    print("| robots | " + " | ".join(cols) + " |")
    print("|---" * (len(cols) + 1) + "|")
    for n in a.robots:
        cells = []
        for al in a.allocators:
            flags = (f" *{short[(n, al)]}" if short.get((n, al)) else "") + \
                    (f" E{errors[(n, al)]}" if errors.get((n, al)) else "")
            cells.append(mean_sd(list(ticks.get((n, al), {}).values()), 1) + flags)
        if len(cols) > len(a.allocators):
            cells.append(paired(ticks.get((n, "minpos"), {}), ticks.get((n, "utility"), {})))
        print(f"| {n} | " + " | ".join(cells) + " |")
    if errors:
        print(f"{sum(errors.values())} run(s) failed", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
