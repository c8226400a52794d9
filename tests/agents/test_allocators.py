"""Every registered allocator against the conformance checks, and greedy, utility and Hungarian on their own:
cost matrices and grids drawn as ASCII art."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from fleet_emu.agents.allocators import AllocStatus, Param, Problem, allocator_class, allocator_names, make_allocator
from fleet_emu.agents.allocators.conformance import FLIP_LIMIT, Targets, api_test, flip_test, seed_test
from fleet_emu.agents.allocators.greedy import greedy_choice, greedy_pairs
from fleet_emu.agents.allocators.hungarian import Assignment, Hungarian, optimal_assignment, total_cost
from fleet_emu.agents.allocators.utility import utility_choice
from fleet_emu.agents.frontiers import find_clusters
from fleet_emu.agents.protocol import PoseBeacon
from fleet_emu.core.errors import ConfigError
from fleet_emu.core.grid import Cell, from_ascii
from fleet_emu.core.messages import Envelope, RadioMsg, decode, open_envelope, seal
from fleet_emu.core.scenario import BASE_PLANNERS
from tests.harness.lockstep import run_fleet

INF = np.inf

CONFIGS: list[dict[str, Any]] = [{"type": name} for name in allocator_names()] + [
    {"type": "minpos", "wavefront": "stop"},
    {"type": "minpos", "wavefront": "parallel"},
    {"type": "utility", "beta": 0.5, "sensor_range": 3.0},
    {"type": "hungarian", "timeout": 3, "period": 2},
    {"type": "trade", "tasks": "regions"},
    {"type": "hungarian", "tasks": "regions"},
]


def _id(config: dict[str, Any]) -> str:
    return "-".join(str(v) for v in config.values())


@pytest.mark.parametrize("config", CONFIGS, ids=_id)
def test_conformance(config: dict[str, Any]) -> None:
    api_test(config)
    seed_test(config)


def explore(art: str, config: dict[str, Any], seed: int) -> Targets:
    """``flip_test``'s run: the memory engine on the drawn map, the ideal radio at loss 0 (a base station for a
    base planner)."""
    return run_fleet(art, config, seed=seed, max_ticks=200, base=config["type"] in BASE_PLANNERS).targets


FLIP_CONFIGS = [{"type": name} for name in allocator_names()] + [{"type": "connectivity", "replan": "tick"}]


@pytest.mark.parametrize("config", FLIP_CONFIGS, ids=_id)
def test_no_allocator_flips_between_two_targets(config: dict[str, Any]) -> None:
    flip_test(config, explore)


def test_the_flip_check_catches_a_planner_that_re_solves_every_tick() -> None:
    with pytest.raises(AssertionError, match="target flips per 100 robot-ticks") as exc:
        flip_test({"type": "hungarian", "replan": "tick"}, explore)
    assert float(str(exc.value).split(": ")[1].split()[0]) > 10 * FLIP_LIMIT


@pytest.mark.parametrize("name", allocator_names())
def test_to_dict_and_unknown_parameters(name: str) -> None:
    alloc = make_allocator({"type": name})
    assert alloc.to_dict() == {"type": name, **alloc.params()}
    assert list(alloc.params()) == list(allocator_class(name).parameters)
    with pytest.raises(ConfigError, match="'bogus'") as exc:
        make_allocator({"type": name, "bogus": 1})
    assert name in str(exc.value)


def bad_values(spec: Param) -> list[Any]:
    """Values of the wrong type, non-finite, out of the range or not among the choices."""
    if spec.kind is bool:
        return [1, "true", None]
    if spec.kind is str:
        return [3, None, "no-such-choice"] if spec.choices else [3, None]
    bad: list[Any] = ["1", None, True]
    if spec.kind is int:
        bad += [1.5, float(spec.default)]
    else:
        bad += [float("nan"), float("inf"), -float("inf")]
    if math.isfinite(spec.low):
        bad.append(spec.kind(spec.low) if spec.low_open else spec.kind(spec.low) - 1)
    if math.isfinite(spec.high):
        bad.append(spec.kind(spec.high) + 1)
    return bad


PARAMS = [(name, param) for name in allocator_names() for param in allocator_class(name).parameters]


@pytest.mark.parametrize("name, param", PARAMS, ids=[f"{n}-{p}" for n, p in PARAMS])
def test_every_bad_parameter_value_is_a_one_line_config_error(name: str, param: str) -> None:
    spec = allocator_class(name).parameters[param]
    for value in bad_values(spec):
        with pytest.raises(ConfigError) as exc:
            make_allocator({"type": name, param: value})
        msg = str(exc.value)
        assert f"{name!r}" in msg and param in msg and spec.span() in msg and "\n" not in msg, msg
    assert make_allocator({"type": name, param: spec.default}).params()[param] == spec.default


def test_param_ranges_in_words() -> None:
    assert Param(0.5, ge=0, le=1).span() == "within [0, 1]"
    assert Param(1.0, gt=0).span() == "> 0"
    assert Param(2, ge=1).span() == ">= 1"
    assert Param(True).span() == "true or false"
    assert Param("a", choices=("a", "b")).span() == "one of a, b"
    assert Param(1.0).check(2) == 2.0 and type(Param(1.0).check(2)) is float


def test_unknown_allocator_lists_the_known_ones() -> None:
    with pytest.raises(ConfigError, match="telepathy") as exc:
        make_allocator({"type": "telepathy"})
    assert all(name in str(exc.value) for name in allocator_names())
    with pytest.raises(ConfigError, match="unknown allocator None"):
        make_allocator({})


def problem(art: str, me: str, tick: int = 0, heard: dict[str, int] | None = None) -> Problem:
    grid, robots = from_ascii(art)
    return Problem(me=me, poses=robots, belief=grid, clusters=find_clusters(grid, 4), tick=tick,
                   heard=heard or {})


# --- greedy (MinPos paper Algorithm 2) ---------------------------------------------------------------

def test_greedy_takes_the_cheapest_pair_first() -> None:
    costs = np.array([[4.0, 1.0, 6.0],
                      [2.0, 3.0, 5.0],
                      [3.0, 2.0, 9.0]])
    assert greedy_pairs(costs) == [(0, 1), (1, 0), (2, 2)]
    assert [greedy_choice(costs, i) for i in range(3)] == [1, 0, 2]


def test_greedy_ties_go_to_lowest_robot_then_lowest_cluster() -> None:
    costs = np.array([[2.0, 2.0], [2.0, 2.0]])
    assert greedy_pairs(costs) == [(0, 0), (1, 1)]


def test_greedy_resets_the_frontiers_when_robots_outnumber_them() -> None:
    costs = np.array([[1.0, 5.0], [2.0, 6.0], [3.0, 4.0], [1.5, 9.0]])
    # r0-F0 (1), then only F1 is left: r2-F1 (4); F is empty, so F = F_init: r3-F0 (1.5), then r1-F1 (6)
    assert greedy_pairs(costs) == [(0, 0), (2, 1), (3, 0), (1, 1)]
    assert greedy_choice(costs, 1) == 1


def test_greedy_skips_unreachable_pairs() -> None:
    costs = np.array([[1.0, INF], [2.0, INF], [INF, INF]])
    assert greedy_choice(costs, 0) == 0
    assert greedy_choice(costs, 1) == 0  # F1 reaches nobody left, so F = F_init again
    assert greedy_choice(costs, 2) is None


# --- utility (Burgard et al. 2005) ---------------------------------------------------------------------

TARGETS = np.array([[0, 0], [0, 2], [0, 20]])  # T0 and T1 within sensor range of each other, T2 far away
UCOSTS = np.array([[1.0, 2.0, 10.0],
                   [2.0, 1.0, 5.0]])


def test_utility_discounts_targets_near_an_assigned_one() -> None:
    # r0: U - V = 1 - 0.1 at T0, r1: 1 - 0.1 at T1: a tie, r0 first, takes T0. T1 is 2 cells away:
    # U_T1 = 1 - P(2) = 1 - (1 - 2/8) = 0.25, so r1 prefers the far T2 (1 - 0.5) to T1 (0.25 - 0.1).
    assert utility_choice(UCOSTS, TARGETS, 0) == 0
    assert utility_choice(UCOSTS, TARGETS, 1) == 2
    assert greedy_choice(UCOSTS, 1) == 1  # greedy, blind to the overlap, sends r1 next to r0


def test_utility_parameters_change_the_trade() -> None:
    assert utility_choice(UCOSTS, TARGETS, 1, sensor_range=2.0) == 1  # T1 out of range: no discount
    assert utility_choice(UCOSTS, TARGETS, 1, beta=10.0) == 1  # cost dominates
    assert make_allocator({"type": "utility", "beta": 2, "sensor_range": 4}).to_dict() == {
        "type": "utility", "beta": 2.0, "sensor_range": 4.0}
    with pytest.raises(ConfigError, match="sensor_range"):
        make_allocator({"type": "utility", "sensor_range": 0})


def test_utility_gives_every_robot_a_target_even_with_few_targets() -> None:
    costs = np.array([[1.0], [2.0], [3.0]])
    assert [utility_choice(costs, np.array([[0, 0]]), i) for i in range(3)] == [0, 0, 0]


# --- hungarian (Kuhn 1955; the reference of Yan et al. 2011) ------------------------------------------

def test_hungarian_finds_the_optimum_where_greedy_does_not() -> None:
    costs = np.array([[1.0, 2.0, 9.0],
                      [2.0, 9.0, 9.0],
                      [9.0, 3.0, 4.0]])
    greedy = np.array([greedy_choice(costs, i) for i in range(3)])
    optimal = optimal_assignment(costs)
    assert greedy.tolist() == [0, 2, 1] and total_cost(costs, greedy) == 1 + 9 + 3
    assert optimal.tolist() == [1, 0, 2] and total_cost(costs, optimal) == 2 + 2 + 4


def test_hungarian_replicates_clusters_and_avoids_unreachable_ones() -> None:
    costs = np.array([[1.0, 8.0], [2.0, 3.0], [1.0, 7.0], [INF, INF]])
    plan = optimal_assignment(costs)
    assert plan[3] == -1 and sorted(plan[:3].tolist()) == [0, 0, 1] and plan[1] == 1
    assert optimal_assignment(np.array([[INF, 1.0], [INF, 2.0]])).tolist() in ([1, -1], [-1, 1])


# r0 is next to the left frontier; r1's nearest is the left one too, but the optimum sends it right.
LINE = """
##############
?.0..1.......?
##############
"""
LEFT, RIGHT = (1, 1), (1, 12)


def test_hungarian_coordinator_broadcasts_the_optimal_assignment() -> None:
    alloc = make_allocator({"type": "hungarian"})
    a = alloc.allocate(problem(LINE, "r0", tick=4, heard={"r1": 4}))
    assert a.target == LEFT
    (msg,) = a.outbox
    assert isinstance(msg.body, Assignment) and msg.dst == "*"
    assert msg.body.targets == {"r0": LEFT, "r1": RIGHT}
    env = seal(msg, "r0", 4, 7)
    assert (env.src, env.origin, env.tick, env.payload_kind) == ("r0", "r0", 4, "assign")
    assert open_envelope(decode(env.encode(), expected=Envelope)).body == msg.body


def test_hungarian_follower_takes_its_target_from_the_coordinator() -> None:
    coordinator = make_allocator({"type": "hungarian"})
    (out,) = coordinator.allocate(problem(LINE, "r0", tick=4, heard={"r1": 4})).outbox
    msg = open_envelope(seal(out, "r0", 4, 2))
    follower = make_allocator({"type": "hungarian"})
    alone = follower.allocate(problem(LINE, "r1", tick=5, heard={"r0": 4}))
    assert alone.target == LEFT and alone.outbox == ()  # nothing heard yet: nearest frontier
    beacon = open_envelope(seal(RadioMsg(PoseBeacon(cell=(1, 2))), "r0", 4, 1))
    told = follower.allocate(problem(LINE, "r1", tick=5, heard={"r0": 4}), [beacon, msg])
    assert told.target == RIGHT and told.outbox == ()
    assert follower.allocate(problem(LINE, "r1", tick=9, heard={"r0": 8})).target == RIGHT  # kept
    stale = follower.allocate(problem(LINE, "r1", tick=15, heard={"r0": 14}))
    assert stale.target == LEFT  # the assignment is older than the timeout: nearest again


def test_hungarian_follower_ignores_assignments_from_others() -> None:
    follower = make_allocator({"type": "hungarian"})
    rogue = open_envelope(seal(RadioMsg(Assignment(round=4, targets={"r1": RIGHT})), "r2", 4, 4))
    p = problem(LINE, "r1", tick=5, heard={"r0": 5})
    assert follower.allocate(p, [rogue]).target == LEFT


def test_hungarian_next_live_robot_takes_over_from_a_silent_coordinator() -> None:
    alloc = make_allocator({"type": "hungarian", "timeout": 5})
    a = alloc.allocate(problem(LINE, "r1", tick=20, heard={"r0": 14}))  # r0 silent for 6 ticks
    (msg,) = a.outbox
    assert msg.body.targets == {"r1": LEFT}  # r0 is no longer assigned
    assert a.target == LEFT
    still = alloc.allocate(problem(LINE, "r1", tick=20, heard={"r0": 15}))
    assert still.outbox == ()


def test_hungarian_broadcasts_every_period_ticks() -> None:
    alloc = make_allocator({"type": "hungarian", "period": 3})
    sent = [bool(alloc.allocate(problem(LINE, "r0", tick=t, heard={"r1": t})).outbox) for t in range(7)]
    assert sent == [True, False, False, True, False, False, True]


def test_hungarian_maps_a_target_cell_to_a_reachable_cluster() -> None:
    p = problem(LINE, "r1")
    h = Hungarian()
    assert h._cluster_of(p, RIGHT) == 1
    assert h._cluster_of(p, (1, 10)) == 1  # not a frontier cell: the cluster with the nearest target
    assert h._cluster_of(p, (1, 3)) == 0


def test_hungarian_without_frontier() -> None:
    art = """
    #####
    #0.1#
    #####
    """
    assert make_allocator({"type": "hungarian"}).allocate(problem(art, "r0")).status is AllocStatus.NO_FRONTIER


def _cells(alloc_targets: dict[str, Cell | None]) -> set[Cell | None]:
    return set(alloc_targets.values())


def test_every_coordinating_allocator_spreads_two_robots_on_the_line() -> None:
    for name in ("greedy", "hungarian", "minpos", "utility"):
        heard = {"r0": 0, "r1": 0}
        got = {}
        for me in ("r0", "r1"):
            alloc = make_allocator({"type": name})
            inbox = []
            if name == "hungarian" and me == "r1":
                sent = make_allocator({"type": name}).allocate(problem(LINE, "r0", heard=heard)).outbox
                inbox = [open_envelope(seal(m, "r0", 0, k)) for k, m in enumerate(sent)]
            got[me] = alloc.allocate(problem(LINE, me, heard=heard), inbox).target
        assert _cells(got) == {LEFT, RIGHT}, name
