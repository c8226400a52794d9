"""The real cause of a run that went wrong, in the launcher's one failure line: a world that stopped answering,
a stop this launcher did not send, a flood of messages of another run, rather than the robots that failed
because of them (docs/reference/errors.md)."""

from __future__ import annotations

import time

from fleet_emu.recording.monitor import Monitor

#: How many of the scenario's ``barrier_timeout`` the launcher waits for the world's next state before it calls
#: the world frozen. A live world publishes a state at least every ``barrier_timeout`` seconds after the tick's
#: last command (it fails the robots still silent then), so three of them is well past any live tick.
STATE_TIMEOUTS = 3.0


def state_timeout(barrier_timeout: float) -> float:
    """Seconds without a new world state after which a running world counts as stopped answering."""
    return STATE_TIMEOUTS * barrier_timeout


def silent_world(monitor: Monitor, timeout: float, now_ns: int | None = None) -> str | None:
    """The failure line of a world that published no state for ``timeout`` seconds since its last one (after
    tick 0, before its stop; the monitor's fold caught up, so the state is not merely queued), or None."""
    st, last = monitor.state, monitor.last_state_ns
    if st is None or last is None or st.done or monitor.stop is not None:
        return None
    silent = ((now_ns if now_ns is not None else time.time_ns()) - last) / 1e9
    if silent < timeout:
        return None
    return f"the world process stopped answering at tick {st.tick} (no state for {timeout:g} s)"


def outside_stop(monitor: Monitor) -> str | None:
    """The failure line of a stop in the launcher's name that this launcher did not send (it sends its own only
    once the run is over or interrupted), or None."""
    stop = monitor.outside_stop
    if stop is None:
        return None
    return (f"a stop from outside this launcher ended the run at tick {stop.tick} (reason {stop.reason!r}, "
            f"sent as {stop.src!r} on the run's own key)")


def flood(failed: list[str], foreign: int) -> str | None:
    """The failure line of a run whose robots failed while the bus carried ``foreign`` messages of another run
    (each dropped, but each a receiver's work), or None."""
    if not failed or not foreign:
        return None
    return (f"robot(s) {', '.join(failed)} failed while the bus carried {foreign} message(s) of another run "
            f"(dropped: not carrying this run's nonce): a foreign message flood")
