"""What a *fold* is: an object that takes one run's bus traffic one message at a time, in the order the bus
delivered it, and keeps running state from it, with no I/O, no clock and no Zenoh. The same fold therefore gives
the same answer live in the launcher, over a recording in ``fleet report`` and in the memory engine.

A fold has one or both of two entry points, each with one signature:

- ``feed(key, data, time_ns=None)``: one *bus sample* as the recorder stores it (the key expression, the msgpack
  bytes, and when it was received or published, in nanoseconds, when known). A fold fed samples decodes them
  itself and drops what does not decode or whose sender does not match its key (:class:`SampleFold`:
  ``recording.monitor.Monitor``, ``recording.metrics.RunMetrics``, ``recording.foxglove_writer.FoxgloveWriter``).
- ``fold(msg)``: one *message*, already decoded and checked against its key (:class:`MessageFold`:
  ``Monitor.fold``, ``recording.foxglove.FoxgloveFold``, ``ros2.fold.Ros2Fold``,
  ``recording.relaystats.RelayStats``, ``recording.first_seen.FirstSeen``). Its return value is what the fold
  derives from that message (Foxglove's or ROS 2's messages to write), or None when it derives nothing.

Both are protocols (structural): a fold declares no base class, and may take further optional parameters after
these (``FoxgloveWriter.feed``'s ``msg``: the message when the caller has decoded it already). Every fold names
the parameters as here (``tests/recording/test_folds.py`` checks it).
"""

from __future__ import annotations

from typing import Protocol, TypeVar, runtime_checkable

from fleet_emu.core.codec import Message

R_co = TypeVar("R_co", covariant=True)


@runtime_checkable
class SampleFold(Protocol[R_co]):
    """A fold fed raw bus samples (module docstring)."""

    def feed(self, key: str, data: bytes, time_ns: int | None = None) -> R_co:
        """Decode, check and fold one sample received on ``key`` (at ``time_ns``, when known)."""
        ...


@runtime_checkable
class MessageFold(Protocol[R_co]):
    """A fold fed decoded, checked messages (module docstring)."""

    def fold(self, msg: Message) -> R_co:
        """Fold one message; what it derives from it."""
        ...
