"""MinPos (Bautin et al. 2012) on grids drawn after the paper's figures, and its wavefront savings (section 4.3)
checked against the plain Algorithm 3 on hand-drawn and random problems."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from fleet_emu.agents.allocators import AllocStatus, Problem, make_allocator
from fleet_emu.agents.allocators.conformance import CLOSED, CROSS, WALLED, random_problem
from fleet_emu.agents.allocators.minpos import minpos_choice, parallel_choice, positions
from fleet_emu.agents.frontiers import find_clusters
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.grid import FREE, UNKNOWN, Cell, flat, from_ascii
from fleet_emu.core.minpos_kernels import minpos_parallel, seen_words

VARIANTS = ("full", "stop", "parallel")


def problem(art: str, me: str, cluster_max: int = 4) -> Problem:
    grid, robots = from_ascii(art)
    return Problem(me=me, poses=robots, belief=grid, clusters=find_clusters(grid, cluster_max))


def target(config: dict[str, Any], art: str, me: str) -> Cell | None:
    """The target cell of the cluster ``config``'s allocator gives robot ``me`` on a drawn grid."""
    return make_allocator(config).allocate(problem(art, me)).target


MINPOS = {"type": "minpos"}
GREEDY = {"type": "greedy"}
NEAREST = {"type": "nearest"}

# Figs. 1(b) and 2: R2 and R5 stand together; F1 and F2 lie close together on the right, F0 far on the left.
# Greedy gives R2 the nearest pair (R2-F1) and R5 the next one, F2: both go toward the same region and F0 is
# left alone. Under MinPos R5 is second toward F1 and F2 and first toward F0, so it goes there.
FIG2 = """
#####################?#?#
?...............5.2.....#
#########################
"""
F0, F1, F2 = (1, 1), (1, 21), (1, 23)


def test_fig1_greedy_sends_two_robots_toward_one_region() -> None:
    assert target(GREEDY, FIG2, "r2") == F1
    assert target(GREEDY, FIG2, "r5") == F2
    assert target(NEAREST, FIG2, "r5") == F1  # Fig. 1(a): nearest, no regard for the other robot


@pytest.mark.parametrize("variant", VARIANTS)
def test_fig2_minpos_spreads_them(variant: str) -> None:
    config = {"type": "minpos", "wavefront": variant}
    assert target(config, FIG2, "r2") == F1
    assert target(config, FIG2, "r5") == F0


# Fig. 6(a): two robots follow each other up a corridor toward a T with frontiers at both ends (the left
# branch is the shorter). Both first head for F1: R0 is first toward both frontiers and F1 is nearer, R1 is
# second toward both and F1 is nearer. Once R0 has turned into the left branch, R1 is first toward F2.
T_BEFORE = """
#############
?...........?
#####0#######
#####1#######
#####.#######
"""
T_AFTER = """
#############
?..0........?
#####1#######
#####.#######
#####.#######
"""
T_LEFT, T_RIGHT = (1, 1), (1, 11)


def test_fig6a_robots_following_each_other_separate_at_the_t() -> None:
    assert target(MINPOS, T_BEFORE, "r0") == T_LEFT
    assert target(MINPOS, T_BEFORE, "r1") == T_LEFT  # following
    assert target(MINPOS, T_AFTER, "r0") == T_LEFT
    assert target(MINPOS, T_AFTER, "r1") == T_RIGHT  # separated
    assert target(NEAREST, T_AFTER, "r1") == T_LEFT  # nearest keeps them together
    assert target(GREEDY, T_BEFORE, "r1") == T_RIGHT  # "with a greedy algorithm ... initially assigned
    # to the different frontiers"


# Fig. 6(c), the limit case: R3 sees three frontiers ahead (F1..F3) with R2 and R1 in front, so it is third
# toward each, and turns back to F4 where it is second behind R0, leaving F2 and F3 to nobody. Greedy
# gives each robot its own frontier.
FIG6C = """
#################?#?#?#
?..0......3.2.1.......#
#######################
"""
F4, AHEAD = (1, 1), [(1, 17), (1, 19), (1, 21)]


