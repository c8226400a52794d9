"""The real cause of a run that went wrong, in the launcher's one failure line: a world that stopped answering,
a stop this launcher did not send, a flood of messages of another run, rather than the robots that failed
because of them (docs/reference/errors.md)."""

from __future__ import annotations

import time

from fleet_emu.recording.monitor import Monitor

#: How many of the scenario's ``barrier_timeout`` the launcher waits, in lockstep, with neither a world state
#: nor a robot command on the bus, before it calls the world frozen. A live world publishes its next state at
#: most ``barrier_timeout`` seconds after the tick's last command (it fails the robots still silent then), and
#: a robot that takes longer to answer is failed: two of them is past any live tick.
STATE_TIMEOUTS = 2.0


def state_timeout(barrier_timeout: float) -> float:
    """Seconds without a world state nor a command after which a running world counts as stopped answering."""
    return STATE_TIMEOUTS * barrier_timeout


def silent_world(monitor: Monitor, timeout: float, now_ns: int | None = None) -> str | None:
    """The failure line of a world silent for ``timeout`` seconds: no state since its last one and no command
    (after tick 0, before its stop; the caller makes sure the monitor's fold caught up), or None."""
    st, last = monitor.state, monitor.last_activity_ns
    if st is None or last is None or st.done or monitor.stop is not None:
        return None
    silent = ((now_ns if now_ns is not None else time.time_ns()) - last) / 1e9
    if silent < timeout:
        return None
    return f"the world process stopped answering at tick {monitor.activity_tick} (no state for {timeout:g} s)"


def froze(monitor: Monitor, barrier_timeout: float) -> str | None:
    """The world's longest silence (no state nor command), when it was longer than a live world's can be
    (``barrier_timeout``), as a cause to put before the line of what followed (the world then lost its session,
    say, and exited without a stop reaching the launcher); or None."""
    gap, tick = monitor.longest_silence
    if gap <= barrier_timeout:
        return None
    return f"the world process stopped answering at tick {tick} (no state for {gap:.0f} s)"


def outside_stop(monitor: Monitor, pending: bool = False) -> str | None:
    """The failure line of a stop in the launcher's name that this launcher did not send (it sends its own only
    once the run is over or interrupted), or of one in the world's name that the world cannot have sent
    (:meth:`~fleet_emu.recording.monitor.Monitor.world_sent`), or None. ``pending``: the one in the world's name
    still waiting for its tick's state (:attr:`~fleet_emu.recording.monitor.Monitor.pending_stop`), which never
    came."""
    stop = monitor.pending_stop if pending else monitor.outside_stop
    if stop is None:
        return None
    if stop.src == "world":
        st = monitor.state
        last = f"its last state was of tick {st.tick}, not done" if st is not None else "before its first state"
        return (f"a stop in the world's name that the world did not send ended the run at tick {stop.tick} "
                f"(reason {stop.reason!r}; {last})")
    return (f"a stop from outside this launcher ended the run at tick {stop.tick} (reason {stop.reason!r}, "
            f"sent as {stop.src!r} on the run's own key)")


def flood(failed: list[str], foreign: int) -> str | None:
    """The failure line of a run whose robots failed while the bus carried ``foreign`` messages of another run
    (each dropped, but each a receiver's work), or None."""
    if not failed or not foreign:
        return None
    return (f"robot(s) {', '.join(failed)} failed while the bus carried {foreign} message(s) of another run "
            f"(dropped: not carrying this run's nonce): a foreign message flood")
