"""The radio's signal model fitted to measured received power (docs/guides/radio-measured.md): pure functions of
arrays, with the distances and wall counts given (``world/site_grid.py`` counts the walls with netem's own
counter).

Every model is eq. 4 of Benavides et al. (``core/radio.py``, with a nominal range of 1 m) written in dBm, with a
reference power ``P0`` at 1 m::

    RSS = P0 - 10 * n * log10(d / 1 m) - min(nW, C) * WAF

``log-distance`` has no walls (P0 and n fitted); ``wall`` fits P0, n and WAF by linear least squares for every
cap C from 0 to the most walls of any reading and keeps the C of least squared error; ``per_anchor`` gives every
anchor its own P0 (antennas differ). ``defaults`` (today's ``[radio]`` constants) and ``cost231`` (COST 231's
multi-wall model: free space, n = 2, and 3.4 dB per light wall, uncapped) fit only P0.

Each fit is scored by its RMSE on the readings it was fitted to, by a spatially blocked k-fold cross-validation
(square blocks of ``block_m`` metres dealt at random, by a seeded generator, into ``folds`` folds: neighbouring
readings are correlated, so a reading's neighbours are held out with it), by its residuals' standard deviation
and by the distance at which their correlation falls to 1/e (:func:`correlation_distance`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.optimize import lsq_linear

from fleet_emu.core.radio import RadioConfig, signal_db
from fleet_emu.core.rng import generator

#: The models :func:`fit` knows, in the order the table shows them.
MODELS = ("defaults", "cost231", "log-distance", "wall")
#: COST 231 multi-wall: attenuation of a light wall in dB (COST Action 231 final report, ch. 4.7.2).
COST231_LIGHT_WALL_DB = 3.4
#: The cross-validation's folds and block size (metres), and the seed that deals the blocks into folds.
FOLDS, BLOCK_M, CV_SEED = 5, 1.0, 0
#: Correlogram of the residuals: bin width and reach in metres, and the most readings of one anchor it pairs (more
#: are subsampled, seeded: the pairs grow as the square).
LAG_BIN_M, LAG_MAX_M, LAG_MAX_READINGS = 0.1, 4.0, 8000


@dataclasses.dataclass(frozen=True)
class Readings:
    """The measured readings, one entry each: its anchor (index), its position (index into ``xy``), the
    distance in metres, the walls counted and the RSS in dBm; ``anchors`` is how many anchors there are."""

    anchor: np.ndarray
    point: np.ndarray
    distance: np.ndarray
    walls: np.ndarray
    rss: np.ndarray
    xy: np.ndarray
    anchors: int

    def subset(self, keep: np.ndarray) -> Readings:
        return dataclasses.replace(self, anchor=self.anchor[keep], point=self.point[keep],
                                   distance=self.distance[keep], walls=self.walls[keep], rss=self.rss[keep])


def links(distance: np.ndarray, walls: np.ndarray, rss: np.ndarray, xy: np.ndarray) -> Readings:
    """The readings of ``rss`` (K x N, NaN: none) with their ``distance`` and ``walls`` (K x N), as links."""
    point, anchor = np.nonzero(np.isfinite(rss))
    return Readings(anchor, point, distance[point, anchor], walls[point, anchor].astype(np.int64),
                 rss[point, anchor], xy, rss.shape[1])


@dataclasses.dataclass(frozen=True)
class Fit:
    """A fitted model: ``p0`` (dBm at 1 m, one per anchor), the path-loss exponent, the dB per wall and the cap
    on walls (None: uncapped)."""

    model: str
    per_anchor: bool
    p0: tuple[float, ...]
    path_loss: float
    waf: float
    max_walls: int | None
    fitted: int

    @property
    def p0_mean(self) -> float:
        return float(np.mean(self.p0))


def predict(f: Fit, anchor: np.ndarray, distance: np.ndarray, walls: np.ndarray) -> np.ndarray:
    """The model's RSS in dBm for links to ``anchor`` (index) at ``distance`` metres through ``walls`` walls:
    the anchor's P0 plus eq. 4 itself (:func:`fleet_emu.core.radio.signal_db`, the function netem uses, with a
    nominal range of 1 m), not a second implementation of it."""
    radio = RadioConfig(comm="wall", comm_range=1.0, path_loss=f.path_loss, waf=f.waf,
                        max_walls=10**6 if f.max_walls is None else f.max_walls)
    eq4 = np.fromiter((signal_db(d, int(w), radio) for d, w in zip(distance.ravel().tolist(),
                                                                   walls.ravel().tolist(), strict=True)),
                      dtype=float, count=distance.size).reshape(distance.shape)
    return np.asarray(f.p0)[anchor] + eq4


def fit(model: str, lk: Readings, per_anchor: bool = False) -> Fit:
    """The least-squares fit of ``model`` (:data:`MODELS`) to the links."""
    defaults = RadioConfig()
    if model == "defaults":
        return _solve(lk, per_anchor, model, path_loss=defaults.path_loss, waf=defaults.waf,
                      cap=defaults.max_walls)
    if model == "cost231":
        return _solve(lk, per_anchor, model, path_loss=2.0, waf=COST231_LIGHT_WALL_DB, cap=None)
    if model == "log-distance":
        return _solve(lk, per_anchor, model, path_loss=None, waf=0.0, cap=0)
    if model != "wall":
        raise ValueError(f"unknown model {model!r}")
    fits = [_solve(lk, per_anchor, model, path_loss=None, waf=None, cap=c) for c in range(1, int(lk.walls.max()) + 1)]
    if not fits:
        return _solve(lk, per_anchor, model, path_loss=None, waf=0.0, cap=0)
    return min(fits, key=lambda f: float(np.sum((lk.rss - predict(f, lk.anchor, lk.distance, lk.walls)) ** 2)))


def _solve(lk: Readings, per_anchor: bool, model: str, *, path_loss: float | None, waf: float | None,
           cap: int | None) -> Fit:
    """Linear least squares for the free ones of P0, n and WAF (n and WAF within ``[radio]``'s ranges), the
    others fixed; one P0 per anchor or one for all."""
    log_d = np.log10(np.maximum(lk.distance, 1e-3))
    capped = lk.walls if cap is None else np.minimum(lk.walls, cap)
    target = lk.rss.copy()
    if path_loss is not None:
        target += 10.0 * path_loss * log_d
    if waf is not None:
        target += waf * capped
    groups = lk.anchors if per_anchor else 1
    cols = [(lk.anchor == a).astype(float) for a in range(groups)] if per_anchor else [np.ones(len(target))]
    low, high = [-np.inf] * groups, [np.inf] * groups
    if path_loss is None:
        cols.append(-10.0 * log_d)
        low.append(0.0)
        high.append(100.0)
    if waf is None:
        cols.append(-capped.astype(float))
        low.append(0.0)
        high.append(1000.0)
    x = lsq_linear(np.stack(cols, axis=1), target, bounds=(low, high)).x
    p0 = tuple(float(v) for v in x[:groups]) if per_anchor else (float(x[0]),) * lk.anchors
    n = float(x[groups]) if path_loss is None else path_loss
    w = float(x[-1]) if waf is None else waf
    return Fit(model, per_anchor, p0, n, w, cap, fitted=len(x) + (1 if model == "wall" else 0))


def residuals(f: Fit, lk: Readings) -> np.ndarray:
    """Measured less predicted, dB."""
    return lk.rss - predict(f, lk.anchor, lk.distance, lk.walls)


def blocks(xy: np.ndarray, block_m: float = BLOCK_M, folds: int = FOLDS, seed: int = CV_SEED) -> np.ndarray:
    """Each position's fold: its square block of ``block_m`` metres, the blocks dealt into ``folds`` folds in a
    seeded random order."""
    block = block_ids(xy, block_m)
    order = generator(seed, "radio-fit-folds").permutation(int(block.max()) + 1)
    return np.asarray(order[block] % folds)


def block_ids(xy: np.ndarray, block_m: float = BLOCK_M) -> np.ndarray:
    """Each position's square block of ``block_m`` metres, numbered from 0."""
    _, block = np.unique(np.floor(xy / block_m).astype(np.int64), axis=0, return_inverse=True)
    return np.asarray(block.ravel())


def cv_errors(model: str, lk: Readings, per_anchor: bool = False, block_m: float = BLOCK_M,
              folds: int = FOLDS) -> np.ndarray:
    """Every reading's error (measured less predicted, dB) under a fit that did not see its block (spatially
    blocked k-fold)."""
    fold = blocks(lk.xy, block_m, folds)[lk.point]
    err = np.empty(len(lk.rss))
    for k in range(folds):
        test = fold == k
        if not test.any():
            continue
        f = fit(model, lk.subset(~test), per_anchor)
        held = lk.subset(test)
        err[test] = residuals(f, held)
    return err


def paired_gain(worse: np.ndarray, better: np.ndarray, block: np.ndarray, reps: int = 2000,
                seed: int = CV_SEED) -> tuple[float, float, float]:
    """How much lower ``better``'s RMSE is than ``worse``'s (errors of the same readings, dB), with a 95 %
    interval from a bootstrap over the readings' blocks (whole blocks resampled: neighbours are correlated)."""
    nblocks = int(block.max()) + 1
    sq_w = np.bincount(block, weights=worse ** 2, minlength=nblocks)
    sq_b = np.bincount(block, weights=better ** 2, minlength=nblocks)
    count = np.bincount(block, minlength=nblocks).astype(float)
    draws = generator(seed, "radio-fit-bootstrap").integers(0, nblocks, size=(reps, nblocks))
    n = count[draws].sum(axis=1)
    gains = np.sqrt(sq_w[draws].sum(axis=1) / n) - np.sqrt(sq_b[draws].sum(axis=1) / n)
    point = float(np.sqrt(np.mean(worse ** 2)) - np.sqrt(np.mean(better ** 2)))
    lo, hi = np.quantile(gains, [0.025, 0.975])
    return point, float(lo), float(hi)


def correlogram(r: np.ndarray, lk: Readings, bin_m: float = LAG_BIN_M,
                reach_m: float = LAG_MAX_M) -> tuple[np.ndarray, np.ndarray]:
    """The residuals' correlation against separation: for pairs of readings of the same anchor at distinct
    positions, the mean product of their residuals over the residuals' mean square, in bins of ``bin_m``
    metres up to ``reach_m`` (beyond :data:`LAG_MAX_READINGS` readings of an anchor, a seeded subsample of
    them); (bin centres, correlation; NaN for an empty bin)."""
    nbins = round(reach_m / bin_m)
    sums, counts = np.zeros(nbins), np.zeros(nbins)
    var = float(np.mean(r ** 2))
    pick = generator(CV_SEED, "radio-fit-correlogram")
    for a in range(lk.anchors):
        sel = np.flatnonzero(lk.anchor == a)
        if len(sel) > LAG_MAX_READINGS:
            sel = np.sort(pick.choice(sel, LAG_MAX_READINGS, replace=False))
        p, ra = lk.xy[lk.point[sel]], r[sel]
        rows = max(1, 2_000_000 // max(len(ra), 1))  # a chunk's pair arrays stay near 16 MB
        for start in range(0, len(ra), rows):  # rows start.., against columns start.. (each pair once)
            q, rest = p[start:start + rows], p[start:]
            sq = (q[:, None, 0] - rest[None, :, 0]) ** 2 + (q[:, None, 1] - rest[None, :, 1]) ** 2
            upper = np.arange(len(q))[:, None] < np.arange(len(rest))[None, :]
            use = upper & (sq < reach_m * reach_m)
            b = (np.sqrt(sq[use]) / bin_m).astype(np.int64)
            prod = (ra[start:start + len(q), None] * ra[None, start:])[use]
            sums += np.bincount(b, weights=prod, minlength=nbins)[:nbins]
            counts += np.bincount(b, minlength=nbins)[:nbins]
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = sums / counts / var
    return (np.arange(nbins) + 0.5) * bin_m, rho


def correlation_distance(lags: np.ndarray, rho: np.ndarray) -> float:
    """The separation at which the correlation first falls to 1/e, interpolated linearly between bin centres
    (from 1 at 0 m); NaN when it never does within the correlogram's reach."""
    x0, y0 = 0.0, 1.0
    for x, y in zip(lags, rho, strict=True):
        if not math.isfinite(y):
            continue
        if y <= 1 / math.e:
            return float(x0 + (y0 - 1 / math.e) / (y0 - y) * (x - x0))
        x0, y0 = float(x), float(y)
    return math.nan


@dataclasses.dataclass(frozen=True)
class Score:
    """One model's row of the table: the fit, its errors in dB (on the readings fitted, and cross-validated),
    its residuals' standard deviation and 1/e correlation distance, and the correlated part of the residuals
    (the correlation at the first lag, ``rho0``: the share of their variance that is spatially correlated;
    ``shadow_m``: where the correlation falls to ``rho0 / e``)."""

    fit: Fit
    rmse: float
    cv_rmse: float
    residual_std: float
    correlation_m: float
    rho0: float
    shadow_m: float
    readings: int
    cv_errors: np.ndarray
    residuals: np.ndarray

    @property
    def shadow_std(self) -> float:
        """The standard deviation of the residuals' correlated part, dB: ``sqrt(rho0)`` of their RMS."""
        return float(math.sqrt(max(self.rho0, 0.0)) * self.rmse)


def score(model: str, lk: Readings, per_anchor: bool = False, block_m: float = BLOCK_M, folds: int = FOLDS) -> Score:
    """Fit ``model`` to every link and score it (the module docstring says how)."""
    f = fit(model, lk, per_anchor)
    r = residuals(f, lk)
    lags, rho = correlogram(r, lk)
    rho0 = float(rho[0])
    err = cv_errors(model, lk, per_anchor, block_m, folds)
    return Score(f, float(np.sqrt(np.mean(r ** 2))), float(np.sqrt(np.mean(err ** 2))), float(np.std(r)),
                 correlation_distance(lags, rho), rho0, correlation_distance(lags, rho / rho0), len(r), err, r)
