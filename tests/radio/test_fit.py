"""The signal model's fits (netem/fit.py) on synthetic links whose true model is known: least squares recovers
it, the cross-validation holds each block out, the correlogram and its 1/e distance, the paired interval."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from fleet_emu.core.radio import RadioConfig
from fleet_emu.netem import fit as F
from tests.radio.synthetic import TRUE, write_site


def _links(tmp_path: Path, noise_db: float = 0.0) -> F.Readings:
    from fleet_emu.launch.radio_cli import site_links

    _, lk, _ = site_links(str(write_site(tmp_path / "site", noise_db=noise_db)), 0.05, None)
    return lk


def test_the_wall_fit_recovers_the_model_the_readings_were_drawn_from(tmp_path: Path) -> None:
    lk = _links(tmp_path)
    f = F.fit("wall", lk)
    p0, n, waf, cap = TRUE
    assert f.max_walls == cap and f.p0 == pytest.approx((p0,) * 3, abs=0.01)
    assert f.path_loss == pytest.approx(n, abs=0.01) and f.waf == pytest.approx(waf, abs=0.01)
    assert float(np.abs(F.residuals(f, lk)).max()) < 0.01
    logd = F.fit("log-distance", lk)  # no walls: the walls' loss goes into a steeper exponent and a worse fit
    assert logd.waf == 0 and np.sqrt(np.mean(F.residuals(logd, lk) ** 2)) > 1.0


def test_per_anchor_p0_and_the_fixed_models_fit_only_what_they_say(tmp_path: Path) -> None:
    lk = _links(tmp_path)
    shifted = F.Readings(lk.anchor, lk.point, lk.distance, lk.walls,
                         lk.rss + np.array([0.0, 4.0, -3.0])[lk.anchor], lk.xy, lk.anchors)
    f = F.fit("wall", shifted, per_anchor=True)
    assert f.p0 == pytest.approx((TRUE[0], TRUE[0] + 4, TRUE[0] - 3), abs=0.01)
    d = F.fit("defaults", lk)
    radio = RadioConfig()
    assert (d.path_loss, d.waf, d.max_walls, d.fitted) == (radio.path_loss, radio.waf, radio.max_walls, 1)
    c = F.fit("cost231", lk)
    assert (c.path_loss, c.waf, c.max_walls) == (2.0, F.COST231_LIGHT_WALL_DB, None)


def test_cross_validation_holds_out_whole_blocks(tmp_path: Path) -> None:
    lk = _links(tmp_path, noise_db=2.0)
    fold = F.blocks(lk.xy, 1.0, 5)
    block = F.block_ids(lk.xy, 1.0)
    for b in np.unique(block):
        assert len(np.unique(fold[block == b])) == 1  # a block is in one fold
    assert set(np.unique(fold)) == set(range(5))
    assert np.array_equal(fold, F.blocks(lk.xy, 1.0, 5))  # seeded: the same folds every time
    calib = np.sqrt(np.mean(F.residuals(F.fit("wall", lk), lk) ** 2))
    cv = np.sqrt(np.mean(F.cv_errors("wall", lk) ** 2))
    assert 1.7 < calib < 2.3 and cv >= calib  # noise of 2 dB; unseen points are not fitted better


def test_the_correlogram_finds_the_decorrelation_distance_of_a_known_field() -> None:
    rng = np.random.default_rng(3)
    xy = np.stack([np.linspace(0, 60, 6000), np.zeros(6000)], axis=1)  # a line, 1 cm apart
    step, d_corr = 0.01, 0.8
    a = math.exp(-step / d_corr)  # AR(1) along the line: correlation exp(-h / d_corr) (Gudmundson)
    r = np.empty(len(xy))
    r[0] = rng.normal()
    for i in range(1, len(r)):
        r[i] = a * r[i - 1] + math.sqrt(1 - a * a) * rng.normal()
    zero = np.zeros(len(r), dtype=np.int64)
    lk = F.Readings(zero, np.arange(len(r)), np.ones(len(r)), zero, r, xy, 1)
    lags, rho = F.correlogram(r - r.mean(), lk, reach_m=3.0)
    assert F.correlation_distance(lags, rho) == pytest.approx(d_corr, rel=0.3)
    assert math.isnan(F.correlation_distance(np.array([0.5, 1.0]), np.array([0.9, 0.8])))


def test_the_paired_gain_of_a_model_over_itself_is_nothing_and_a_real_gain_shows() -> None:
    rng = np.random.default_rng(1)
    e = rng.normal(0, 5, 2000)
    block = np.arange(2000) % 40
    assert F.paired_gain(e, e, block) == (0.0, 0.0, 0.0)
    gain, lo, hi = F.paired_gain(e, e * 0.8, block)
    assert lo < gain < hi and lo > 0
