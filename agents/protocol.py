"""The brain's own radio protocol: pose beacons and map deltas (DESIGN.md "What it is": a robot knows only what
its sensor and its radio tell it). Each is a :class:`~fleet_emu.core.codec.Payload`, sealed in an envelope by
the brain; netem never decodes them."""

from __future__ import annotations

import dataclasses

import numpy as np

from fleet_emu.core.codec import Context, Payload
from fleet_emu.core.grid import Cell
from fleet_emu.core.messages import check_cell, check_cells


@dataclasses.dataclass(frozen=True)
class PoseBeacon(Payload):
    """A robot's own pose, broadcast every tick."""

    KIND = "pose"
    cell: Cell

    def validate(self, ctx: Context | None) -> None:
        check_cell(self.cell, ctx.shape if ctx else None, "pose")


@dataclasses.dataclass(frozen=True)
class MapDelta(Payload):
    """Cells a robot learned (flat indices and their values): the news of one tick, or its whole known map for
    a teammate heard again after a silence."""

    KIND = "map"
    cells: np.ndarray
    values: np.ndarray

    def validate(self, ctx: Context | None) -> None:
        check_cells(self.cells, self.values, ctx.shape if ctx else None, "map")
