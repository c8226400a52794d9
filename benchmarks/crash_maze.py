"""A robot crashing in the maze with one-cell corridors: per seed and crashed robot, whether the others reach the
target, the reason and the body that blocks, and the same run with robots blind to bodies.

    python -m benchmarks.crash_maze [--seeds 10] [--robots 4] [--crash-tick 30] [--all-robots]
        [--map maze] [--cell-size 2.0] [--max-ticks 2000]

Each run is the default scenario on ``--map`` at ``--cell-size`` (the 30 m maze at 2 m: every corridor one cell
wide) with one ``[[faults]]`` crash at ``--crash-tick``: robot ``seed mod robots``, or each robot in turn with
``--all-robots``, on the memory engine in this process (docs/guides/faults.md). *Blind* is the same run with
robots that neither sense bodies nor plan around them (the brain's ``silent_after`` past any run: no body is ever
a wreck), the behaviour before bodies were reported. Per row: the seed, the crashed robot, the ticks, whether the
target was reached, the reason and ``blocked_by``, the coverage, and the blind run's ticks and coverage; then the
blocked runs' ticks saved, paired by run (mean and 95 % t-interval). One line per run goes to stderr.
"""

from __future__ import annotations

import dataclasses
import statistics
import sys
from typing import Any

from benchmarks._common import fail, machine, parser


def scenario(seed: int, robot: int, a: Any) -> Any:
    from fleet_emu.core.scenario import Scenario
    from fleet_emu.launch.cli import DEFAULT_SCENARIO

    return Scenario.load(DEFAULT_SCENARIO).override(
        map=a.map, cell_size=a.cell_size, robots=a.robots, seed=seed, max_ticks=a.max_ticks,
        faults=[{"robot": robot, "tick": a.crash_tick, "kind": "crash"}])


def run(s: Any, blind: bool) -> dict[str, Any]:
    """The run's ``result.json``; ``blind``: robots whose brains take no body for a wreck."""
    import fleet_emu.launch.memory as memory
    from fleet_emu.agents.brain import brain_config

    def blind_config(scenario: Any) -> Any:
        return dataclasses.replace(brain_config(scenario), silent_after=10**9)

    if blind:
        memory.brain_config = blind_config
    try:
        return memory.Fleet(s).run().data
    finally:
        memory.brain_config = brain_config


def saved(pairs: list[tuple[int, int]]) -> str:
    """Mean and 95 % t-interval of the ticks the blocked runs saved against their blind twins."""
    if len(pairs) < 2:
        return f"n = {len(pairs)}: too few for an interval"
    from scipy import stats

    d = [blind - seen for seen, blind in pairs]
    m, se = statistics.fmean(d), statistics.stdev(d) / len(d) ** 0.5
    t = float(stats.t.ppf(0.975, len(d) - 1))
    return f"n = {len(d)}: {m:.1f} ticks sooner on average, 95 % t-interval {m - t * se:.1f} to {m + t * se:.1f}"


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.crash_maze", __doc__)
    p.add_argument("--seeds", type=int, default=10)
    p.add_argument("--robots", type=int, default=4)
    p.add_argument("--crash-tick", type=int, default=30)
    p.add_argument("--all-robots", action="store_true", help="each robot crashing in turn, per seed")
    p.add_argument("--map", default="maze")
    p.add_argument("--cell-size", type=float, default=2.0)
    p.add_argument("--max-ticks", type=int, default=2000)
    a = p.parse_args(argv)
    from fleet_emu.core.errors import FleetError

    if a.seeds < 1:
        fail("crash_maze", f"--seeds must be at least 1 (got {a.seeds})")
    try:
        scenario(0, 0, a)  # bad input before any run: one line
    except FleetError as exc:
        fail("crash_maze", str(exc))
    print(machine())
    print(f"\n{a.map} at {a.cell_size:g} m a cell, {a.robots} robots, a crash at tick {a.crash_tick}, memory engine\n")
    print("| seed | crashed | ticks | reached | reason | blocked_by | coverage | blind ticks | blind coverage |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    pairs = []
    for seed in range(a.seeds):
        for robot in range(a.robots) if a.all_robots else [seed % a.robots]:
            s = scenario(seed, robot, a)
            seen, blind = run(s, False), run(s, True)
            blocked = ",".join(f"{r}@{tuple(b['cell'])}:{b['cut_off']}" for r, b in seen.get("blocked_by", {}).items())
            if blocked:
                pairs.append((seen["ticks"], blind["ticks"]))
            print(f"seed {seed} r{robot}: {seen['ticks']} ticks ({seen['reason']}), blind {blind['ticks']}",
                  file=sys.stderr, flush=True)
            print(f"| {seed} | r{robot} | {seen['ticks']} | {'yes' if seen['completed'] else 'no'} | "
                  f"{seen['reason']} | {blocked or '-'} | {seen['coverage']:.3f} | {blind['ticks']} | "
                  f"{blind['coverage']:.3f} |", flush=True)
    print(f"\nblocked runs: {saved(pairs)}")


if __name__ == "__main__":
    main()
