"""The statistics of the claims on synthetic numbers, not on fleets: the interval's coverage over repeated
experiments, its verdicts against a region, the replicates an undecided figure needs, and the sequential plan's
looks and levels."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fleet_emu.sweep.decide import look_level, looks
from fleet_emu.sweep.intervals import (
    Bootstrap,
    Interval,
    Region,
    Verdict,
    decide,
    interval,
    replicates_needed,
    resample_weights,
)


def _interval_of_mean(x: np.ndarray, boot: Bootstrap) -> Interval:
    w = resample_weights(len(x), boot)
    return interval(float(x.mean()), (w @ x) / len(x), len(x), boot.level)


@pytest.mark.parametrize(("n", "draw"), [
    (10, lambda rng, n: rng.normal(5.0, 2.0, n)),             # a paired difference of times
    (20, lambda rng, n: rng.exponential(3.0, n) + 2.0),        # skewed, as times to a target are
])
def test_the_interval_covers_the_true_mean_at_its_level(n: int, draw: object) -> None:
    """200 repetitions of an experiment of n replicates: the 95 % interval holds the true mean in 92-98 % of
    them (within 3 points of the level)."""
    truth = 5.0
    rng = np.random.default_rng(12)
    hits = 0
    for rep in range(200):
        x = draw(rng, n)  # type: ignore[operator]
        iv = _interval_of_mean(x, Bootstrap(resamples=1000, seed=rep))
        hits += iv.low <= truth <= iv.high
    assert 92 <= hits / 2 <= 98, f"coverage {hits / 2:.1f} %"


def test_the_expanded_percentile_is_wider_than_the_plain_one_at_few_replicates() -> None:
    x = np.array([1.0, 4.0, 2.0, 8.0, 3.0])
    boot = Bootstrap()
    w = resample_weights(5, boot)
    wide = interval(float(x.mean()), (w @ x) / 5, 5, 0.95)
    plain = np.quantile((w @ x) / 5, [0.025, 0.975])
    assert wide.low < plain[0] and wide.high > plain[1]


@pytest.mark.parametrize(("low", "high", "n", "region", "verdict"), [
    (1.0, 2.0, 10, Region(low=0.0, low_closed=False), Verdict.REPRODUCED),
    (-2.0, -1.0, 10, Region(low=0.0, low_closed=False), Verdict.NOT_REPRODUCED),
    (-1.0, 2.0, 10, Region(low=0.0, low_closed=False), Verdict.INCONCLUSIVE),
    (0.0, 2.0, 10, Region(low=0.0, low_closed=False), Verdict.INCONCLUSIVE),  # 0 is not above 0
    (0.0, 2.0, 10, Region(low=0.0), Verdict.REPRODUCED),                       # but is at least 0
    (1.0, 2.0, 2, Region(low=0.0), Verdict.TOO_FEW),
    (3.0, 4.0, 10, Region(0.0, 5.0), Verdict.REPRODUCED),
    (4.0, 6.0, 10, Region(0.0, 5.0), Verdict.INCONCLUSIVE),
    (6.0, 7.0, 10, Region(0.0, 5.0), Verdict.NOT_REPRODUCED),
])
def test_a_verdict_is_where_the_whole_interval_lies(low: float, high: float, n: int, region: Region,
                                                    verdict: Verdict) -> None:
    assert decide(Interval((low + high) / 2, low, high, 0.95, n), region) == verdict


def test_the_replicates_needed_grow_as_the_interval_must_shrink() -> None:
    iv = Interval(1.0, -1.0, 3.0, 0.95, 10)  # half-width 2, the figure 1 from the bound 0
    assert replicates_needed(iv, Region(low=0.0)) == 40  # (2 / 1)^2 x 10
    assert replicates_needed(Interval(0.0, -1.0, 1.0, 0.95, 10), Region(low=0.0)) is None  # on the bound


def test_the_sequential_plan_doubles_to_the_cap_and_spends_alpha_over_its_looks() -> None:
    assert looks(60, 200) == [60, 120, 200] and looks(10, 40) == [10, 20, 40] and looks(5, 5) == [5]
    assert look_level(0.95, 3) == pytest.approx(1 - 0.05 / 3)
    assert math.isclose(look_level(0.9, 1), 0.9)


def test_bad_bootstrap_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="level"):
        Bootstrap(level=1.2)
    with pytest.raises(ValueError, match="resamples"):
        Bootstrap(resamples=5)
