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
