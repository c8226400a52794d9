"""Fault trials at scale; not run in CI (``tests/integration/test_faults.py`` runs a few).
The trials themselves are the tests' harness (``tests/harness/faults.py``), so run this from the repository's
root as a module:

    python -m benchmarks.fault_trials [--kill 100] [--sigint 50] [--fuzz 100000] [--fuzz-auth]
                                         [--loss-allocators all] [--seed 0]

Runs the real ``fleet run`` CLI on a small map and short runs, and prints one row per kind of fault: kill -9
of a random robot at a random tick, SIGINT at a random moment (sometimes twice), fuzzed messages on every key
of a run (through an unauthenticated router the script starts, so that they reach every node's decoder; with
``--fuzz-auth`` also through an authenticated one with robot r1's credentials), and loss 0.9 with each
allocator. Columns: trials, runs that ended (no hang), valid recordings (the mcap reader opens run.mcap to the
end and counts result.json's messages), result.json present, orphans (a process of the fleet alive after the
launcher exited), deaths (a node that died other than the one killed), wrong exit codes, and for the fuzz rows
runs whose seeded result differs from a run without fuzz. One progress line per trial goes to stderr; the
exit code is 1 when any trial broke an invariant (each is listed under the table). Trial ``i`` of a phase
draws from ``numpy.random.default_rng([seed, phase, i])``.
"""

from __future__ import annotations

import argparse
import signal
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from fleet_emu.agents.allocators import allocator_names
from tests.harness.faults import RunSpec, Trial, fuzz_trial, kill_trial, loss_trial, plain_trial, sigint_trial

# 384 x 384 px at 0.05 m: 192 x 192 cells at 0.1 m
MAP = "turtlebot3_world"  # a registry map: `fleet maps fetch turtlebot3_world` once
PHASES = {"kill": 1, "sigint": 2, "fuzz": 3, "fuzz-auth": 4}
COLUMNS = ("trials", "ended", "valid rec", "result.json", "orphans", "deaths", "wrong exit", "changed")


def row(name: str, trials: list[Trial]) -> str:
    values = [len(trials), sum(t.ended for t in trials), sum(t.recording_valid for t in trials),
              sum(t.result is not None for t in trials), sum(t.orphans for t in trials),
              sum(len(t.deaths) for t in trials), sum(t.wrong_exit for t in trials)]
    changed = str(sum(t.changed for t in trials)) if name.startswith("fuzz (open") else "-"
    return f"{name:<26}" + "".join(f"{v:>12}" for v in values) + f"{changed:>12}"


def main(argv: list[str] | None = None) -> None:
    # A background job of a non-interactive shell starts with SIGINT ignored, and the launchers it spawns would
    # inherit that until their own handler is installed: a signal in their first half second would be lost.
    # A handler here (exec resets it to the default) gives every launcher the terminal's default disposition.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--kill", type=int, default=100, help="kill -9 trials")
    p.add_argument("--sigint", type=int, default=50, help="SIGINT trials")
    p.add_argument("--fuzz", type=int, default=100_000, help="fuzzed messages per fuzz run (0: none)")
    p.add_argument("--fuzz-runs", type=int, default=1, help="fuzz runs through the open router")
    p.add_argument("--fuzz-auth", action="store_true", help="also fuzz through an authenticated router as r1")
    p.add_argument("--loss-allocators", nargs="*", default=["all"], metavar="NAME",
                   help="allocators to run at --loss (default all of `fleet allocators`; none: skip)")
    p.add_argument("--loss", type=float, default=0.9)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--map", default=MAP, help="a small map (default: the registry's turtlebot3_world)")
    p.add_argument("--cell-size", default="0.1")
    p.add_argument("--sensor-range", default="1.5")
    p.add_argument("--robots", type=int, default=3)
    p.add_argument("--max-ticks", type=int, default=60)
    p.add_argument("--fuzz-ticks", type=int, default=3000, help="the fuzz runs' tick limit")
    p.add_argument("--fuzz-cell-size", default="0.05", help="a finer grid: fuzz runs outlast the fuzz")
    p.add_argument("--fuzz-sensor-range", default="0.5")
    p.add_argument("--work", type=Path, help="keep every run here (default: a temporary directory)")
    a = p.parse_args(argv)
    extra = ("--cell-size", a.cell_size, "--sensor-range", a.sensor_range)
    spec = RunSpec(a.map, a.robots, a.max_ticks, seed=a.seed, extra=extra)
    allocators = allocator_names() if a.loss_allocators == ["all"] else \
        [] if a.loss_allocators == ["none"] else a.loss_allocators
    rows: list[tuple[str, list[Trial]]] = []
    t0 = time.monotonic()

    def go(name: str, n: int, make: Callable[[int], Trial]) -> list[Trial]:
        trials = []
        for i in range(n):
            t = make(i)
            trials.append(t)
            verdict = "ok" if not t.failures else "FAILED: " + "; ".join(t.failures)
            notes = f" ({'; '.join(t.notes)})" if t.notes else ""
            print(f"[{name} {i + 1}/{n}] {t.label}: exit {t.exit_code}, {t.seconds:.1f} s, {verdict}{notes}",
                  file=sys.stderr, flush=True)
        rows.append((name, trials))
        return trials

    with tempfile.TemporaryDirectory(prefix="fault-trials-") as tmp:
        work = a.work or Path(tmp)
        rng = lambda phase, i: np.random.default_rng([a.seed, PHASES[phase], i])  # noqa: E731
        base = go("no fault", 1, lambda i: plain_trial(spec, work, f"plain{i}"))[0]
        window = 1.2 * base.seconds
        if a.kill:
            kspec = RunSpec(a.map, a.robots, a.max_ticks, 1.0, a.seed, extra)  # the target out of reach
            go("kill -9 robot", a.kill, lambda i: kill_trial(kspec, work, rng("kill", i), f"kill{i}"))
        if a.sigint:
            go("SIGINT", a.sigint, lambda i: sigint_trial(spec, work, rng("sigint", i), f"sigint{i}", window))
        if a.fuzz:
            fextra = ("--cell-size", a.fuzz_cell_size, "--sensor-range", a.fuzz_sensor_range)
            fspec = RunSpec(a.map, a.robots, a.fuzz_ticks, 0.99, a.seed, fextra)
            ref = go("fuzz baseline (open)", 1, lambda i: plain_trial(fspec, work, "fuzzbase", True))[0].result
            go("fuzz (open router)", a.fuzz_runs,
               lambda i: fuzz_trial(fspec, work, rng("fuzz", i), f"fuzz{i}", a.fuzz, None, ref))
            if a.fuzz_auth:
                go("fuzz (auth, as r1)", 1,
                   lambda i: fuzz_trial(fspec, work, rng("fuzz-auth", i), f"fuzzauth{i}", a.fuzz, "r1"))
        if allocators:
            go(f"loss {a.loss:g}", len(allocators),
               lambda i: loss_trial(spec, work, allocators[i], f"loss{i}", a.loss))
    print(f"{'':<26}" + "".join(f"{c:>12}" for c in COLUMNS))
    for name, trials in rows:
        print(row(name, trials))
    bad = [(name, t) for name, trials in rows for t in trials if t.failures]
    print(f"\n{sum(len(t) for _, t in rows)} trials in {time.monotonic() - t0:.0f} s; {len(bad)} broke an invariant")
    for name, t in bad:
        print(f"  {name} / {t.label}: {'; '.join(t.failures)}" + (f" ({'; '.join(t.notes)})" if t.notes else ""))
    raise SystemExit(1 if bad else 0)


if __name__ == "__main__":
    main()
