"""Connectivity-aware MinPos (Benavides et al. 2016) on hand-drawn grids."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fleet_emu.agents.allocators import AllocStatus, Problem, make_allocator
from fleet_emu.agents.allocators.conformance import CROSS, WALLED, api_test, random_problem, seed_test
from fleet_emu.agents.allocators.connectivity import connectivity, signal_at, utilities, wall_mask
from fleet_emu.agents.allocators.minpos import positions
from fleet_emu.agents.frontiers import find_clusters
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.grid import from_ascii
from fleet_emu.core.radio import RadioConfig

RADIO = RadioConfig()  # c = 10 m, PL = 2, WAF = 3.1 dB, C = 4


def problem(art: str, me: str = "r0") -> Problem:
    grid, robots = from_ascii(art)
    return Problem(me=me, poses=robots, belief=grid, clusters=find_clusters(grid, 4))


def test_conformance() -> None:
    api_test({"type": "connectivity"})
    seed_test({"type": "connectivity"})
    api_test({"type": "connectivity", "alpha": 0.0, "beta": 1.0, "lam": 1.0, "unknown_walls": True})
    assert make_allocator({"type": "connectivity"}).to_dict() == {
        "type": "connectivity", "alpha": 0.6, "beta": 0.4, "lam": 0.5, "comm_range": 10.0, "cell_size": 0.5,
        "path_loss": 2.0, "waf": 3.1, "max_walls": 4, "unknown_walls": False, "position": "without_self",
        "predict": "pose", "replan": "tick"}
    for position in ("literal", "cost"):
        api_test({"type": "connectivity", "position": position, "predict": "target"})
        seed_test({"type": "connectivity", "position": position, "predict": "target"})
    with pytest.raises(ConfigError, match=r"lam must be within \[0, 1\] \(got 1.5\)"):
        make_allocator({"type": "connectivity", "lam": 1.5})


def test_beta_zero_is_minpos() -> None:
    minpos = make_allocator({"type": "minpos"})
    conn = make_allocator({"type": "connectivity", "beta": 0.0})
    rng = np.random.default_rng(3)
    problems = [problem(CROSS, me) for me in ("r0", "r1", "r2", "r3")] + [problem(WALLED)]
    problems += [random_problem(rng, me=f"r{k % 4}") for k in range(40)]
    others = [make_allocator({"type": "connectivity", "beta": 0.0, "position": pos, "predict": pred})
              for pos in ("literal", "cost") for pred in ("pose", "target")]
    for p in problems:
        assert conn.allocate(p) == minpos.allocate(p)
        assert all(o.allocate(p) == minpos.allocate(p) for o in others)


# r1's room has no door: r1 cannot reach any frontier (its positions never count), but its radio hears
# through the one wall below it. Frontier A (3,1) is 1 m below r1 through that wall; frontier B (5,14) is
# nearer r0 (5 cells against 10) but 6.8 m from r1 through two walls.
TWO_WAYS = """
################
#1.............#
################
?..........0...#
##############.#
##############.#
##############?#
"""


def test_prefers_the_frontier_in_radio_range() -> None:
    p = problem(TWO_WAYS)
    targets = [c.target for c in p.clusters]
    a, b = targets.index((3, 1)), targets.index((5, 14))
    walls = wall_mask(p.belief)
    r1 = [p.poses["r1"]]
    assert connectivity(walls, (3, 1), r1, 1.0, 0.5, RADIO) == pytest.approx(-20 * math.log10(1.0 / 10) - 3.1)
    assert connectivity(walls, (5, 14), r1, 1.0, 0.5, RADIO) == pytest.approx(
        -20 * math.log10(math.hypot(4, 13) * 0.5 / 10) - 2 * 3.1)
    assert make_allocator({"type": "minpos"}).allocate(p).cluster == b
    assert make_allocator({"type": "connectivity", "beta": 0.0}).allocate(p).cluster == b
    assert make_allocator({"type": "connectivity", "alpha": 0.1, "beta": 1.0}).allocate(p).cluster == a
    assert make_allocator({"type": "connectivity"}).allocate(p).cluster == a  # the paper's alpha = 0.6 too
    assert make_allocator({"type": "connectivity", "alpha": 0.99, "beta": 0.01}).allocate(p).cluster == b
    assert make_allocator({"type": "connectivity", "lam": 0.0}).allocate(p).cluster == b  # lambda 0: ideal radio


# Eq. 8 at T = (0, 0): r2 is nearer (3 cells = 1.5 m, one wall), so it takes lambda^1; r1 (9 cells = 4.5 m,
# no wall) takes lambda^2.
EQ8 = """
.........1.....
...............
###############
2..............
"""


def test_eq8_by_hand() -> None:
    p = problem(EQ8)
    walls = wall_mask(p.belief)
    others = [p.poses["r1"], p.poses["r2"]]
    lam = 0.5
    expected = lam * (-20 * math.log10(1.5 / 10) - 1 * 3.1) + lam ** 2 * (-20 * math.log10(4.5 / 10))
    assert expected == pytest.approx(0.5 * 13.3782 + 0.25 * 6.9357, abs=1e-4)  # 8.4230 dB
    assert connectivity(walls, (0, 0), others, lam, 0.5, RADIO) == pytest.approx(expected)
    # lambda = 1 weighs both alike; a 6 m range lowers every term by 20 log10(10 / 6)
    both = (-20 * math.log10(0.15) - 3.1) + (-20 * math.log10(0.45))
    assert connectivity(walls, (0, 0), others, 1.0, 0.5, RADIO) == pytest.approx(both)
    six = RadioConfig(comm_range=6.0)
    assert connectivity(walls, (0, 0), others, 1.0, 0.5, six) == pytest.approx(both - 2 * 20 * math.log10(10 / 6))
    # a teammate on the target counts as one cell away, not 1 mm
    assert connectivity(walls, (0, 9), [p.poses["r1"]], 1.0, 0.5, RADIO) == pytest.approx(-20 * math.log10(0.05))


def test_utilities_match_eq9() -> None:
    p = problem(TWO_WAYS)
    alpha, beta, lam = 0.6, 0.4, 0.5
    u = utilities(p, alpha, beta, lam, 0.5, RADIO)
    walls = wall_mask(p.belief)
    i = p.index
    for j, c in enumerate(p.clusters):
        cost = p.costs[i, j]
        if np.isfinite(cost):
            conn = connectivity(walls, c.target, [p.poses["r1"]], lam, 0.5, RADIO)
            assert u[i, j] == pytest.approx(-alpha * cost * 0.5 + beta * conn)
        else:
            assert u[i, j] == -np.inf
    assert (u[p.robots.index("r1")] == -np.inf).all()  # r1 reaches nothing


def test_unknown_cells_as_walls() -> None:
    art = """
    0..?..1
    """
    p = problem(art)
    free = wall_mask(p.belief)
    unknown = wall_mask(p.belief, unknown_walls=True)
    base = -20 * math.log10(3.0 / 10)
    assert connectivity(free, (0, 0), [p.poses["r1"]], 1.0, 0.5, RADIO) == pytest.approx(base)
    assert connectivity(unknown, (0, 0), [p.poses["r1"]], 1.0, 0.5, RADIO) == pytest.approx(base - 3.1)


def test_alone_is_minpos_on_cost() -> None:
    p = problem("""
    ?....0..?
    """)
    a = make_allocator({"type": "connectivity", "beta": 1.0}).allocate(p)
    assert a.status is AllocStatus.ASSIGNED and a.target == (0, 7)


# Each robot stands one cell from its own frontier: L = (1, 1) for r0, M = (1, 6) (below the opening) for r1.
SWAP = """
######?#####
?.0..1.....#
############
"""
SIX = RadioConfig(comm_range=6.0)  # the paper's experiment


def test_literal_eq9_makes_a_robot_yield_the_target_it_stands_by() -> None:
    """The suspected cause, confirmed: read literally, a teammate's eq. 9 for a task sums the signal from that
    task to the deciding robot's own cell, so the robot nearest a task hands it to the teammate it is far from."""
    p = problem(SWAP)
    targets = [c.target for c in p.clusters]
    left = targets.index((1, 1))
    assert list(p.costs[:, left]) == [1.0, 4.0]  # r0 is 1 step from L, r1 4
    assert positions(p.costs, 0)[left] == 0  # MinPos: r0 is first
    literal = utilities(p, 0.6, 0.4, 0.5, 0.5, SIX)
    assert positions(-literal, 0)[left] == 1  # literal eq. 9: r1 counts as better placed for L than r0
    mine = signal_at(wall_mask(p.belief), (1, 1), p.poses["r0"], 0.5, SIX)  # L to r0's own cell: 21.6 dB
    without = utilities(p, 0.6, 0.4, 0.5, 0.5, SIX, without=0)
    assert literal[1, left] - without[1, left] == pytest.approx(0.4 * 0.5 * mine)  # that term alone
    assert positions(-without, 0)[left] == 0  # without it r0 stays first for L
    # literal positions swap the pair (r0 to M, r1 to L: head-on in a corridor); MinPos and "cost" do not
    lit = {"type": "connectivity", "comm_range": 6.0, "position": "literal"}
    for me, own, other in (("r0", (1, 1), (1, 6)), ("r1", (1, 6), (1, 1))):
        q = problem(SWAP, me)
        assert make_allocator(lit).allocate(q).target == other
        assert make_allocator({"type": "minpos"}).allocate(q).target == own
        assert make_allocator({**lit, "position": "cost"}).allocate(q).target == own


