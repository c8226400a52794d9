"""A teammate in the way: when an allocator that commits to a target should give it up.

An allocator that keeps its target (``trade``'s tasks, held until the task's frontier is gone) can lock: two
robots meet head-on in a one-cell door, each stepping down its own wavefront onto the other, and the world
refuses both moves. The brain's unsticking (a random free step after ``BrainConfig.unstick_after`` blocked
ticks) moves a robot aside and back, but both keep their targets and meet again, for as long as the targets
are kept (on the autolab map, until ``trade``'s ``task_timeout``, 300 ticks).

The robot sees the lock as MinPos's ``replan="observed"`` does (:func:`~.minpos.open_clusters`): its target's
cluster is *closed* when it does not stand on it and every 4-neighbour one step nearer on the cluster's
wavefront holds a teammate heard at most a tick ago (where its beacon says it is now). :class:`Blockage`
counts the closed ticks since the robot last came nearer its target than where the first of them found it: a
sidestep and the step back (unsticking) are no progress, so they do not end the count, but getting past the
teammate does. After ``after`` such ticks the allocator gives the target up and decides afresh among the
clusters it can step toward (:func:`open_costs`).

``after`` is chosen once (the papers give none): 4, one more than the closed ticks of one unsticking cycle
in a head-on (three: the refused step, a tick waiting, the tick the sidestep is decided; only from the side
cell is the way open), so the brain's own remedy gets one try before the target is given up, and a teammate
that crosses the robot's way (closed for a tick or two, then the robot moves on) never counts to it. A
teammate not heard for more than a tick (a dead robot, out of radio range) is not seen as in the way: it never
closes a cluster.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from fleet_emu.agents.allocators.interface import Problem
from fleet_emu.agents.allocators.minpos import open_clusters, restricted

#: Closed ticks without progress after which a target is given up (module docstring).
BLOCKED_AFTER = 4


@dataclasses.dataclass
class Blockage:
    """The closed ticks since the robot last came nearer its target (``count``) and its distance to the target
    when the first of them came (``mark``, -1 when none)."""

    count: int = 0
    mark: int = -1

    def clear(self) -> None:
        """A new target: nothing counted."""
        self.count, self.mark = 0, -1

    def held(self, problem: Problem, j: int, after: int = BLOCKED_AFTER) -> bool:
        """Count this tick toward cluster ``j`` of ``problem`` (the robot's target, which it reaches); True once
        the robot has been held ``after`` closed ticks without coming nearer the target than where the first
        found it (never when ``after`` is 0)."""
        if after <= 0:
            return False
        d = int(problem.wavefronts[j][problem.poses[problem.me]])
        if d < self.mark:  # nearer than where it was first held: on its way again
            self.clear()
        if not open_clusters(problem)[j]:
            if self.mark < 0:
                self.mark = d
            self.count += 1
        return self.count >= after


def open_costs(problem: Problem) -> np.ndarray:
    """The deciding robot's costs (wavefront distances, ``inf`` unreachable) with the clusters it cannot step
    toward now set to ``inf`` (:func:`~.minpos.restricted`: unchanged when it can step toward none)."""
    return restricted(problem, open_clusters(problem)).costs[problem.index]
