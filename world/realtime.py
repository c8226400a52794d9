"""The world's wall clock in real-time mode (``fleet run --realtime HZ``; docs/guides/realtime.md), pure:
every time is passed in, so these are unit-tested without a clock.

- :class:`TickClock`. Tick ``k`` is due at ``t0 + k / hz`` on a monotonic clock: the schedule is fixed in
  advance, so the time the world spends stepping does not add up into drift. When the world finishes
  publishing tick ``k`` only after tick ``k + 1`` was due (it could not keep the rate), that is an
  *overrun*: it is counted, and the schedule is re-anchored so that tick ``k + 1`` is due one period after
  now. The lost time is not caught up with back-to-back ticks, which would leave the robots no time at all.
- :class:`CommandLatch`. Between two ticks the world keeps, per robot, the last command received (in arrival
  order, whatever tick it is stamped with). A command stamped for an earlier tick than the one the world is
  collecting for arrived after its tick ended: it is *late*, and applied at the next tick like any other
  (unless the same robot sends another before that tick). Late commands are counted per robot in two kinds:
  decisions (``late``) and the steps along its last plan a robot sends while it decides (``late_steps``, status
  ``STALE``: late when the robot's process itself is slow to answer). A robot from which nothing came
  between two ticks stands still that tick (*missed*, counted). A command stamped for a tick the world has
  not published yet cannot be genuine and is refused.
"""

from __future__ import annotations

import dataclasses

from fleet_emu.core.grid import Cell


@dataclasses.dataclass
class TickClock:
    """The schedule of a run at ``hz`` ticks per second from ``t0`` (seconds on a monotonic clock)."""

    hz: float
    t0: float
    overruns: int = 0

    def due(self, k: int) -> float:
        """When tick ``k`` is due."""
        return self.t0 + k / self.hz

    def deadline(self, k: int, now: float) -> float:
        """Tick ``k`` was published at ``now``: until when the world collects commands for it (when tick
        ``k + 1`` is due). An overrun, counted and re-anchored, when that time has already passed."""
        due = self.due(k + 1)
        if now >= due:
            self.overruns += 1
            self.t0 = now + 1.0 / self.hz - (k + 1) / self.hz
            due = self.due(k + 1)
        return due


class CommandLatch:
    """The commands received between two ticks, with the late and missed counts per robot."""

    def __init__(self, robots: list[str], now: float) -> None:
        self.late = {r: 0 for r in robots}
        self.late_steps = {r: 0 for r in robots}
        self.missed = {r: 0 for r in robots}
        self.heard = {r: now for r in robots}
        self._moves: dict[str, Cell] = {}

    def receive(self, robot: str, stamped: int, move: Cell, tick: int, now: float, decided: bool = True) -> bool:
        """A command of ``robot`` stamped for tick ``stamped`` (``decided``: a decision's, not a step along the
        last plan), received at ``now`` while the world collects for ``tick``; False (refused) when it is
        stamped for a tick not yet published."""
        if stamped > tick:
            return False
        if stamped < tick:
            (self.late if decided else self.late_steps)[robot] += 1
        self._moves[robot] = move
        self.heard[robot] = now
        return True

    def take(self, live: list[str]) -> dict[str, Cell]:
        """The moves to apply at this tick (each live robot's last command; the robots without one stand
        still, counted as missed), and a fresh start for the next tick."""
        moves = {r: self._moves[r] for r in live if r in self._moves}
        for r in live:
            if r not in moves:
                self.missed[r] += 1
        self._moves.clear()
        return moves

    def silent(self, live: list[str], now: float, timeout: float) -> list[str]:
        """The live robots nothing came from for ``timeout`` seconds (the world fails them, as the lockstep
        barrier does)."""
        return [r for r in live if now - self.heard[r] > timeout]
