"""A robot's inbox heard at once (``agents/hearing.py``): what validates comes in the order it came, each message
that does not is dropped and counted alone, and the memory engine's receivers of one broadcast decode it once."""

from __future__ import annotations

import numpy as np

from fleet_emu.agents.hearing import hear
from fleet_emu.agents.protocol import MapDelta, PoseBeacon
from fleet_emu.core.codec import Context
from fleet_emu.core.envelope import RadioMsg, seal

CTX = Context(senders=frozenset({"r0", "r1", "r2"}), shape=(4, 5))


def _delta(*cells: int) -> MapDelta:
    return MapDelta(cells=np.array(cells, np.int32), values=np.zeros(len(cells), np.int8))


def test_what_does_not_validate_is_dropped_alone_and_the_rest_kept_in_order() -> None:
    inbox = [seal(RadioMsg(PoseBeacon(cell=(1, 2))), "r1", 3, 1), seal(RadioMsg(_delta(0, 19)), "r1", 3, 2),
             seal(RadioMsg(PoseBeacon(cell=(0, 0))), "r9", 3, 1),  # a sender outside the team
             seal(RadioMsg(_delta(20)), "r2", 3, 5),  # a cell past the 4 x 5 grid
             seal(RadioMsg(PoseBeacon(cell=(9, 9))), "r2", 3, 6),  # outside the grid
             seal(RadioMsg(PoseBeacon(cell=(3, 4), next=(3, 3))), "r2", 3, 7), seal(RadioMsg(_delta(7)), "r0", 3, 9)]
    drops: list[tuple[str, str]] = []
    heard = hear(inbox, CTX, lambda key, why: drops.append((key, why)))
    assert [(env.origin, env.seq) for env, _ in heard] == [("r1", 1), ("r1", 2), ("r2", 7), ("r0", 9)]
    assert heard[0][1] == PoseBeacon(cell=(1, 2)) and heard[3][1].cells.tolist() == [7]  # type: ignore[attr-defined]
    assert [key for key, _ in drops] == ["radio/pose", "radio/map", "radio/pose"]
    assert "r9" in drops[0][1] and "out of range" in drops[1][1] and "outside" in drops[2][1]


def test_a_broadcast_heard_by_several_receivers_is_decoded_once_when_shared() -> None:
    inbox = [seal(RadioMsg(PoseBeacon(cell=(1, 2))), "r1", 3, 1), seal(RadioMsg(_delta(0, 19)), "r1", 3, 2),
             seal(RadioMsg(_delta(4)), "r2", 3, 2)]
    first = hear(inbox, CTX, shared=True)
    again = hear(inbox, Context(senders=CTX.senders, shape=(4, 5)), shared=True)
    assert all(a[1] is b[1] for a, b in zip(first, again, strict=True))
    other_grid = hear(inbox, Context(senders=CTX.senders, shape=(9, 9)), shared=True)  # checked afresh
    assert all(a[1] is not b[1] for a, b in zip(first, other_grid, strict=True))
    assert other_grid[0][1] == first[0][1]
    assert hear(inbox, CTX)[0][1] is not first[0][1]  # not shared: its own decode, as over Zenoh