def test_fig6c_minpos_limit_case_where_greedy_does_better() -> None:
    assert target(MINPOS, FIG6C, "r3") == F4
    assert target(GREEDY, FIG6C, "r3") in AHEAD
    robots = ("r0", "r1", "r2", "r3")
    greedy = {target(GREEDY, FIG6C, r) for r in robots}
    minpos = {target(MINPOS, FIG6C, r) for r in robots}
    assert greedy == {F4, *AHEAD}  # every frontier has a robot
    assert minpos == {F4, AHEAD[0]}  # two frontiers left unassigned
    p = problem(FIG6C, "r3")
    assert positions(p.costs, p.index).tolist() == [1, 2, 2, 2]


# Ties: R1 is second toward both ends at equal cost, so the lowest cluster index decides (F_left).
TIE = """
#############
?.....0.....?
######.######
######1######
"""

HAND_DRAWN = [FIG2, T_BEFORE, T_AFTER, FIG6C, TIE, CROSS, CLOSED, WALLED, """
?????????
?.0...1.?
?...#...?
?.2.#.3.?
?????????
""", """
#########
#0.1#..??
#...#.#??
#2..#...#
#########
"""]


def _choices(p: Problem) -> dict[str, int | None]:
    """Each variant's cluster on a fresh copy of the problem (no cached wavefronts shared)."""
    out = {}
    for w in VARIANTS:
        q = Problem(me=p.me, poses=p.poses, belief=p.belief, clusters=p.clusters, tick=p.tick)
        out[w] = make_allocator({"type": "minpos", "wavefront": w}).allocate(q).cluster
    return out


def test_ties_go_to_least_position_then_cost_then_lowest_index() -> None:
    for w in VARIANTS:
        assert target({"type": "minpos", "wavefront": w}, TIE, "r1") == (1, 1)
        assert target({"type": "minpos", "wavefront": w}, TIE, "r0") == (1, 1)


@pytest.mark.parametrize("art", HAND_DRAWN)
def test_stop_and_parallel_equal_full_on_hand_drawn_grids(art: str) -> None:
    _, robots = from_ascii(art)
    for me in robots:
        c = _choices(problem(art, me))
        assert c["stop"] == c["full"] and c["parallel"] == c["full"], (me, c)


def _tie_problem(rng: np.random.Generator) -> Problem:
    """Small open rooms with a few walls, many robots, some on the same cell: positions and costs tie often."""
    size = int(rng.integers(5, 12))
    grid = np.full((size, size), FREE, dtype=np.int8)
    grid[rng.random((size, size)) < 0.08] = 100
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = UNKNOWN
    grid[rng.random((size, size)) < 0.05] = UNKNOWN
    free = np.argwhere(grid == FREE)
    n = int(rng.integers(1, min(8, len(free)) + 1))
    cells = [tuple(int(v) for v in free[k]) for k in rng.choice(len(free), size=n)]  # repeats allowed
    poses = {f"r{k}": c for k, c in enumerate(cells)}
    me = f"r{int(rng.integers(n))}"
    return Problem(me=me, poses=poses, belief=grid, clusters=find_clusters(grid, int(rng.integers(1, 5))))


def test_stop_and_parallel_equal_full_on_random_problems() -> None:
    rng = np.random.default_rng(2012)
    ties = unreachable = shared = level = 0
    for k in range(400):
        if k % 2:
            n = int(rng.integers(1, 9))
            p = random_problem(rng, me=f"r{int(rng.integers(n))}", size=int(rng.integers(6, 32)), robots=n)
        else:
            p = _tie_problem(rng)
        c = _choices(p)
        assert c["stop"] == c["full"] and c["parallel"] == c["full"], (k, c)
        costs = p.costs
        j = minpos_choice(costs, p.index)
        if j is not None:
            pos = positions(costs, p.index)
            own = costs[p.index]
            ties += int(((pos == pos[j]) & (own == own[j])).sum() > 1)
            level += int((costs[:, j] == own[j]).sum() > 1)  # a teammate on the same cost as me
        unreachable += int(not np.isfinite(costs).all())
        shared += int(len(set(p.poses.values())) < len(p.poses))
    counts = (ties, unreachable, shared, level)
    assert min(counts) >= 20, counts  # the cases we meant to cover did occur


