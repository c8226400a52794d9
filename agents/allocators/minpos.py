"""MinPos, Bautin et al. 2012, section 4.3, Algorithm 3, with the section's two computation savings.

The position of robot i toward frontier j is ``P_ij = |{k != i : C_kj < C_ij}|``, the number of teammates
closer to it; the robot takes ``argmin_j P_ij``, and "in case of equality [chooses] the minimum cost among
min P_ij" (then the lowest cluster index). Frontiers the robot cannot reach are never chosen. O(nm).

``wavefront`` selects how the costs are obtained; every variant returns the same cluster:

- ``"full"``: the plain algorithm on the full cost matrix (one complete BFS per cluster).
- ``"stop"``: "Wavefront propagation stopping": each cluster's BFS stops when it reaches the deciding robot.
  Every cell nearer than the robot is then labelled, so every teammate with ``C_kj < C_ij`` is counted and
  the ones not reached are farther: ``P_ij`` and the robot's own cost (the tie-break) are exact.
- ``"parallel"``: "Parallel computation of wavefronts": all BFS advance together, a wavefront pauses on
  each robot it meets, and the first to reach the deciding robot wins
  (:func:`core.kernels.minpos_parallel`, which orders wavefronts by (robots met, distance, cluster index)
  and therefore breaks ties exactly as Algorithm 3 does). The cost matrix is never built.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from fleet_emu.agents.allocators.base import Allocation, Allocator, Problem
from fleet_emu.agents.allocators.params import Param
from fleet_emu.core.grid import flat
from fleet_emu.core.kernels import minpos_parallel, wavefront
from fleet_emu.core.messages import RadioMsg

WAVEFRONTS = ("full", "stop", "parallel")


def positions(costs: np.ndarray, i: int) -> np.ndarray:
    """``P_ij`` for every frontier j of the cost matrix (robots x frontiers)."""
    closer = costs < costs[i][None, :]
    closer[i] = False
    return closer.sum(axis=0)


def minpos_choice(costs: np.ndarray, i: int) -> int | None:
    """Algorithm 3 on a cost matrix: the frontier of least position, then least cost; None if none reachable."""
    own = costs[i]
    reachable = np.isfinite(own)
    if not reachable.any():
        return None
    pos = positions(costs, i).astype(float)
    pos[~reachable] = np.inf
    best = pos.min()
    candidates = np.flatnonzero(pos == best)
    return int(candidates[np.argmin(own[candidates])])


def stopped_costs(problem: Problem) -> np.ndarray:
    """The cost matrix as far as wavefronts stopped on the deciding robot compute it: the deciding robot's
    row is exact; a teammate's entry is exact where it is smaller than the deciding robot's, else ``inf`` or
    not smaller (enough for :func:`positions`)."""
    shape = problem.belief.shape
    me = flat(shape, problem.poses[problem.me])
    cells = np.array([flat(shape, c) for c in problem.poses.values()], dtype=np.int64)
    costs = np.full((len(cells), len(problem.clusters)), np.inf)
    for j, cluster in enumerate(problem.clusters):
        d = wavefront(problem.passable, cluster.cells, me).ravel()[cells]
        costs[:, j] = np.where(d >= 0, d, np.inf)
    return costs


def parallel_choice(problem: Problem) -> int | None:
    """The cluster the parallel wavefronts of :func:`core.kernels.minpos_parallel` select, None if none."""
    shape = problem.belief.shape
    clusters = problem.clusters
    sources = np.concatenate([c.cells for c in clusters]).astype(np.int64) if clusters else np.empty(0, np.int64)
    offsets = np.zeros(len(clusters) + 1, dtype=np.int64)
    offsets[1:] = np.cumsum([c.size for c in clusters])
    me = flat(shape, problem.poses[problem.me])
    others = np.array([flat(shape, c) for r, c in problem.poses.items() if r != problem.me], dtype=np.int64)
    j, _, _ = minpos_parallel(problem.passable, sources, offsets, me, others)
    return None if j < 0 else int(j)


class MinPos(Allocator, plugin_name="minpos"):
    """``wavefront``: ``"full"`` (Algorithm 3 on the full cost matrix), ``"stop"`` or ``"parallel"``."""

    parameters = {"wavefront": Param("full", choices=WAVEFRONTS)}
    wavefront: str

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        if self.wavefront == "parallel":  # compile or load the kernel now, not in the first decision
            one = np.zeros(1, dtype=np.int64)
            minpos_parallel(np.ones((1, 1), dtype=np.bool_), one, np.array([0, 1], dtype=np.int64), 0, one[:0])

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        if not problem.clusters:
            return Allocation.none()
        if self.wavefront == "parallel":
            j = parallel_choice(problem)
        elif self.wavefront == "stop":
            j = minpos_choice(stopped_costs(problem), problem.index)
        else:
            j = minpos_choice(problem.costs, problem.index)
        return Allocation.none() if j is None else Allocation.assigned(problem, j)
