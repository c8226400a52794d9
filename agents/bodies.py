"""Robots' bodies as a robot senses them: which of them are obstacles to plan around.

The world reports the cells among a robot's sensed ones that hold another robot's body (``Observation.bodies``),
never as map values: a body moves on, and a belief that took it for a wall would keep the wall after it left,
and send it to the team. A body on a cell that a teammate heard lately announced (its cell, or the cell its
last command moves it to) is that teammate: the brain's navigation already steps around one that stands still
and follows one that moves on (``agents/brain.py``); one unheard for a few ticks (a lost beacon) is taken for the
body within as many steps of its announced cells. Any other body is a *wreck*: a robot that no longer
speaks (a failed one, whose body stays where it stopped) or one this robot has not heard from. A wreck is
remembered at its cell, off the passable cells of every plan and decision (:attr:`Problem.obstacles
<fleet_emu.agents.allocators.interface.Problem.obstacles>`), until the robot senses that cell again with no body on
it. The team is told (:class:`WreckNotice`, broadcast when a robot's wrecks change and again every
:data:`RESEND` ticks while it knows some): a teammate that never came within sensing range of a wreck plans
around it too, and one that senses the cell empty tells the others to forget it. Pure: no I/O.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol

import numpy as np

from fleet_emu.agents.frontiers import Cluster
from fleet_emu.core.codec import Context, Payload
from fleet_emu.core.errors import DecodeError
from fleet_emu.core.grid import Cell
from fleet_emu.core.messages import Observation

#: Ticks a teammate may go unheard and a body within as many steps of where it announced itself still be taken
#: for it, not for a wreck (the brain's ``resync_after``: a teammate silent longer is one heard again after a
#: silence): a failed robot's last beacon is heard a tick after it was sent, so its body becomes a wreck this
#: many ticks after that. Before tick SILENT_AFTER no body is a wreck: the radio has not yet introduced the team
#: (every robot starts beside teammates it has never heard).
SILENT_AFTER = 10
#: Ticks between two notices of the same wrecks, and for which a cell seen empty is told again (a lost notice
#: is made good this much later).
RESEND = 10
#: The most cells one notice lists (a team has at most 256 robots: as many bodies).
MAX_WRECKS = 256


class WreckNotice(Payload, kw_only=True, frozen=True):
    """A robot's wrecks (flat cell indices, ascending) and the cells it last listed that it has since sensed with
    no body on them (``cleared``): a receiver plans around the first and forgets the second."""

    KIND = "wrecks"
    cells: tuple[int, ...] = ()
    cleared: tuple[int, ...] = ()

    def validate(self, ctx: Context | None) -> None:
        size = ctx.shape[0] * ctx.shape[1] if ctx is not None and ctx.shape is not None else None
        for name, cells in (("cells", self.cells), ("cleared", self.cleared)):
            if len(cells) > MAX_WRECKS:
                raise DecodeError(f"wrecks: {len(cells)} {name}, more than {MAX_WRECKS}")
            if any(c < 0 or (size is not None and c >= size) for c in cells):
                raise DecodeError(f"wrecks: a cell of {name} outside the grid")


class Heard(Protocol):
    """What the brain keeps of a teammate (``agents.brain.Teammate``): its last beacon's cells and tick."""

    cell: Cell
    next: Cell | None
    heard: int


