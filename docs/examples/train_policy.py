"""Train a frontier-choosing policy in ``fleet_emu.rl`` with numpy alone, then compare it on maps it never saw.

    python3 docs/examples/train_policy.py [--map hall] [--robots 4] [--iterations 6] [--population 8] [--elite 3]
        [--episodes 2] [--out policy.npz] [--eval office,maze] [--eval-seeds 10] [--max-ticks 1500]
        [--train-max-ticks 500] [--seed 0] [--tiny]

The policy is linear over each candidate target's features (``fleet_emu.agents.allocators.policy.FEATURES``):
every tick each robot goes to the best-scored of its K nearest frontier targets. Training is the cross-entropy
method (Rubinstein and Kroese, *The Cross-Entropy Method*, 2004): each iteration draws ``population`` weight
vectors from a Gaussian, runs each for ``episodes`` episodes of the environment (training maps drawn from the
seeds 1000, 1001, ...: ``hall`` places its obstacles from the seed, so every episode is another hall), keeps the
``elite`` of fewest ticks to the target coverage (95 %) and refits the Gaussian to them (its spread floored at
0.05); the Gaussian starts at mean 0, spread 1. An episode that misses the target counts its ``max_ticks``
(``--train-max-ticks`` in training, 500: a bad draw is cut short; ``--max-ticks`` in the comparison, 1500).
The radio is the default scenario's (wall attenuation, 10 % loss): the policy learns with what the robots
actually hear.

Then the policy is saved (``--out``, the ``policy`` allocator's file) and compared, by ticks to 95 % (mean ±
sd over ``--eval-seeds`` seeds, 0, 1, ...), on the ``--eval`` maps against a uniform choice among the same K
candidates redrawn every tick (in the environment, from a seeded generator), and the allocators ``random`` (a
reachable frontier drawn at random and kept until seen), ``nearest`` and ``minpos`` (memory engine); the
trained policy runs as the ``policy`` allocator reading the saved file, as a robot process would. ``--tiny`` is
a smoke test of a few seconds (what the documentation's test runs): it shows that training, saving and comparing
run, not a policy (4 episodes of 150 ticks learn nothing, and every run of its table misses the target), and
says so. Prints the training log, a table, and the seconds each part took.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from fleet_emu import rl
from fleet_emu.agents.allocators.policy import FEATURES, save_policy
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.memory import Fleet

TARGET = 0.95
MAX_TICKS = 1500
TRAIN_MAX_TICKS = 500  # a training episode that has not reached the target by then scores this: a bad draw costs less
TRAIN_SEED = 1000
#: What ``--tiny`` prints first and last: its policy is not one.
SMOKE = ("smoke test (--tiny): checks that training, saving and comparing run; its policy learned nothing "
         "(2 x 2 candidates, 1 episode of 150 ticks) and its table compares nothing. Drop --tiny to train one.")
Obs = dict[str, np.ndarray]
Chooser = Callable[[Obs], int]


def scenario(map_name: str, robots: int, max_ticks: int = MAX_TICKS) -> Scenario:
    """The default scenario's radio on ``map_name``, run to :data:`TARGET`."""
    return Scenario.load("default").override(map=map_name, robots=robots, target_coverage=TARGET,
                                             max_ticks=max_ticks)


def linear(weights: np.ndarray) -> Chooser:
    """The ``policy`` allocator's choice from an observation: the best-scored candidate (none without one)."""
    def choose(obs: Obs) -> int:
        n = int(obs["action_mask"][:-1].sum())
        return int(np.argmax(obs["targets"][:n] @ weights)) if n else len(obs["action_mask"]) - 1
    return choose


def uniform(rng: np.random.Generator) -> Chooser:
    """A random choice among the candidates."""
    def choose(obs: Obs) -> int:
        n = int(obs["action_mask"][:-1].sum())
        return int(rng.integers(n)) if n else len(obs["action_mask"]) - 1
    return choose


def episode(env: rl.FleetParallelEnv, choose: Chooser, seed: int) -> int:
    """Ticks to the target coverage of one episode (``max_ticks`` when it was not reached)."""
    obs, _ = env.reset(seed=seed)
    while env.agents:
        obs, *_ = env.step({r: choose(o) for r, o in obs.items()})
    f = env.fleet
    return int(f.world.tick) if f.reason == "coverage" else int(f.scenario.max_ticks)


def cem(env: rl.FleetParallelEnv, iterations: int, population: int, elite: int, episodes: int,
        rng: np.random.Generator, log: Callable[[str], None]) -> np.ndarray:
    """The cross-entropy method over linear weights (module docstring); the final mean."""
    mean, sd = np.zeros(len(FEATURES)), np.ones(len(FEATURES))
    seeds = iter(range(TRAIN_SEED, TRAIN_SEED + iterations * episodes))
    for it in range(iterations):
        batch = [next(seeds) for _ in range(episodes)]  # every candidate of an iteration on the same maps
        draws = mean + sd * rng.standard_normal((population, len(FEATURES)))
        scores = np.array([np.mean([episode(env, linear(w), s) for s in batch]) for w in draws])
        best = draws[np.argsort(scores, kind="stable")[:elite]]
        mean, sd = best.mean(axis=0), np.maximum(best.std(axis=0), 0.05)
        log(f"iteration {it + 1}/{iterations}: ticks best {scores.min():.0f} mean {scores.mean():.0f}; "
            f"weights {np.round(mean, 2).tolist()}")
    return mean


