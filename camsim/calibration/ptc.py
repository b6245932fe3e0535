"""The photon transfer method: the system gain K from pairs of flat frames, and the PRNU.

For a pair A, B of flat frames of equal exposure, per plane: the mean signal μ = (Ā + B̄)/2 − black and the temporal
variance var(A − B)/2 (the difference cancels every fixed pattern — PRNU, DSNU, the light's shading — and its
mean, a flicker of the light between the two frames). Less the dark temporal variance (read, row and quantisation
noise, the same in the dark and in the light), what is left is the shot noise of the photo-electrons, K² · μ/K:

    var − var_dark = K μ,

a line through the origin whose slope is K (DN/e⁻). :func:`fit_photon_transfer` fits it by weighted least squares
(with an intercept, reported, that should be ≈ 0) over the levels of :func:`fit_range`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from camsim.calibration.estimate import Estimate, sqrt_estimate
from camsim.core.errors import CamsimError

#: The fit uses the levels up to this fraction of saturation (EMVA 1288: 70 %).
FIT_FRACTION = 0.7


def pair_statistics(a: np.ndarray, b: np.ndarray, black_dn: float) -> tuple[float, float]:
    """Mean signal and temporal variance of one plane of a flat pair.

    Parameters
    ----------
    a, b : numpy.ndarray
        The plane in the two frames. Unit: DN.
    black_dn : float
        The plane's black level. Unit: DN.

    Returns
    -------
    (float, float)
        μ = (mean(A) + mean(B))/2 − black (DN) and var(A − B)/2 (ddof 1; DN²).
    """
    a = a.astype(np.float64)
    b = b.astype(np.float64)
    mean = 0.5 * (float(np.mean(a)) + float(np.mean(b))) - black_dn
    return mean, float(np.var(a - b, ddof=1)) / 2


def fit_range(mean_dn: np.ndarray, variance_dn2: np.ndarray, full_scale_dn: float) -> np.ndarray:
    """Which levels the photon transfer fit uses: those at most :data:`FIT_FRACTION` of saturation.

    Saturation is where the temporal variance peaks (EMVA 1288): the level of the largest variance if a brighter
    level has less (the full well, or a non-linear top, clips the noise), else — the curve still rising at the
    brightest level — the ADC's range above the black level, ``full_scale_dn``.

    Parameters
    ----------
    mean_dn, variance_dn2 : numpy.ndarray
        μ and var of each pair. Units: DN, DN².
    full_scale_dn : float
        White level − black level. Unit: DN.

    Returns
    -------
    numpy.ndarray of bool
    """
    mean_dn = np.asarray(mean_dn, dtype=np.float64)
    peak = int(np.argmax(variance_dn2))
    brighter = mean_dn > mean_dn[peak]
    saturation = mean_dn[peak] if np.any(brighter) else full_scale_dn
    return mean_dn <= FIT_FRACTION * saturation


@dataclass(frozen=True)
class PtcFit:
    """The photon transfer fit of one plane.

    Attributes
    ----------
    k_dn_per_e : Estimate
        The slope K, with its standard error. Unit: DN/e⁻.
    intercept_dn2 : Estimate
        The line's value at μ = 0 (≈ 0 when the dark variance was subtracted right). Unit: DN².
    r_squared : float
        The weighted coefficient of determination.
    chi2_per_dof : float or None
        Σ w (y − ŷ)² / (m − 2): ≈ 1 when the points scatter as their sampling noise says (None with 2 points).
    used : numpy.ndarray of bool
        The pairs fitted.
    """

    k_dn_per_e: Estimate
    intercept_dn2: Estimate
    r_squared: float
    chi2_per_dof: float | None
    used: np.ndarray


def fit_photon_transfer(mean_dn, variance_dn2, dark_variance_dn2: float, pixels: int, used=None) -> PtcFit:
    """Weighted least squares of var − var_dark = K μ + c over the pairs ``used``.

    Each point's variance is a sample variance of N − 1 degrees of freedom: its standard deviation is
    √(2/(N − 1)) var (Gaussian fourth moment), and the weight 1/that². The covariance of (K, c) is (XᵀWX)⁻¹,
    widened by χ²/(m − 2) where the points scatter more than that (non-linearity); the 95 % interval is K ± 1.96 SE.

    Parameters
    ----------
    mean_dn, variance_dn2 : array_like
        μ and var(A − B)/2 of each pair. Units: DN, DN².
    dark_variance_dn2 : float
        The dark temporal variance. Unit: DN².
    pixels : int
        N, the plane's pixels.
    used : array_like of bool, optional
        The pairs to fit (default all).

    Returns
    -------
    PtcFit

    Raises
    ------
    CamsimError
        Fewer than 2 distinct levels to fit.
    """
    mu = np.asarray(mean_dn, dtype=np.float64)
    var = np.asarray(variance_dn2, dtype=np.float64)
    used = np.ones(mu.shape, bool) if used is None else np.asarray(used, bool)
    if np.unique(np.round(mu[used], 6)).size < 2:
        raise CamsimError("the photon transfer fit needs at least 2 distinct flat levels below saturation")
    x, y = mu[used], var[used] - dark_variance_dn2
    sd = np.sqrt(2.0 / (pixels - 1)) * np.maximum(var[used], 1e-12)
    w = 1.0 / sd**2
    design = np.stack([x, np.ones_like(x)], axis=1)
    normal = design.T @ (design * w[:, None])
    cov = np.linalg.inv(normal)
    beta = cov @ (design.T @ (w * y))
    residual = y - design @ beta
    m = x.size
    chi2 = float(np.sum(w * residual**2))
    chi2_per_dof = chi2 / (m - 2) if m > 2 else None
    if chi2_per_dof is not None and chi2_per_dof > 1:
        cov = cov * chi2_per_dof
    y_bar = float(np.sum(w * y) / np.sum(w))
    total = float(np.sum(w * (y - y_bar) ** 2))
    r2 = 1.0 - chi2 / total if total > 0 else 1.0
    k = Estimate(float(beta[0]), math.sqrt(cov[0, 0]))
    c = Estimate(float(beta[1]), math.sqrt(cov[1, 1]))
    return PtcFit(k, c, r2, chi2_per_dof, used)


def combine(estimates: list) -> Estimate:
    """The inverse-variance weighted mean of independent estimates of one quantity (K of the planes)."""
    se = np.array([e.standard_error for e in estimates], dtype=np.float64)
    values = np.array([e.value for e in estimates], dtype=np.float64)
    if np.any(~(se > 0)):
        return Estimate(float(np.mean(values)), None)
    w = 1 / se**2
    return Estimate(float(np.sum(w * values) / np.sum(w)), float(1 / math.sqrt(np.sum(w))))


def detrend(plane: np.ndarray, block: int = 16) -> np.ndarray:
    """``plane`` less a quadratic surface in x and y fitted to its block means (the light's shading, a lens's
    vignetting), plus the plane's mean: what is left is the pixel-to-pixel non-uniformity. The surface has 6
    parameters, so a uniform field loses a fraction of only ~6/N of its spatial variance. Unit: that of ``plane``."""
    h, w = plane.shape
    sy, sx = min(block, h), min(block, w)  # block sides; the blocks cover the plane but its last partial ones
    ny, nx = h // sy, w // sx
    means = plane[: ny * sy, : nx * sx].reshape(ny, sy, nx, sx).mean(axis=(1, 3))
    y = (np.arange(ny) * sy + sy / 2) / h * 2 - 1  # the blocks' centres, in the pixels' coordinates below
    x = (np.arange(nx) * sx + sx / 2) / w * 2 - 1
    yy, xx = np.meshgrid(y, x, indexing="ij")
    terms = lambda X, Y: [np.ones_like(X * Y), X, Y, X * X, X * Y, Y * Y]  # noqa: E731
    design = np.stack([t.ravel() for t in terms(xx, yy)], axis=1)
    coef, *_ = np.linalg.lstsq(design, means.ravel(), rcond=None)
    Y = ((np.arange(h) + 0.5) / h * 2 - 1)[:, None]
    X = ((np.arange(w) + 0.5) / w * 2 - 1)[None, :]
    surface = sum(c * t for c, t in zip(coef, terms(X, Y)))
    return plane - surface + float(np.mean(plane))


def prnu(flat_mean_dn: np.ndarray, dark_mean_dn: np.ndarray, pair_variance_dn2: float,
         dark_variance_dn2: float, dark_frames: int, row_variance_dn2: float = 0.0) -> Estimate:
    """Photo-response non-uniformity of one plane from one flat pair: the spatial standard deviation of the
    signal, relative to its mean, in %.

    The signal image is the pair's mean less the dark frames' mean (which removes the DSNU pixel by pixel),
    detrended (:func:`detrend`: the light's shading is not the sensor's). Its spatial variance, less the temporal
    variance left in it — the pair mean's, var(A − B)/4, and the dark mean's, σ²_dark / n — is (PRNU · μ)².

    Parameters
    ----------
    flat_mean_dn : numpy.ndarray
        (A + B)/2, the plane. Unit: DN.
    dark_mean_dn : numpy.ndarray
        The per-pixel mean of the dark frames, the plane. Unit: DN.
    pair_variance_dn2 : float
        var(A − B)/2 of the pair. Unit: DN².
    dark_variance_dn2 : float
        The dark temporal variance. Unit: DN².
    dark_frames : int
    row_variance_dn2 : float
        σ_row², for the standard error: the row noise left in both means (σ_row²/2 + σ_row²/n), which only the
        H rows sample. Unit: DN².

    Returns
    -------
    Estimate
        PRNU in % (0 where the estimate of its square is negative; NaN where the plane is not brighter than the
        darks).
    """
    signal = detrend(flat_mean_dn.astype(np.float64) - dark_mean_dn)
    mu = float(np.mean(signal))
    if not mu > 0:
        return Estimate(math.nan)
    spatial = float(np.var(signal, ddof=1))
    row_part = max(row_variance_dn2, 0.0) * (0.5 + 1.0 / dark_frames)
    se2 = (2 * spatial**2 / signal.size + 2 * row_part**2 / signal.shape[0]
           + pair_variance_dn2**2 / (2 * signal.size))  # the last: var(A − B)/2's own error, halved
    square = Estimate(spatial - pair_variance_dn2 / 2 - dark_variance_dn2 / dark_frames, math.sqrt(se2))
    return sqrt_estimate(square).scaled(100.0 / mu)

