"""An allocator that talks over the radio: each robot claims the frontier it heads for, and leaves a frontier
that a nearer teammate has claimed.

Every tick a robot broadcasts a :class:`Claim` (its target cell and its wavefront cost to it). It takes the
nearest reachable frontier cluster that no teammate claimed more cheaply within the last ``forget`` ticks (a
tie goes to the lower robot id); when every reachable cluster is claimed, the nearest. Claims cross the same
lossy radio as everything else: a lost claim only means two robots may head for the same frontier a while.

This file is the worked example of the documentation ("Writing an allocator"); the test suite runs it on the
memory engine (``tests/test_docs.py`` runs every example of the pages).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from fleet_emu.agents.allocators import Allocation, Allocator, Param, Problem, robot_order
from fleet_emu.core.codec import Context, Payload
from fleet_emu.core.errors import DecodeError
from fleet_emu.core.grid import Cell
from fleet_emu.core.messages import RadioMsg, check_cell


class Claim(Payload, kw_only=True, frozen=True):
    """A robot's claim on a frontier: the target cell it heads for and its wavefront cost to it (cells).

    ``KIND`` names the payload on the radio: it must be unique among every payload kind (the brain's ``pose``,
    ``map`` and ``mapfill``, the built-in allocators' kinds). ``validate`` runs on every receiver before the
    allocator sees the message: a claim that does not validate is counted and dropped."""

    KIND = "claim"
    target: Cell
    cost: int

    def validate(self, ctx: Context | None) -> None:
        check_cell(self.target, ctx.shape if ctx is not None else None, "claim")
        if self.cost < 0:
            raise DecodeError(f"claim: negative cost {self.cost}")


class Claims(Allocator, plugin_name="claims"):
    """Claims its frontier over the radio and leaves one that a nearer teammate claimed.

    ``forget``: ticks after which a teammate's claim no longer holds (it may have been lost, or the teammate may
    have gone)."""

    parameters = {"forget": Param(5, ge=1)}
    forget: int

    def __init__(self, **params: Any) -> None:
        super().__init__(**params)  # checks the parameters and sets them as attributes
        self.claims: dict[str, tuple[int, Claim]] = {}  # each teammate's newest claim, with the tick it was made

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self.claims = {}

    def allocate(self, problem: Problem, inbox: Sequence[RadioMsg] = ()) -> Allocation:
        for msg in inbox:  # the radio messages of this tick that the brain did not consume itself
            if isinstance(msg.body, Claim) and msg.origin != problem.me:
                self.claims[msg.origin] = (msg.tick, msg.body)
        me = problem.poses[problem.me]
        cost = {j: int(wf[me]) for j, wf in enumerate(problem.wavefronts) if wf[me] >= 0}
        if not cost:
            return Allocation.none()
        mine = robot_order(problem.me)
        taken = {claim.target: (claim.cost, robot_order(robot)) for robot, (tick, claim) in self.claims.items()
                 if problem.tick - tick <= self.forget}
        free = [j for j in cost if taken.get(problem.clusters[j].target, (np.inf, mine)) >= (cost[j], mine)]
        j = min(free or cost, key=lambda k: (cost[k], k))
        claim = Claim(target=problem.clusters[j].target, cost=cost[j])
        return Allocation.assigned(problem, j, outbox=(RadioMsg(claim),))  # dst "*": every robot in range
