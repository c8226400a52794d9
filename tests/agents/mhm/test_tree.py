"""MHM's exploration tree: the backbone A and its siblings B (III-B), parent choice by eqs. (2)-(3) (III-E.1),
tree breaking with the stack (III-E.2), and phase 2's chain (III-D steps 8-9) on a drawn grid."""

from __future__ import annotations

import math
from collections import Counter
from itertools import pairwise

import numpy as np
import pytest

from fleet_emu.agents.allocators.mhm.chain import (
    base_distance,
    chain_positions,
    closest_frontier,
    path_from_base,
    phase2_chain,
)
from fleet_emu.agents.allocators.mhm.tree import (
    ExplorationTree,
    break_stack,
    choose_parent,
    parent_candidate_set,
    parent_candidates,
    recall_levels,
)
from fleet_emu.core.grid import from_ascii


def sample_tree() -> ExplorationTree:
    """
                 0 base (10,10)
              /        \\
         1 (10,14)    3 (14,14)
            |    \\          \\
         2 (10,18) 5 (6,16)   4 (18,14)
            |
         6 (10,22)
    """
    t = ExplorationTree((10, 10))
    assert t.add((10, 14), 0) == 1
    assert t.add((10, 18), 1) == 2
    assert t.add((14, 14), 0) == 3
    assert t.add((18, 14), 3) == 4
    assert t.add((6, 16), 1) == 5
    assert t.add((10, 22), 2) == 6
    return t


def test_backbone_siblings_leaves_and_hops() -> None:
    t = sample_tree()
    assert t.backbone(6) == [0, 1, 2, 6]
    assert t.backbone_siblings(6) == [3, 5]  # siblings of 1 (3), of 2 (5); 6 has none
    assert t.backbone_siblings(0) == []
    assert t.leaves(1) == [6, 5] and t.leaves(0) == [6, 5, 4]
    assert t.subtree(1) == [1, 2, 6, 5]
    assert [t.hopcount(i) for i in range(7)] == [0, 1, 2, 1, 2, 2, 3]
    t[2].processed = True
    assert t.next_unprocessed_child(1) == 5


def test_parent_choice_by_eqs_2_and_3() -> None:
    t = sample_tree()
    new = (12, 17)  # 3.6 from node 1, 2.2 from node 2, 4.2 from node 3, 7.6 from the base
    hinged = range(1, 7)
    assert parent_candidates(t, new, 5.0, hinged) == [1, 2, 3]  # eq. 2: d < r_comm
    assert parent_candidate_set(t, [1, 2, 3]) == [1, 3]  # eq. 3: fewest hops (1), not the nearest (2)
    picks = Counter(choose_parent(t, new, 5.0, hinged, np.random.default_rng(s)) for s in range(200))
    assert set(picks) == {1, 3} and min(picks.values()) > 60  # a random member of K, both drawn
    again = [choose_parent(t, new, 5.0, hinged, np.random.default_rng(7)) for _ in range(3)]
    assert len(set(again)) == 1  # the seed decides
    # a node whose robot is not hinged now is not in J
    assert parent_candidates(t, new, 5.0, [1, 2]) == [1, 2]
    assert choose_parent(t, new, 5.0, [2], np.random.default_rng(0)) == 2
    assert choose_parent(t, (40, 40), 5.0, hinged, np.random.default_rng(0)) is None
    assert parent_candidates(t, (11, 12), 3.0, []) == [0]  # the base station is always hinged
    assert math.dist((10, 14), new) < 5.0


def test_the_break_stack_goes_level_by_level() -> None:
    t = sample_tree()
    assert break_stack(t, [1, 3]) == [[1, 3], [2, 5, 4], [6]]
    assert break_stack(t, [5]) == [[5]]
    assert break_stack(t, []) == []


def test_tree_breaking_brings_every_robot_to_the_parent_cell() -> None:
    t = sample_tree()
    # a node robot on every node but the base, and explorers in cells 6, 4 and 2; e0 is in the base's cell
    members = {f"n{i}": i for i in range(1, 7)} | {"e6": 6, "e6b": 6, "e4": 4, "e2": 2, "e0": 0}
    levels = recall_levels(t, [2, 3], members)  # recall the subtrees at 2 and 3
    where = dict(members)
    unhinged: list[int] = []
    for moves in levels:
        cells = {frm for _, frm, _ in moves}
        assert not cells & set(unhinged), "a cell emptied twice"
        for frm in cells:  # the deepest first: no robot is left below a cell when it is emptied
            assert all(where[r] != d for r in where for d in t.subtree(frm)[1:])
        for robot, frm, to in moves:
            assert where[robot] == frm and t.parent(frm) == to
            where[robot] = to
        unhinged.extend(cells)
    broken = {r for r, c in members.items() if c in set(t.subtree(2)) | set(t.subtree(3))}
    assert broken == {"n2", "n6", "n3", "n4", "e6", "e6b", "e4", "e2"}
    for robot in broken:  # every robot of a broken subtree ends in the parent cell of its root
        root = 2 if members[robot] in t.subtree(2) else 3
        assert where[robot] == t.parent(root)
    for robot in set(members) - broken:
        assert where[robot] == members[robot]
    assert sorted(unhinged) == [2, 3, 4, 6]
    assert [sorted({f for _, f, _ in m}) for m in levels] == [[4, 6], [2, 3]]  # popped: deepest first


# An L-shaped corridor from the base at (1, 1) to a frontier at (4, 8); a pocket at (3, 1..3) has a frontier
# that is nearer in a straight line but that no known path reaches.
L_MAP = """
##########
#........#
########.#
#...####.#
#?######.#
########?#
"""
BASE = (1, 1)


def test_closest_frontier_is_by_path_not_straight_line() -> None:
    grid, _ = from_ascii(L_MAP)
    assert closest_frontier(grid, BASE) == (4, 8)
    assert base_distance(grid, BASE)[3, 1] == -1


def test_phase2_chain_places_nodes_every_r_comm_along_the_path() -> None:
    grid, _ = from_ascii(L_MAP)
    path = path_from_base(base_distance(grid, BASE), (4, 8))
    assert path[0] == BASE and path[-1] == (4, 8) and len(path) == 11
    # r_comm 4: (1,4) is 3 from the base, (1,5) would be 4; (1,7) is 3 from (1,4); (4,8) is 3.2 from (1,7)
    assert chain_positions(path, 4.0) == [(1, 4), (1, 7), (4, 8)]
    frontier, lh = phase2_chain(grid, BASE, 4.0)
    assert frontier == (4, 8) and lh == [(1, 4), (1, 7), (4, 8)]
    # every point of the path is within r_comm of a node or the base, and each hop is within r_comm
    hops = [BASE, *lh]
    assert all(math.dist(a, b) < 4.0 for a, b in pairwise(hops))
    assert all(min(math.dist(p, n) for n in hops) < 4.0 for p in path)
    assert chain_positions(path, 20.0) == [(4, 8)]  # in range of the base: C_f alone


def test_phase2_without_a_reachable_frontier() -> None:
    grid, _ = from_ascii(L_MAP.replace("########?#", "##########"))
    assert phase2_chain(grid, BASE, 4.0) is None


def test_chain_needs_r_comm_above_one_cell() -> None:
    with pytest.raises(ValueError, match="r_comm"):
        chain_positions([(0, 0), (0, 1), (0, 2)], 1.0)