def test_positions_without_self_still_favour_the_connected_task() -> None:
    """``without_self`` keeps the deciding robot first where it is nearest, and eq. 9 then picks, among the
    tasks of least position, the one nearer the teammate's radio: here M, beside r1, over L, beside r0."""
    p = problem(SWAP)
    targets = [c.target for c in p.clusters]
    u = utilities(p, 0.6, 0.4, 0.5, 0.5, SIX, without=0)
    assert list(positions(-u, 0)) == [0, 0]
    assert make_allocator({"type": "connectivity", "comm_range": 6.0}).allocate(p).target == (1, 6)
    assert u[0, targets.index((1, 6))] > u[0, targets.index((1, 1))]
    # with alpha near 1 the path cost wins: L
    near_one = {"type": "connectivity", "comm_range": 6.0, "alpha": 0.99, "beta": 0.01}
    assert make_allocator(near_one).allocate(p).target == (1, 1)


def test_predicting_teammates_at_their_targets() -> None:
    """``predict="target"`` places a teammate, for eq. 8, on the target MinPos gives it, not on its cell."""
    from fleet_emu.agents.allocators.connectivity import predicted_cells

    p = problem(SWAP)
    assert predicted_cells(p, "pose") == [(1, 2), (1, 5)]
    assert predicted_cells(p, "target") == [(1, 2), (1, 6)]  # r1 is MinPos-first for M


