"""A wall-clock cap on ticks per second (``fleet run --live-hz``), shared by the memory engine's loop and the
lockstep world: it only delays, never decides, so a paced run gives the same result."""

from __future__ import annotations

import time


class Pacer:
    """At most ``hz`` ticks per wall-clock second (``hz`` None or 0: no cap), none before ``first`` (a live run's
    viewers' moment to subscribe, launch/live.py). Before each tick, :meth:`wait`
    sleeps (or an asyncio loop awaits :meth:`delay`'s seconds); a late tick is not made up by a burst."""

    def __init__(self, hz: float | None, first: float = 0.0) -> None:
        self.period = 1.0 / hz if hz else 0.0
        self.next = first  # ``first``: the monotonic time before which the first tick must not come

    def delay(self) -> float:
        """The seconds to wait before the next tick (0 without a cap and once ``first`` is past), the one after
        it planned from then."""
        now = time.monotonic()
        if not self.period:
            return max(0.0, self.next - now)
        wait = max(0.0, self.next - now)
        self.next = max(now, self.next) + self.period
        return wait

    def wait(self) -> None:
        """:meth:`delay`, slept."""
        if (seconds := self.delay()) > 0:
            time.sleep(seconds)
