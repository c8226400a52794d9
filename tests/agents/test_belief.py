from __future__ import annotations

import numpy as np

from fleet_emu.agents.belief import Belief


def test_merge_and_news() -> None:
    b = Belief((3, 3))
    assert b.merge(np.array([0, 1, 4]), np.array([0, 100, 0], np.int8)) == 3
    idx, val = b.take_news()
    assert idx.tolist() == [0, 1, 4] and val.tolist() == [0, 100, 0]
    assert b.take_news()[0].size == 0  # news are taken once
    assert b.merge(np.array([0, 2]), np.array([0, -1], np.int8)) == 0  # unknown values never overwrite
    assert b.take_news()[0].size == 0  # nothing changed
    b.merge(np.array([1]), np.array([0], np.int8))  # a changed cell is news again
    assert b.take_news()[0].tolist() == [1]
    assert b.known()[0].tolist() == [0, 1, 4]


def test_changed_cells_are_taken_once_and_news_come_in_order() -> None:
    b = Belief((4, 4))
    b.merge(np.array([9, 2]), np.array([0, 100], np.int8))
    b.merge(np.array([2, 5], np.int32), np.array([100, 0], np.int8))  # 2 unchanged
    assert sorted(b.take_changed().tolist()) == [2, 5, 9]
    assert b.take_changed().size == 0
    idx, val = b.take_news()
    assert idx.tolist() == [2, 5, 9] and val.tolist() == [100, 0, 0] and idx.dtype == np.int32
    b.merge(np.array([5]), np.array([100], np.int8))
    assert b.take_changed().tolist() == [5] and b.take_news()[0].tolist() == [5]
