"""The world's messages, built once for both engines: the world's node shell (``world/node.py``) publishes
them over Zenoh and the memory engine (``launch/memory.py``) hands them to its fold, so that a seed gives the
same messages, field for field, in either. Pure: the sequence numbers come from the caller's counter."""

from __future__ import annotations

from collections.abc import Callable

from fleet_emu.core.messages import Hello, Observation, Stop, WorldState
from fleet_emu.world.sim import Reading, World


def hello() -> Hello:
    """The start handshake's hello (repeated until every node answers: seq 0, drawn from no counter)."""
    return Hello(src="world", tick=0, seq=0)


def tick_messages(world: World, readings: dict[str, Reading], cell_size: float, seq: Callable[[], int],
                  dropped: int) -> tuple[dict[str, Observation], WorldState]:
    """The world's messages of its current tick: each live robot's observation (none once the run is over:
    nobody acts again), then the state; ``seq`` draws the world's sequence numbers in that order; ``dropped``:
    the messages the world has dropped so far as malformed or spoofed."""
    w = world
    t = w.tick
    obs = {}
    for r in () if w.done else w.live:
        rd = readings[r]
        obs[r] = Observation(src="world", tick=t, seq=seq(), robot=r, cell=rd.cell, shape=w.shape,
                             cell_size=cell_size, cells=rd.cells, values=rd.values, bodies=rd.bodies)
    state = WorldState(src="world", tick=t, seq=seq(), poses=dict(w.poses), live=tuple(w.live),
                       coverage=float(w.coverage), path_length=dict(w.path_length), done=w.done, reason=w.reason,
                       dropped=dropped, blocked=dict(w.blocked))
    return obs, state


def stop(world: World, seq: int, interrupted: bool = False) -> Stop:
    """The world's stop at the end of the run: the world's reason (``done`` without one), or ``interrupted``
    when the launcher stopped it."""
    reason = "interrupted" if interrupted else (world.reason or "done")
    return Stop(src="world", tick=world.tick, seq=seq, reason=reason)
