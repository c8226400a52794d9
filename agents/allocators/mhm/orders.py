"""MHM's one radio message: the base station's orders (Mukhija et al., section III-D: the base station plans,
the robots obey), broadcast by the base every tick and relayed hop by hop.

It carries everything a robot needs to obey without knowing the plan: per robot its ``role`` (``node``: stay
on its node's cell, a relay; ``explorer``) and its ``goal`` (absent: hold), the ``routes`` (each robot's next
relay toward the base, the parent map of the ``tree`` relay policy, ``agents/relay.py``), the ``relays`` (the
cells where the base and the hinged node robots stand, so that a robot computes the safe area itself: its
known-free cells within r_comm of one, section III's "an explorer is never farther than r_comm from its
closest node") and ``plan_tick``, the base's tick the orders were made at (a robot keeps the newest it heard;
relayed copies arrive late, or never). ``done``: the planner reached step 18.

Each robot that has orders answers every tick with an :class:`MhmAck` to the base (``dst = "base"``, relayed up
the tree): the plan tick of the orders it follows and the cell it stands on. The base breaks a tree only once
every explorer has confirmed that it follows the orders that told it to hold (``planner.py``, tree breaking).

A payload of its own kind (``mhm``), owned by this protocol like the trade messages are by ``trade.py``; netem
and relays never decode it. Decoding checks every robot id against the team, every cell against the grid and
every role against :data:`ROLES`, so a malformed order is counted and dropped by the receiving brain.
"""

from __future__ import annotations

from fleet_emu.core.codec import Context, Payload
from fleet_emu.core.errors import DecodeError
from fleet_emu.core.grid import Cell
from fleet_emu.core.keys import BASE
from fleet_emu.core.messages import check_cell

ROLES = ("node", "explorer")
MAX_RELAYS = 1024


def _check_robot(robot: str, ctx: Context | None, what: str) -> None:
    if robot == BASE or (ctx is not None and ctx.senders is not None and robot not in ctx.senders):
        raise DecodeError(f"mhm: {what} names {robot!r}, not a robot of the team")


class MhmOrders(Payload, kw_only=True, frozen=True):
    """The base's orders of ``plan_tick`` (module docstring)."""

    KIND = "mhm"
    plan_tick: int
    roles: dict[str, str]
    goals: dict[str, Cell]
    routes: dict[str, str]
    relays: tuple[Cell, ...]
    done: bool = False

    def validate(self, ctx: Context | None) -> None:
        shape = ctx.shape if ctx else None
        if self.plan_tick < 0:
            raise DecodeError("mhm: negative plan tick")
        for robot, role in self.roles.items():
            _check_robot(robot, ctx, "a role")
            if role not in ROLES:
                raise DecodeError(f"mhm: role {role!r} is not one of {', '.join(ROLES)}")
        for robot, goal in self.goals.items():
            if robot not in self.roles:
                raise DecodeError(f"mhm: a goal for {robot!r}, which has no role")
            check_cell(goal, shape, "mhm")
        for robot, parent in self.routes.items():
            _check_robot(robot, ctx, "a route")
            if parent != BASE:
                _check_robot(parent, ctx, "a route's parent")
            if parent == robot:
                raise DecodeError(f"mhm: {robot!r} is its own parent")
        if not self.relays or len(self.relays) > MAX_RELAYS:
            raise DecodeError("mhm: no relay cells, or too many")
        for cell in self.relays:
            check_cell(cell, shape, "mhm")


class MhmAck(Payload, kw_only=True, frozen=True):
    """A robot's answer to the base: it follows the orders of ``plan_tick``, and stands on ``cell``."""

    KIND = "mhm_ack"
    plan_tick: int
    cell: Cell

    def validate(self, ctx: Context | None) -> None:
        if self.plan_tick < 0:
            raise DecodeError("mhm_ack: negative plan tick")
        check_cell(self.cell, ctx.shape if ctx else None, "mhm_ack")
