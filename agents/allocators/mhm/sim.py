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

from fleet_emu.agents.allocators.mhm.explore import Box, bounds, boxed_wavefront
from fleet_emu.agents.allocators.mhm.planner import MhmConfig, MhmPlanner, View
from fleet_emu.core.base_connectivity import base_connected
from fleet_emu.core.grid import FREE, MOVES, OCCUPIED, UNKNOWN, Cell
from fleet_emu.core.kernels import visible_cells, wavefront


@dataclasses.dataclass
class SimResult:
    """``ticks`` run, final ``coverage`` (known share of the free cells reachable from the base), whether the
    planner reached step 18 (``done``), ``connected`` (per tick, the fraction of robots with a path to the
    base), ``seen`` (known cells per tick), ``nodes`` (node robots per tick), ``step_ms`` (planner time per
    tick, when a clock was given), the planner itself, and the team map at the end (``keep_belief``)."""

    ticks: int
    coverage: float
    done: bool
    connected: list[float]
    seen: list[int]
    nodes: list[int]
    step_ms: list[float]
    planner: MhmPlanner
    belief: np.ndarray | None = None


def start_cells(free: np.ndarray, base: Cell, n: int) -> list[Cell]:
    """The ``n`` free cells nearest the base by path (not the base's own), the paper's start "within the
    base-station communication range"."""
    cols = free.shape[1]
    dist = wavefront(free, np.array([base[0] * cols + base[1]], dtype=np.int64), -1)
    rc = np.argwhere(dist > 0)  # row-major: (distance, row, col) order is a stable sort by distance
    order = np.argsort(dist[rc[:, 0], rc[:, 1]], kind="stable")[:n]
    return [(int(rc[k, 0]), int(rc[k, 1])) for k in order]


def _links(cells: list[Cell], r_comm: float) -> np.ndarray:
    rc = np.array(cells, dtype=float)
    gap = np.hypot(rc[:, None, 0] - rc[None, :, 0], rc[:, None, 1] - rc[None, :, 1])
    return (gap < r_comm) & ~np.eye(len(cells), dtype=bool)


def simulate(truth: np.ndarray, base: Cell, robots: int, config: MhmConfig, seed: int = 0,
             max_ticks: int = 3000, clock: Callable[[], float] | None = None, keep_belief: bool = False,
             progress: Callable[[int, int], None] | None = None) -> SimResult:
    """Run the planner on the true map ``truth`` (0 free, 100 occupied) from ``base`` until step 18 or
    ``max_ticks``; ``progress(tick, cells seen)`` is called every 10,000 ticks."""
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
    known = 0
    for t in range(max_ticks):
        for cell in poses.values():
            idx = sensed(occ, cell, config.sensor_range)
            known += int(np.count_nonzero(belief.flat[idx] == UNKNOWN))
            belief.flat[idx] = truth.flat[idx]
        t0 = clock() if clock else 0.0
        orders = planner.step(View(t, belief, dict(poses)))
        if clock:
            step_ms.append((clock() - t0) * 1000.0)
        flags = base_connected(["base", *names], _links([base, *poses.values()], config.r_comm))
        connected.append(sum(flags.values()) / len(flags))
        seen.append(known)
        nodes.append(sum(o.role == "node" for o in orders.values()))
        if planner.done:
            break
        if progress is not None and t % 10_000 == 0:
            progress(t, known)
        passable = planner.passable()
        box = relay_box(passable.shape, planner.relays(), config.r_comm)
        for r in names:
            o = orders[r]
            if o.role == "node" or o.goal is None or o.goal == poses[r]:
                continue
            step_toward(r, o.goal, poses, passable, stuck, rng, box)
    cols = truth.shape[1]
    reach = wavefront(truth == FREE, np.array([base[0] * cols + base[1]], dtype=np.int64), -1) >= 0
    coverage = float((belief[reach] != UNKNOWN).mean())
    return SimResult(t, coverage, planner.done, connected, seen, nodes, step_ms, planner,
                     belief if keep_belief else None)


def sensed(occupied: np.ndarray, cell: Cell, radius: float) -> np.ndarray:
    """``visible_cells`` of a sensor at ``cell``, computed in the square of the sensor's reach (the same
    cells: rays never leave it) rather than on the whole grid; flat indices of the grid, ascending."""
    k = max(0, math.ceil(radius)) + 1
    r0, c0 = max(0, cell[0] - k), max(0, cell[1] - k)
    win = np.ascontiguousarray(occupied[r0:cell[0] + k + 1, c0:cell[1] + k + 1])
    rows, cols = np.divmod(visible_cells(win, cell[0] - r0, cell[1] - c0, radius), win.shape[1])
    return (rows + r0) * occupied.shape[1] + cols + c0


def relay_box(shape: tuple[int, int], relays: list[Cell], r_comm: float) -> Box:
    """A box holding every cell within ``r_comm`` of a relay (so every cell of the safe area)."""
    k = math.ceil(r_comm)
    rc = np.array(relays)
    lo = np.maximum(rc.min(axis=0) - k, 0)
    hi = np.minimum(rc.max(axis=0) + k + 1, shape)
    return (int(lo[0]), int(lo[1]), int(hi[0]), int(hi[1]))


def step_toward(r: str, goal: Cell, poses: dict[str, Cell], passable: np.ndarray, stuck: dict[str, int],
                rng: np.random.Generator, box: Box | None = None) -> None:
    """One step of robot ``r`` down the wavefront from ``goal``; a random free step after two blocked ticks.
    ``box``: one holding every ``passable`` cell (``explore.bounds``), where the wavefront runs."""
    rows, cols = passable.shape
    here = poses[r]
    b = bounds(passable) if box is None else box
    b = (min(b[0], goal[0], here[0]), min(b[1], goal[1], here[1]),
         max(b[2], goal[0] + 1, here[0] + 1), max(b[3], goal[1] + 1, here[1] + 1))
    local = boxed_wavefront(passable, b, np.array([goal]))

    def dist(cell: Cell) -> int:
        i, j = cell[0] - b[0], cell[1] - b[1]
        return int(local[i, j]) if 0 <= i < local.shape[0] and 0 <= j < local.shape[1] else -1

    taken = set(poses.values())
    steps = [(here[0] + dr, here[1] + dc) for dr, dc in MOVES]
    steps = [n for n in steps if 0 <= n[0] < rows and 0 <= n[1] < cols and n not in taken]
    down = [n for n in steps if 0 <= dist(n) < dist(here)]
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
