"""MHM's planner (section III-D) driven tick by tick on drawn maps by a small in-test world: robots step one
4-connected cell per tick toward their goal inside the planner's safe area, sense a disk, and the base's team
map is the union of what they sensed. Every tick the robots' link graph (``d < r_comm``, the paper's model)
must join every robot to the base station."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from fleet_emu.agents.allocators.mhm.planner import MhmConfig, MhmPlanner, View
from fleet_emu.agents.allocators.mhm.tree import BASE_NODE
from fleet_emu.core.grid import FREE, MOVES, OCCUPIED, UNKNOWN, Cell, from_ascii
from fleet_emu.core.kernels import visible_cells, wavefront
from fleet_emu.core.reach import base_connected

# Two rooms off a hall, a long room along the bottom; every passage at least two cells wide, so that a node
# robot standing in one does not block it.
OFFICE = """
##############################################
#..........................#.................#
#..........................#.................#
#..........................#.................#
#.........########.........#.........#########
#.........#......#...................#.......#
#.........#......#...................#.......#
#.........#..........................#.......#
#.........#..........................#.......#
#.........#......#...................#.......#
#.........########.........#.........#.......#
#..........................#.................#
#..........................#.................#
#######....#################.........#########
#............................................#
#............................................#
#............................................#
##############################################
"""
BASE = (2, 2)


@dataclasses.dataclass
class Outcome:
    ticks: int
    coverage: float
    done: bool
    worst_fraction: float
    planner: MhmPlanner
    nodes_seen: int


def start_cells(free: np.ndarray, base: Cell, n: int) -> list[Cell]:
    cols = free.shape[1]
    dist = wavefront(free, np.array([base[0] * cols + base[1]], dtype=np.int64), -1)
    cells = sorted((int(dist[r, c]), r, c) for r, c in np.argwhere(dist > 0))
    return [(r, c) for _, r, c in cells[:n]]


def simulate(art: str, robots: int, config: MhmConfig, seed: int = 0, max_ticks: int = 3000) -> Outcome:
    truth, _ = from_ascii(art)
    occ = truth == OCCUPIED
    belief = np.full(truth.shape, UNKNOWN, dtype=np.int8)
    names = [f"r{k}" for k in range(robots)]
    poses = dict(zip(names, start_cells(truth == FREE, BASE, robots), strict=True))
    planner = MhmPlanner(BASE, names, config, np.random.default_rng(seed))
    worst, nodes_seen, t = 1.0, 0, 0
    rng = np.random.default_rng(seed + 1)
    stuck = dict.fromkeys(names, 0)
    for t in range(max_ticks):
        for r, c in poses.values():
            idx = visible_cells(occ, r, c, config.sensor_range)
            belief.flat[idx] = truth.flat[idx]
        orders = planner.step(View(t, belief, dict(poses)))
        cells = [BASE, *poses.values()]
        gap = np.array([[math.dist(a, b) for b in cells] for a in cells])
        link = (gap < config.r_comm) & ~np.eye(len(cells), dtype=bool)
        flags = base_connected(["base", *names], link)
        worst = min(worst, sum(flags.values()) / len(flags))
        nodes_seen = max(nodes_seen, sum(o.role == "node" for o in orders.values()))
        for r, o in orders.items():
            if o.role == "node":
                assert o.goal == poses[r], f"tick {t}: node {r} is not where it hinged"
        if planner.done:
            break
        passable = planner.passable()
        for r in names:  # one step toward the goal, inside the safe area, never onto a teammate
            o = orders[r]
            if o.role == "node" or o.goal is None or o.goal == poses[r]:
                continue
            dist = wavefront(passable, np.array([o.goal[0] * truth.shape[1] + o.goal[1]], dtype=np.int64), -1)
            here = poses[r]
            taken = set(poses.values())
            steps = [(here[0] + dr, here[1] + dc) for dr, dc in MOVES]
            steps = [n for n in steps if 0 <= n[0] < truth.shape[0] and 0 <= n[1] < truth.shape[1]]
            best = [n for n in steps if 0 <= dist[n] < dist[here] and n not in taken]
            if best:
                poses[r], stuck[r] = best[0], 0
                continue
            stuck[r] += 1  # blocked by a teammate: after two ticks, a random free step inside the safe area
            sides = [n for n in steps if passable[n] and n not in taken]
            if stuck[r] >= 2 and sides:
                poses[r] = sides[int(rng.integers(len(sides)))]
    free = truth == FREE
    cols = truth.shape[1]
    reach = wavefront(free, np.array([BASE[0] * cols + BASE[1]], dtype=np.int64), -1) >= 0
    coverage = float((belief[reach] != UNKNOWN).mean())
    return Outcome(t, coverage, planner.done, worst, planner, nodes_seen)


CONFIG = MhmConfig(r_comm=10.0, sensor_range=4.0, x_min=1, cluster_max=8, patience=40)


@pytest.mark.parametrize("robots", [6, 10])
def test_mhm_keeps_every_robot_connected_and_explores(robots: int) -> None:
    out = simulate(OFFICE, robots, CONFIG)
    assert out.worst_fraction == 1.0  # the base-station constraint held on every tick
    assert out.done  # step 18 was reached
    assert out.coverage >= 0.95
    assert out.nodes_seen >= 2  # robots did hinge
    tree = out.planner.tree
    assert len(tree) > 3 and all(tree[i].processed for i in range(len(tree)) if tree[i].kind != "chain")
    for i in range(1, len(tree)):  # every node was within r_comm of its parent when it joined
        assert math.dist(tree[i].pos, tree[tree.parent(i)].pos) < CONFIG.r_comm  # type: ignore[index]


def test_a_seed_reproduces_the_run() -> None:
    a = simulate(OFFICE, 6, CONFIG, seed=3)
    b = simulate(OFFICE, 6, CONFIG, seed=3)
    assert a.ticks == b.ticks and a.coverage == b.coverage
    assert [(n.pos, n.parent) for n in a.planner.tree.nodes] == [(n.pos, n.parent) for n in b.planner.tree.nodes]


def test_routes_lead_every_robot_to_the_base() -> None:
    planner = simulate(OFFICE, 6, dataclasses.replace(CONFIG), max_ticks=60).planner
    routes = planner.routes()
    assert set(routes) == {f"r{k}" for k in range(6)}
    for robot in routes:
        seen, hop = set(), robot
        while hop != "base":
            assert hop not in seen, "a cycle in the routes"
            seen.add(hop)
            hop = routes[hop]
    assert planner.hinged() >= {BASE_NODE}
