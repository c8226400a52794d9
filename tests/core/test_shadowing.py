"""Correlated shadowing (core/shadowing.py): the field's statistics over a large map, the link term's, its
symmetry, its seed, and how netem adds it to eq. 4 and counts what eq. 4 alone calls wrongly."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fleet_emu.core.errors import ConfigError
from fleet_emu.core.grid import OCCUPIED, from_ascii
from fleet_emu.core.radio import RadioConfig, link_matrix
from fleet_emu.core.rng import generator
from fleet_emu.core.scenario import Scenario
from fleet_emu.core.shadowing import Shadowing, shadowing
from fleet_emu.netem.channel import Counters, count_predictions, make_channel

SIGMA = 6.0
CELL = 0.5
CORR_M = 2.5  # 5 cells
SIDE = 400  # a 200 m square map: 80 decorrelation distances a side


@pytest.fixture(scope="module")
def big() -> Shadowing:
    field = shadowing(generator(7, "netem", "shadowing"), (SIDE, SIDE), CELL, SIGMA, CORR_M)
    assert field is not None and field.step == 1 and field.field.shape == (SIDE, SIDE)
    return field


def _corr(f: np.ndarray, dr: int, dc: int) -> float:
    """The correlation of ``f`` with itself shifted by (dr, dc) cells (dc may be negative)."""
    h, w = f.shape
    a = f[: h - dr, max(0, -dc): w - max(0, dc)]
    b = f[dr:, max(0, dc): w - max(0, -dc) if dc < 0 else w]
    return float(np.corrcoef(a.ravel(), b.ravel())[0, 1])


def test_the_field_has_the_stated_spread_and_correlation_at_the_decorrelation_distance(big: Shadowing) -> None:
    db = SIGMA * big.field.astype(np.float64)
    assert abs(db.std() - SIGMA) <= 0.1 * SIGMA
    assert abs(db.mean()) < 0.1 * SIGMA
    d = round(CORR_M / CELL)
    for dr, dc in ((d, 0), (0, d), (3, 4), (4, -3)):  # along both axes and two diagonals: isotropic
        assert 0.3 <= _corr(big.field, dr, dc) <= 0.45, (dr, dc)
    assert _corr(big.field, 1, 0) > _corr(big.field, d, 0) > _corr(big.field, 4 * d, 0)  # falls with distance
    assert abs(_corr(big.field, 6 * d, 0)) < 0.05


def test_a_link_s_term_has_the_stated_spread_and_keeps_the_correlation_when_the_link_moves(big: Shadowing) -> None:
    rng = np.random.default_rng(3)
    d = round(CORR_M / CELL)
    a = rng.integers(0, SIDE - d, size=(20000, 2))
    b = rng.integers(0, SIDE - d, size=(20000, 2))
    far = np.hypot(*(a - b).T) > 10 * d
    a, b = a[far], b[far]
    down, right = np.array([d, 0]), np.array([0, 1])
    s = big.link_db(a, b)
    assert abs(s.std() - SIGMA) <= 0.1 * SIGMA
    moved = big.link_db(a + down, b + down)  # both ends moved by the decorrelation distance
    assert 0.3 <= float(np.corrcoef(s, moved)[0, 1]) <= 0.45
    one_end = big.link_db(a + down, b)  # one end moved: the other end's half of the term stays
    assert 0.6 <= float(np.corrcoef(s, one_end)[0, 1]) <= 0.75  # (1 + 1/e) / 2 = 0.68
    near = big.link_db(a, a + right)  # the normalisation keeps the spread for neighbours too
    assert abs(near.std() - SIGMA) <= 0.1 * SIGMA


def test_the_term_is_symmetric_and_equal_pair_by_pair(big: Shadowing) -> None:
    cells = [(5, 7), (100, 300), (101, 300), (399, 0), (5, 7)]
    s = big.pair_db(cells)
    assert np.array_equal(s, s.T) and np.all(np.diag(s) == 0.0)
    assert s[1, 0] == big.link_db([cells[0]], [cells[1]])[0] == big.link_db([cells[1]], [cells[0]])[0]
    assert s[0, 4] == pytest.approx(SIGMA * float(big.at([(5, 7)])[0]))  # both ends on one cell: sigma F
    assert np.array_equal(s[0, 1:4], s[4, 1:4])  # two endpoints on one cell: the same terms
    assert len({round(float(x), 9) for x in s[np.triu_indices(5, 1)]}) == 7  # every other pair its own


def test_the_field_is_the_seed_s_and_off_at_zero() -> None:
    radio = RadioConfig(shadowing_db=4.0, shadowing_m=1.0)
    one, again, other = (make_channel(seed, radio, 1.0, (60, 80), 0.5).shadowing for seed in (1, 1, 2))
    assert one is not None and again is not None and other is not None
    assert np.array_equal(one.field, again.field) and not np.array_equal(one.field, other.field)
    mine = shadowing(generator(1, "netem", "shadowing"), (60, 80), 0.5, 4.0, 1.0)
    assert mine is not None and np.array_equal(mine.field, one.field)  # the run's own stream, not a global one
    assert make_channel(1, RadioConfig(), 1.0, (60, 80), 0.5).shadowing is None
    plain, shadowed = make_channel(1, RadioConfig(), 1.0), make_channel(1, radio, 1.0, (60, 80), 0.5)
    assert plain.rng.random(5).tolist() == shadowed.rng.random(5).tolist()  # the loss draws are untouched
    with pytest.raises(ValueError, match="shape"):
        make_channel(1, radio, 1.0)


def test_a_very_large_map_draws_the_field_on_every_kth_cell() -> None:
    field = shadowing(generator(0, "netem", "shadowing"), (5000, 4000), 0.05, 3.0, 0.2)
    assert field is not None and field.step == 2 and field.field.shape == (2500, 2000)
    assert field.at([(4999, 3999), (4998, 3998)]).tolist() == [float(field.field[-1, -1])] * 2
    assert abs(float(field.field.std()) - 1.0) < 0.1


def test_netem_adds_the_term_and_counts_what_eq4_alone_calls_wrongly() -> None:
    grid, robots = from_ascii("""
    0.........1.........2
    """)
    occ = grid == OCCUPIED
    cells = [robots["r0"], robots["r1"], robots["r2"]]
    p = RadioConfig(comm_range=5.0, threshold=0.0)  # 10 cells = 5 m: 0 dB, linked; 20 cells: -6 dB, not
    plain, link0 = link_matrix(occ, cells, 0.5, p)
    assert link0[0, 1] and link0[1, 2] and not link0[0, 2]
    shadow = np.array([[0.0, -1.0, 7.0], [-1.0, 0.0, 0.5], [7.0, 0.5, 0.0]])
    strength, link = link_matrix(occ, cells, 0.5, p, shadow)
    assert np.allclose(strength[np.triu_indices(3, 1)], (plain + shadow)[np.triu_indices(3, 1)])
    assert link.tolist() == [[False, False, True], [False, False, True], [True, True, False]]
    c = Counters()
    count_predictions(c, strength, shadow, link, 3, p)
    assert (c.pair_ticks, c.false_links, c.missed_links) == (3, 1, 1)  # r0-r1 lost, r0-r2 gained
    count_predictions(c, strength, shadow, link, 2, p)  # the base (the last endpoint) is not a robot pair
    assert (c.pair_ticks, c.false_links, c.missed_links) == (4, 2, 1)
    disk = RadioConfig(comm="disk", comm_range=5.0)
    strength, link = link_matrix(occ, cells, 0.5, disk, shadow)
    assert link.tolist() == link_matrix(occ, cells, 0.5, disk)[1].tolist()  # a disk's links ignore the signal
    c = Counters()
    count_predictions(c, strength, shadow, link, 3, disk)
    assert (c.pair_ticks, c.false_links, c.missed_links) == (3, 0, 0)


def test_the_settings_are_checked_and_quiet_at_their_defaults() -> None:
    s = Scenario()
    assert "shadowing_db" not in s.to_dict()["radio"] and "shadowing_m" not in s.to_dict()["radio"]
    on = s.override(shadowing_db=4.0, shadowing_m=0.8)
    assert on.to_dict()["radio"]["shadowing_db"] == 4.0 and on.to_dict()["radio"]["shadowing_m"] == 0.8
    assert Scenario.from_dict(on.to_dict()).radio == on.radio
    for bad, flag in (({"shadowing_db": -1.0}, "shadowing_db"), ({"shadowing_db": math.inf}, "shadowing_db"),
                      ({"shadowing_m": 0.0}, "shadowing_m")):
        with pytest.raises(ConfigError, match=flag) as err:
            s.override(**bad)
        assert "\n" not in str(err.value)