ABREAST = """
##########
?....0...?
?...1....?
##########
"""
MIRRORED = """
##########
?...0....?
?....1...?
##########
"""


def test_heavy_beta_abreast_robots_cross_and_flip_every_tick() -> None:
    """The stalls of ``conn:0.4:0.6`` (maze seeds 2-5, mbicp, hospital_section at loss 0):
    two robots abreast between two frontiers each take the frontier nearer its *teammate* (eq. 8 at the
    teammate's pose; with ``without_self`` both are first everywhere), step toward it, stand abreast mirrored,
    and take the other one: a period-2 cycle that senses nothing. Eq. 9 as the paper gives it, not a bug:
    MinPos and ``position="cost"`` send each to its nearer frontier."""
    conn = {"type": "connectivity", "comm_range": 6.0, "alpha": 0.4, "beta": 0.6}
    left, right = (1, 1), (1, 8)  # the clusters' targets: L, R
    for art, r0_near, r1_near in ((ABREAST, right, left), (MIRRORED, left, right)):
        for me, near, far in (("r0", r0_near, r1_near), ("r1", r1_near, r0_near)):
            p = problem(art, me)
            assert {c.target for c in p.clusters} == {left, right}
            assert make_allocator({"type": "minpos"}).allocate(p).target == near
            assert make_allocator({**conn, "position": "cost"}).allocate(p).target == near
            assert make_allocator(conn).allocate(p).target == far  # toward the teammate's side
    # each robot's step toward its target turns ABREAST into MIRRORED and back: the allocation flips each tick


