"""Time per run of the memory engine against the Zenoh engines on the same scenarios, as a ratio.

    python -m benchmarks.engine_speed [--seeds 2] [--processes] [--quick] [--bandwidth KBITPS] [--memory-only]

Each scenario runs with every seed on the memory engine (``fleet_emu.Fleet``, in this process, after one
warm-up run), on the in-process Zenoh engine (``fe.run(in_process=True)``: every node in this process, a
session each, through an embedded router) and, with ``--processes``, on the default one (one OS process per
node). Every run's deterministic keys are checked equal across engines. Prints one table: seconds per run
(mean over seeds) per engine, and the ratio in-process / memory (and processes / memory). ``--bandwidth``
runs every scenario on a bandwidth-limited radio (kbit/s; netem/medium.py), to measure what airtime costs;
``--memory-only`` times the memory engine alone (a change's cost on it, against another checkout), and adds
its CPU seconds per run (this process's), steadier than wall time on a loaded machine, and per tick (a limited
radio changes the run, and its length).
"""

from __future__ import annotations

import sys
import time
from typing import Any

from benchmarks._common import HOSPITAL, parser

SCENARIOS = [  # (label, overrides)
    ("office x3 minpos wall 0.1", {"robots": 3, "allocator": "minpos"}),
    ("office x4 trade full 0.3", {"robots": 4, "allocator": "trade", "comm": "full", "loss": 0.3}),
    ("hospital x5 minpos ideal 100%", {"map": HOSPITAL, "robots": 5, "allocator": "minpos", "comm": "ideal",
                                       "loss": 0.0, "target_coverage": 1.0, "max_ticks": 5000, "start": "random"}),
    ("hospital x10 utility ideal 100%", {"map": HOSPITAL, "robots": 10, "allocator": "utility",
                                         "comm": "ideal", "loss": 0.0, "target_coverage": 1.0, "max_ticks": 5000,
                                         "start": "random"}),
]


def main(argv: list[str] | None = None) -> None:
    """The table; exit 1 when a run's deterministic keys differ between engines."""
    import fleet_emu as fe
    from fleet_emu.recording.result import deterministic

    p = parser("benchmarks.engine_speed", __doc__, full=False)
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--processes", action="store_true", help="also the default engine (one process per node)")
    p.add_argument("--quick", action="store_true", help="the two office scenarios only")
    p.add_argument("--max-ticks", type=int, help="cut every run at this tick (a smoke test)")
    p.add_argument("--bandwidth", type=float, default=0.0, help="kbit/s of a limited radio (0: unlimited)")
    p.add_argument("--memory-only", action="store_true", help="the memory engine alone")
    args = p.parse_args(argv)
    from fleet_emu.world.registry import is_fetched

    scenarios = SCENARIOS[:2] if args.quick or not is_fetched(HOSPITAL) else SCENARIOS
    engines = ["memory"] if args.memory_only else ["memory", "in-process"] + (["processes"] if args.processes else [])
    fe.Fleet(fe.Scenario().override(robots=2, max_ticks=5)).run()  # compile or load the kernels once
    rows: list[tuple[str, dict[str, float]]] = []
    differ = 0
    for label, over in scenarios:
        times: dict[str, list[float]] = {e: [] for e in engines}
        cpu: list[float] = []
        ticks: list[int] = []
        for seed in range(args.seeds):
            s = fe.Scenario().override(seed=seed, **over, **({"bandwidth": args.bandwidth} if args.bandwidth else {}))
            s = s.override(max_ticks=min(args.max_ticks, s.max_ticks)) if args.max_ticks else s
            seen: dict[str, Any] | None = None
            for engine in engines:
                t0, c0 = time.perf_counter(), time.process_time()
                res = fe.Fleet(s).run() if engine == "memory" else fe.run(s, in_process=engine == "in-process")
                times[engine].append(time.perf_counter() - t0)
                if engine == "memory":
                    cpu.append(time.process_time() - c0)
                    ticks.append(res["ticks"])
                keys = deterministic(res.data)
                if seen is not None and keys != seen:
                    differ += 1
                    print(f"{label} seed {seed}: {engine} differs from memory", file=sys.stderr)
                seen = seen or keys
            print(f"{label} seed {seed}: ticks {res['ticks']}, "
                  + ", ".join(f"{e} {times[e][-1]:.2f} s" for e in engines), file=sys.stderr, flush=True)
        mean = {e: sum(v) / len(v) for e, v in times.items()}
        rows.append((label, mean | {"cpu": sum(cpu) / len(cpu), "cpu_ms_tick": 1e3 * sum(cpu) / sum(ticks)}))
    cols = engines + (["cpu", "cpu_ms_tick"] if args.memory_only else [])
    names = {"cpu": "memory cpu s/run", "cpu_ms_tick": "cpu ms/tick"}
    head = f"{'scenario':34s}" + "".join(f"{names.get(e, e + ' s/run'):>18s}" for e in cols) + \
        "".join(f"{e + '/memory':>22s}" for e in engines[1:])
    print(head)
    for label, t in rows:
        print(f"{label:34s}" + "".join(f"{t[e]:18.2f}" for e in cols)
              + "".join(f"{t[e] / t['memory']:22.1f}" for e in engines[1:]))
    total = {e: sum(t[e] for _, t in rows) for e in cols}
    if "cpu_ms_tick" in total:  # a sum of rates means nothing: their mean
        total["cpu_ms_tick"] /= len(rows)
    print(f"{'all (sum)':34s}" + "".join(f"{total[e]:18.2f}" for e in cols)
          + "".join(f"{total[e] / total['memory']:22.1f}" for e in engines[1:]))
    if differ:
        print(f"engine_speed: {differ} run(s) differ between engines (see above)", file=sys.stderr)
        raise SystemExit(1)


if __name__ == "__main__":
    main()
