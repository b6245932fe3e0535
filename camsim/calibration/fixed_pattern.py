"""Estimates of the dark fixed pattern from dark frames (issue 28): hot pixels, the dark-shading map, column FPN, and
the per-frame black-level error.

Each is a pure function of the reductions :mod:`camsim.calibration.measure` already makes of n dark frames of one
exposure: the per-pixel mean x̄ and temporal variance over the frames, and per frame the mean of each plane. The
model of a dark pixel (i, j) of a plane in frame f, in DN::

    x_fij = B + s_ij + c_j + h_ij + b_f + ρ_fi + ε_fij

B the plane's black level, s the dark shading (every fixed per-pixel offset: the offset DSNU, the dark current's
non-uniformity at this exposure, a smooth shading and fixed rows), c a fixed per-column offset (column FPN,
variance σ_c²), h ≥ 0 a hot pixel's extra dark charge (0 for most pixels), b_f the frame's black-level error of the
plane's colour (variance σ_b²), ρ the row noise (σ_row², one per physical row and frame) and ε the pixel's temporal
noise (σ_Y², read noise, quantisation and shot noise of the dark charge). The mean over n frames keeps the fixed
terms and divides the temporal ones' variance by n.

Expectations used (derived here; the tests check them on arrays of known law):

* the dark-shading map x̄ − B has, per pixel, the standard error √((σ_Y² + σ_row²) / n): the pixel's temporal
  noise and the row noise, averaged over the n frames (the frames' offsets b average to b̄, which B, the plane's
  mean over the same frames, holds too);
* hot pixels: d = x̄ − med₅ₓ₅(x̄), the mean less the median of its plane's 5 × 5 neighbourhood (which follows a
  smooth shading, and which a few hot pixels do not move); a pixel is hot where
  d > median(d) + m · max(1.4826 · MAD(d), √(σ̄²_pixel / n)), m = :data:`HOT_THRESHOLD_SIGMAS` = 5 — 5 σ of the
  spread of d (DSNU, fixed rows and columns, the mean's temporal noise) and never below 5 σ of the mean's temporal
  noise alone: a normal pixel's d exceeds it with probability 2.9 × 10⁻⁷ where d is Gaussian — and, in each half
  of the frames, half of it (a heavy-tailed read noise's one-frame outlier is in one half only); its extra dark
  current is d / (K T) (e⁻/s, T the exposure);
* column FPN, on the map of one chip (H × W, hot pixels replaced by their neighbourhood's median): the column means
  C_j vary as σ_c² + v_e / H, v_e the variance of what is neither row nor column (pixel DSNU and the temporal
  noise / n), with E[Σᵢⱼ e²] = v_e (H − 1)(W − 1) for e the map less its row and column means; C is first freed of
  a smooth trend (a polynomial of degree :data:`COLUMN_TREND_DEGREE` in j, the shading's), which leaves
  E[Σ C'²] = (W − d − 1)(σ_c² + v_e / H). So σ_c² = Σ C'² / (W − d − 1) − v_e / H;
* the black-level error: the mean F_f of a colour's N pixels in frame f varies over the frames as
  σ_b² + σ_Y² / N + σ_row² / R — the fixed pattern cancels, each pixel's temporal noise (without rows) averages over
  N, the row noise over the R physical rows that hold the colour's sites (a Bayer R or B: H/2, G: H) — so
  σ_b² = s²(F) − σ_Y² / N − σ_row² / R, s² with n − 1 degrees of freedom, averaged over the colours.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from camsim.calibration.estimate import Estimate, sqrt_estimate

#: m: a pixel is hot where its mean dark lies more than m robust standard deviations above its neighbourhood's.
HOT_THRESHOLD_SIGMAS = 5.0
#: The side of the neighbourhood (plane pixels) whose median is a pixel's local dark level.
LOCAL_WINDOW = 5
#: The degree of the polynomial trend removed from the column means before their spread is taken as column FPN.
COLUMN_TREND_DEGREE = 3
#: σ = 1.4826 · MAD for a normal law.
MAD_TO_SIGMA = 1.482602218505602


def local_level(mean_dn: np.ndarray, size: int = LOCAL_WINDOW) -> np.ndarray:
    """The median of each pixel's ``size`` × ``size`` neighbourhood in its plane (edges mirrored). Unit: DN.

    Parameters
    ----------
    mean_dn : numpy.ndarray, shape (H, W)
        One plane's mean dark frame. Unit: DN.
    """
    from scipy import ndimage

    return ndimage.median_filter(np.asarray(mean_dn, np.float64), size=size, mode="mirror")


@dataclass(frozen=True)
class HotPixels:
    """The hot pixels of one plane.

    Attributes
    ----------
    mask : numpy.ndarray of bool, shape (H, W)
    excess_dn : numpy.ndarray, shape (H, W)
        Mean dark less the local level where hot, 0 elsewhere. Unit: DN.
    local_dn : numpy.ndarray, shape (H, W)
        The local level (:func:`local_level`). Unit: DN.
    threshold_dn : float
        The excess above the local level beyond which a pixel is hot. Unit: DN.
    spread_dn : float
        The robust σ of the mean less its local level (or the mean's temporal noise, if larger). Unit: DN.
    """

    mask: np.ndarray
    excess_dn: np.ndarray
    local_dn: np.ndarray
    threshold_dn: float
    spread_dn: float

    @property
    def count(self) -> int:
        return int(np.count_nonzero(self.mask))


def find_hot_pixels(mean_dn: np.ndarray, variance_dn2, frames: int, halves: tuple | None = None,
                    sigmas: float = HOT_THRESHOLD_SIGMAS, size: int = LOCAL_WINDOW) -> HotPixels:
    """The hot pixels of one plane: mean dark far above the neighbourhood's (module docstring).

    Parameters
    ----------
    mean_dn : numpy.ndarray, shape (H, W)
        The plane's mean over the dark frames. Unit: DN.
    variance_dn2 : numpy.ndarray, shape (H, W), or float
        The pixels' temporal variance over the frames (ddof 1); of an array, the mean over the pixels that a first
        threshold (on the robust spread alone) leaves, so that the hot pixels' own shot noise does not count.
        Unit: DN².
    frames : int
        n.
    halves : tuple of numpy.ndarray, optional
        The plane's means over two halves of the frames (e.g. the even and the odd ones). Then a hot pixel must also
        lie more than half the threshold above its local level in each half: a fixed extra charge is in every
        frame, one frame's outlier of a heavy-tailed read noise in one half only. For a hot pixel right at the
        threshold this costs at most 4 % (z = 2.5/√2 in a half of at most √2 times the mean's noise); it removes 96 %
        of one-frame outliers.
    sigmas : float
        m, the threshold in robust standard deviations.
    size : int
        The neighbourhood's side.

    Returns
    -------
    HotPixels
    """
    mean_dn = np.asarray(mean_dn, np.float64)
    local = local_level(mean_dn, size)
    d = mean_dn - local
    centre = float(np.median(d))
    mad = MAD_TO_SIGMA * float(np.median(np.abs(d - centre)))
    if np.ndim(variance_dn2):
        first = d > centre + sigmas * mad
        variance = float(np.mean(np.asarray(variance_dn2)[~first])) if not first.all() else 0.0
    else:
        variance = float(variance_dn2)
    spread = max(mad, math.sqrt(max(variance, 0.0) / frames))
    threshold = centre + sigmas * spread
    mask = d > threshold
    if halves is not None:
        for half in halves:
            mask &= np.asarray(half, np.float64) - local > centre + 0.5 * sigmas * spread
    return HotPixels(mask, np.where(mask, d, 0.0), local, threshold, spread)


def shading_map(mean_dn: np.ndarray, black_dn: float, hot: HotPixels | None = None) -> np.ndarray:
    """The dark-shading map of one plane: its mean dark less its black level, a hot pixel's value its
    neighbourhood's median (its excess is the hot-pixel map's). Unit: DN (÷ K for e⁻)."""
    out = np.asarray(mean_dn, np.float64) - black_dn
    if hot is not None and hot.count:
        out = np.where(hot.mask, hot.local_dn - black_dn, out)
    return out


def map_standard_error(temporal_variance_dn2: float, frames: int) -> float:
    """The map's per-pixel standard error √(σ² / n), σ² a pixel's temporal variance less the black-level error's
    (which its plane's black level, a mean over the same frames, takes away): σ_Y² + σ_row². Unit: DN."""
    return math.sqrt(max(temporal_variance_dn2, 0.0) / frames)


def fixed_pattern_variance(map_dn: np.ndarray, variance_dn2: float, frames: int) -> Estimate:
    """The variance of the fixed pattern the map holds, its temporal noise removed: s²(map) − σ² / n (σ² =
    σ_Y² + σ_row², :func:`map_standard_error`), with the standard error of s² (√(2/N) s², a Gaussian's).
    Unit: DN²."""
    s2 = float(np.var(map_dn, ddof=1))
    return Estimate(s2 - variance_dn2 / frames, s2 * math.sqrt(2.0 / map_dn.size))


def fixed_pattern_rms(map_dn: np.ndarray, variance_dn2: float, frames: int) -> Estimate:
    """√ of :func:`fixed_pattern_variance` (0 where it is negative). Unit: DN."""
    return sqrt_estimate(fixed_pattern_variance(map_dn, variance_dn2, frames))


def mean_of_squares(estimates) -> Estimate:
    """The mean of independent estimates of squares (variances of several planes or chips), its standard error
    √(Σ SE²) / count. Unit: that of the squares."""
    estimates = list(estimates)
    value = float(np.mean([e.value for e in estimates]))
    return Estimate(value, math.sqrt(sum(e.standard_error**2 for e in estimates)) / len(estimates))


def column_fpn(map_dn: np.ndarray, degree: int = COLUMN_TREND_DEGREE) -> Estimate:
    """σ_c: √ of :func:`column_fpn_variance` (0 where that is negative). Unit: DN."""
    return sqrt_estimate(column_fpn_variance(map_dn, degree))


def column_fpn_variance(map_dn: np.ndarray, degree: int = COLUMN_TREND_DEGREE) -> Estimate:
    """Column fixed-pattern noise σ_c² of one chip's map (module docstring): the spread of the column means about a
    smooth trend, less what the pixels' own variance leaves in a mean of H. Unit: DN².

    Parameters
    ----------
    map_dn : numpy.ndarray, shape (H, W)
        The dark-shading map of a whole chip (a Bayer mosaic: both sites of each physical column), hot pixels
        replaced (:func:`shading_map`). Unit: DN.
    degree : int
        The trend's polynomial degree (−1: none).

    Returns
    -------
    Estimate
        σ_c² (it may be negative), its standard error √(2/(W − d − 1)) · s²(C').
    """
    x = np.asarray(map_dn, np.float64)
    h, w = x.shape
    rows, cols = x.mean(axis=1), x.mean(axis=0)
    e = x - rows[:, None] - cols[None, :] + x.mean()
    v_e = float(np.sum(e * e)) / ((h - 1) * (w - 1))
    if degree >= 0:
        t = np.linspace(-1.0, 1.0, w)
        basis = np.polynomial.legendre.legvander(t, degree)
        coef, *_ = np.linalg.lstsq(basis, cols, rcond=None)
        resid = cols - basis @ coef
        dof = w - degree - 1
    else:
        resid, dof = cols - cols.mean(), w - 1
    s2 = float(np.sum(resid * resid)) / dof
    return Estimate(s2 - v_e / h, s2 * math.sqrt(2.0 / dof))


def black_level_error_variance(frame_means_dn: np.ndarray, pixel_variance_dn2, pixels, row_variance_dn2: float,
                               rows) -> Estimate:
    """σ_b², the variance of the per-frame, per-colour black-level offset (module docstring). Unit: DN².

    Parameters
    ----------
    frame_means_dn : numpy.ndarray, shape (n, C)
        Per frame and colour: the mean of the colour's pixels (any constant per colour may be subtracted). Unit: DN.
    pixel_variance_dn2 : array_like, shape (C,)
        σ_Y² per colour: a pixel's temporal variance without row noise or the frame's offset. Unit: DN².
    pixels : array_like, shape (C,)
        N, the pixels of each colour.
    row_variance_dn2 : float
        σ_row², one offset per physical row and frame. Unit: DN².
    rows : array_like, shape (C,)
        R, the physical rows holding each colour's sites.

    Returns
    -------
    Estimate
        The colours' mean of s²(F) − σ_Y²/N − σ_row²/R (it may be negative), its standard error
        √(Σ_c 2 s_c⁴ / (n − 1)) / C.
    """
    f = np.asarray(frame_means_dn, np.float64)
    n, colours = f.shape
    s2 = np.var(f, axis=0, ddof=1)
    noise = (np.asarray(pixel_variance_dn2, np.float64) / np.asarray(pixels, np.float64)
             + max(row_variance_dn2, 0.0) / np.asarray(rows, np.float64))
    value = float(np.mean(s2 - noise))
    se = math.sqrt(float(np.sum(2 * s2 * s2 / (n - 1)))) / colours
    return Estimate(value, se)


def black_level_error(frame_means_dn: np.ndarray, pixel_variance_dn2, pixels, row_variance_dn2: float,
                      rows) -> Estimate:
    """σ_b: the square root of :func:`black_level_error_variance` (0 where that is negative). Unit: DN."""
    return sqrt_estimate(black_level_error_variance(frame_means_dn, pixel_variance_dn2, pixels, row_variance_dn2,
                                                    rows))


def hot_fraction(count: int, pixels: int) -> Estimate:
    """The share of hot pixels, with its binomial standard error √(p (1 − p) / N)."""
    p = count / pixels
    return Estimate(p, math.sqrt(max(p * (1 - p), 1.0 / pixels**2) / pixels))
