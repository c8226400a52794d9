"""The errors a user can meet, under one root (:class:`FleetError`), each with a one-line message.

The CLI catches :class:`FleetError` once: bad input (config, map, report, a recording) exits 2 and a run that
could not go on exits 1. A malformed bus message raises :class:`DecodeError` inside a node, which counts and
drops it; it is never fatal.
"""

from __future__ import annotations


class FleetError(Exception):
    """Root of every error of this package; ``str()`` is one line for the user."""

    exit_code = 2

    def __init__(self, message: str = "") -> None:
        super().__init__(" ".join(str(message).split()))


class ConfigError(FleetError, ValueError):
    """Bad user input in a scenario, a flag or an allocator's parameters."""


class MapError(FleetError, ValueError):
    """A map that cannot be built or read."""


class DecodeError(FleetError, ValueError):
    """A message that does not validate; the receiver counts and drops it."""


class ReportError(FleetError):
    """A recording or run directory that cannot be read (missing, not MCAP, from a newer version)."""


class RunError(FleetError, RuntimeError):
    """The run could not go on (a process died, start-up timed out)."""

    exit_code = 1
