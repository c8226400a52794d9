"""SIGINT and SIGTERM as a request to stop, never an exception in the middle of a write.

The CLI installs :class:`Interrupts` before it imports anything heavy. The first signal sets ``requested``:
the runner sees it within a fraction of a second, stops the fleet, and goes through its normal teardown, so
``result.json`` and the MCAP footer are always written. A second signal sets ``hurry``: the runner skips the
grace period it gives the processes to report, and kills them at once; the files are still written. The exit
code is 128 + the first signal's number (130 for SIGINT, 143 for SIGTERM).
"""

from __future__ import annotations

import contextlib
import signal
import sys
import threading
from collections.abc import Iterator
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


@contextlib.contextmanager
def sigterm_unwinds() -> Iterator[None]:
    """SIGTERM ends a command that writes files (a map or radio fetch, an export) as Ctrl-C does, by an exception
    (exit 143), so that its cleanup removes what it wrote; by default it would end the process on the spot.
    (On the main thread only: signals go there.)"""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def stop(_signum: int, _frame: FrameType | None) -> None:
        print("fleet: terminated", file=sys.stderr)
        raise SystemExit(143)

    previous = signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def signal_name(interrupts: Interrupts | None, interrupted: bool) -> str | None:
    """``result.json``'s ``signal``: the first signal the CLI's handlers got, or, without them (a Python caller's
    Ctrl-C, KeyboardInterrupt), ``SIGINT`` when that interrupted the run."""
    return interrupts.name if interrupts is not None else ("SIGINT" if interrupted else None)
