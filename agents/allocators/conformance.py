"""Checks every registered allocator must pass, after PettingZoo's ``api_test`` and ``seed_test``.

``api_test`` drives an allocator through drawn problems (frontiers in several directions, none at all,
an unreachable one) and checks the typed contract; ``seed_test`` checks that the same generator gives the
same decisions; ``flip_test`` checks that a fleet run does not oscillate between two targets (the run itself
is passed in: this layer does not step a fleet). Each raises AssertionError with a message naming what broke.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from fleet_emu.agents.allocators.interface import Allocation, Allocator, AllocStatus, Problem
from fleet_emu.agents.allocators.registry import make_allocator
from fleet_emu.agents.frontiers import find_clusters
from fleet_emu.core.codec import Payload
from fleet_emu.core.grid import FREE, UNKNOWN, Cell, from_ascii
from fleet_emu.core.messages import RadioMsg

CROSS = """
???????.???????
???????.???????
???????.???????
.......0.......
???????1???????
???????.???????
???????2.3.....
"""

CLOSED = """
#######
#0...1#
#.....#
#######
"""

WALLED = """
?##?????
#..#....
#0.#.2..
#..#....
"""


def _problem(art: str, me: str, tick: int = 0) -> Problem:
    grid, robots = from_ascii(art)
    return Problem(me=me, poses=robots, belief=grid, clusters=find_clusters(grid, 4), tick=tick)


def random_problem(rng: np.random.Generator, me: str = "r0", size: int = 24, robots: int = 4) -> Problem:
    """A random belief: free space with walls, a band of unknown, robots on free cells."""
    grid = np.where(rng.random((size, size)) < 0.12, 100, FREE).astype(np.int8)
    grid[:, size // 2 + int(rng.integers(0, size // 3)):] = UNKNOWN
    grid[rng.random((size, size)) < 0.05] = UNKNOWN
    free = np.argwhere(grid == FREE)
    picks = rng.choice(len(free), size=robots, replace=False)
    poses = {f"r{k}": (int(free[p][0]), int(free[p][1])) for k, p in enumerate(picks)}
    return Problem(me=me, poses=poses, belief=grid, clusters=find_clusters(grid, 6))


def _check(problem: Problem, a: Any, name: str) -> None:
    assert isinstance(a, Allocation), f"{name}: allocate returned {type(a).__name__}, not Allocation"
    assert isinstance(a.status, AllocStatus), f"{name}: status is not an AllocStatus"
    if a.status is AllocStatus.ASSIGNED:
        assert a.cluster is not None and 0 <= a.cluster < len(problem.clusters), f"{name}: cluster out of range"
        assert a.target == problem.clusters[a.cluster].target, f"{name}: target is not the cluster's target"
        me = problem.poses[problem.me]
        assert problem.wavefronts[a.cluster][me] >= 0, f"{name}: assigned an unreachable cluster"
    else:
        assert a.cluster is None or a.status is AllocStatus.WAITING, f"{name}: a cluster without ASSIGNED"
    if a.status is AllocStatus.GOAL:
        rows, cols = problem.belief.shape
        assert a.target is not None and 0 <= a.target[0] < rows and 0 <= a.target[1] < cols, \
            f"{name}: goal off the grid"
        assert a.passable is None or (a.passable.shape == problem.belief.shape and a.passable.dtype == bool), \
            f"{name}: passable is not a boolean mask of the grid"
    assert isinstance(a.outbox, tuple), f"{name}: outbox is not a tuple"
    for m in a.outbox:
        assert isinstance(m, RadioMsg) and isinstance(m.dst, str), f"{name}: an outbox entry is not a RadioMsg"
        assert m.kind in Payload.REGISTRY, f"{name}: payload kind {m.kind!r} is not registered"
        assert m.body.encode(), f"{name}: an outbox payload does not encode"


def api_test(config: dict[str, Any], rounds: int = 6) -> None:
    """The typed contract of one allocator configuration."""
    name = config["type"]
    alloc = make_allocator(config)
    assert isinstance(alloc, Allocator)
    assert alloc.to_dict()["type"] == name, f"{name}: to_dict lost the type"
    assert make_allocator(alloc.to_dict()).to_dict() == alloc.to_dict(), f"{name}: to_dict does not round-trip"
    alloc.reset(np.random.default_rng(0))
    for tick in range(rounds):  # a protocol may need a few rounds; each answer must still be well-formed
        for me in ("r0", "r1", "r3"):
            p = _problem(CROSS, me, tick)
            _check(p, alloc.allocate(p, ()), name)
    closed = _problem(CLOSED, "r0")
    a = alloc.allocate(closed, ())
    _check(closed, a, name)
    assert a.status is not AllocStatus.ASSIGNED, f"{name}: assigned a frontier where there is none"
    walled = _problem(WALLED, "r0")
    _check(walled, alloc.allocate(walled, ()), name)
    rng = np.random.default_rng(1)
    for k in range(10):
        p = random_problem(rng)
        if k % 2 and p.clusters:  # a previous target (Problem.previous_target), reachable or not
            p.previous_target = p.clusters[int(rng.integers(len(p.clusters)))].target
        _check(p, alloc.allocate(p, ()), name)


def seed_test(config: dict[str, Any], seed: int = 7, rounds: int = 12) -> None:
    """Same seed, same decisions: two fresh allocators fed the same problems agree on every call."""
    name = config["type"]

    def run() -> list[tuple[str, int | None]]:
        alloc = make_allocator(config)
        alloc.reset(np.random.default_rng(seed))
        rng = np.random.default_rng(seed + 1)
        out = []
        for t in range(rounds):
            p = random_problem(rng, me=f"r{t % 4}")
            p.tick = t
            a = alloc.allocate(p, ())
            out.append((a.status.name, a.cluster))
        return out

    assert run() == run(), f"{name}: the same seed gave different decisions"


#: A flip: a robot's target goes A -> B -> A, the return to A at most this many ticks after it left A.
FLIP_WINDOW = 10
#: The most flips per 100 robot-ticks an allocator may make at loss 0 (``flip_test``).
FLIP_LIMIT = 3.0

Targets = Sequence[Mapping[str, Cell | None]]


def count_flips(targets: Targets, window: int = FLIP_WINDOW) -> int:
    """The flips in a run: ``targets[t]`` maps each robot deciding at tick t to its target (None: none). Per
    robot, ticks without a target are skipped and runs of one target merged; a flip is three runs in a row
    A, B, A (A != B) whose return to A comes at most ``window`` ticks after the robot left A."""
    runs: dict[str, list[tuple[Cell, int]]] = {}  # robot -> [(target, first tick of the run)]
    for t, row in enumerate(targets):
        for robot, target in row.items():
            seq = runs.setdefault(robot, [])
            if target is not None and (not seq or seq[-1][0] != target):
                seq.append((target, t))
    flips = 0
    for seq in runs.values():
        for (a, _), (b, left), (c, back) in zip(seq, seq[1:], seq[2:], strict=False):
            if a == c and a != b and back - left <= window:
                flips += 1
    return flips


def flip_rate(targets: Targets, window: int = FLIP_WINDOW) -> float:
    """Flips (``count_flips``) per 100 robot-ticks, a robot-tick being one robot's decision in one tick."""
    robot_ticks = sum(len(row) for row in targets)
    return 100.0 * count_flips(targets, window) / robot_ticks if robot_ticks else 0.0