class Wrecks:
    """The wrecks one robot knows of, as flat cell indices (:meth:`update` every tick)."""

    def __init__(self, silent_after: int = SILENT_AFTER) -> None:
        self.silent_after = silent_after
        self.cells: set[int] = set()
        self._told: frozenset[int] = frozenset()  # the cells of the last notice sent
        self._told_at = 0
        self._cleared: dict[int, int] = {}  # a cell told and since seen empty -> the tick of the notice saying so

    def hear(self, notice: WreckNotice) -> None:
        """A teammate's notice: its wrecks are this robot's too, and the cells it cleared are forgotten."""
        self.cells |= set(notice.cells)
        self.cells -= set(notice.cleared)

    def notice(self, t: int) -> WreckNotice | None:
        """The notice to broadcast at tick ``t``: when the wrecks changed since the last one, or :data:`RESEND`
        ticks after it while there are some, or cells cleared in the last notice; None otherwise. A cell cleared
        is listed as such in the notices of the :data:`RESEND` ticks after it was first."""
        now = frozenset(self.cells)
        cleared = self._cleared
        for c in self._told - now:
            cleared[c] = t
        for c in now:
            cleared.pop(c, None)
        if now == self._told and not ((now or cleared) and t - self._told_at >= RESEND):
            return None
        notice = WreckNotice(cells=tuple(sorted(now)), cleared=tuple(sorted(cleared)))
        self._cleared = {c: at for c, at in cleared.items() if t - at < RESEND}
        self._told, self._told_at = now, t
        return notice

    def update(self, obs: Observation, teammates: Mapping[str, Heard]) -> frozenset[int]:
        """The wrecks after ``obs``: a body that no teammate heard within :attr:`silent_after` ticks accounts
        for (:func:`_accounted`) is added; a remembered one whose cell the sensor returned with no body on it, or
        that such a teammate accounts for, is dropped."""
        bodies, cells = obs.bodies, self.cells
        if not len(bodies) and not cells:
            return frozenset()
        cols, t = obs.shape[1], obs.tick
        now = set(bodies.tolist())
        if cells:
            cells -= set(obs.cells.tolist()) - now  # sensed again, with no body: gone
        if now:
            recent = [tm for tm in teammates.values() if tm.heard >= t - self.silent_after]
            exact = {c[0] * cols + c[1] for tm in recent for c in (tm.cell, tm.next) if c is not None}
            loose = sorted(now - exact)  # most bodies stand where a teammate heard last tick said it would
            found = _accounted(loose, recent, t, cols) if loose else ()
            for b in now - set(loose):
                cells.discard(b)
            for b, ok in zip(loose, found, strict=True):
                if ok:
                    cells.discard(b)
                elif t >= self.silent_after:
                    cells.add(b)
        return frozenset(cells)


def _accounted(bodies: list[int], teammates: list[Heard], t: int, cols: int) -> Sequence[bool]:
    """For each body (a flat cell), whether one of ``teammates`` can stand on it at tick ``t``: within as many
    steps of the cell it announced moving to as ticks went by since it was heard (a beacon lost meanwhile), or
    one more of the cell it announced standing on (its move failed)."""
    if not teammates:
        return [False] * len(bodies)
    a = np.array([(*tm.cell, *(tm.next if tm.next is not None else tm.cell), tm.heard) for tm in teammates])
    b = np.array(bodies, dtype=np.int64)
    rows, cs = (b // cols)[:, None], (b % cols)[:, None]
    slack = np.maximum(0, t - a[:, 4])
    near_next = np.abs(rows - a[:, 2]) + np.abs(cs - a[:, 3]) <= slack
    near_cell = np.abs(rows - a[:, 0]) + np.abs(cs - a[:, 1]) <= slack + 1
    return (near_next | near_cell).any(axis=1).tolist()


def clear_of(clusters: list[Cluster], wrecks: frozenset[int], cols: int) -> list[Cluster]:
    """``clusters`` without the frontier cells a wreck stands on (a wavefront seeds every source, passable or
    not: a wreck's cell as one would lead robots onto it); a cluster left empty is dropped, and one whose target
    was a wreck's cell aims at its first cell left."""
    if not wrecks:
        return clusters
    drop = np.fromiter(wrecks, dtype=np.int64, count=len(wrecks))
    out = []
    for c in clusters:
        keep = ~np.isin(c.cells, drop)
        if keep.all():
            out.append(c)
        elif keep.any():
            cells = c.cells[keep]
            target = c.target
            if target[0] * cols + target[1] in wrecks:
                target = (int(cells[0]) // cols, int(cells[0]) % cols)
            out.append(Cluster(cells, target))
    return out


def as_cells(wrecks: frozenset[int], cols: int) -> set[Cell]:
    """The wrecks as (row, col) cells."""
    return {(w // cols, w % cols) for w in wrecks}
