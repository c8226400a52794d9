"""Lockstep speed and agent memory, multi-process, on the office map.

    python -m benchmarks.ticks_per_second [--robots 4 16] [--ticks 300] [--repeat 1]

Prints a table: robots, ticks run, wall seconds, ticks per second, and the peak RSS of the agent processes
(max and mean over agents, from getrusage in each agent). Timings are of the whole system (world, netem and N
agents sharing this machine's cores), measured by the launcher from first spawn to the end of the run. One line
per finished run goes to stderr; a run that failed is a ``failed`` row, and the exit code is then 1.
"""

from __future__ import annotations

import sys
from typing import Any

from benchmarks._common import fleet_run, parser


def run_once(robots: int, ticks: int, allocator: str, extra: list[str]) -> tuple[dict[str, Any] | None, str]:
    """One run: its result.json, or None and the reason when it did not end normally (``_common.fleet_run``)."""
    res = fleet_run(["--map", "office", "--robots", str(robots), "--max-ticks", str(ticks), "--target-coverage",
                     "1.0", "--allocator", allocator, *extra])
    return (None, f"exit {res['code']}: {res['error']}") if "error" in res else (res, "ok")


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.ticks_per_second", __doc__)
    p.add_argument("--robots", type=int, nargs="+", default=[4, 16])
    p.add_argument("--ticks", type=int, default=300)
    p.add_argument("--allocator", default="minpos")
    p.add_argument("--repeat", type=int, default=1)
    p.add_argument("--in-process", action="store_true")
    a = p.parse_args(argv)
    extra = ["--in-process"] if a.in_process else []
    print(f"{'robots':>6} {'ticks':>6} {'wall s':>8} {'ticks/s':>8} {'coverage':>9} "
          f"{'agent RSS max MB':>17} {'mean MB':>8} {'decision ms':>12}")
    total = len(a.robots) * a.repeat
    failed = done = 0
    for n in a.robots:
        for _ in range(a.repeat):
            r, why = run_once(n, a.ticks, a.allocator, extra)
            done += 1
            if r is None:
                failed += 1
                print(f"[{done}/{total}] {n} robots: FAILED ({why})", file=sys.stderr, flush=True)
                print(f"{n:>6} {'failed':>6}")
                continue
            print(f"[{done}/{total}] {n} robots: {r['ticks']} ticks in {r['wall_seconds']:.1f} s", file=sys.stderr,
                  flush=True)
            rss = list(r["robot_peak_rss_kb"].values()) or [0]
            print(f"{n:>6} {r['ticks']:>6} {r['wall_seconds']:>8.1f} {r['ticks_per_second'] or 0:>8.1f} "
                  f"{r['coverage']:>9.3f} {max(rss) / 1024:>17.1f} {sum(rss) / len(rss) / 1024:>8.1f} "
                  f"{r['decision_ms']['mean']:>12.3f}")
    if failed:
        print(f"ticks_per_second: {failed} of {total} runs failed (see the lines above)", file=sys.stderr)
        raise SystemExit(1)


if __name__ == "__main__":
    main()
