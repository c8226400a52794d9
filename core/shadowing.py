"""Correlated shadowing: a seeded, static, spatially correlated log-normal term on every link's signal
(``[radio] shadowing_db``, ``shadowing_m``; docs/guides/radio.md, "Shadowing").

**The field.** Gudmundson (1991, "Correlation model for shadow fading in mobile radio systems", Electronics
Letters 27(23)) measured shadow fading in dB as a Gaussian process whose autocorrelation falls exponentially
with the distance moved, ``R(d) = sigma^2 exp(-d / d_c)``, ``d_c`` the decorrelation distance (the correlation
is ``1/e`` there). Here that autocorrelation is taken in both dimensions of the map, isotropic: one zero-mean
Gaussian field ``F`` over the map's cells, of unit variance, with ``corr(F(x), F(y)) = exp(-|x - y| / d_c)``,
drawn once per run from the run's seeded generator (``generator(seed, "netem", "shadowing")``) and static for
the run. It is drawn exactly by circulant embedding (Dietrich & Newsam 1997, SIAM J. Sci. Comput. 18(4)): the
covariance laid on a torus larger than the map by ``6 d_c`` (or twice the map, whichever is smaller), its
eigenvalues by FFT, white noise filtered by their square roots (the few slightly negative ones set to 0, and
the variance renormalised to 1); pairs further apart than the padding are off by at most ``exp(-6)`` in
correlation. A map whose torus would exceed :data:`MAX_TORUS` cells draws the field on every ``k``-th cell
(``k`` a power of two) and a cell reads its block's value.

**A link.** A field per position is what a decorrelation distance describes; a link joins two moving
positions. Its term is derived symmetrically from both ends::

    S(a, b) = sigma * (F(a) + F(b)) / sqrt(2 (1 + exp(-|a - b| / d_c)))

which is the same for (a, b) and (b, a), has standard deviation exactly ``sigma`` for every pair (the
denominator is the standard deviation of ``F(a) + F(b)``), is ``sigma F(a)`` when both ends share a cell, and
keeps Gudmundson's correlation ``exp(-delta / d_c)`` for a link whose two far-apart ends both move by ``delta``
(``(1 + exp(-delta / d_c)) / 2`` when only one end moves). The connectivity allocator's prediction (eq. 4 on a
belief, ``agents/allocators/connectivity.py``) does not include it: a robot does not know the field.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from fleet_emu.core.grid import Cell

#: Most cells of the torus a field is drawn on (16 M float64 draws: 128 MiB at most, briefly); a larger map
#: draws the field on every k-th cell.
MAX_TORUS = 1 << 24
#: Padding of the torus beyond the map, in decorrelation distances: correlations wrap at most exp(-6) = 0.25 %.
PAD = 6.0


@dataclasses.dataclass(frozen=True, eq=False)
class Shadowing:
    """A run's shadowing: the unit field ``field`` (one value per ``step`` x ``step`` block of map cells),
    ``sigma`` dB and the decorrelation distance ``corr_cells`` in cells."""

    field: np.ndarray
    sigma: float
    corr_cells: float
    step: int = 1

    def at(self, cells: Sequence[Cell]) -> np.ndarray:
        """The unit field at each cell (``F``, standard deviation 1)."""
        rc = np.asarray(cells, dtype=np.int64).reshape(len(cells), 2) // self.step
        return self.field[rc[:, 0], rc[:, 1]].astype(np.float64)

    def pair_db(self, cells: Sequence[Cell]) -> np.ndarray:
        """The term ``S`` (dB) added to the signal of each pair of endpoints at ``cells``: symmetric, 0 on the
        diagonal (see the module docstring)."""
        f = self.at(cells)
        rc = np.asarray(cells, dtype=np.float64).reshape(len(cells), 2)
        gap = np.hypot(rc[:, None, 0] - rc[None, :, 0], rc[:, None, 1] - rc[None, :, 1])
        s = self._term(f[:, None], f[None, :], gap)
        np.fill_diagonal(s, 0.0)
        return s

    def link_db(self, a: Sequence[Cell], b: Sequence[Cell]) -> np.ndarray:
        """The term ``S`` (dB) of each link ``a[k]``-``b[k]`` (the same as :meth:`pair_db`'s, pair by pair)."""
        ra = np.asarray(a, dtype=np.float64).reshape(len(a), 2)
        rb = np.asarray(b, dtype=np.float64).reshape(len(b), 2)
        return self._term(self.at(a), self.at(b), np.hypot(*(ra - rb).T))

    def _term(self, fa: np.ndarray, fb: np.ndarray, gap: np.ndarray) -> np.ndarray:
        """``sigma (F(a) + F(b)) / sqrt(2 (1 + exp(-gap / d_c)))``, ``gap`` in cells."""
        return self.sigma * (fa + fb) / np.sqrt(2.0 * (1.0 + np.exp(-gap / self.corr_cells)))


def shadowing(rng: np.random.Generator, shape: tuple[int, int], cell_size: float, sigma_db: float,
              corr_m: float) -> Shadowing | None:
    """A run's shadowing on a map of ``shape`` cells of ``cell_size`` metres (None when ``sigma_db`` is 0)."""
    if sigma_db <= 0:
        return None
    corr_cells = corr_m / cell_size
    field, step = unit_field(rng, shape, corr_cells)
    return Shadowing(field, float(sigma_db), corr_cells, step)


def unit_field(rng: np.random.Generator, shape: tuple[int, int], corr_cells: float) -> tuple[np.ndarray, int]:
    """A zero-mean, unit-variance Gaussian field with the autocorrelation ``exp(-d / corr_cells)`` (``d`` in
    cells), by circulant embedding; drawn on every ``step``-th cell (1 unless the map is very large). Returns
    the field (float32, ``ceil(shape / step)``) and ``step``."""
    h, w = (max(1, int(n)) for n in shape)
    step = 1
    while True:
        hs, ws, ell = -(-h // step), -(-w // step), corr_cells / step
        pad = math.ceil(PAD * ell)
        size = (_fast(hs + min(hs, pad)), _fast(ws + min(ws, pad)))
        if size[0] * size[1] <= MAX_TORUS:
            break
        step *= 2
    lam = _spectrum(size, ell)
    noise = rng.standard_normal(size)
    field = np.fft.irfft2(np.fft.rfft2(noise) * np.sqrt(lam), s=size)
    field /= math.sqrt(_variance(lam, size))
    return field[:hs, :ws].astype(np.float32), step


def _spectrum(size: tuple[int, int], ell: float) -> np.ndarray:
    """The eigenvalues (half spectrum, ``rfft2``'s layout) of the exponential covariance on a torus of ``size``
    cells, the negative ones set to 0."""
    p, q = size
    dr = np.minimum(np.arange(p), p - np.arange(p)).astype(np.float64)
    dc = np.minimum(np.arange(q), q - np.arange(q)).astype(np.float64)
    cov = np.exp(-np.hypot(dr[:, None], dc[None, :]) / max(ell, 1e-9))
    return np.maximum(np.fft.rfft2(cov).real, 0.0)


def _variance(lam: np.ndarray, size: tuple[int, int]) -> float:
    """The pointwise variance of the filtered noise: the mean of the full spectrum (from its half)."""
    p, q = size
    half = q // 2 + 1
    weights = np.full(half, 2.0)
    weights[0] = 1.0
    if q % 2 == 0:
        weights[-1] = 1.0
    return float((lam * weights[None, :]).sum() / (p * q))


def _fast(n: int) -> int:
    """The smallest 2^a 3^b 5^c at least ``n`` (sizes FFT is quick at)."""
    best = 1 << max(0, (n - 1).bit_length())
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            m = p35
            while m < n:
                m *= 2
            best = min(best, m)
            p35 *= 3
        p5 *= 5
    return best
