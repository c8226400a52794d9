"""Connectivity-aware MinPos, Benavides et al. 2016 (LARS/SBR), section III-D and III-E.

Each frontier cluster is a task ``T_j`` (its target cell, eqs. 10-12). Robot ``k``'s utility for it is eq. 9:

    utility_k(T_j) = -alpha * pathCost_k(T_j) + beta * connectivity_{T_j}(others of k)

with ``pathCost`` the wavefront distance of eq. 7 (in metres: cells times ``cell_size``) and the connectivity of
eq. 8 evaluated at the task's location:

    connectivity_{T_j} = sum_{p=1..P} lambda^p * com(d_p)

where ``d_1 <= d_2 <= ... <= d_P`` are the distances from ``T_j`` to the other robots (the paper's "increasing
ordered set of distances", ties by robot id) and ``com`` is the signal strength of eq. 4 in dB, *not* a
probability: ``com(d) = -10 PL log10(d / c) - min(nW, C) WAF`` (``fleet_emu.core.radio.signal_db``). So a teammate in
range adds a positive term and one out of range (far, or behind walls) a negative one; ``lambda`` weighs the
nearest teammates most. Every known teammate pose is a "sub-group member" (``P`` = all of them).

Allocation (section III-E-2): "the same allocation criterion as in the minPos approach, but using the task
utility function defined in Eq. 9 instead of just the path cost". The position of robot ``i`` toward ``T_j`` is
the number of teammates with a higher utility for it, ``P_ij = |{k != i : U_kj > U_ij}|``; the robot takes the
task of least position and, among those, of highest utility (then the lowest cluster index) — MinPos's
Algorithm 3 on ``-U``. With ``beta = 0`` (and ``alpha > 0``) this is exactly MinPos, whatever ``position``.

Choices the paper leaves open, as parameters:

- ``position``: how the deciding robot evaluates a teammate's eq. 9. Read literally (``"literal"``), teammate
  ``k``'s eq. 8 at ``T_j`` sums over every robot but ``k``, the deciding robot at its own cell included. So the
  nearer robot ``i`` gets to its target, the better that target looks for ``k`` (the signal from it to ``i``
  grows), and ``i`` yields it: two robots each beside its own frontier swap them (tests), and on real maps runs
  oscillate until the tick limit. Yet if ``k`` took ``T_j``, ``i`` would not be there. ``"without_self"``
  (default) leaves the deciding robot out of its teammates' eq. 8, since where it will be depends on the very
  decision; its own eq. 9 stays literal. ``"cost"`` takes the pair's term as common to both (positions on path
  cost, as MinPos), so eq. 9 only chooses among the tasks of least position.
- ``predict``: where a teammate is expected for eq. 8: its last known cell (``"pose"``, default, as the paper's
  Fig. 4) or the target MinPos's rule gives it on the deciding robot's data (``"target"``).
- ``replan``: when the allocation is recomputed. Benavides adopts "the same allocation criterion as in the
  minPos approach" (section III-E-2), and MinPos (Bautin et al. 2012, section 2) says the assignment "has to be
  reevaluated at each time step or at least every time the robot observes the targeted frontier": ``"tick"``
  (default, as ``minpos``'s default) recomputes at every decision. ``"observed"`` keeps the previous target until
  the robot has observed it, or can no longer reach it, exactly as ``minpos``'s option of the same name (see its
  module docstring: observed means the target cell is no longer a frontier cell of the robot's belief, known free
  beside an unknown cell, so that no cluster holds it; reachable means the robot can step toward it, a teammate
  heard last tick holding the cell of the step counting as an obstacle, and the fresh decision ranks only the
  clusters so reachable). Eq. 8 and 9 are untouched; only when they are applied changes. Re-planning every tick is
  what lets eq. 9 pull the robots together at every step: on the paper's setting (``fleet sweep benavides``: the
  hospital section, 3 m sensing, 6 m range) ``"tick"`` keeps the two robots linked about twice as often as
  ``"observed"``, whose commitment leaves them apart until each has seen its target, at more ticks
  (docs/performance/papers.md). With a heavy ``beta``, two robots abreast between two frontiers may swap targets
  at every tick (tests); ``"observed"`` keeps each on its target until it has seen it, and ended no run as a
  stall in ``benchmarks/connectivity_table.py``'s settings where ``"tick"`` ended a few.
- ``beta`` and ``lam`` (below).

What the robot can know (docs/design/architecture.md): the signal is predicted on its *belief* map from teammates'
*last known* poses. Walls are the cells the belief holds as occupied; unknown cells count as free by default (a
robot cannot know a wall it has not seen, and frontier targets border unknown space, so counting unknown runs as
walls would penalise every frontier alike); ``unknown_walls=True`` counts them as walls instead. Distances are
clamped to one cell: two robots never stand closer (one cell holds one robot), and the 1 mm clamp of ``signal_db``
would give a teammate standing on a target a spurious +80 dB.

Settings (``params()``): the paper's experiment that favours connectivity (Fig. 8, Table I) uses
``alpha = 0.6``; the paper gives no value for ``beta`` or ``lambda``. With ``alpha, beta`` in ``[0, 1]`` weighed
against each other, the defaults take ``beta = 1 - alpha = 0.4`` and ``lambda = 0.5`` (between the paper's two
limits: 0, connectivity ignored; 1, every teammate weighed alike). Its other setting, ``alpha`` "very close to
1.0" (Fig. 7), is ``alpha=0.99, beta=0.01``. The radio parameters default to the scenario's (``comm_range``
10 m, PL 2.0, WAF 3.1 dB, C = 4, ``cell_size`` 0.5 m); the paper's experiment used a 6 m range
(``comm_range=6.0``). The paper states eq. 9 maps to [0, 1], which eq. 9 as written cannot do; metres and dB
are kept as they are, not normalised.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from fleet_emu.agents.allocators.interface import Allocation, Allocator, Problem
from fleet_emu.agents.allocators.minpos import REPLANS, minpos_choice, observed_choice, positions
from fleet_emu.agents.allocators.params import Param
from fleet_emu.core.grid import FREE, OCCUPIED, Cell
from fleet_emu.core.kernels import count_walls
from fleet_emu.core.messages import RadioMsg
from fleet_emu.core.radio import RadioConfig, signal_db

POSITIONS = ("without_self", "literal", "cost")
PREDICTIONS = ("pose", "target")


def wall_mask(belief: np.ndarray, unknown_walls: bool = False) -> np.ndarray:
    """The cells that attenuate the predicted signal: occupied in the belief (and unknown ones if asked)."""
    return belief != FREE if unknown_walls else belief == OCCUPIED


def signal_at(walls: np.ndarray, target: Cell, other: Cell, cell_size: float, radio: RadioConfig) -> float:
    """Eq. 4 between a task's cell and a robot's cell, on the belief's walls, distance clamped to one cell."""
    d = max(math.hypot(target[0] - other[0], target[1] - other[1]), 1.0) * cell_size
    nw = int(count_walls(walls, target[0], target[1], other[0], other[1]))
    return signal_db(d, nw, radio)