def compare(policy: Path, maps: list[str], robots: int, seeds: int, max_ticks: int) -> list[list[Any]]:
    """Ticks to the target per map and chooser: a uniform choice among the candidates redrawn every tick (in the
    environment), then the allocators random, nearest, minpos and the policy (memory engine)."""
    rows = []
    for name in maps:
        s = scenario(name, robots, max_ticks)
        env = rl.parallel_env(s)
        rng = np.random.default_rng(0)
        ticks: dict[str, list[float]] = {"uniform": [float(episode(env, uniform(rng), k)) for k in range(seeds)]}
        for label, alloc in (("random", {"type": "random"}), ("nearest", {"type": "nearest"}),
                             ("minpos", {"type": "minpos"}),
                             ("trained", {"type": "policy", "path": str(policy)})):
            runs = [Fleet(s.override(allocator=alloc)).run(seed=k) for k in range(seeds)]
            ticks[label] = [float(r["ticks"]) if r["reason"] == "coverage" else float(max_ticks) for r in runs]
        rows.append([name, *(mean_sd(ticks[k]) for k in ("uniform", "random", "nearest", "minpos", "trained"))])
    return rows


def mean_sd(values: list[float]) -> str:
    """``mean ± sd`` of a table cell, in whole ticks."""
    sd = statistics.stdev(values) if len(values) > 1 else 0.0
    return f"{statistics.fmean(values):.0f} ± {sd:.0f}"


def compares_nothing(rows: list[list[Any]], max_ticks: int) -> bool:
    """Whether every cell of the table is a run that missed the target (``max_ticks ± 0``): nothing to compare."""
    return all(cell == f"{max_ticks} ± 0" for row in rows for cell in row[1:])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="train_policy.py", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--map", default="hall", help="the training map (default hall)")
    p.add_argument("--robots", type=int, default=4)
    p.add_argument("--iterations", type=int, default=6)
    p.add_argument("--population", type=int, default=8)
    p.add_argument("--elite", type=int, default=3)
    p.add_argument("--episodes", type=int, default=2, help="episodes per candidate (default 2)")
    p.add_argument("--out", type=Path, help="where to save the policy (default: a temporary file)")
    p.add_argument("--eval", default="office,maze", help="maps to compare on, comma-separated ('' for none)")
    p.add_argument("--eval-seeds", type=int, default=10)
    p.add_argument("--max-ticks", type=int, default=MAX_TICKS, help="the comparison's (default 1500)")
    p.add_argument("--train-max-ticks", type=int, default=TRAIN_MAX_TICKS, help="training's (default 500)")
    p.add_argument("--seed", type=int, default=0, help="the trainer's generator (default 0)")
    p.add_argument("--tiny", action="store_true", help="a smoke run: 2 x 2 candidates, 1 episode, 1 seed, 150 ticks")
    a = p.parse_args(argv)
    if a.tiny:
        a.iterations, a.population, a.elite, a.episodes, a.eval_seeds = 2, 2, 1, 1, 1
        a.max_ticks = a.train_max_ticks = 150
    if min(a.iterations, a.population, a.elite, a.episodes, a.eval_seeds, a.robots, a.max_ticks,
           a.train_max_ticks) < 1 or a.elite > a.population:
        p.error("iterations, population, episodes, eval seeds, robots and max ticks must be >= 1, and elite in "
                "[1, population]")
    if a.tiny:
        print(SMOKE)
    print(f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f} at start")
    t0 = time.perf_counter()
    env = rl.parallel_env(scenario(a.map, a.robots, a.train_max_ticks))
    weights = cem(env, a.iterations, a.population, a.elite, a.episodes, np.random.default_rng(a.seed), print)
    trained = time.perf_counter() - t0
    out = a.out or Path(tempfile.mkdtemp()) / "policy.npz"
    save_policy(out, weights)
    print(f"trained in {trained:.1f} s: {dict(zip(FEATURES, np.round(weights, 3).tolist(), strict=True))} -> {out}")
    maps = [m for m in a.eval.split(",") if m]
    if maps:
        t1 = time.perf_counter()
        rows = compare(out, maps, a.robots, a.eval_seeds, a.max_ticks)
        print(f"\nticks to {TARGET:.0%}, {a.robots} robots, seeds 0..{a.eval_seeds - 1} (mean ± sd; "
              f"{a.max_ticks} when missed)")
        print("| map | uniform | random | nearest | minpos | trained |\n|---|---|---|---|---|---|")
        for row in rows:
            print("| " + " | ".join(str(c) for c in row) + " |")
        print(f"compared in {time.perf_counter() - t1:.1f} s")
        if compares_nothing(rows, a.max_ticks):
            print(f"warning: every run missed {TARGET:.0%} within {a.max_ticks} ticks: this table compares nothing "
                  f"(raise --max-ticks)")
    if a.tiny:
        print(SMOKE)
    return 0


if __name__ == "__main__":
    sys.exit(main())
