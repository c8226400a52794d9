"""The recording clock: the log and publish time of tick ``t`` is the run's real UTC start plus ``t`` tick periods,
so a viewer shows a run on the day it ran and one tick as the time it stands for.

The tick period is one parameter, passed in by the engine that runs the scenario (default
:data:`DEFAULT_TICK_S`). The start is kept in the recording's ``scenario`` metadata (``start_ns``, ``tick_s``):
two recordings of one seed differ only by that offset.
"""

from __future__ import annotations

import dataclasses
import time

#: Seconds of simulated time per tick, where the scenario states none.
DEFAULT_TICK_S = 1.0
U64 = 2**64 - 1  # MCAP times are unsigned 64-bit nanoseconds


@dataclasses.dataclass(frozen=True)
class RunClock:
    """Log time of a tick: ``start_ns + tick * tick_s`` in nanoseconds since the Unix epoch."""

    start_ns: int
    tick_s: float = DEFAULT_TICK_S

    @classmethod
    def now(cls, tick_s: float = DEFAULT_TICK_S) -> RunClock:
        """A clock starting at this moment (whole milliseconds, so the start reads cleanly)."""
        return cls(time.time_ns() // 1_000_000 * 1_000_000, tick_s)

    @property
    def tick_ns(self) -> int:
        return max(1, round(self.tick_s * 1e9))

    @property
    def max_tick(self) -> int:
        """The largest tick a log time can hold."""
        return (U64 - self.start_ns) // self.tick_ns

    def ns(self, tick: int) -> int:
        return self.start_ns + tick * self.tick_ns

    def stamp(self, tick: int) -> dict[str, int]:
        """A Foxglove ``Time`` (``{sec, nsec}``) of the tick."""
        ns = self.ns(tick)
        return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}

    def metadata(self) -> dict[str, str]:
        """What the recording's ``scenario`` metadata keeps of the clock."""
        return {"start_ns": str(self.start_ns), "tick_s": repr(float(self.tick_s))}


#: A clock from the epoch: for tests and folds that need no real start.
EPOCH = RunClock(0)