def connectivity(walls: np.ndarray, target: Cell, others: Sequence[Cell], lam: float, cell_size: float,
                 radio: RadioConfig) -> float:
    """Eq. 8 at ``target``: ``sum_p lam^p com(d_p)``, the others sorted by increasing distance (stable)."""
    dist = [math.hypot(target[0] - o[0], target[1] - o[1]) for o in others]
    order = sorted(range(len(others)), key=lambda k: dist[k])
    return sum(lam ** (p + 1) * signal_at(walls, target, others[k], cell_size, radio) for p, k in enumerate(order))


def utilities(problem: Problem, alpha: float, beta: float, lam: float, cell_size: float, radio: RadioConfig,
              unknown_walls: bool = False, cells: Sequence[Cell] | None = None,
              without: int | None = None) -> np.ndarray:
    """Eq. 9 for every robot with a known pose (rows, in ``problem.robots`` order) and every task (columns);
    ``-inf`` where the robot cannot reach the task. Row ``k``'s eq. 8 sums over every robot but ``k``, placed
    at ``cells`` (default: the poses), the deciding robot included: eq. 9 read literally for every robot."""
    costs = problem.costs
    n, m = costs.shape
    reach = np.isfinite(costs)
    u = np.where(reach, -alpha * np.where(reach, costs, 0.0) * cell_size, -np.inf)
    if beta == 0.0 or lam == 0.0 or n < 2 or m == 0:
        return u
    walls = wall_mask(problem.belief, unknown_walls)
    cells = list(problem.poses.values()) if cells is None else list(cells)
    targets = [c.target for c in problem.clusters]
    dist = np.array([[math.hypot(t[0] - p[0], t[1] - p[1]) for t in targets] for p in cells])  # (n, m)
    sig = np.array([[signal_at(walls, t, p, cell_size, radio) for t in targets] for p in cells])
    weights = lam ** np.arange(1, n, dtype=float)  # lambda^p, p = 1 .. n-1
    for k in range(n):
        rows = np.array([r for r in range(n) if r != k and (r != without or k == without)])
        if len(rows) == 0:
            continue
        order = np.argsort(dist[rows], axis=0, kind="stable")  # per task: the others by increasing distance
        ranked = np.take_along_axis(sig[rows], order, axis=0)
        conn = weights[: len(rows)] @ ranked
        u[k] = np.where(reach[k], u[k] + beta * conn, -np.inf)
    return u


