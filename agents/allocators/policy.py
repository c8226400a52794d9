"""A learned allocator: a linear score over the robot's K nearest frontier targets, read from a weights file.

The choice a reinforcement-learning policy makes in ``fleet_emu.rl`` (pick one of the robot's K best frontier
targets, as Explore-Bench and MAexp do) is made here from the same features, computed from the same
:class:`Problem`, so a policy trained in the memory engine runs unchanged in every robot process. The features
of a candidate cluster *j* (:data:`FEATURES`), all from what the robot knows:

- ``distance``: its wavefront cost from the robot, in units of :data:`DIST_SCALE` cells;
- ``size``: its frontier cells, in units of :data:`SIZE_SCALE`;
- ``closer``: how many teammates the robot believes are closer to it (their last known cells' costs);
- ``age``: the mean age of those beliefs (ticks since each closer teammate was heard), in units of
  :data:`AGE_SCALE` ticks (0 when none is closer);
- ``previous``: 1 when its target is the robot's previous decision's.

The candidates are the reachable clusters in order of ``distance`` (ties by cluster index), the first K. The
policy scores each ``w @ features`` and goes to the best (the first on a tie); without a file (``path=""``) the
weights are :data:`DEFAULT_WEIGHTS`, -1 on distance: the nearest frontier, exactly ``nearest``'s choice. The
scales are chosen once, so that each feature is of order one on the built-in maps.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from fleet_emu.agents.allocators.base import Allocation, Allocator, Problem
from fleet_emu.agents.allocators.params import Param
from fleet_emu.core.messages import RadioMsg

FEATURES = ("distance", "size", "closer", "age", "previous")
DIST_SCALE = 32.0
SIZE_SCALE = 16.0
AGE_SCALE = 10.0
DEFAULT_K = 8
DEFAULT_WEIGHTS = (-1.0, 0.0, 0.0, 0.0, 0.0)


def candidates(problem: Problem, k: int) -> list[int]:
    """The robot's ``k`` nearest reachable clusters (indices into ``problem.clusters``), nearest first."""
    if not problem.clusters:
        return []
    mine = problem.costs[problem.index]
    order = sorted((d, j) for j, d in enumerate(mine) if np.isfinite(d))
    return [j for _, j in order[:k]]


def target_features(problem: Problem, cands: Sequence[int]) -> np.ndarray:
    """The :data:`FEATURES` of each candidate, a ``(len(cands), len(FEATURES))`` float32 array."""
    out = np.zeros((len(cands), len(FEATURES)), dtype=np.float32)
    if not cands:
        return out
    costs, me = problem.costs, problem.index
    robots = problem.robots
    ages = np.array([problem.tick - problem.heard.get(r, problem.tick) for r in robots], dtype=np.float64)
    for row, j in enumerate(cands):
        mine = costs[me, j]
        closer = [i for i in range(len(robots)) if i != me and costs[i, j] < mine]
        out[row] = (mine / DIST_SCALE, problem.clusters[j].size / SIZE_SCALE, len(closer),
                    float(ages[closer].mean()) / AGE_SCALE if closer else 0.0,
                    float(problem.clusters[j].target == problem.previous_target))
    return out


def choose(weights: np.ndarray, feats: np.ndarray) -> int | None:
    """The row of the best-scored candidate (the first on a tie), None without one."""
    return int(np.argmax(feats @ weights)) if len(feats) else None


@functools.lru_cache(maxsize=16)
def load_policy(path: str) -> tuple[np.ndarray, int]:
    """The weights and K of a policy file (``.npz`` with ``weights``, ``k`` and ``features``); ValueError of
    one line when it cannot be read or was saved for other features."""
    try:
        with np.load(Path(path)) as data:
            weights = np.asarray(data["weights"], dtype=np.float64)
            k = int(data["k"])
            names = tuple(str(n) for n in data["features"])
    except (OSError, KeyError, ValueError) as exc:
        raise ValueError(f"cannot read the policy file {path!r}: {exc}") from None
    if names != FEATURES or weights.shape != (len(FEATURES),) or k < 1 or not np.isfinite(weights).all():
        raise ValueError(f"policy file {path!r} is not a linear policy over {', '.join(FEATURES)}")
    return weights, k


def save_policy(path: str | Path, weights: np.ndarray, k: int = DEFAULT_K) -> None:
    """Write a policy file :func:`load_policy` reads."""
    np.savez(Path(path), weights=np.asarray(weights, dtype=np.float64), k=np.int64(k), features=np.array(FEATURES))


class Policy(Allocator, plugin_name="policy"):
    """A learned linear policy over the K nearest frontier targets (fleet_emu.rl trains one)."""

    DESCRIPTION = "a learned linear policy over the robot's K nearest frontier targets, from a weights file (path)"
    parameters = {"path": Param("")}
    path: str

    def __init__(self, **params: object) -> None:
        super().__init__(**params)
        if self.path:
            self.weights, self.k = load_policy(str(self.path))
        else:
            self.weights, self.k = np.array(DEFAULT_WEIGHTS), DEFAULT_K

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        cands = candidates(problem, self.k)
        row = choose(self.weights, target_features(problem, cands))
        return Allocation.none() if row is None else Allocation.assigned(problem, cands[row])
