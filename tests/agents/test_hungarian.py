"""The Hungarian planner's commitment (``replan="commit"``, the default) against re-solving every tick
(``replan="tick"``): on drawn problems, what the coordinator keeps and when it lets a task go, and on the memory
engine, the two-tick limit cycle of ``"tick"`` and its absence with ``"commit"``."""

from __future__ import annotations

import numpy as np

from fleet_emu.agents.allocators import Problem
from fleet_emu.agents.allocators.conformance import FLIP_MAP, count_flips
from fleet_emu.agents.allocators.hungarian import Assignment, Hungarian
from fleet_emu.agents.frontiers import find_clusters
from fleet_emu.core.grid import Cell, from_ascii
from fleet_emu.core.messages import open_envelope, seal
from tests.harness.lockstep import run_fleet

LINE = """
##############
?.0..1.......?
##############
"""
LEFT, RIGHT = (1, 1), (1, 12)
# the robots have passed each other: the optimum is now r1 left, r0 right
PASSED = """
##############
?....1..0....?
##############
"""
# the left frontier has been observed: a wall where the unknown was
LEFT_SEEN = """
##############
#....1..0....?
##############
"""


def problem(art: str, me: str, tick: int, heard: dict[str, int] | None = None) -> Problem:
    grid, robots = from_ascii(art)
    return Problem(me=me, poses=robots, belief=grid, clusters=find_clusters(grid, 4), tick=tick,
                   heard=heard if heard is not None else {r: tick for r in robots if r != me})


def targets(alloc: Hungarian, p: Problem) -> dict[str, Cell]:
    (msg,) = alloc.allocate(p).outbox
    assert isinstance(msg.body, Assignment)
    return msg.body.targets


def test_commit_keeps_the_tasks_that_tick_swaps() -> None:
    kept, resolved = Hungarian(), Hungarian(replan="tick")
    for alloc in (kept, resolved):
        assert targets(alloc, problem(LINE, "r0", 0)) == {"r0": LEFT, "r1": RIGHT}
    assert targets(resolved, problem(PASSED, "r0", 1)) == {"r0": RIGHT, "r1": LEFT}  # the optimum, re-solved
    assert targets(kept, problem(PASSED, "r0", 1)) == {"r0": LEFT, "r1": RIGHT}  # each keeps its task
    assert kept.held["r0"].cell == LEFT and resolved.held == {}
    kept.reset(np.random.default_rng(0))
    assert kept.held == {} and targets(kept, problem(PASSED, "r0", 2)) == {"r0": RIGHT, "r1": LEFT}


def test_commit_lets_an_observed_task_go() -> None:
    alloc = Hungarian()
    targets(alloc, problem(LINE, "r0", 0))
    # LEFT is no frontier any more: r0 is free, the only cluster is held by r1, so r0 shares it
    assert targets(alloc, problem(LEFT_SEEN, "r0", 1)) == {"r0": RIGHT, "r1": RIGHT}


def test_commit_lets_a_task_go_after_patience_ticks_without_progress() -> None:
    alloc = Hungarian(patience=3)
    first = targets(alloc, problem(LINE, "r0", 0))
    stuck = [targets(alloc, problem(LINE, "r0", t)) for t in range(1, 4)]  # nobody moves
    assert stuck[:2] == [first, first]
    # at tick 3 both gave up; neither gets its own cluster back while it can reach the other
    assert stuck[2] == {"r0": RIGHT, "r1": LEFT}


def test_a_new_coordinator_carries_on_the_last_assignment() -> None:
    coordinator = Hungarian()
    (out,) = coordinator.allocate(problem(LINE, "r0", 4)).outbox
    msg = open_envelope(seal(out, "r0", 4, 2))
    for replan, expected in (("commit", RIGHT), ("tick", LEFT)):
        follower = Hungarian(replan=replan, timeout=5)
        assert follower.allocate(problem(LINE, "r1", 5, {"r0": 4}), [msg]).target == RIGHT  # told
        # r0 silent for 6 ticks: r1 coordinates; with commit it keeps the task r0 gave it, with tick it re-solves
        # for itself alone (its nearest frontier)
        a = follower.allocate(problem(LINE, "r1", 20, {"r0": 14}))
        assert a.target == expected and a.outbox[0].body.targets == {"r1": expected}


def test_a_follower_forgets_its_tasks() -> None:
    alloc = Hungarian()
    targets(alloc, problem(LINE, "r1", 0, {"r0": -20}))  # r0 silent: r1 coordinates
    assert alloc.held
    alloc.allocate(problem(LINE, "r1", 1, {"r0": 1}))  # r0 heard again: it coordinates
    assert alloc.held == {}


def longest_alternation(seq: list[Cell | None]) -> int:
    """The longest run of ticks whose targets alternate between two cells: A B A B ..."""
    best = run = 0
    for k in range(len(seq)):
        alternating = k >= 2 and seq[k] == seq[k - 2] and seq[k] != seq[k - 1] and seq[k] is not None
        run = run + 1 if alternating else 0
        best = max(best, run)
    return best + 2 if best else 0


def test_the_two_tick_limit_cycle_of_tick_is_gone_with_commit() -> None:
    runs = {replan: run_fleet(FLIP_MAP, {"type": "hungarian", "replan": replan}, max_ticks=200)
            for replan in ("tick", "commit")}
    for trace in runs.values():
        assert trace.coverage == 1.0
    cycles = {replan: max(longest_alternation([row.get(r) for row in t.targets]) for r in ("r0", "r1"))
              for replan, t in runs.items()}
    flips = {replan: count_flips(t.targets) for replan, t in runs.items()}
    robot_ticks = {replan: sum(len(row) for row in t.targets) for replan, t in runs.items()}
    assert cycles["tick"] >= 10 and 100 * flips["tick"] > 3 * robot_ticks["tick"]  # A B A B ... for 10+ ticks
    assert cycles["commit"] < 4 and 100 * flips["commit"] <= 3 * robot_ticks["commit"]
