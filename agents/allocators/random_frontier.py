"""A random frontier: the baseline a learned or coordinated allocator should beat, not any paper's method.

Each robot draws one of the frontier clusters it can reach, uniformly, from its allocator's seeded generator
(:meth:`Allocator.reset`), and keeps it until it has observed it or can no longer step toward it, by MinPos's
``replan="observed"`` rule (:func:`~fleet_emu.agents.allocators.minpos.observed_choice`): a robot that drew
afresh every tick would turn back and forth between targets and explore almost nothing, which would make the
baseline a straw man. The draw uses only the robot's own generator, so a seed reproduces the run in every engine.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from fleet_emu.agents.allocators.interface import Allocation, Allocator, Problem
from fleet_emu.agents.allocators.minpos import observed_choice
from fleet_emu.core.messages import RadioMsg


class RandomFrontier(Allocator, plugin_name="random"):
    DESCRIPTION = "each robot draws a reachable frontier at random and keeps it until it is seen (a baseline)"

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        if not problem.clusters:
            return Allocation.none()
        kept, decide = observed_choice(problem)
        if kept is not None:
            return Allocation.assigned(problem, kept)
        reach = np.flatnonzero(np.isfinite(decide.costs[decide.index]))
        if not len(reach):
            return Allocation.none()
        return Allocation.assigned(problem, int(reach[self.rng.integers(len(reach))]))
