"""Benavides eq. 4 on hand-computed cases with walls, and the link graph."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fleet_emu.core.grid import OCCUPIED, from_ascii
from fleet_emu.core.radio import RadioConfig, connected, link_matrix, signal_db

P = RadioConfig(comm_range=10.0, path_loss=2.0, waf=3.1, max_walls=4, threshold=0.0)


def test_free_space_is_zero_db_at_the_nominal_range() -> None:
    assert signal_db(10.0, 0, P) == pytest.approx(0.0)
    assert signal_db(5.0, 0, P) == pytest.approx(20 * math.log10(2))  # 6.02 dB
    assert signal_db(20.0, 0, P) == pytest.approx(-20 * math.log10(2))
    assert signal_db(1.0, 9, P) == pytest.approx(20.0 - 4 * 3.1)  # the wall count is capped at C = 4


def test_walls_on_the_segment_cut_the_link() -> None:
    grid, robots = from_ascii("""
    0....#....1....#.#..2
    """)
    occ = grid == OCCUPIED
    cells = [robots["r0"], robots["r1"], robots["r2"]]
    strength, link = link_matrix(occ, cells, 0.5, P)
    # r0-r1: 10 cells = 5 m, one wall: 6.02 - 3.1 = 2.92 dB -> linked
    assert strength[0, 1] == pytest.approx(20 * math.log10(2) - 3.1)
    # r1-r2: 10 cells = 5 m, two walls (two separate runs): 6.02 - 6.2 = -0.18 dB -> no link
    assert strength[1, 2] == pytest.approx(20 * math.log10(2) - 6.2)
    # r0-r2: 20 cells = 10 m, three walls: -9.3 dB
    assert strength[0, 2] == pytest.approx(-9.3)
    assert link.tolist() == [[False, True, False], [True, False, False], [False, False, False]]
    assert np.allclose(strength, strength.T)
    assert not connected(link)


def test_ideal_links_everyone_and_connectivity() -> None:
    grid, robots = from_ascii("0#######################1")
    cells = list(robots.values())
    _, link = link_matrix(grid == OCCUPIED, cells, 0.5, RadioConfig(comm="full"))
    assert link.tolist() == [[False, True], [True, False]] and connected(link)
    chain = np.array([[0, 1, 0], [1, 0, 1], [0, 1, 0]], dtype=bool)
    assert connected(chain)  # connected through a relay
    assert connected(np.zeros((1, 1), dtype=bool))


def test_disk_links_within_range_through_walls_and_full_links_all() -> None:
    grid, robots = from_ascii("""
    0.#.1.....2
    """)
    cells = list(robots.values())  # r0 and r1 4 cells (2 m) apart across a wall, r2 10 cells (5 m) from r0
    disk = RadioConfig(comm="disk", comm_range=3.0)
    _, link = link_matrix(grid == OCCUPIED, cells, 0.5, disk)
    assert link.tolist() == [[False, True, False], [True, False, True], [False, True, False]]
    _, full = link_matrix(grid == OCCUPIED, cells, 0.5, RadioConfig(comm="full", comm_range=0.1))
    assert full.sum() == 6
    assert RadioConfig(comm="ideal", loss=0.5).applied_loss == 0.0
    assert RadioConfig(comm="full", loss=0.5).applied_loss == 0.5


def test_sure_range_is_where_eq4_meets_the_threshold_through_every_counted_wall() -> None:
    import math

    from fleet_emu.core.radio import RadioConfig, signal_db

    p = RadioConfig(comm="wall", comm_range=10.0, threshold=0.0)
    assert math.isclose(signal_db(p.sure_range, p.max_walls + 3, p), p.threshold, abs_tol=1e-9)
    assert signal_db(p.sure_range * 1.01, p.max_walls, p) < p.threshold
    assert RadioConfig(comm="disk", comm_range=7.0).sure_range == 7.0
    assert math.isinf(RadioConfig(comm="full").sure_range)
