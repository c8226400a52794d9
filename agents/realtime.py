"""A robot in real-time mode (``fleet run --realtime HZ``; docs/guides/realtime.md): it keeps executing its
last plan while it decides.

The world ticks on the wall clock and does not wait (:mod:`world.realtime`). The robot's decision — the
brain's whole step: merging its map, frontier clusters, the allocator, navigation — runs in a worker thread,
one decision at a time, so the node shell stays free on its event loop. On each observation the shell first
sends, at once, a step along the robot's last plan (:class:`agents.brain.Plan`: the next cell down the
wavefront of the last decided target, from the cell this observation gives), or a stay while a decision runs
and the robot has no plan yet (its first ticks). These commands carry the status ``STALE`` and are counted
(``plan_steps``, ``waits``). Then:

- no decision running: a decision starts on this observation, with every radio message received since the
  last one, after merging the observations that came while the last one ran (:meth:`Brain.absorb`);
- a decision running: the observation is kept for the next decision's map.

When a decision ends, its command — stamped with the tick of the observation it started from — and its radio
bundle go out at once. The world applies the last command it received from the robot in a tick: a decision
that ends within its tick overrides that tick's plan step; one that ends later is late, and the world applies
it at its next tick (the plan step of that tick, sent earlier, is overridden) and counts it. So an allocator
slower than 1/HZ acts on stale plans, and its late moves, computed for a cell the robot has since left, may go
nowhere useful (into a wall, which the world refuses, or away from the target): the failure mode is the real
one, not hidden. A decision that ends starts no other at once; the next starts on the next observation (at
most one tick later).

Only the worker touches the brain while a decision runs; the shell reads the plan the last decision left (a
frozen snapshot) and draws sequence numbers under the brain's lock. :class:`Timing` is the pure bookkeeping.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from fleet_emu.core.grid import STAY, Cell
from fleet_emu.core.messages import STALE, Command

if TYPE_CHECKING:
    from fleet_emu.agents.brain import Plan

PERCENTILES = (50, 90, 99)


def percentiles(ms: list[float]) -> dict[str, float]:
    """p50, p90, p99, max and mean of ``ms`` (all 0 when empty), rounded to 0.1 µs."""
    a = np.asarray(ms if ms else [0.0], dtype=float)
    out = {f"p{q}": float(np.percentile(a, q)) for q in PERCENTILES}
    out |= {"max": float(a.max()), "mean": float(a.mean())}
    return {k: round(v, 4) for k, v in out.items()}


@dataclasses.dataclass
class Timing:
    """A robot's real-time counts: decisions and their wall times, steps along the last plan, waits."""

    decisions: int = 0
    plan_steps: int = 0
    waits: int = 0
    decision_ms: list[float] = dataclasses.field(default_factory=list)

    def stale_command(self, robot: str, tick: int, seq: int, cell: Cell, plan: Plan | None) -> Command:
        """The command for ``tick`` while a decision runs: a step of ``plan`` from ``cell``, or a stay
        without one."""
        if plan is None:
            self.waits += 1
            return Command(src=robot, tick=tick, seq=seq, move=STAY, status=STALE)
        self.plan_steps += 1
        return Command(src=robot, tick=tick, seq=seq, move=plan.step(cell), target=plan.target, status=STALE)

    def decided(self, wall_ms: float) -> None:
        self.decisions += 1
        self.decision_ms.append(wall_ms)
