"""MHM's exploration tree T_0 (Mukhija et al., sections III, III-B and III-E) as plain data and functions.

Tree nodes are node cells; node 0 is the base station's cell C_0. Every node keeps the grid cell where its
node robot hinges. This module gives what section III names on the tree: the backbone A to a node and the
set B of the backbone's siblings (III-B), the parent choice of a new cell by eqs. (2)-(3) (III-E.1), and the
tree-breaking stack (III-E.2). Which robot stands where is the planner's; the tree only gets told which
nodes are hinged now.

Choices where the paper is silent, and why:

- Eq. (2) takes the tree nodes "such that the hinged-robot corresponding to each tree-node is within
  communication range": a node whose robot is not hinged now (its subtree broken) has no hinged robot, so it
  is not in J. The base station is always hinged. This makes the parent a relay that is up, so that the
  tree is also the live routing tree.
- The random member of K comes from the generator passed in (the run's seed); K is sorted by node id
  before the draw, so the draw does not depend on set order.
- Children are kept in the order they were added; the depth-first traversal of RTG visits them in that
  order.
- Tree breaking recalls, at each popped level, the robots of each cell into its parent cell: first the
  explorers that belong to the cell, then its node robot, which unhinges and becomes an explorer of the
  parent cell (it already stands within r_comm of the parent). ``recall_levels`` gives those moves.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping

import numpy as np

from fleet_emu.core.grid import Cell

BASE_NODE = 0


@dataclasses.dataclass
class TreeNode:
    """One node cell: ``pos`` where its node robot hinges, its ``parent`` (None for C_0), its ``children``
    in the order they were added, ``kind`` (``base``, ``cell``, or ``chain`` for phase 2's hop path) and
    whether RTG has processed it."""

    id: int
    pos: Cell
    parent: int | None
    children: list[int] = dataclasses.field(default_factory=list)
    kind: str = "cell"
    processed: bool = False


class ExplorationTree:
    """T_0: node 0 is the base station's cell; ids are indices into :attr:`nodes`."""

    def __init__(self, base: Cell) -> None:
        self.nodes: list[TreeNode] = [TreeNode(BASE_NODE, base, None, kind="base")]

    def __len__(self) -> int:
        return len(self.nodes)

    def __getitem__(self, i: int) -> TreeNode:
        return self.nodes[i]

    def add(self, pos: Cell, parent: int, kind: str = "cell") -> int:
        """Add a leaf at ``pos`` under ``parent``; its id."""
        node = TreeNode(len(self.nodes), pos, parent, kind=kind)
        self.nodes.append(node)
        self.nodes[parent].children.append(node.id)
        return node.id

    def parent(self, i: int) -> int | None:
        return self.nodes[i].parent

    def up(self, i: int) -> int:
        """The parent of C_i, a node other than C_0 (the root, which has none)."""
        p = self.nodes[i].parent
        if p is None:
            raise ValueError(f"C_{i} is the root: it has no parent")
        return p

    def hopcount(self, i: int) -> int:
        """Hops from C_i to C_0 along the tree (eq. 3's hopcount)."""
        hops = 0
        while (p := self.nodes[i].parent) is not None:
            hops, i = hops + 1, p
        return hops

    def backbone(self, i: int) -> list[int]:
        """Section III-B's set A: the hop path from the base station to C_i, both included, base first."""
        path = [i]
        while (p := self.nodes[path[-1]].parent) is not None:
            path.append(p)
        return path[::-1]

    def subtree(self, i: int) -> list[int]:
        """T_i: C_i and all its descendants, depth-first preorder."""
        out, stack = [], [i]
        while stack:
            j = stack.pop()
            out.append(j)
            stack.extend(reversed(self.nodes[j].children))
        return out

    def leaves(self, i: int) -> list[int]:
        """The set L: the leaf nodes of T_i (C_i itself when it has no children)."""
        return [j for j in self.subtree(i) if not self.nodes[j].children]

    def backbone_siblings(self, i: int) -> list[int]:
        """Section III-B's set B: the siblings of every member of A, i.e. the roots of the subtrees whose
        robots are recalled before C_i is expanded."""
        out: list[int] = []
        for j in self.backbone(i):
            p = self.nodes[j].parent
            if p is not None:
                out.extend(s for s in self.nodes[p].children if s != j)
        return out

    def next_unprocessed_child(self, i: int) -> int | None:
        """RTG step 6: the first child of C_i not yet processed."""
        return next((c for c in self.nodes[i].children if not self.nodes[c].processed), None)


def parent_candidates(tree: ExplorationTree, pos: Cell, r_comm: float, hinged: Iterable[int]) -> list[int]:
    """Eq. (2): J, the hinged tree nodes whose robot is within r_comm of a new cell's node at ``pos``."""
    return sorted(i for i in set(hinged) | {BASE_NODE} if math.dist(tree[i].pos, pos) < r_comm)


def parent_candidate_set(tree: ExplorationTree, j: Iterable[int]) -> list[int]:
    """Eq. (3): K, the members of J with the fewest hops to the base station (sorted by id)."""
    j = list(j)
    if not j:
        return []
    best = min(tree.hopcount(i) for i in j)
    return sorted(i for i in j if tree.hopcount(i) == best)


def choose_parent(tree: ExplorationTree, pos: Cell, r_comm: float, hinged: Iterable[int],
                  rng: np.random.Generator) -> int | None:
    """Section III-E.1: a random member of K for a new cell at ``pos``; None when J is empty (no hinged
    node in range: the cell cannot join the tree)."""
    k = parent_candidate_set(tree, parent_candidates(tree, pos, r_comm, hinged))
    return k[int(rng.integers(len(k)))] if k else None


def break_stack(tree: ExplorationTree, roots: Iterable[int]) -> list[list[int]]:
    """Section III-E.2's stack, bottom first: the roots B, then the children of all of them (C), then
    theirs, until a set has no children. Popping from the end unhinges the deepest cells first."""
    level = sorted(set(roots))
    stack = []
    while level:
        stack.append(level)
        level = [c for i in level for c in tree[i].children]
    return stack


def recall_levels(tree: ExplorationTree, roots: Iterable[int], members: Mapping[str, int]
                  ) -> list[list[tuple[str, int, int]]]:
    """The moves of breaking the subtrees at ``roots``, one list per popped set: ``(robot, from, to)``,
    every robot that belongs to a cell of the set (``members``: robot -> the node cell it is in, node robots
    included) going to that cell's parent. Robots of other cells do not move."""
    where = dict(members)
    out = []
    for level in reversed(break_stack(tree, roots)):
        moves = []
        for i in level:
            parent = tree[i].parent
            if parent is None:  # C_0 is never broken
                continue
            for robot in sorted(r for r, c in where.items() if c == i):
                moves.append((robot, i, parent))
        for robot, _, to in moves:
            where[robot] = to
        out.append(moves)
    return out
