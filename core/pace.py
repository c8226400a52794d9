"""A wall-clock cap on ticks per second (``fleet run --live-hz``), shared by the memory engine's loop and the
lockstep world: it only delays, never decides, so a paced run gives the same result."""

from __future__ import annotations

import time


class Pacer:
    """At most ``hz`` ticks per wall-clock second (``hz`` None or 0: no cap). Before each tick, :meth:`wait`
    sleeps (or an asyncio loop awaits :meth:`delay`'s seconds); a late tick is not made up by a burst."""

    def __init__(self, hz: float | None) -> None:
        self.period = 1.0 / hz if hz else 0.0
        self.next = 0.0

    def delay(self) -> float:
        """The seconds to wait before the next tick (0 without a cap), the one after it planned from then."""
        if not self.period:
            return 0.0
        now = time.monotonic()
        wait = max(0.0, self.next - now)
        self.next = max(now, self.next) + self.period
        return wait

    def wait(self) -> None:
        """:meth:`delay`, slept."""
        if (seconds := self.delay()) > 0:
            time.sleep(seconds)
