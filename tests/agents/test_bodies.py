"""Which sensed bodies a robot plans around (agents/bodies.py): a teammate heard lately is followed or stepped
around as before; any other body is a wreck, remembered at its cell, off every wavefront and frontier, until the
sensor returns that cell with no body on it."""

from __future__ import annotations

import dataclasses

import numpy as np

from fleet_emu.agents.allocators.interface import Problem
from fleet_emu.agents.bodies import RESEND, SILENT_AFTER, WreckNotice, Wrecks, clear_of
from fleet_emu.agents.frontiers import Cluster
from fleet_emu.core.grid import Cell
from fleet_emu.core.messages import Observation

SHAPE = (5, 10)


@dataclasses.dataclass
class Mate:
    cell: Cell
    heard: int
    next: Cell | None = None


def _obs(tick: int, sensed: list[int], bodies: list[int]) -> Observation:
    return Observation(src="world", tick=tick, seq=1, robot="r0", cell=(2, 0), shape=SHAPE, cell_size=0.5,
                       cells=np.array(sensed, np.int32), values=np.zeros(len(sensed), np.int8),
                       bodies=np.array(bodies, np.int32))


def test_a_silent_body_is_a_wreck_until_its_cell_is_sensed_empty() -> None:
    w = Wrecks()
    body = 2 * 10 + 3
    assert w.update(_obs(SILENT_AFTER - 1, [21, 22, body], [body]), {}) == frozenset()  # the team not yet heard
    assert w.update(_obs(SILENT_AFTER, [21, 22, body], [body]), {}) == {body}
    assert w.update(_obs(SILENT_AFTER + 1, [21], []), {}) == {body}  # out of view: remembered
    assert w.update(_obs(SILENT_AFTER + 2, [21, 22, body], []), {}) == frozenset()  # sensed empty: gone


def test_a_body_a_teammate_accounts_for_is_no_wreck() -> None:
    w = Wrecks()
    t, body = 20, (2, 3)
    b = body[0] * 10 + body[1]
    assert w.update(_obs(t, [b], [b]), {"r1": Mate((2, 2), heard=t, next=body)}) == frozenset()
    # heard two ticks ago, announced two steps away: it walked on while its beacon was lost
    assert w.update(_obs(t, [b], [b]), {"r1": Mate((2, 5), heard=t - 2, next=(2, 5))}) == frozenset()
    # heard too long ago, or announced too far away: a wreck
    assert w.update(_obs(t, [b], [b]), {"r1": Mate(body, heard=t - SILENT_AFTER - 1, next=body)}) == {b}
    assert w.update(_obs(t, [b], [b]), {"r1": Mate((2, 8), heard=t - 1, next=(2, 8))}) == {b}
    assert w.update(_obs(t, [b], [b]), {"r1": Mate(body, heard=t, next=body)}) == frozenset()  # it speaks again


def test_a_wreck_is_off_the_passable_cells_and_the_frontiers() -> None:
    belief = np.zeros(SHAPE, np.int8)
    wreck = 2 * 10 + 3
    p = Problem(me="r0", poses={"r0": (2, 0)}, belief=belief, clusters=[], obstacles=frozenset({wreck}))
    assert not p.passable[2, 3] and p.passable.sum() == belief.size - 1
    assert Problem(me="r0", poses={"r0": (2, 0)}, belief=belief, clusters=[]).passable.all()
    clusters = [Cluster(np.array([wreck, wreck + 1], np.int64), (2, 3)), Cluster(np.array([wreck]), (2, 3)),
                Cluster(np.array([5]), (0, 5))]
    kept = clear_of(clusters, frozenset({wreck}), SHAPE[1])
    assert [c.cells.tolist() for c in kept] == [[wreck + 1], [5]]
    assert kept[0].target == (2, 4) and kept[1] is clusters[2]
    assert clear_of(clusters, frozenset(), SHAPE[1]) is clusters


def test_a_robot_tells_the_team_its_wrecks_and_what_it_cleared() -> None:
    from fleet_emu.core.codec import Context, decode_payload

    a, b = Wrecks(), Wrecks()
    body = 2 * 10 + 3
    a.update(_obs(SILENT_AFTER, [body], [body]), {})
    told = a.notice(SILENT_AFTER)
    assert told == WreckNotice(cells=(body,), cleared=())
    assert a.notice(SILENT_AFTER + 1) is None  # nothing new
    assert a.notice(SILENT_AFTER + RESEND) == told  # again, in case it was lost
    heard = decode_payload("wrecks", told.encode(), Context(shape=SHAPE))
    b.hear(heard)
    assert b.cells == {body}  # a teammate that never sensed it plans around it too
    a.update(_obs(SILENT_AFTER + RESEND + 1, [body], []), {})
    cleared = a.notice(SILENT_AFTER + RESEND + 1)
    assert cleared == WreckNotice(cells=(), cleared=(body,))
    b.hear(cleared)
    assert b.cells == set()
    assert a.notice(SILENT_AFTER + RESEND + 2) is None
    assert a.notice(SILENT_AFTER + 2 * RESEND + 1) == cleared  # told again, in case it was lost
    assert a.notice(SILENT_AFTER + 4 * RESEND) is None  # nothing left to tell


def test_a_notice_outside_the_grid_is_refused() -> None:
    import pytest

    from fleet_emu.core.codec import Context, decode_payload
    from fleet_emu.core.errors import DecodeError

    for bad in (WreckNotice(cells=(SHAPE[0] * SHAPE[1],)), WreckNotice(cleared=(-1,)),
                WreckNotice(cells=tuple(range(300)))):
        with pytest.raises(DecodeError):
            decode_payload("wrecks", bad.encode(), Context(shape=SHAPE))
