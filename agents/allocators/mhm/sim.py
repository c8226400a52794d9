"""A minimal kinematic world to drive the MHM planner without processes (tests and ``benchmarks/``).

Not the project's world (``world/``) and not its radio: robots step one 4-connected cell per tick toward the
goal the planner gives them, over the planner's :meth:`~.planner.MhmPlanner.passable` cells (the safe area,
around node robots), never onto a teammate; a robot blocked for two ticks takes a random free step inside the
safe area (like the brain's unsticking). Each robot senses a disk (ray cast on the true map), and the base's
team map is the union of what they sensed: loss-free and instant, so the planner's constraint is checked on
its own. Links are the paper's model, ``d < r_comm`` between any two of the base and the robots, and every
tick records the fraction of robots with a path to the base.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from fleet_emu.agents.allocators.mhm.planner import MhmConfig, MhmPlanner, View
from fleet_emu.core.grid import FREE, MOVES, OCCUPIED, UNKNOWN, Cell
from fleet_emu.core.kernels import visible_cells, wavefront
from fleet_emu.core.reach import base_connected


@dataclasses.dataclass
class SimResult:
    """``ticks`` run, final ``coverage`` (known share of the free cells reachable from the base), whether the
    planner reached step 18 (``done``), ``connected`` (per tick, the fraction of robots with a path to the
    base), ``seen`` (known cells per tick), ``nodes`` (node robots per tick), ``step_ms`` (planner time per
    tick, when a clock was given), and the planner itself."""

    ticks: int
    coverage: float
    done: bool
    connected: list[float]
    seen: list[int]
    nodes: list[int]
    step_ms: list[float]
    planner: MhmPlanner


def start_cells(free: np.ndarray, base: Cell, n: int) -> list[Cell]:
    """The ``n`` free cells nearest the base by path (not the base's own), the paper's start "within the
    base-station communication range"."""
    cols = free.shape[1]
    dist = wavefront(free, np.array([base[0] * cols + base[1]], dtype=np.int64), -1)
    cells = sorted((int(dist[r, c]), int(r), int(c)) for r, c in np.argwhere(dist > 0))
    return [(r, c) for _, r, c in cells[:n]]


def _links(cells: list[Cell], r_comm: float) -> np.ndarray:
    rc = np.array(cells, dtype=float)
    gap = np.hypot(rc[:, None, 0] - rc[None, :, 0], rc[:, None, 1] - rc[None, :, 1])
    return (gap < r_comm) & ~np.eye(len(cells), dtype=bool)


def simulate(truth: np.ndarray, base: Cell, robots: int, config: MhmConfig, seed: int = 0,
             max_ticks: int = 3000, clock: Callable[[], float] | None = None) -> SimResult:
    """Run the planner on the true map ``truth`` (0 free, 100 occupied) from ``base`` until step 18 or
    ``max_ticks``."""
    occ = truth == OCCUPIED
    belief = np.full(truth.shape, UNKNOWN, dtype=np.int8)
    names = [f"r{k}" for k in range(robots)]
    poses = dict(zip(names, start_cells(truth == FREE, base, robots), strict=True))
    planner = MhmPlanner(base, names, config, np.random.default_rng(seed))
    rng = np.random.default_rng(seed + 1)
    stuck = dict.fromkeys(names, 0)
    connected: list[float] = []
    seen: list[int] = []
    nodes: list[int] = []
    step_ms: list[float] = []
    t = 0
    for t in range(max_ticks):
        for row, col in poses.values():
            idx = visible_cells(occ, row, col, config.sensor_range)
            belief.flat[idx] = truth.flat[idx]
        t0 = clock() if clock else 0.0
        orders = planner.step(View(t, belief, dict(poses)))
        if clock:
            step_ms.append((clock() - t0) * 1000.0)
        flags = base_connected(["base", *names], _links([base, *poses.values()], config.r_comm))
        connected.append(sum(flags.values()) / len(flags))
        seen.append(int((belief != UNKNOWN).sum()))
        nodes.append(sum(o.role == "node" for o in orders.values()))
        if planner.done:
            break
        passable = planner.passable()
        for r in names:
            o = orders[r]
            if o.role == "node" or o.goal is None or o.goal == poses[r]:
                continue
            step_toward(r, o.goal, poses, passable, stuck, rng)
    cols = truth.shape[1]
    reach = wavefront(truth == FREE, np.array([base[0] * cols + base[1]], dtype=np.int64), -1) >= 0
    coverage = float((belief[reach] != UNKNOWN).mean())
    return SimResult(t, coverage, planner.done, connected, seen, nodes, step_ms, planner)


def step_toward(r: str, goal: Cell, poses: dict[str, Cell], passable: np.ndarray, stuck: dict[str, int],
          rng: np.random.Generator) -> None:
    """One step of robot ``r`` down the wavefront from ``goal``; a random free step after two blocked ticks."""
    rows, cols = passable.shape
    dist = wavefront(passable, np.array([goal[0] * cols + goal[1]], dtype=np.int64), -1)
    here = poses[r]
    taken = set(poses.values())
    steps = [(here[0] + dr, here[1] + dc) for dr, dc in MOVES]
    steps = [n for n in steps if 0 <= n[0] < rows and 0 <= n[1] < cols and n not in taken]
    down = [n for n in steps if 0 <= dist[n] < dist[here]]
    if down:
        poses[r], stuck[r] = down[0], 0
        return
    stuck[r] += 1
    sides = [n for n in steps if passable[n]]
    if stuck[r] >= 2 and sides:
        poses[r] = sides[int(rng.integers(len(sides)))]


def fraction_at(seen: list[int], ticks: list[int]) -> list[int]:
    """Known cells at each of ``ticks`` (the last value after the run ended)."""
    return [seen[min(t, len(seen) - 1)] if seen else 0 for t in ticks]


def worst(connected: list[float]) -> float:
    """The lowest per-tick base-connected fraction (1.0: the constraint never broke)."""
    return min(connected, default=math.nan)
