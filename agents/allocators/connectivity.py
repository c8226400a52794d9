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
Algorithm 3 on ``-U``. With ``beta = 0`` (and ``alpha > 0``) this is exactly MinPos.

What the robot can know (DESIGN.md): the signal is predicted on its *belief* map from teammates' *last known*
poses. Walls are the cells the belief holds as occupied; unknown cells count as free by default (a robot cannot
know a wall it has not seen, and frontier targets border unknown space, so counting unknown runs as walls would
penalise every frontier alike); ``unknown_walls=True`` counts them as walls instead. Distances are clamped to one
cell: two robots never stand closer (one cell holds one robot), and the 1 mm clamp of ``signal_db`` would give a
teammate standing on a target a spurious +80 dB.

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

from fleet_emu.agents.allocators.base import Allocation, Allocator, Problem
from fleet_emu.agents.allocators.minpos import minpos_choice
from fleet_emu.agents.allocators.params import Param
from fleet_emu.core.grid import FREE, OCCUPIED, Cell
from fleet_emu.core.kernels import count_walls
from fleet_emu.core.messages import RadioMsg
from fleet_emu.core.radio import RadioConfig, signal_db


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
              unknown_walls: bool = False) -> np.ndarray:
    """Eq. 9 for every robot with a known pose (rows, in ``problem.robots`` order) and every task (columns);
    ``-inf`` where the robot cannot reach the task."""
    costs = problem.costs
    n, m = costs.shape
    reach = np.isfinite(costs)
    u = np.where(reach, -alpha * np.where(reach, costs, 0.0) * cell_size, -np.inf)
    if beta == 0.0 or lam == 0.0 or n < 2 or m == 0:
        return u
    walls = wall_mask(problem.belief, unknown_walls)
    cells = list(problem.poses.values())
    targets = [c.target for c in problem.clusters]
    dist = np.array([[math.hypot(t[0] - p[0], t[1] - p[1]) for t in targets] for p in cells])  # (n, m)
    sig = np.array([[signal_at(walls, t, p, cell_size, radio) for t in targets] for p in cells])
    weights = lam ** np.arange(1, n, dtype=float)  # lambda^p, p = 1 .. n-1
    for k in range(n):
        rows = np.array([r for r in range(n) if r != k])
        order = np.argsort(dist[rows], axis=0, kind="stable")  # per task: the others by increasing distance
        ranked = np.take_along_axis(sig[rows], order, axis=0)
        conn = weights @ ranked
        u[k] = np.where(reach[k], u[k] + beta * conn, -np.inf)
    return u


class Connectivity(Allocator, plugin_name="connectivity"):
    """Benavides et al. 2016: MinPos's criterion on the task utility of eq. 9 (see the module docstring)."""

    parameters = {"alpha": Param(0.6, ge=0), "beta": Param(0.4, ge=0), "lam": Param(0.5, ge=0, le=1),
                  "comm_range": Param(10.0, gt=0), "cell_size": Param(0.5, gt=0), "path_loss": Param(2.0, ge=0),
                  "waf": Param(3.1, ge=0), "max_walls": Param(4, ge=0), "unknown_walls": Param(False)}
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

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        self.radio = RadioConfig(comm_range=self.comm_range, path_loss=self.path_loss, waf=self.waf,
                                 max_walls=self.max_walls)

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        if not problem.clusters:
            return Allocation.none()
        u = utilities(problem, self.alpha, self.beta, self.lam, self.cell_size, self.radio, self.unknown_walls)
        j = minpos_choice(-u, problem.index)  # positions on -U: U_kj > U_ij counts as "closer"
        return Allocation.none() if j is None else Allocation.assigned(problem, j)
