"""A claim's figure with its interval, and the verdict the interval allows.

The replicate (a seed, or a start cell a study lists as ``replicates``) is the unit of resampling: every run of
one replicate is drawn together, whatever allocator, robot count or loss it has, so that a comparison stays
paired and a figure pooled over several grid points rests on its true number of independent repetitions.

The interval is a seeded nonparametric bootstrap over replicates (Efron & Tibshirani 1993, ch. 13) with
Hesterberg's *expanded percentile* correction for small samples (Hesterberg 2015, "What teachers should know
about the bootstrap", The American Statistician 69(4), section 4.2): the percentiles are taken at
``Phi(±sqrt(n / (n - 1)) * t_{1-a/2, n-1})`` rather than at ``a/2`` (``a = 1 - level``), which widens the plain
percentile interval by the factor a Student interval has over a normal one, so that it does not under-cover at 5
or 10 replicates.

Pure functions of arrays: :func:`resample_weights` draws the bootstrap counts, :func:`interval` reads an
interval off the resampled figures, :func:`decide` compares it with the criterion's region.
"""

from __future__ import annotations

import dataclasses
import enum
import math

import numpy as np

#: Fewer replicates than this decide nothing.
MIN_REPLICATES = 3


class Verdict(enum.StrEnum):
    """What the runs can tell of a claim."""

    REPRODUCED = "reproduced"          # the whole interval on the claim's side of its criterion
    NOT_REPRODUCED = "not reproduced"  # the whole interval on the other side
    INCONCLUSIVE = "inconclusive"      # the interval straddles the criterion
    TOO_FEW = "too few runs"           # under MIN_REPLICATES replicates
    NO_DATA = "no data"                # no run gives the figure
    NOT_JUDGED = "not judged"          # the paper's words only: no criterion


@dataclasses.dataclass(frozen=True)
class Bootstrap:
    """How intervals are computed: the confidence ``level``, the number of ``resamples`` and the generator's
    ``seed`` (the same seed and rows give the same intervals)."""

    level: float = 0.95
    resamples: int = 2000
    seed: int = 0

    def __post_init__(self) -> None:
        if not 0.5 <= self.level < 1.0:
            raise ValueError(f"the level must be in [0.5, 1) (got {self.level})")
        if not 100 <= self.resamples <= 100_000:
            raise ValueError(f"resamples must be 100 to 100000 (got {self.resamples})")


@dataclasses.dataclass(frozen=True)
class Interval:
    """A figure (``value``, on every replicate once), its interval ``[low, high]`` at ``level`` and the number
    of replicates ``n`` it rests on."""

    value: float
    low: float
    high: float
    level: float
    n: int


@dataclasses.dataclass(frozen=True)
class Region:
    """Where a figure must lie for the claim to hold: ``low`` .. ``high`` (infinite for a one-sided bound),
    each end closed or open."""

    low: float = -math.inf
    high: float = math.inf
    low_closed: bool = True
    high_closed: bool = True

    def holds(self, x: float) -> bool:
        above = x >= self.low if self.low_closed else x > self.low
        below = x <= self.high if self.high_closed else x < self.high
        return above and below

    def distance(self, x: float) -> float:
        """How far ``x`` is from the nearest finite end of the region."""
        ends = [abs(x - e) for e in (self.low, self.high) if math.isfinite(e)]
        return min(ends) if ends else math.inf


def level_text(level: float) -> str:
    """A level as the tables print it: ``95 %``, ``98.3 %``."""
    return f"{100 * level:.3g} %"


def resample_weights(n: int, boot: Bootstrap) -> np.ndarray:
    """``boot.resamples`` bootstrap draws of ``n`` replicates: how many times each replicate is drawn, shape
    (resamples, n)."""
    rng = np.random.default_rng(boot.seed)
    return rng.multinomial(n, np.full(n, 1.0 / n), size=boot.resamples).astype(float)


def expanded_alpha(n: int, level: float) -> float:
    """The two-sided tail probability the percentiles are read at for ``n`` replicates (Hesterberg 2015)."""
    from scipy.special import ndtr, stdtrit  # not scipy.stats: its import alone was a third of a report's CPU

    if n < 2:
        return 1.0 - level
    z = math.sqrt(n / (n - 1)) * float(stdtrit(n - 1, 0.5 + level / 2))  # Student's t quantile
    return 2.0 * float(ndtr(-z))  # the normal's upper tail


def interval(value: float, resampled: np.ndarray, n: int, level: float) -> Interval:
    """The interval of a figure from its values on the resamples (NaN where a resample lacks the runs)."""
    finite = resampled[np.isfinite(resampled)]
    if not math.isfinite(value) or n == 0 or not len(finite):
        return Interval(value, math.nan, math.nan, level, n)
    alpha = expanded_alpha(n, level)
    low, high = np.quantile(finite, [alpha / 2, 1 - alpha / 2])
    return Interval(value, float(low), float(high), level, n)


def decide(iv: Interval, region: Region) -> Verdict:
    """The verdict an interval allows against the region where the claim holds."""
    if not math.isfinite(iv.value):
        return Verdict.NO_DATA
    if iv.n < MIN_REPLICATES:
        return Verdict.TOO_FEW
    if region.holds(iv.low) and region.holds(iv.high):
        return Verdict.REPRODUCED
    outside_low = iv.high < region.low or (iv.high == region.low and not region.low_closed)
    outside_high = iv.low > region.high or (iv.low == region.high and not region.high_closed)
    if outside_low or outside_high:
        return Verdict.NOT_REPRODUCED
    return Verdict.INCONCLUSIVE


def replicates_needed(iv: Interval, region: Region) -> int | None:
    """For an undecided figure: the replicates its interval would need to clear the nearest end of the region,
    from the observed spread (the half-width shrinks as 1/sqrt(n)); None when the figure sits on an end (no
    number of runs is known to decide it)."""
    half = (iv.high - iv.low) / 2
    d = region.distance(iv.value)
    if not (math.isfinite(half) and d > 0 and math.isfinite(d)) or iv.n < 1:
        return None
    return max(iv.n + 1, math.ceil(iv.n * (half / d) ** 2))