def _with_previous(art: str, me: str, previous: tuple[int, int] | None) -> Problem:
    p = problem(art, me)
    p.previous_target = previous
    return p


def test_observed_replanning_keeps_the_abreast_robots_on_their_targets() -> None:
    """The period-2 swap above, with MinPos's second option (section 2: reevaluate "at least every time the
    robot observes the targeted frontier"): each robot keeps the frontier it took until it has observed it, so
    the pair stops flipping and walks on to L and R. Stepped here down each cluster's wavefront; eq. 9 unchanged."""
    from fleet_emu.agents.navigation import next_move

    conn = {"type": "connectivity", "comm_range": 6.0, "alpha": 0.4, "beta": 0.6}
    grid, poses = from_ascii(ABREAST)

    def walk(replan: str) -> list[dict[str, tuple[int, int]]]:
        cells, previous, out = dict(poses), {"r0": None, "r1": None}, []
        for _ in range(4):
            chosen, moved = {}, {}
            for me in ("r0", "r1"):
                p = Problem(me=me, poses=cells, belief=grid, clusters=find_clusters(grid, 4),
                            previous_target=previous[me])
                a = make_allocator({**conn, "replan": replan}).allocate(p)
                chosen[me] = a.target
                step = next_move(p.wavefronts[a.cluster], cells[me])
                moved[me] = (cells[me][0] + step[0], cells[me][1] + step[1])
            cells, previous = moved, chosen
            out.append(chosen)
        return out

    left, right = (1, 1), (1, 8)
    flips = walk("tick")
    assert [t["r0"] for t in flips] == [left, right, left, right]  # the swap, every tick
    kept = walk("observed")
    assert kept == [{"r0": left, "r1": right}] * 4  # the first choice (toward the teammate's side), kept


# r0 alone between two frontiers: L at (0, 1) four steps away, R at (0, 7) two steps away.
LINE = """
?....0..?
"""
SEEN = """
.....0..?
"""
WALL = """
?..#.0..?
"""


@pytest.mark.parametrize("config", [{"type": "minpos", "replan": "observed"},
                                    {"type": "connectivity", "replan": "observed"},
                                    {"type": "connectivity", "alpha": 0.4, "beta": 0.6, "replan": "observed"}],
                         ids=["minpos", "conn", "conn-heavy-beta"])
