"""The base station's MHM planner (Mukhija et al., section III-D), run tick by tick as a pure object.

The baseline algorithm is written as the paper lists it: explore the base's cell (step 1), Recursive Tree
Growth from C_0 (steps 2-7, III-B), then phase 2 (steps 8-17: the frontier closest to the base, a chain of
nodes to it, RTG from its cell C_f) until step 18. Each physical action (hinging robots, exploring cells,
breaking trees) waits for the robots over as many ticks as it takes: the algorithm is a generator that
yields once per tick, and :meth:`MhmPlanner.step` feeds it the base's view (its team map and the robots'
last known cells) and returns every robot's order (role and goal). Nothing here touches a clock, Zenoh or
files; every random draw (eq. 3's pick) comes from the generator passed in.

Choices where the paper is silent, and why (the geometry's are in ``wavefront``, the tree's in ``tree``,
phase 2's in ``chain``, the explorers' in ``explore``):

- *Which nodes stay hinged when RTG visits C_j*: A (the backbone to C_j) and T_j (C_j and its descendants):
  III-B keeps "the communication backbone to N_j or its children", and the Exploration Wavefront of C_j
  lies on T_j's leaf cells, whose nodes must be up for a hinge point on their boundary to be in range.
  Nodes of A and T_j that a previous break unhinged are hinged again, shallowest first, so that each robot
  drives inside the safe area, and never so many that fewer than X_min explorers remain.
- *The pruning embellishment of III-C* is applied (the paper states it): a subtree whose leaf cells have no
  EW is marked processed without moving a robot. The other two embellishments (dynamic relaxation of X_min,
  a SHM fallback) are "not discussed due to space constraints": the paper gives neither rule, and they are
  not implemented (SHM itself is, as a method of its own: ``method = "shm"``, ``shm.py``). Neither can move
  the method's end: both act in a Wavefront Expansion, and step 10 ends the method when the closest frontier
  needs as many nodes as there are robots, whatever those expansions did (on an open map,
  ``benchmarks/mhm_reach.py``: the final reach is set by step 10 and the chain's geometry, ``chain`` and
  ``geodesic``).
- *Phase 2's RTG from C_f* takes C_f "as the base": eq. 2's J is limited to T_f's hinged nodes, so that the
  new cells join the subtree the RTG traverses (a chain node, with fewer hops, would otherwise adopt them and
  RTG from C_f would never expand them). The chain's nodes are tree nodes (kind ``chain``, processed), so
  that routes and tree breaking see them. The chain is hinged one node after the other (step 12's
  "sequentially"), and C_f's cell is explored before its Wavefront Expansion, as step 1 does for C_0.
  Step 11 is retried (three times at most) while a robot that could not leave keeps a cell up.
- *An exploration frontier* for the EW and for phase 2 is a frontier cell reachable from the base over
  known-free cells: one seen across a gap that no robot can reach calls for no hinge. For the EW, a
  frontier cell still within R_s of a new node after its cell was explored (the frontier that put the node
  there, which the exploration could not reach) is not one either, and an EW point where a tree node
  already stands (hinged or not) is no candidate: without these two rules a sibling cell that RTG broke
  could be created again at the same place, over and over.
- *Waiting*: an action whose robots make no progress for ``patience`` ticks ends (progress: a robot nearer
  its goal by path, or, while exploring, a newly known cell); a hinge position not reached by then is
  dropped, and a phase-2 frontier whose chain could not be completed is not tried again. A recalled robot
  that cannot reach the parent cell keeps its cell hinged, and the cell's ancestors with it: the constraint
  comes before the recall. Recalled robots drive toward the parent's node until the last of them is in the
  cell, so that the first ones in do not park on the cell's edge, often a doorway, in the way of the
  others. ``stalls`` counts these.
- *Membership for tree breaking*: an explorer belongs to the hinged node nearest it (Euclidean, lower id on
  ties), taken afresh before each popped level; an explorer that no relay staying up covers (``d < r_comm``)
  belongs to the nearest cell of the level whatever node is nearest (ties between node cells would otherwise
  leave it stranded when its real relay unhinges). A recalled robot has arrived in the parent cell when it is
  within r_comm of the parent's node (the definition of a cell).
- *Orders take time and get lost* (the fleet's radio; none in ``sim``): with ``latency`` > 0, before each
  popped level every explorer holds until it has confirmed (its ack, ``View.follows``) that it follows orders
  at least as new as the hold, or ``patience`` ticks passed: its pose, from that ack or later, is then where
  it stopped, and the base takes the level's membership from it. An explorer that missed the hold would
  otherwise still be moving on an older goal, into a cell whose relay is about to leave. A cell of the level
  within r_comm of an explorer that never confirmed (lost acks, or a robot out of reach) stays hinged, with its
  ancestors: the constraint comes first.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Generator, Mapping, Sequence
from typing import TypeVar

import numpy as np

from fleet_emu.agents.allocators.interface import robot_order
from fleet_emu.agents.allocators.mhm.chain import base_distance, phase2_chain
from fleet_emu.agents.allocators.mhm.explore import (
    area_clusters,
    assign_explorers,
    assign_positions,
    cells_area,
    make_way,
    near_any,
    path_gaps,
    safe_area,
)
from fleet_emu.agents.allocators.mhm.shm import direction_points
from fleet_emu.agents.allocators.mhm.tree import BASE_NODE, ExplorationTree, break_stack, choose_parent
from fleet_emu.agents.allocators.mhm.wavefront import (
    bearing,
    exploration_wavefront,
    frontier_distance,
    hinge_positions,
    hinging_allowed,
)
from fleet_emu.agents.frontiers import frontier_mask
from fleet_emu.core.grid import UNKNOWN, Cell

_T = TypeVar("_T")
#: How a node grows the tree: MHM's Wavefront Expansion, or the Single Hinged Method (``shm.py``).
METHODS = ("mhm", "shm")
#: A stage of the planner's program: it yields once per tick it waits for the robots, then returns its result.
Wait = Generator[None, None, _T]


@dataclasses.dataclass(frozen=True)
class MhmConfig:
    """``r_comm`` and ``sensor_range`` in cells (the paper: 40 and 15 pixels), ``x_min`` eq. 1's X_min,
    ``hinges`` the cap on H per Wavefront Expansion iteration (0: none), ``method`` how a node grows the tree
    (``mhm``: section III-A's Wavefront Expansion; ``shm``: the Single Hinged Method, ``shm.py``),
    ``cluster_max`` frontier cells per cluster, ``patience`` ticks without progress before a wait ends,
    ``latency`` the radio's ticks per hop (0: orders arrive at once, as in ``sim``)."""

    r_comm: float = 40.0
    sensor_range: float = 15.0
    x_min: int = 1
    hinges: int = 0
    method: str = "mhm"
    cluster_max: int = 30
    patience: int = 60
    latency: int = 0


@dataclasses.dataclass(frozen=True)
class Order:
    """What the base tells one robot: its ``role`` (``node``: do not move; ``explorer``) and its ``goal``
    (None: hold)."""

    role: str
    goal: Cell | None


@dataclasses.dataclass(frozen=True)
class View:
    """What the base knows at ``tick``: its team map, each robot's last known cell, and (over a radio) the plan
    tick of the newest orders each robot confirmed it follows."""

    tick: int
    grid: np.ndarray
    poses: Mapping[str, Cell]
    follows: Mapping[str, int] = dataclasses.field(default_factory=dict)


class MhmPlanner:
    """Section III-D, one :meth:`step` per tick (see the module docstring)."""

    def __init__(self, base: Cell, robots: Sequence[str], config: MhmConfig, rng: np.random.Generator) -> None:
        if config.x_min < 1:
            raise ValueError("x_min must be >= 1")
        if config.method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}")
        self.base, self.config, self.rng = base, config, rng
        self.robots = sorted(robots, key=robot_order)
        self.tree = ExplorationTree(base)
        self.node_of: dict[int, str] = {}  # hinged tree node -> its robot
        self.pending: dict[str, Cell] = {}  # robots hinged in this WE iteration, not yet in the tree
        self.goals: dict[str, Cell] = {}
        self.phase = 1
        self.done = False
        self.stalls = 0
        self.events: list[tuple[int, str]] = []  # (tick, what happened), for the record
        self.given_up: set[Cell] = set()
        self.dead: np.ndarray | None = None  # frontier cells the exploration of their cell left (see _bury)
        self.view: View | None = None
        self._run_gen = self._run()

    # --- state -------------------------------------------------------------------------------------------

    @property
    def grid(self) -> np.ndarray:
        assert self.view is not None
        return self.view.grid

    @property
    def poses(self) -> Mapping[str, Cell]:
        assert self.view is not None
        return self.view.poses

    def hinged(self) -> set[int]:
        """Tree nodes with a robot on them now, the base's included."""
        return set(self.node_of) | {BASE_NODE}

    def explorers(self) -> dict[str, Cell]:
        busy = set(self.node_of.values()) | set(self.pending)
        return {r: self.poses[r] for r in self.robots if r not in busy and r in self.poses}

    def relays(self) -> list[Cell]:
        """Where relays stand: the base, hinged nodes, robots hinged in the current iteration."""
        return [self.tree[i].pos for i in sorted(self.hinged())] + list(self.pending.values())

    def safe_mask(self) -> np.ndarray:
        """The known-free cells an explorer may be on: within r_comm of a relay."""
        return safe_area(self.grid, self.relays(), self.config.r_comm)

    def passable(self) -> np.ndarray:
        """:meth:`safe_mask` less the cells node robots stand on: they do not move, so paths go around them."""
        mask = self.safe_mask()
        for r in list(self.node_of.values()) + list(self.pending):
            if r in self.poses:
                mask[self.poses[r]] = False
        return mask

    def orders(self) -> dict[str, Order]:
        node_pos = {r: self.tree[i].pos for i, r in self.node_of.items()} | self.pending
        return {r: Order("node", node_pos[r]) if r in node_pos else Order("explorer", self.goals.get(r))
                for r in self.robots}

    def routes(self) -> dict[str, str]:
        """Each robot's next relay toward the base (``base`` or a node robot): a node robot's parent node's;
        a robot hinged in the current iteration, its nearest hinged node's; an explorer, its nearest relay's
        (those two included; ties by id). The parent map the ``tree`` relay policy reads."""
        tree_relays = [(self.tree[i].pos, "base" if i == BASE_NODE else self.node_of[i]) for i in sorted(self.hinged())]
        out: dict[str, str] = {}
        for i, r in self.node_of.items():
            p = self.tree.up(i)
            out[r] = self.node_of.get(p, "base")
        for r, cell in self.pending.items():
            out[r] = min(tree_relays, key=lambda pn: math.dist(pn[0], cell))[1]
        relays = tree_relays + sorted((c, r) for r, c in self.pending.items())
        for r, cell in self.poses.items():
            if r not in out:
                out[r] = min(relays, key=lambda pn: (math.dist(pn[0], cell), robot_order(pn[1])))[1]
        return out

    def _note(self, what: str) -> None:
        self.events.append((self.view.tick if self.view else -1, what))

    def step(self, view: View) -> dict[str, Order]:
        """Advance the algorithm by one tick with the base's latest view; every robot's order."""
        self.view = view
        if not self.done:
            try:
                next(self._run_gen)
            except StopIteration:
                self.done = True
                self.goals = {}
        return self.orders()

    # --- section III-D ----------------------------------------------------------------------------------

    def _run(self) -> Wait[None]:
        yield from self._explore([self.base])  # step 1
        yield from self._rtg(BASE_NODE, scope=None)  # steps 2-7
        self.phase = 2
        self._note("phase 2")
        while True:  # steps 8-17
            found = self._closest_frontier_chain()
            if found is None or len(found[1]) >= len(self.robots):  # step 10 -> 18
                self._note("stop: " + ("no reachable frontier" if found is None else
                                       f"frontier {found[0]} needs {len(found[1])} nodes"))
                return
            frontier, lh = found
            self._note(f"chain to {frontier}: {lh}")
            for _ in range(3):  # step 11; a robot that could not leave keeps its cell up: try again
                yield from self._break(self.tree[BASE_NODE].children)
            cf = yield from self._extend_chain(lh)  # step 12
            if cf is None:
                self._note(f"chain to {frontier} failed; frontier given up")
                self.given_up.add(frontier)
                continue
            yield from self._explore([self.tree[cf].pos])  # C_f is created by exploring it
            yield from self._rtg(cf, scope=cf)  # steps 13-17

    def _rtg(self, root: int, scope: int | None) -> Wait[None]:
        """Recursive Tree Growth of T_root, depth first, new children included (steps 3-7, 13-17)."""
        cur = root
        while True:
            if not self.tree[cur].processed:
                yield from self._visit(cur, scope)
                self.tree[cur].processed = True
            child = self.tree.next_unprocessed_child(cur)
            if child is not None:
                cur = child
            elif cur == root:
                return
            else:
                cur = self.tree.up(cur)

    def _visit(self, i: int, scope: int | None) -> Wait[None]:
        """Recall the backbone's siblings (III-B), hinge A and T_i again, then the Wavefront Expansion of C_i."""
        fdist = self._fdist()
        leaves = [self.tree[j].pos for j in self.tree.leaves(i)]
        if not len(exploration_wavefront(self.grid, leaves, self.config.r_comm, self.config.sensor_range, fdist)):
            for j in self.tree.subtree(i):  # III-C: no EW for T_i, none for its children
                self.tree[j].processed = True
            return
        yield from self._break(self.tree.backbone_siblings(i))
        yield from self._rehinge(self.tree.backbone(i) + self.tree.subtree(i))
        if i in self.hinged():
            yield from (self._expand_single(i, scope) if self.config.method == "shm" else self._expand(i, scope))

    def _expand(self, i: int, scope: int | None) -> Wait[None]:
        """Section III-A's Wavefront Expansion of C_i: iterations of EW, hinging and exploring while eq. 1 holds."""
        cfg = self.config
        while True:
            hinged = self.hinged()
            leaves = [self.tree[j].pos for j in self.tree.leaves(i) if j in hinged]
            taken = [n.pos for n in self.tree.nodes]  # a cell that exists is not created again
            positions = hinge_positions(self.grid, leaves, self.base, cfg.r_comm, cfg.sensor_range, cfg.hinges,
                                        taken, self._fdist())
            if not positions or not hinging_allowed(len(positions), len(self.explorers()), cfg.x_min):
                return
            self._note(f"WE of {i}: hinge at {positions}")
            placed = yield from self._hinge(positions)
            if not placed:
                return
            yield from self._grow(placed, scope)

    def _grow(self, placed: list[tuple[Cell, str]], scope: int | None) -> Wait[list[int]]:
        """The robots just hinged at ``placed`` explore their cells, which join the tree (III-E.1, one new cell
        after the other); the new nodes."""
        self.pending = {r: p for p, r in placed}
        yield from self._explore([p for p, _ in placed])
        self._bury([p for p, _ in placed])
        allowed = self.hinged() if scope is None else self.hinged() & set(self.tree.subtree(scope))
        new = []
        for p, r in placed:
            parent = choose_parent(self.tree, p, self.config.r_comm, allowed, self.rng)
            if parent is None:  # no allowed node in range (phase 2 at C_f's edge): its leaf in range
                parent = min(sorted(allowed), key=lambda j: math.dist(self.tree[j].pos, p))
            n = self.tree.add(p, parent)
            self.node_of[n] = r
            allowed.add(n)
            new.append(n)
        self.pending = {}
        return new

    def _expand_single(self, i: int, scope: int | None) -> Wait[None]:
        """SHM (``shm.py``): C_i hinges one robot at a time along one of its directions, each useful direction
        once, and the tree grows from the new cell depth first before the next; the subtrees grown are broken
        first (the rollback), and C_i's backbone hinged again should a recall have taken it."""
        cfg = self.config
        tried: set[int] = set()
        grown: list[int] = []
        while True:
            yield from self._break(grown)
            if i not in self.hinged():
                yield from self._rehinge(self.tree.backbone(i))
                if i not in self.hinged():
                    return
            taken = {n.pos for n in self.tree.nodes}
            points = direction_points(self.grid, self.tree[i].pos, cfg.r_comm, cfg.sensor_range, self._fdist())
            todo = sorted((bearing(p, self.base), k, p) for k, p in points.items() if k not in tried and p not in taken)
            if not todo or not hinging_allowed(1, len(self.explorers()), cfg.x_min):
                return
            _, k, p = todo[0]
            tried.add(k)
            self._note(f"SHM of {i}: direction {k}, hinge at {[p]}")
            placed = yield from self._hinge([p])
            if not placed:
                continue
            new = yield from self._grow(placed, scope)
            grown += new
            for n in new:
                yield from self._rtg(n, scope)

    def _extend_chain(self, lh: list[Cell]) -> Wait[int | None]:
        """Step 12: hinge L_h one node after the other from the base; C_f's id, or None if a hinge failed."""
        prev = BASE_NODE
        for k, p in enumerate(lh):
            placed = yield from self._hinge([p])
            if not placed:
                yield from self._break(self.tree[BASE_NODE].children)
                return None
            last = k == len(lh) - 1
            n = self.tree.add(p, prev, kind="cell" if last else "chain")
            self.tree[n].processed = not last
            self.node_of[n] = placed[0][1]
            prev = n
        return prev

    # --- physical actions ---------------------------------------------------------------------------------

    def _explore(self, centers: list[Cell]) -> Wait[None]:
        """Frontier exploration of the node cells at ``centers`` with every explorer, inside the safe area.
        Progress is a newly known cell or an explorer nearer its goal than it has been."""
        quiet, known = 0, -1
        best: dict[tuple[str, Cell], int] = {}
        while True:
            area = cells_area(self.grid, centers, self.config.r_comm)
            clusters = area_clusters(self.grid, area, self.config.cluster_max)
            targets = assign_explorers(self.grid, self.passable(), clusters, self.explorers(),
                                       self.goals) if clusters else {}
            seen = int(np.count_nonzero(self.grid != UNKNOWN))
            closer = any(d < best.get((r, g), 1 << 30) for r, (g, d) in targets.items())
            best.update({(r, g): min(d, best.get((r, g), 1 << 30)) for r, (g, d) in targets.items()})
            quiet = 0 if seen != known or closer else quiet + 1
            known = seen
            if not targets or quiet > self.config.patience:
                if targets:
                    self.stalls += 1
                    self._note(f"exploring {centers}: no progress, stopped")
                self.goals = {}
                return
            self.goals = {r: g for r, (g, _) in targets.items()}
            yield

    def _hinge(self, positions: list[Cell]) -> Wait[list[tuple[Cell, str]]]:
        """Send the nearest explorers to ``positions``; the (position, robot) pairs that arrived."""
        chosen = assign_positions(self.passable(), positions, self.explorers())
        best: dict[str, float] = {}
        quiet = 0
        while any(self.poses[r] != p for r, p in chosen.items()):
            gaps = self._path_gaps(chosen)
            moved = any(gaps[r] < best.get(r, math.inf) for r in chosen)
            best = {r: min(gaps[r], best.get(r, math.inf)) for r in chosen}
            quiet = 0 if moved else quiet + 1
            if quiet > self.config.patience:
                self.stalls += 1
                self._note(f"hinge: {sorted((r, p) for r, p in chosen.items() if self.poses[r] != p)} not reached")
                chosen = {r: p for r, p in chosen.items() if self.poses[r] == p}
                break
            idle = [r for r in self.explorers() if r not in chosen]
            self.goals = dict(chosen) | make_way(self.passable(), self.poses, chosen, idle)
            yield
        self.goals = {}
        order = {p: k for k, p in enumerate(positions)}
        return sorted(((p, r) for r, p in chosen.items()), key=lambda pr: order[pr[0]])

    def _rehinge(self, nodes: list[int]) -> Wait[None]:
        """Hinge the unhinged ``nodes`` again, shallowest first, while X_min explorers remain."""
        todo = sorted({n for n in nodes if n not in self.hinged()}, key=lambda n: (self.tree.hopcount(n), n))
        while todo:
            depth = self.tree.hopcount(todo[0])
            level = [n for n in todo if self.tree.hopcount(n) == depth and self.tree.parent(n) in self.hinged()]
            level = level[:max(0, len(self.explorers()) - self.config.x_min)]
            todo = [n for n in todo if self.tree.hopcount(n) > depth]
            if not level:
                continue
            placed = yield from self._hinge([self.tree[n].pos for n in level])
            at = {p: r for p, r in placed}
            for n in level:
                if self.tree[n].pos in at:
                    self.node_of[n] = at[self.tree[n].pos]

    def _break(self, roots: list[int]) -> Wait[None]:
        """Section III-E.2: pop the stack level by level; each cell's explorers go into its parent cell, then
        its node robot unhinges."""
        roots = [b for b in roots if any(j in self.node_of for j in self.tree.subtree(b))]
        if not roots:
            return
        keep: set[int] = set()  # cells a recalled robot could not leave, and their ancestors
        for level in reversed(break_stack(self.tree, roots)):
            unsure = yield from self._settle()
            members = self._members(level)
            movers = {r: self.tree.up(i) for r, i in members.items()}
            best: dict[str, float] = {}
            quiet = 0
            while True:
                targets = {r: self.tree[p].pos for r, p in movers.items()}
                away = {r for r in movers if math.dist(self.poses[r], targets[r]) >= self.config.r_comm}
                gaps = self._path_gaps({r: targets[r] for r in away})
                quiet = 0 if any(gaps[r] < best.get(r, math.inf) for r in away) else quiet + 1
                best = {r: min(gaps[r], best.get(r, math.inf)) for r in away}
                if not away or quiet > self.config.patience:
                    break
                self.goals = targets  # the arrived ones too: they drive on toward the node, clearing the way
                yield
            self.goals = {}
            stuck = {members[r] for r in away}
            stuck |= {i for i in level for r in unsure if r in self.poses
                      and math.dist(self.poses[r], self.tree[i].pos) < self.config.r_comm}
            if stuck:
                self.stalls += 1
                self._note(f"break: {sorted(away)} could not leave cells {sorted(stuck)}; kept hinged")
            for i in level:
                if i in stuck or i in keep:  # the constraint first: a cell with a robot left in it stays up
                    keep.add(self.tree.up(i))
                elif i in self.node_of:
                    self.node_of.pop(i)

    def _members(self, level: list[int]) -> dict[str, int]:
        """The explorers in the cells of ``level`` (module docstring, membership), each with its cell."""
        hinged = sorted(self.hinged())
        staying = [self.tree[j].pos for j in hinged if j not in level] + list(self.pending.values())
        out: dict[str, int] = {}
        for r, c in self.explorers().items():
            nearest = min(hinged, key=lambda j: math.dist(self.tree[j].pos, c))
            if nearest in level:
                out[r] = nearest
            elif not any(math.dist(c, p) < self.config.r_comm for p in staying):
                out[r] = min(level, key=lambda j: (math.dist(self.tree[j].pos, c), j))
        return out

    def _settle(self) -> Wait[set[str]]:
        """With ``latency`` > 0: every explorer holds until it confirmed that it follows orders from now on,
        or ``patience`` ticks (module docstring); the explorers that did not confirm."""
        if self.config.latency <= 0:
            return set()
        self.goals = {}
        t0 = self.view.tick if self.view else 0
        unsure: set[str] = set()
        for _ in range(self.config.patience):
            yield
            follows = self.view.follows if self.view else {}
            unsure = {r for r in self.explorers() if follows.get(r, -1) < t0}
            if not unsure:
                return unsure
        self.stalls += 1
        self._note(f"break: {sorted(unsure)} did not confirm the hold; their cells stay hinged")
        return unsure

    # --- helpers ------------------------------------------------------------------------------------------

    def _path_gaps(self, targets: Mapping[str, Cell]) -> dict[str, float]:
        """Each robot's path distance to its target over :meth:`passable` cells: progress along the way."""
        return path_gaps(self.passable(), self.poses, targets)

    def _fdist(self) -> np.ndarray:
        """Distance to the nearest exploration frontier: reachable from the base, not given up."""
        where = base_distance(self.grid, self.base) >= 0
        if self.dead is not None:
            where &= ~self.dead
        return frontier_distance(self.grid, where)

    def _bury(self, centers: list[Cell]) -> None:
        """After new cells were explored: the frontier cells still within R_s of their nodes (those that put
        the nodes there) could not be explored from them, and call for no hinge again."""
        if self.dead is None:
            self.dead = np.zeros(self.grid.shape, dtype=bool)
        self.dead |= near_any(self.grid.shape, centers, self.config.sensor_range) & frontier_mask(self.grid)

    def _closest_frontier_chain(self) -> tuple[Cell, list[Cell]] | None:
        """Steps 8-9 over the reachable frontiers not given up."""
        return phase2_chain(self.grid, self.base, self.config.r_comm, self.given_up)
