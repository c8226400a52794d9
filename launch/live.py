"""``fleet run --live [HOST:]PORT``: the run's live Foxglove server (:class:`~fleet_emu.recording.live.LiveServer`)
opened for the run's length in any engine, and the ``--live-hz`` pacer. A viewer never changes a run: the
server never waits for one, and the pacer only spaces a lockstep run's ticks on the wall clock.

The server advertises every channel of the run from its start, and the run's first tick comes no sooner than
:data:`GRACE` after the ``live:`` line (:attr:`LiveOptions.on_url`), whatever the viewers do: a viewer started
on that line has subscribed by then and sees the run from tick 0. (A fleet of processes takes longer than that
to start; the memory engine waits the rest.)"""

from __future__ import annotations

import contextlib
import dataclasses
import sys
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from fleet_emu.core.errors import ConfigError
from fleet_emu.recording.clock import RunClock

if TYPE_CHECKING:
    from fleet_emu.recording.live import LiveServer

#: Seconds from the ``live:`` line to the run's first tick, at least.
GRACE = 0.5


@dataclasses.dataclass(frozen=True)
class LiveOptions:
    """Where to serve (``port`` 0: one the OS picks), the tick cap (``hz``) and who is told the server's URL."""

    host: str
    port: int
    hz: float | None = None
    on_url: Callable[[str], None] | None = None


def open_live(stack: contextlib.ExitStack, opts: LiveOptions | None, clock: RunClock,
              robots: Sequence[str] = ()) -> LiveServer | None:
    """The live server of a run of ``robots`` (closed by ``stack``), every channel advertised from its start,
    its URL told to ``opts.on_url``; None without ``opts``. Its ``first_tick`` is the monotonic time before which
    the run's first tick must not come (:data:`GRACE` after the URL was told)."""
    if opts is None:
        return None
    from fleet_emu.recording.foxglove import live_topics
    from fleet_emu.recording.live import LiveServer

    try:
        server = LiveServer(opts.host, opts.port, clock, topics=live_topics(robots))
    except Exception as exc:  # the SDK's error: the port is taken, the host is not this machine's
        raise ConfigError(f"--live {opts.host}:{opts.port}: cannot serve there: {str(exc).splitlines()[0]}") \
            from None
    stack.callback(server.close)
    if opts.on_url is not None:
        opts.on_url(server.url)
    server.first_tick = time.monotonic() + GRACE
    return server


def say_url(url: str) -> None:
    """The one line a viewer (or a script) waits for."""
    print(f"live: {url}", file=sys.stderr, flush=True)


def live_options(live: str | None, hz: float | None, realtime: bool) -> LiveOptions | None:
    """``--live`` and ``--live-hz`` checked (a ConfigError on bad input); None without ``--live``."""
    if live is None:
        if hz is not None:
            raise ConfigError("--live-hz needs --live")
        return None
    from fleet_emu.recording.live import parse_live

    try:
        host, port = parse_live(live)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    if hz is not None and realtime:
        raise ConfigError("--live-hz paces a lockstep run: a --realtime run already ticks at its own rate")
    return LiveOptions(host, port, hz, say_url)