def test_observed_replanning_keeps_until_seen_or_unreachable(config: dict) -> None:
    alloc = make_allocator(config)
    assert alloc.allocate(_with_previous(LINE, "r0", None)).target == (0, 7)  # no previous target: decide
    assert alloc.allocate(_with_previous(LINE, "r0", (0, 1))).target == (0, 1)  # L unobserved: kept
    # L observed ((0, 0) now known: (0, 1) is no longer a frontier cell): decide afresh
    assert alloc.allocate(_with_previous(SEEN, "r0", (0, 1))).target == (0, 7)
    # L still a frontier cell, but a wall found across the way: unreachable, decide afresh
    p = _with_previous(WALL, "r0", (0, 1))
    assert (0, 1) in [c.target for c in p.clusters]
    assert alloc.allocate(p).target == (0, 7)
    # a previous target that is no frontier at all (a wall, off the grid): decide afresh
    for cell in ((0, 3), (5, 5), (-1, 0)):
        assert alloc.allocate(_with_previous(WALL, "r0", cell)).target == (0, 7)
    # "tick" never keeps
    tick = make_allocator({**config, "replan": "tick"})
    assert tick.allocate(_with_previous(LINE, "r0", (0, 1))).target == (0, 7)


# A frontier of five cells, one cluster; r0 last targeted (1, 1), and its cluster's target now is (2, 1).
RECLUSTERED = """
#######
?.....#
?....0#
?.....#
#######
"""


def test_observed_replanning_follows_the_cluster_that_holds_the_previous_target() -> None:
    """Clusters are formed afresh every tick: the robot is assigned the cluster holding its previous target cell,
    whose own target (returned, and kept next) may be another of its cells."""
    p = _with_previous(RECLUSTERED, "r0", (1, 1))
    (cluster,) = p.clusters
    assert cluster.target == (2, 1)
    a = make_allocator({"type": "connectivity", "replan": "observed"}).allocate(p)
    assert (a.cluster, a.target) == (0, (2, 1))


def test_replan_conformance() -> None:
    for config in ({"type": "connectivity", "replan": "observed"},
                   {"type": "connectivity", "alpha": 0.4, "beta": 0.6, "position": "cost", "replan": "observed"},
                   {"type": "minpos", "replan": "observed", "wavefront": "parallel"}):
        api_test(config)
        seed_test(config)
        assert make_allocator(config).to_dict()["replan"] == "observed"
    with pytest.raises(ConfigError, match="replan"):
        make_allocator({"type": "connectivity", "replan": "sometimes"})


# r0 last targeted R = (2, 5), behind r1: its only step nearer R, (2, 3), is r1's cell (the way round, through
# row 1 or 3, starts with a step that is not nearer). L = (2, 1) is on r0's own side.
HEAD_ON = """
#######
#.....#
?.01..?
#.....#
#######
"""
APART = """
#######
#.....#
?.0..1?
#.....#
#######
"""


@pytest.mark.parametrize("config", [{"type": "minpos", "replan": "observed"},
                                    {"type": "connectivity", "alpha": 0.4, "beta": 0.6, "replan": "observed"}],
                         ids=["minpos", "conn-heavy-beta"])
def test_observed_replanning_gives_up_a_target_a_teammate_stands_in_front_of(config: dict) -> None:
    """Head-on in a passage, a committed robot whose every step nearer its target is onto a teammate (heard last
    tick) decides afresh among the clusters it can step toward: it turns to L instead of waiting for ever."""
    alloc = make_allocator(config)
    right, left = (2, 5), (2, 1)
    for art in (HEAD_ON, APART):
        assert {c.target for c in problem(art).clusters} == {left, right}
    p = _with_previous(APART, "r0", right)
    assert alloc.allocate(p).target == right  # not in the way: kept
    p = _with_previous(HEAD_ON, "r0", right)
    p.tick, p.heard = 7, {"r1": 6}
    assert alloc.allocate(p).target == left  # r1 in the way: given up
    p = _with_previous(HEAD_ON, "r0", right)
    p.tick, p.heard = 7, {"r1": 5}  # r1 not heard for two ticks: not known to be there
    assert alloc.allocate(p).target == right
    # r1 in the way of both (r0 boxed in): ranked as if nobody blocked
    boxed = HEAD_ON.replace("?.01", "?#01")
    q = _with_previous(boxed, "r0", right)
    assert [c.target for c in q.clusters] == [right]
    assert alloc.allocate(q).target == right
