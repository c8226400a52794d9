"""Connectivity-aware exploration (Benavides et al. 2016, section IV) against MinPos: connected fraction and ticks.

    python -m benchmarks.connectivity_table [--maps hospital_section maze]
        [--configs minpos conn:0.6:0.4 conn:0.4:0.6 conn:0.6:0.4:literal] [--seeds 6] [--loss 0.1]
        [--max-ticks 3000] [--jobs 2] [--check]

The paper's experiment: 2 robots, sensing 3 m, communication 6 m, stop at 95 % coverage; here on the wall radio
(eq. 4) with 0.5 m cells and a random start per seed. A config is ``minpos`` or
``conn:ALPHA:BETA[:POSITION[:PREDICT]]`` (the connectivity allocator's parameters, see its module docstring),
either followed by ``:NAME=VALUE`` items for any other parameter: ``conn:0.6:0.4:replan=observed``,
``minpos:replan=observed`` (``conn:...`` alone is the allocator's default, ``replan="observed"``).
Each run is stepped in this process on the memory engine (``fleet_emu.Fleet``: the same World, Channel and Brain
as ``fleet run``, without Zenoh); ``--check`` first compares one run against a real ``fleet run`` of it.
Per cell: mean connected fraction, mean ticks (a run that did not reach the target counts at its last tick), and
``kS/kT`` runs that ended as a stall / at the tick limit. One line per finished run goes to stderr.
"""

from __future__ import annotations

import dataclasses
import json
import statistics
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from benchmarks._common import fleet_run, parser
from fleet_emu.core.scenario import Scenario
from fleet_emu.launch.cli import param_value
from fleet_emu.launch.memory import Fleet

#: Registry maps (`fleet maps fetch hospital_section autolab mbicp cave` once) and a built-in one.
DEFAULT_MAPS = ["hospital_section", "autolab", "mbicp", "cave", "maze"]
SETTINGS = {"robots": 2, "sensor_range": 3.0, "comm_range": 6.0, "target_coverage": 0.95, "cell_size": 0.5,
            "comm": "wall", "start": "random"}


@dataclasses.dataclass(frozen=True)
class Outcome:
    """What ``result.json`` says of a run (the keys the table needs)."""

    ticks: int
    coverage: float
    reason: str | None
    connected_fraction: float
    path_length: list[int]


def simulate(sc: Scenario) -> Outcome:
    r = Fleet(sc).run().data
    return Outcome(r["ticks"], r["coverage"], r["reason"], r["connected_fraction"] or 0.0, r["path_length"])


def allocator(config: str) -> dict[str, Any]:
    """``minpos`` or ``conn:ALPHA:BETA[:POSITION[:PREDICT]]``, then any ``:NAME=VALUE``, as an allocator table
    (strings; the allocator checks and converts them: a bad value is a one-line ConfigError)."""
    name, *parts = config.split(":")
    named = {k: param_value(v) for k, v in (p.split("=", 1) for p in parts if "=" in p)}
    parts = [p for p in parts if "=" not in p]
    if name != "conn":
        return {"type": name, **named}
    out: dict[str, Any] = {"type": "connectivity", "alpha": float(parts[0]), "beta": float(parts[1])}
    out.update(zip(("position", "predict"), parts[2:], strict=False))
    return out | named


def scenario(map_name: str, config: str, seed: int, loss: float, max_ticks: int) -> Scenario:
    base = Scenario().override(map=map_name, seed=seed, loss=loss, max_ticks=max_ticks, **SETTINGS)
    return dataclasses.replace(base, allocator=allocator(config)).validate()


def run_one(map_name: str, config: str, seed: int, loss: float, max_ticks: int) -> Outcome:
    return simulate(scenario(map_name, config, seed, loss, max_ticks))


def check(map_name: str, loss: float) -> None:
    """One run stepped here and the same scenario as a real fleet (``fleet run``) must agree."""
    sc = scenario(map_name, "conn:0.6:0.4", 0, loss, 3000)
    mine = simulate(sc)
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "s.json").write_text(json.dumps(sc.to_dict()))
        real = fleet_run(["--scenario", f"{tmp}/s.json"])
    if "error" in real:
        print(f"check on {Path(map_name).stem}: fleet run failed (exit {real['code']}): {real['error']}",
              file=sys.stderr)
        raise SystemExit(1)
    same = (real["ticks"], real["path_length"], round(real["connected_fraction"], 6)) == (
        mine.ticks, mine.path_length, round(mine.connected_fraction, 6))
    print(f"check on {Path(map_name).stem}: fleet run ticks {real['ticks']}, connected "
          f"{real['connected_fraction']:.3f}; stepped here {mine.ticks}, {mine.connected_fraction:.3f}: "
          f"{'identical' if same else 'DIFFERENT'}", file=sys.stderr)
    if not same:
        raise SystemExit(1)


def cell(outcomes: list[Outcome]) -> str:
    conn = statistics.mean(o.connected_fraction for o in outcomes)
    ticks = statistics.mean(o.ticks for o in outcomes)
    stalls = sum(o.reason == "stall" for o in outcomes)
    limit = sum(o.reason == "max_ticks" for o in outcomes)
    flags = (f" {stalls}S" if stalls else "") + (f" {limit}T" if limit else "")
    return f"{conn:.0%}, {ticks:.0f}{flags}"


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.connectivity_table", __doc__)
    p.add_argument("--maps", nargs="+", default=DEFAULT_MAPS)
    p.add_argument("--configs", nargs="+", default=["minpos", "conn:0.6:0.4", "conn:0.4:0.6"])
    p.add_argument("--seeds", type=int, default=6)
    p.add_argument("--loss", type=float, default=0.1)
    p.add_argument("--max-ticks", type=int, default=3000)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--check", action="store_true", help="first compare one stepped run with a real fleet run")
    a = p.parse_args(argv)
    if a.check:
        check(a.maps[0], a.loss)
    jobs = [(m, c, s) for m in a.maps for c in a.configs for s in range(a.seeds)]
    results: dict[tuple[str, str], list[Outcome]] = {}
    with ProcessPoolExecutor(a.jobs) as pool:
        futures = {pool.submit(run_one, m, c, s, a.loss, a.max_ticks): (m, c, s) for m, c, s in jobs}
        for done, future in enumerate(as_completed(futures), start=1):
            m, c, s = futures[future]
            o = future.result()
            results.setdefault((m, c), []).append(o)
            print(f"[{done}/{len(jobs)}] {Path(m).stem} {c} seed {s}: {o.reason} at {o.ticks}, coverage "
                  f"{o.coverage:.1%}, connected {o.connected_fraction:.1%}", file=sys.stderr, flush=True)
    print(f"connected fraction, mean ticks (2 robots, sensing 3 m, range 6 m, 95 %, wall radio, loss {a.loss}, "
          f"seeds 0..{a.seeds - 1}, tick limit {a.max_ticks}; kS/kT: runs ended as a stall / at the limit)")
    print("| map | " + " | ".join(a.configs) + " |")
    print("|---" * (len(a.configs) + 1) + "|")
    for m in a.maps:
        print(f"| {Path(m).stem} | " + " | ".join(cell(results[(m, c)]) for c in a.configs) + " |")
    rows = [[results[(m, c)] for m in a.maps] for c in a.configs]
    print("| mean of maps | " + " | ".join(
        f"{statistics.mean(statistics.mean(o.connected_fraction for o in r) for r in row):.0%}, "
        f"{statistics.mean(statistics.mean(o.ticks for o in r) for r in row):.0f}" for row in rows) + " |")


if __name__ == "__main__":
    main()
