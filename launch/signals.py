"""SIGINT and SIGTERM as a request to stop, never an exception in the middle of a write.

The CLI installs :class:`Interrupts` before it imports anything heavy. The first signal sets ``requested``:
the runner sees it within a fraction of a second, stops the fleet, and goes through its normal teardown, so
``result.json`` and the MCAP footer are always written. A second signal sets ``hurry``: the runner skips the
grace period it gives the processes to report, and kills them at once; the files are still written. The exit
code is 128 + the first signal's number (130 for SIGINT, 143 for SIGTERM).
"""

from __future__ import annotations

import signal
import threading
from types import FrameType
from typing import Any

HANDLED = (signal.SIGINT, signal.SIGTERM)


class Interrupts:
    """The signals a run received; install on the main thread."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self.count = 0
        self.requested = threading.Event()
        self.hurry = threading.Event()
        self._previous: dict[int, Any] = {}

    def install(self) -> Interrupts:
        for sig in HANDLED:
            self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def restore(self) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)
        self._previous.clear()

    def _handle(self, signum: int, _frame: FrameType | None) -> None:
        self.count += 1
        if self.signum is None:
            self.signum = signum
        self.requested.set()
        if self.count > 1:
            self.hurry.set()

    @property
    def name(self) -> str | None:
        """``SIGINT`` or ``SIGTERM`` (the first one received), or None."""
        return signal.Signals(self.signum).name if self.signum is not None else None

    @property
    def exit_code(self) -> int:
        return 128 + (self.signum or signal.SIGINT)
