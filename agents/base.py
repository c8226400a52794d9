"""The base station's functional core: a fixed radio endpoint that holds the team map.

A :class:`BaseStation` is stepped once per tick with what the radio delivered to it (netem's rx bundle for
``base``), as :class:`~fleet_emu.agents.brain.Brain` is for a robot, but it has no body, no sensor and no
allocator. It merges every map delta and map fill that reaches it into a :class:`~fleet_emu.agents.belief.Belief`
(the team map as far as what reached the base), and keeps each robot's last pose beacon. Robots broadcast their
map deltas (``dst = "*"``), so the base hears them whenever it is linked to the sender; fills addressed to a
robot are not for the base. It asks for nothing: a delta lost on the way to the base stays missing until the
cells come again in another robot's delta (the robots' map sync, ``agents/mapsync.py``, is between robots).

:meth:`BaseStation.plan` is where a base-station planner goes (the ``mhm`` allocator:
``agents/allocators/mhm/station.py``): it gets the station (its belief, the robots' last cells, the tick) and
returns the radio messages the base sends; :meth:`BaseStation.step` seals them as the base's envelopes (origin
``base``, its one sequence counter), which the node shell publishes on ``radio/tx/base``. Without a planner the
base only listens and sends nothing.

No Zenoh, no clock, no files.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from fleet_emu.agents.belief import Belief
from fleet_emu.agents.protocol import MapDelta, MapFill, PoseBeacon
from fleet_emu.agents.relay import SeenCache
from fleet_emu.core.codec import Context
from fleet_emu.core.errors import DecodeError
from fleet_emu.core.grid import UNKNOWN, Cell
from fleet_emu.core.keys import BASE
from fleet_emu.core.messages import Envelope, RadioMsg, open_envelope, seal

#: A base-station planner: the station after its tick's merge, to the radio messages it would send.
Planner = Callable[["BaseStation"], Sequence[RadioMsg]]


@dataclasses.dataclass
class Heard:
    """A robot's last pose beacon that reached the base: its cell and the tick it was sent."""

    cell: Cell
    tick: int


class BaseStation:
    """The base station's state: its fixed ``cell``, its belief of the team map, the robots it heard."""

    def __init__(self, cell: Cell, shape: tuple[int, int], team: frozenset[str],
                 planner: Planner | None = None, on_drop: Callable[[str, str], None] | None = None) -> None:
        self.cell = cell
        self.belief = Belief(shape)
        self.team = team
        self.ctx = Context(senders=team, shape=shape)
        self.planner = planner
        self.on_drop = on_drop
        self.heard: dict[str, Heard] = {}
        self.mail: list[RadioMsg] = []  # this tick's protocol messages addressed to the base, for the planner
        self.seen = SeenCache()  # message ids handled: relayed copies are merged once
        self.merged = 0  # map deltas and fills merged
        self.ticks = 0  # rx bundles stepped
        self.tick = -1
        self.seq = 0

    def next_seq(self) -> int:
        """The base's one sequence counter: its envelopes, its tx bundles and its report."""
        self.seq += 1
        return self.seq

    def step(self, tick: int, inbox: Sequence[Envelope]) -> tuple[Envelope, ...]:
        """Merge what the radio delivered at ``tick``; the planner's messages, sealed (none without a planner)."""
        self.tick = tick
        self.ticks += 1
        self.mail = []
        for env in inbox:
            if env.src == BASE or env.origin == BASE or env.dst not in ("*", BASE):
                continue  # with relaying: overheard on its way to a robot, or its own orders relayed back
            try:
                env.validate(self.ctx)
                if not self.seen.add((env.origin, env.seq)):
                    continue  # with relaying: a copy already handled (the base does not relay, agents/relay.py)
                msg = open_envelope(env, self.ctx)
            except DecodeError as exc:
                if self.on_drop is not None:
                    self.on_drop(f"radio/{env.payload_kind}", str(exc))
                continue
            body = msg.body
            if isinstance(body, MapDelta | MapFill):
                self.belief.merge(body.cells, body.values)
                self.merged += 1
            elif isinstance(body, PoseBeacon):
                prev = self.heard.get(msg.origin)
                if prev is None or msg.tick >= prev.tick:
                    self.heard[msg.origin] = Heard(cell=body.cell, tick=msg.tick)
            elif env.dst == BASE:  # a protocol message for the base (mhm's acks): the planner's mail
                self.mail.append(msg)
            # other protocol messages broadcast by robots (an allocator's) are not for the base: ignored
        self.belief.take_news()  # the base shares nothing yet: do not let the news pile up
        self.belief.take_changed()
        return tuple(seal(m, BASE, tick, self.next_seq()) for m in self.plan())

    def plan(self) -> tuple[RadioMsg, ...]:
        """The hook for a base-station planner (module docstring); no planner, no messages."""
        return tuple(self.planner(self)) if self.planner is not None else ()

    @property
    def known_cells(self) -> int:
        """Cells of the team map the base knows (free or occupied)."""
        return int(np.count_nonzero(self.belief.grid != UNKNOWN))

    @property
    def known_fraction(self) -> float:
        """Known cells over the map's cells."""
        return self.known_cells / self.belief.grid.size