def own_utility(problem: Problem, alpha: float, beta: float, lam: float, cell_size: float, radio: RadioConfig,
                unknown_walls: bool = False, cells: Sequence[Cell] | None = None) -> np.ndarray:
    """Eq. 9 of the deciding robot for every task (``-inf`` where it cannot reach it): its path cost, and eq. 8
    over its teammates placed at ``cells`` (every robot's, in ``problem.robots`` order; default the poses)."""
    i = problem.index
    cost = problem.costs[i]
    reach = np.isfinite(cost)
    u = np.where(reach, -alpha * np.where(reach, cost, 0.0) * cell_size, -np.inf)
    if beta == 0.0 or lam == 0.0 or len(problem.poses) < 2 or not problem.clusters:
        return u
    walls = wall_mask(problem.belief, unknown_walls)
    every = list(problem.poses.values()) if cells is None else list(cells)
    others = [c for k, c in enumerate(every) if k != i]
    conn = np.array([connectivity(walls, c.target, others, lam, cell_size, radio) for c in problem.clusters])
    return np.where(reach, u + beta * conn, -np.inf)


def predicted_cells(problem: Problem, predict: str) -> list[Cell]:
    """Where each robot is expected to be for eq. 8 (``problem.robots`` order): its last known cell
    (``"pose"``), or, for a teammate, the target of the cluster MinPos's rule gives it from the deciding
    robot's data (``"target"``; its pose when it reaches none). The deciding robot keeps its own cell."""
    cells = list(problem.poses.values())
    if predict == "pose":
        return cells
    for k in range(len(cells)):
        if k != problem.index:
            j = minpos_choice(problem.costs, k)
            if j is not None:
                cells[k] = problem.clusters[j].target
    return cells


def choose(problem: Problem, alpha: float, beta: float, lam: float, cell_size: float, radio: RadioConfig,
           position: str = "without_self", predict: str = "pose", unknown_walls: bool = False) -> int | None:
    """The task the deciding robot takes (section III-E-2: MinPos's criterion on eq. 9), None if it reaches
    none. ``position="literal"`` or ``"without_self"``: positions counted on every robot's eq. 9
    (:func:`utilities`; ``"without_self"`` leaves the deciding robot out of its teammates' eq. 8), ties on the
    robot's utility. ``position="cost"``: a teammate and the deciding robot are compared on one eq. 8 (the
    team without the two of them, wherever it is, and whichever of the pair takes the task, the other is
    elsewhere), so the connectivity term is common to both and the position is MinPos's, on path cost; among
    the tasks of least position the robot takes the one of highest eq. 9 utility (then the lowest index)."""
    cells = predicted_cells(problem, predict)
    if position in ("literal", "without_self"):
        without = problem.index if position == "without_self" else None
        u = utilities(problem, alpha, beta, lam, cell_size, radio, unknown_walls, cells, without)
        return minpos_choice(-u, problem.index)  # positions on -U: U_kj > U_ij counts as "closer"
    own = own_utility(problem, alpha, beta, lam, cell_size, radio, unknown_walls, cells)
    reach = np.isfinite(problem.costs[problem.index])
    if not reach.any():
        return None
    pos = positions(problem.costs, problem.index).astype(float)
    pos[~reach] = np.inf
    candidates = np.flatnonzero(pos == pos.min())
    return int(candidates[np.argmax(own[candidates])])


class Connectivity(Allocator, plugin_name="connectivity"):
    """Benavides et al. 2016: MinPos's criterion on the task utility of eq. 9 (see the module docstring)."""

    DESCRIPTION = "Benavides et al. 2016: MinPos on a utility that weighs path cost against radio links to teammates"

    parameters = {"alpha": Param(0.6, ge=0), "beta": Param(0.4, ge=0), "lam": Param(0.5, ge=0, le=1),
                  "comm_range": Param(10.0, gt=0), "cell_size": Param(0.5, gt=0), "path_loss": Param(2.0, ge=0),
                  "waf": Param(3.1, ge=0), "max_walls": Param(4, ge=0), "unknown_walls": Param(False),
                  "position": Param("without_self", choices=POSITIONS), "predict": Param("pose", choices=PREDICTIONS),
                  "replan": Param("tick", choices=REPLANS)}
    # in a run the radio and the cell size are the scenario's, unless the [allocator] section sets its own
    scenario_fields = {"comm_range": "radio.comm_range", "path_loss": "radio.path_loss", "waf": "radio.waf",
                       "max_walls": "radio.max_walls", "cell_size": "cell_size"}
    alpha: float
    beta: float
    lam: float
    comm_range: float
    cell_size: float
    path_loss: float
    waf: float
    max_walls: int
    unknown_walls: bool
    position: str
    predict: str
    replan: str

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        self.radio = RadioConfig(comm_range=self.comm_range, path_loss=self.path_loss, waf=self.waf,
                                 max_walls=self.max_walls)

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        if not problem.clusters:
            return Allocation.none()
        decide = problem
        if self.replan == "observed":
            kept, decide = observed_choice(problem)
            if kept is not None:
                return Allocation.assigned(problem, kept)
        j = choose(decide, self.alpha, self.beta, self.lam, self.cell_size, self.radio, self.position,
                   self.predict, self.unknown_walls)
        return Allocation.none() if j is None else Allocation.assigned(problem, j)