#: The map of ``flip_test``: two rooms each side of a corridor, the two robots in its middle. Re-solving an
#: optimal assignment every tick sends them back and forth between two frontiers here (``hungarian`` with
#: ``replan="tick"``: 60 flips in 168 robot-ticks).
FLIP_MAP = """
#####################
#.....#.....#.......#
#.....#.....#.......#
#.....#.....#.......#
###.#####.#####.#####
#...................#
#.........01........#
#...................#
###.#####.#####.#####
#.....#.....#.......#
#.....#.....#.......#
#.....#.....#.......#
#####################
"""


def flip_test(config: dict[str, Any], run: Callable[[str, dict[str, Any], int], Targets],
              seeds: Sequence[int] = (0,), limit: float = FLIP_LIMIT) -> float:
    """No oscillation between two targets: ``run(FLIP_MAP, config, seed)`` explores the drawn map with the
    allocator at loss 0 and gives each tick's targets (a fleet engine's, which this layer does not import); over
    the seeds together the allocator makes at most ``limit`` flips per 100 robot-ticks. Returns the rate."""
    traces = [run(FLIP_MAP, config, seed) for seed in seeds]
    flips = sum(count_flips(t) for t in traces)
    robot_ticks = sum(len(row) for t in traces for row in t)
    rate = 100.0 * flips / robot_ticks if robot_ticks else 0.0
    assert rate <= limit, f"{config['type']}: {rate:.1f} target flips per 100 robot-ticks (at most {limit:g})"
    return rate
