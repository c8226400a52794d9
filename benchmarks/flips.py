"""Target flips per 100 robot-ticks per allocator, map and fleet size at loss 0, and the ticks to 99 %.

    python -m benchmarks.flips [--allocators hungarian hungarian:replan=tick trade ...] [--maps office autolab]
        [--robots 2 3 4] [--seeds 10] [--loss 0] [--comm full] [--start map] [--max-ticks 3000]

A flip is a robot's target going A -> B -> A, the return at most 10 ticks after it left A
(``agents/allocators/conformance.py``: ``count_flips``, the rule of the conformance check ``flip_test``, whose
limit is 3 per 100 robot-ticks). A robot-tick is one robot's command in one tick. Each run is the default
scenario (``launch/scenarios/default.toml``: 4 m sensing) with the ``yan-loss`` study's radio by default
(``--comm full``: every pair in range, so at loss 0 every message arrives), loss ``--loss``, the map's own start
(``--start map``; ``random`` draws it from the seed), on the memory engine in this process; a base-station
planner (``mhm``) gets a base at the start. An allocator is ``NAME`` or ``NAME:PARAM=VALUE,...`` (values as TOML:
``replan="tick"`` or ``replan=tick``). Per row: the runs, how many reached 99 %, mean ± sd of the ticks to 99 %
(a run that did not counts its last tick, flagged ``*``), the flips per 100 robot-ticks over all its runs and
the largest of one run. One line per run goes to stderr.
"""

from __future__ import annotations

import dataclasses
import sys
import tomllib
from typing import Any

from benchmarks._common import fail, machine, mean_sd, parser


@dataclasses.dataclass(frozen=True)
class Run:
    """One run: ticks to 99 % (None: not reached), last tick, flips and robot-ticks."""

    t99: int | None
    ticks: int
    flips: int
    robot_ticks: int


def allocator(spec: str) -> dict[str, Any]:
    """``NAME:PARAM=VALUE,...`` -> an allocator table; a value is read as TOML, else kept as a string."""
    name, _, rest = spec.partition(":")
    out: dict[str, Any] = {"type": name}
    for item in filter(None, rest.split(",")):
        key, _, value = item.partition("=")
        if not key or not value:
            raise ValueError(f"{spec!r} is not NAME or NAME:PARAM=VALUE,...")
        try:
            out[key] = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            out[key] = value
    return out


@dataclasses.dataclass(frozen=True)
class Setting:
    """What every run of the table shares."""

    loss: float = 0.0
    comm: str = "full"
    start: str = "map"  # "map", "random" or "ROW,COL"
    max_ticks: int = 3000


def scenario(config: dict[str, Any], map_name: str, robots: int, seed: int, s: Setting) -> Any:
    """The default scenario with these settings (a base at the start for a base-station planner)."""
    from fleet_emu.core.scenario import BASE_PLANNERS, Scenario
    from fleet_emu.launch.cli import DEFAULT_SCENARIO

    start: Any = None if s.start == "map" else s.start
    if start not in (None, "random"):
        row_, _, col = start.partition(",")
        if not (row_.isdigit() and col.isdigit()):
            raise ValueError(f"--start must be map, random or ROW,COL (got {s.start!r})")
        start = (int(row_), int(col))
    sc = Scenario.load(DEFAULT_SCENARIO).override(
        map=map_name, robots=robots, seed=seed, loss=s.loss, comm=s.comm, max_ticks=s.max_ticks,
        allocator=config, base=config["type"] in BASE_PLANNERS or None)
    return dataclasses.replace(sc, start=start).validate()


def run_one(config: dict[str, Any], map_name: str, robots: int, seed: int, s: Setting) -> Run:
    """One memory-engine run, its commands' targets tapped."""
    from fleet_emu.agents.allocators.conformance import count_flips
    from fleet_emu.core.grid import Cell
    from fleet_emu.core.messages import Command, Message
    from fleet_emu.launch.memory import Fleet

    targets: dict[int, dict[str, Cell | None]] = {}

    def tap(_key: str, msg: Message, _ns: int) -> None:
        if isinstance(msg, Command):
            targets.setdefault(msg.tick, {})[msg.src] = msg.target

    fleet = Fleet(scenario(config, map_name, robots, seed, s), tap=tap)
    try:
        result = fleet.run()
    finally:
        fleet.close()
    rows = [targets[t] for t in sorted(targets)]
    return Run(result["t99"], fleet.world.tick, count_flips(rows), sum(len(r) for r in rows))


def row(label: str, map_name: str, robots: int, runs: list[Run]) -> str:
    reached = sum(r.t99 is not None for r in runs)
    ticks = [float(r.t99 if r.t99 is not None else r.ticks) for r in runs]
    star = "" if reached == len(runs) else "*"
    rate = 100.0 * sum(r.flips for r in runs) / max(1, sum(r.robot_ticks for r in runs))
    worst = max(100.0 * r.flips / max(1, r.robot_ticks) for r in runs)
    return (f"| {label} | {map_name} | {robots} | {len(runs)} | {reached} | {mean_sd(ticks, 0)}{star} "
            f"| {rate:.2f} | {worst:.2f} |")


def main(argv: list[str] | None = None) -> None:
    p = parser("benchmarks.flips", __doc__)
    p.add_argument("--allocators", nargs="+", default=["hungarian", "hungarian:replan=tick", "trade"])
    p.add_argument("--maps", nargs="+", default=["office"])
    p.add_argument("--robots", type=int, nargs="+", default=[2, 3, 4])
    p.add_argument("--seeds", type=int, default=10)
    p.add_argument("--loss", type=float, default=0.0)
    p.add_argument("--comm", default="full", help="the radio model (default full: every pair in range)")
    p.add_argument("--start", default="map", help="'map' (the map's own), 'random' (drawn per seed), or ROW,COL")
    p.add_argument("--max-ticks", type=int, default=3000)
    a = p.parse_args(argv)
    setting = Setting(a.loss, a.comm, a.start, a.max_ticks)
    from fleet_emu.core.errors import FleetError

    try:
        configs = [(spec, allocator(spec)) for spec in a.allocators]
        for _, config in configs:  # bad input before any run: one line
            scenario(config, a.maps[0], a.robots[0], 0, setting)
    except (ValueError, FleetError) as exc:
        fail("flips", str(exc))
    print(machine())
    print(f"\nloss {a.loss:g}, radio {a.comm}, start {a.start}, seeds 0-{a.seeds - 1}, memory engine\n")
    print("| allocator | map | robots | runs | reached 99 % | ticks to 99 % | flips / 100 robot-ticks | worst run |")
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for map_name in a.maps:
        for n in a.robots:
            for spec, config in configs:
                runs = []
                for seed in range(a.seeds):
                    try:
                        r = run_one(config, map_name, n, seed, setting)
                    except FleetError as exc:
                        fail("flips", f"{spec} on {map_name}: {exc}")
                    runs.append(r)
                    print(f"{spec} {map_name} {n} robots seed {seed}: t99 {r.t99}, ticks {r.ticks}, "
                          f"{r.flips} flips in {r.robot_ticks} robot-ticks", file=sys.stderr, flush=True)
                print(row(spec, map_name, n, runs), flush=True)


if __name__ == "__main__":
    main()
