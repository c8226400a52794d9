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
  (:func:`core.minpos_kernels.minpos_parallel`, which orders wavefronts by (robots met, distance, cluster index)
  and therefore breaks ties exactly as Algorithm 3 does). The cost matrix is never built.

``replan`` selects when the assignment is recomputed. Section 2: "optimization has to be reevaluated at each
time step or at least every time the robot observes the targeted frontier".

- ``"tick"`` (default): Algorithm 3 at every decision, the first option.
- ``"observed"``: the second option; the robot keeps its target until it has observed it. On this grid the
  targeted frontier is the target cell of the robot's previous decision (``Problem.previous_target``, which
  the Brain passes). It is *observed* once that cell is no longer a frontier cell of the robot's belief (known
  free with an unknown 4-neighbour): its unknown neighbours have been sensed, by the robot or by a teammate
  whose map delta arrived, so that no cluster holds it any more. Until then the robot is assigned the cluster
  that holds the cell now (:func:`kept_cluster`; clusters are formed afresh every tick, so that cluster's
  target may be another of its cells, and it is the one kept next), unless the robot cannot reach it: then, as
  when it was observed, or when there was no previous target (the first decision, or one that found nothing),
  the robot decides afresh.

  *Reachable* with ``"observed"`` means the robot can take a step toward the cluster now: it stands on it, or
  one of its 4-neighbours one step nearer on the cluster's wavefront (over known-free cells) is not a
  teammate's cell (:func:`open_clusters`; teammates at their cells in ``Problem.poses``, if heard at most a tick
  ago: section 4's configuration space, which enlarges "obstacles (including other robots)", for the path's
  first step). A kept target that the robot can no longer step toward is given up, and the fresh decision
  ranks only the clusters it can step toward (Algorithm 3 on its own costs, ``inf`` elsewhere; all of them
  when it can step toward none). Costs and positions are still wavefront distances on the belief.
  Reachability on the belief alone was tried first and is not kept: two robots committed to targets behind
  each other (as eq. 9 of ``connectivity`` with a heavy beta sends them) then met head-on in a passage and
  waited there until the run stalled, each stepping down its wavefront onto the other.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import numpy as np

from fleet_emu.agents.allocators.interface import Allocation, Allocator, Problem
from fleet_emu.agents.allocators.params import Param
from fleet_emu.core.grid import MOVES, Cell, flat
from fleet_emu.core.kernels import wavefront
from fleet_emu.core.messages import RadioMsg
from fleet_emu.core.minpos_kernels import minpos_parallel, minpos_parallel_into, seen_words

WAVEFRONTS = ("full", "stop", "parallel")
REPLANS = ("tick", "observed")


def open_clusters(problem: Problem) -> np.ndarray:
    """Per cluster, whether the robot can step toward it now (module docstring): it reaches it on its belief
    and stands on it or has a 4-neighbour one step nearer that no teammate holds (a teammate absent from
    ``Problem.heard`` counts as heard now; one not heard for more than a tick does not block)."""
    me = problem.poses[problem.me]
    held = {cell for robot, cell in problem.poses.items()
            if robot != problem.me and problem.heard.get(robot, problem.tick) >= problem.tick - 1}
    rows, cols = problem.belief.shape
    steps = [(me[0] + dr, me[1] + dc) for dr, dc in MOVES if (dr, dc) != (0, 0)]
    steps = [c for c in steps if 0 <= c[0] < rows and 0 <= c[1] < cols and c not in held]
    out = np.zeros(len(problem.clusters), dtype=bool)
    for j, dist in enumerate(problem.wavefronts):
        d = dist[me]
        out[j] = d == 0 or (d > 0 and any(dist[c] == d - 1 for c in steps))
    return out


def kept_cluster(problem: Problem, reach: np.ndarray) -> int | None:
    """With ``replan="observed"``: the cluster that holds the previous target cell while that cell is still a
    frontier cell and the cluster is in ``reach``; None when there was no previous target, or it has been
    observed (no cluster holds it), or the robot cannot reach it (module docstring)."""
    target: Cell | None = problem.previous_target
    shape = problem.belief.shape
    if target is None or not (0 <= target[0] < shape[0] and 0 <= target[1] < shape[1]):
        return None
    cell = flat(shape, target)
    for j, cluster in enumerate(problem.clusters):
        k = int(np.searchsorted(cluster.cells, cell))
        if k < cluster.size and cluster.cells[k] == cell:  # a frontier cell still: not yet observed
            return j if reach[j] else None
    return None


