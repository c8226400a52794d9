"""Steps per second of ``fleet_emu.rl``'s environment beside the memory engine's own ticks per second.

    python -m benchmarks.env_speed [--robots 4 16] [--ticks 200] [--big-ticks 100] [--big-map maze] [--repeat 3]

On ``office`` and on ``--big-map`` fitted to 512 cells across (``_common.fitted_maps``; sensor 8 cells, radio
range 20 cells, from its most open start), each with every ``--robots``: the memory engine (``Fleet``) running
the ``nearest`` allocator, then the environment where every robot takes action 0 (its nearest candidate: the
same choice, so the same run), for the same ticks (``--ticks`` on office, ``--big-ticks`` on the big map;
target coverage 1, so that no run ends early), each ``--repeat`` times, the fastest kept (the machine may be
shared). Prints ticks per second of each (wall time, this process) and their ratio: what building the
observations costs (the map crop, the K candidates' features, the teammates).
"""

from __future__ import annotations

import sys
import time
from typing import Any

from benchmarks._common import fitted_maps, fitted_scenario, machine, parser
from fleet_emu import rl
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet


def rates(s: Any, repeat: int) -> tuple[float, float]:
    """Ticks per second of the memory engine and of the environment on scenario ``s`` (nearest, same run), the
    fastest of ``repeat`` runs each."""
    engine = steps = 0.0
    for _ in range(repeat):
        fleet = Fleet(s)
        t0 = time.perf_counter()
        fleet.run()
        engine = max(engine, fleet.world.tick / (time.perf_counter() - t0))
        env = rl.parallel_env(s)
        t0 = time.perf_counter()
        obs, _ = env.reset()
        while env.agents:
            obs, *_ = env.step(dict.fromkeys(obs, 0))
        steps = max(steps, env.fleet.world.tick / (time.perf_counter() - t0))
        if env.fleet.world.tick != fleet.world.tick or env.fleet.world.coverage != fleet.world.coverage:
            raise SystemExit("env_speed: the environment's run differs from the memory engine's")
    return engine, steps


def main(argv: list[str] | None = None) -> int:
    p = parser("benchmarks.env_speed", __doc__)
    p.add_argument("--robots", type=int, nargs="+", default=[4, 16])
    p.add_argument("--ticks", type=int, default=200)
    p.add_argument("--big-ticks", type=int, default=100)
    p.add_argument("--big-map", default="maze")
    p.add_argument("--repeat", type=int, default=3)
    a = p.parse_args(argv)
    if min([a.ticks, a.big_ticks, a.repeat, *a.robots]) < 1:
        p.error("robots, ticks and repeat must be >= 1")
    print(machine())
    big = fitted_maps("env_speed", [a.big_map], 512, 0)[0]
    Fleet(Scenario.load("default").override(robots=2, max_ticks=5)).run()  # warm-up: the kernels, the map cache
    print("| map | robots | ticks | memory engine ticks/s | environment steps/s | ratio |")
    print("| --- | --- | --- | --- | --- | --- |")
    for n in a.robots:
        office = Scenario.load("default").override(robots=n, allocator="nearest", max_ticks=a.ticks,
                                                   target_coverage=1.0)
        wide = fitted_scenario(big, n, 0, 8.0, 20.0, {"type": "nearest"}, max_ticks=a.big_ticks, target_coverage=1.0)
        for label, s in (("office", office), (f"{big.label} {big.cells}", wide)):
            engine, steps = rates(s, a.repeat)
            print(f"| {label} | {n} | {s.max_ticks} | {engine:.1f} | {steps:.1f} | {steps / engine:.2f} |",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
