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


def test_merge_many_is_the_merges_in_turn() -> None:
    """Random parts (repeated cells across parts, cells changed and changed back, unknown values, and parts
    that repeat a cell themselves): the same grid, news, changed cells and count as merging them one by one."""
    rng = np.random.default_rng(5)
    for trial in range(300):
        shape = (int(rng.integers(1, 6)), int(rng.integers(1, 6)))
        size = shape[0] * shape[1]
        start = rng.choice(np.array([-1, 0, 100], np.int8), size=shape)
        parts = []
        for _ in range(int(rng.integers(0, 6))):
            n = int(rng.integers(0, size + 1))
            cells = (rng.integers(0, size, n) if trial % 3 == 0 else rng.permutation(size)[:n]).astype(np.int32)
            parts.append((cells, rng.choice(np.array([-1, 0, 100], np.int8), size=n)))
        one, many = Belief(shape), Belief(shape)
        one.grid[:] = start
        many.grid[:] = start
        counted = sum(one.merge(c, v) for c, v in parts)
        assert many.merge_many(parts) == counted
        assert (many.grid == one.grid).all()
        assert many.take_changed().tolist() == one.take_changed().tolist()  # the same cells, in the same order
        got, want = many.take_news(), one.take_news()
        assert got[0].tolist() == want[0].tolist() and got[1].tolist() == want[1].tolist()


def test_known_is_kept_until_a_merge_changes_a_cell() -> None:
    """A robot may send its whole map to several teammates in one tick: ``known`` is computed once and kept
    (read-only) until a merge, one at a time or many at once, changes a cell."""
    b = Belief((3, 4))
    b.merge(np.array([5, 1]), np.array([100, 0], np.int8))
    first = b.known()
    assert first[0].tolist() == [1, 5] and first[1].tolist() == [0, 100] and first[0].dtype == np.int32
    assert not first[0].flags.writeable and not first[1].flags.writeable
    b.merge(np.array([5, 7]), np.array([100, -1], np.int8))  # nothing changes
    b.merge_many([(np.array([1]), np.array([0], np.int8)), (np.array([3]), np.array([-1], np.int8))])
    assert b.known() is first
    b.merge(np.array([5]), np.array([0], np.int8))  # a value changes
    assert b.known()[1].tolist() == [0, 0]
    b.merge_many([(np.array([0]), np.array([0], np.int8)), (np.array([11]), np.array([100], np.int8))])
    assert b.known()[0].tolist() == [0, 1, 5, 11] and b.known()[1].tolist() == [0, 0, 0, 100]


def test_known_updated_from_the_changed_cells_is_the_pass_over_the_grid() -> None:
    """:meth:`Belief.known` after merges (single and many, unknown values among them, a cell changed from free
    to occupied, long runs without a call) gives what a pass over the grid gives."""
    rng = np.random.default_rng(5)
    b = Belief((40, 50))
    for step in range(300):
        parts = []
        for _ in range(int(rng.integers(1, 4))):
            cells = rng.integers(0, 2000, int(rng.integers(0, 30)))
            parts.append((cells, rng.choice(np.array([-1, 0, 100], np.int8), len(cells))))
        b.merge_many(parts) if step % 2 else b.merge(*parts[0])
        if step % 7 == 0 or step > 250:
            cells, values = b.known()
            flat = b.grid.reshape(-1)
            expected = np.flatnonzero(flat != -1)
            assert cells.dtype == np.int32 and np.array_equal(cells, expected)
            assert np.array_equal(values, flat[expected])