def restricted(problem: Problem, reach: np.ndarray) -> Problem:
    """The problem with the deciding robot's costs ``inf`` outside ``reach`` (unchanged when ``reach`` holds
    every cluster the belief lets it reach, or none)."""
    own = np.isfinite(problem.costs[problem.index])
    if not (own & reach).any() or not (own & ~reach).any():
        return problem
    costs = problem.costs.copy()
    costs[problem.index, ~reach] = np.inf
    q = dataclasses.replace(problem)
    q.costs = costs  # the cached property, preset
    return q


def observed_choice(problem: Problem) -> tuple[int | None, Problem]:
    """``replan="observed"``: the kept cluster if any (first item), else the problem to decide afresh on."""
    reach = open_clusters(problem)
    kept = kept_cluster(problem, reach)
    return (kept, problem) if kept is not None else (None, restricted(problem, reach))


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


def parallel_choice(problem: Problem, seen: np.ndarray | None = None) -> int | None:
    """The cluster the parallel wavefronts of :func:`core.minpos_kernels.minpos_parallel` select, None if none;
    ``seen``: a zeroed bitset of :func:`core.minpos_kernels.seen_words` words or more to work in (and leave zeroed)."""
    shape = problem.belief.shape
    clusters = problem.clusters
    sources = np.concatenate([c.cells for c in clusters]).astype(np.int64) if clusters else np.empty(0, np.int64)
    offsets = np.zeros(len(clusters) + 1, dtype=np.int64)
    offsets[1:] = np.cumsum([c.size for c in clusters])
    me = flat(shape, problem.poses[problem.me])
    others = np.array([flat(shape, c) for r, c in problem.poses.items() if r != problem.me], dtype=np.int64)
    if seen is None or len(seen) < seen_words(problem.belief.size, len(clusters)):
        j, _, _ = minpos_parallel(problem.passable, sources, offsets, me, others)
    else:
        j, _, _ = minpos_parallel_into(problem.passable, sources, offsets, me, others, seen)
    return None if j < 0 else int(j)


class MinPos(Allocator, plugin_name="minpos"):
    """``wavefront``: ``"full"`` (Algorithm 3 on the full cost matrix), ``"stop"`` or ``"parallel"``;
    ``replan``: ``"tick"`` or ``"observed"`` (module docstring)."""

    DESCRIPTION = "MinPos (Bautin et al. 2012): the frontier with the fewest teammates closer to it, then the nearest"

    parameters = {"wavefront": Param("full", choices=WAVEFRONTS), "replan": Param("tick", choices=REPLANS)}
    wavefront: str
    replan: str

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)
        self._bits = np.zeros(0, dtype=np.uint64)  # the parallel wavefronts' bitset, kept zeroed across calls
        if self.wavefront == "parallel":  # compile or load the kernel now, not in the first decision
            one = np.zeros(1, dtype=np.int64)
            minpos_parallel_into(np.ones((1, 1), dtype=np.bool_), one, np.array([0, 1], dtype=np.int64), 0, one[:0],
                                 np.zeros(1, dtype=np.uint64))

    def _seen(self, problem: Problem) -> np.ndarray:
        """The bitset :func:`parallel_choice` works in, grown (by half again) when the clusters outgrow it."""
        need = seen_words(problem.belief.size, len(problem.clusters))
        if len(self._bits) < need:
            self._bits = np.zeros(need + need // 2, dtype=np.uint64)
        return self._bits

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        if not problem.clusters:
            return Allocation.none()
        if self.replan == "observed":
            kept, decide = observed_choice(problem)
            if kept is not None:
                return Allocation.assigned(problem, kept)
            if decide is not problem:  # a teammate cuts some clusters off: Algorithm 3 on the masked costs
                j = minpos_choice(decide.costs, problem.index)
                return Allocation.none() if j is None else Allocation.assigned(problem, j)
        if self.wavefront == "parallel":
            j = parallel_choice(problem, self._seen(problem))
        elif self.wavefront == "stop":
            j = minpos_choice(stopped_costs(problem), problem.index)
        else:
            j = minpos_choice(problem.costs, problem.index)
        return Allocation.none() if j is None else Allocation.assigned(problem, j)