def test_parallel_kernel_reports_position_and_cost() -> None:
    rng = np.random.default_rng(5)
    seen = np.zeros(seen_words(30 * 30, 64), dtype=np.uint64)  # one bitset through every call, as MinPos keeps
    for _ in range(100):
        p = random_problem(rng, robots=int(rng.integers(1, 7)))
        shape = p.belief.shape
        sources = np.concatenate([c.cells for c in p.clusters]) if p.clusters else np.empty(0, np.int64)
        offsets = np.concatenate([[0], np.cumsum([c.size for c in p.clusters])]).astype(np.int64)
        others = np.array([flat(shape, c) for r, c in p.poses.items() if r != p.me], dtype=np.int64)
        j, pos, cost = minpos_parallel(p.passable, sources, offsets, flat(shape, p.poses[p.me]), others)
        full = minpos_choice(p.costs, p.index)
        assert (None if j < 0 else j) == full == parallel_choice(p) == parallel_choice(p, seen)
        assert not seen.any()  # the kept bitset is left zeroed for the next call
        if full is not None:
            assert (pos, cost) == (positions(p.costs, p.index)[full], p.costs[p.index, full])


def test_stop_computes_less_than_full() -> None:
    """The stopped wavefronts leave far cells unlabelled: the saving section 4.3 is after."""
    from fleet_emu.agents.allocators.minpos import stopped_costs

    p = problem(FIG6C, "r1")
    partial = stopped_costs(p)
    assert np.isinf(partial).sum() > np.isinf(p.costs).sum()
    assert np.array_equal(partial[p.index], p.costs[p.index])


def test_unknown_wavefront_mode_fails() -> None:
    with pytest.raises(ConfigError, match="wavefront"):
        make_allocator({"type": "minpos", "wavefront": "fast"})


def test_no_reachable_frontier_means_no_frontier() -> None:
    art = """
    #####?
    #0.#.?
    #####?
    """
    for w in VARIANTS:
        a = make_allocator({"type": "minpos", "wavefront": w}).allocate(problem(art, "r0"))
        assert a.status is AllocStatus.NO_FRONTIER


# The position counts only teammates strictly closer (C_kj < C_ij): R0 and R1 are level toward F_A, so R0 is
# first toward it, as toward F_B, and takes F_A, the nearer. Counting the level teammate (<=) would make it
# second toward F_A and send it to F_B. F_A has the lower index, so the tie-break rule does not matter here.
LEVEL = """
#####?#######
#..1...0....?
#############
"""
F_A, F_B = (1, 5), (1, 11)


@pytest.mark.parametrize("variant", VARIANTS)
def test_a_teammate_level_with_the_robot_is_not_ahead_of_it(variant: str) -> None:
    p = problem(LEVEL, "r0")
    assert [c.target for c in p.clusters] == [F_A, F_B]
    assert p.costs[:, 0].tolist() == [2, 2]  # level toward F_A
    assert positions(p.costs, p.index).tolist() == [0, 0]
    assert target({"type": "minpos", "wavefront": variant}, LEVEL, "r0") == F_A
    assert target({"type": "minpos", "wavefront": variant}, LEVEL, "r1") == F_A  # the same for R1


# Equal positions go to the least cost, not the lowest index: R0 is first toward both; F_far (index 0) is
# four steps away, F_near (index 1) two.
NEAR_FAR = """
########?####
#?....0.....#
#############
"""
F_FAR, F_NEAR = (1, 2), (1, 8)


@pytest.mark.parametrize("variant", VARIANTS)
def test_equal_positions_go_to_the_least_cost_not_the_lowest_index(variant: str) -> None:
    p = problem(NEAR_FAR, "r0")
    assert [c.target for c in p.clusters] == [F_FAR, F_NEAR]
    assert p.costs[0].tolist() == [4, 2]
    assert target({"type": "minpos", "wavefront": variant}, NEAR_FAR, "r0") == F_NEAR
