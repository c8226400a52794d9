"""The brain's own radio protocol: pose beacons and map deltas (DESIGN.md "What it is": a robot knows only what
its sensor and its radio tell it). Each is a :class:`~fleet_emu.core.codec.Payload`, sealed in an envelope by
the brain; netem never decodes them."""

from __future__ import annotations

import dataclasses

import numpy as np

from fleet_emu.core.codec import Context, Payload
from fleet_emu.core.errors import DecodeError
from fleet_emu.core.grid import Cell
from fleet_emu.core.messages import check_cell, check_cells


@dataclasses.dataclass(frozen=True)
class PoseBeacon(Payload):
    """A robot's own pose, broadcast every tick: ``cell``, where it stands at the beacon's tick, and ``next``,
    the cell its command of that same tick moves it to (``cell`` when it stays). The beacon arrives a tick
    later, when the robot has made that move, so ``next`` is where a teammate should expect it (MinPos
    section 4.3 compares every robot's cost at the moment of the decision). ``next`` is absent (None) in a
    schema-2 recording made before it existed: the teammate is then expected at ``cell``."""

    KIND = "pose"
    cell: Cell
    next: Cell | None = None

    @property
    def expected(self) -> Cell:
        """Where the robot stands once its command of the beacon's tick is applied, if the move succeeds."""
        return self.cell if self.next is None else self.next

    def validate(self, ctx: Context | None) -> None:
        check_cell(self.cell, ctx.shape if ctx else None, "pose")
        if self.next is not None:
            check_cell(self.next, ctx.shape if ctx else None, "pose")
            if abs(self.next[0] - self.cell[0]) + abs(self.next[1] - self.cell[1]) > 1:
                raise DecodeError(f"pose: next cell {self.next} is not one step from {self.cell}")


@dataclasses.dataclass(frozen=True)
class MapDelta(Payload):
    """Cells a robot learned (flat indices and their values): the news of one tick, or its whole known map for
    a teammate heard again after a silence."""

    KIND = "map"
    cells: np.ndarray
    values: np.ndarray

    def validate(self, ctx: Context | None) -> None:
        check_cells(self.cells, self.values, ctx.shape if ctx else None, "map")
