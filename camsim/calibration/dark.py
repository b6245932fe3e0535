"""Estimates from dark frames: black level, temporal dark variance, read noise, row noise, DSNU.

The dark frames of one plane are reduced to per-pixel moments over the n frames (:func:`pixel_moments`) and, in a
second pass, to residuals r = x − x̄ (each pixel about its own mean, which removes the black level and every fixed
pattern), their row means m (per frame and row) and the residuals less their row mean (which removes the row
noise). Each estimate is then one pure function of those sums, in DN (DN² for variances); :class:`Estimate` carries
its standard error. Expectations used (σ² the per-pixel temporal variance without the row noise, σ_row² the row
noise's, W the pixels averaged per row, n the frames):

* E[mean over pixels of the per-pixel variance (ddof 1)] = σ² + σ_row² (the dark temporal variance, what
  var(A − B)/2 of a dark pair estimates);
* E[(r − m)²] = σ² (1 − 1/n)(1 − 1/W);
* E[Σᵢ m²] / (n − 1) = σ_row² + σ² / W.
"""

from __future__ import annotations

import math

import numpy as np

from camsim.calibration.estimate import Estimate, sqrt_estimate


def pixel_moments(total: np.ndarray, squares: np.ndarray, frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel mean and temporal variance (ddof 1) over ``frames`` frames from exact integer sums.

    Parameters
    ----------
    total, squares : numpy.ndarray, int64
        Σ x and Σ x² over the frames, per pixel. Unit: DN, DN².
    frames : int
        n ≥ 2.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Mean (DN) and variance (DN²), float64. The variance's numerator n Σx² − (Σx)² is formed in integers.
    """
    mean = total / frames
    variance = (frames * squares - total * total) / (frames * (frames - 1.0))
    return mean, variance


def black_level(mean_dn: np.ndarray, variance_dn2: np.ndarray, frames: int, row_variance_dn2: float = 0.0) -> Estimate:
    """The black level: the mean of the dark frames' values over one plane. Unit: DN.

    Its standard error, as an estimate of the mean of an unlit pixel (over the fixed pattern's law too):
    √(s²_spatial / N + σ_row² / (n H)) — the spatial spread of the per-pixel means (DSNU and temporal noise)
    over N pixels, plus the row noise, common to the W pixels of a row (H rows).

    Parameters
    ----------
    mean_dn : numpy.ndarray
        Per-pixel mean over the frames (one plane, (H, W)). Unit: DN.
    variance_dn2 : numpy.ndarray
        Per-pixel temporal variance. Unit: DN².
    frames : int
    row_variance_dn2 : float
        σ_row². Unit: DN².
    """
    n_pixels = mean_dn.size
    rows = mean_dn.shape[0] if mean_dn.ndim > 1 else 1
    spatial = float(np.var(mean_dn, ddof=1)) if n_pixels > 1 else 0.0
    se2 = spatial / n_pixels + max(row_variance_dn2, 0.0) / (frames * rows)
    return Estimate(float(np.mean(mean_dn)), math.sqrt(se2))


def temporal_variance(variance_dn2: np.ndarray, frames: int) -> Estimate:
    """The dark temporal variance of one plane: the mean over pixels of each pixel's variance over the frames
    (ddof 1), read noise, quantisation, row noise and dark-current shot noise together — the same expectation as
    var(A − B)/2 of a pair. Unit: DN². Standard error √(2/(N (n − 1))) × the value (Gaussian fourth moment)."""
    value = float(np.mean(variance_dn2))
    return Estimate(value, value * math.sqrt(2.0 / (variance_dn2.size * (frames - 1))))


def sheppard_read_variance_dn2(variance_dn2: float, step_dn: float = 1.0) -> float:
    """The noise variance before the ADC from the variance of its integer output: Sheppard's correction, σ² − Δ²/12.
    Unit: DN².

    For a noise X of density f and a pixel level m, the ADC's output floor(X + m) has a variance that differs from
    σ² + Δ²/12 by terms of the order of f's characteristic function at 2π/Δ, periodic in m. Measured against the
    exact variance of the integer law (``tests/calibration/test_calibrate.py``), relative to σ²:

    ==================  ===========================  ===============================
    read noise          worst pixel level m          averaged over levels m
    ==================  ===========================  ===============================
    Gaussian, ½ DN      3 %                          1e-5
    Gaussian, 0.8 DN    1.4e-5                       < 1e-12
    Gaussian, 1 DN      1e-8                         < 1e-15
    Tukey −0.15, 1 DN   0.4 %                        2e-6
    Tukey −0.15, 1.5 DN 1.3e-4                       < 1e-7
    ==================  ===========================  ===============================

    So near 1 DN the correction is right for a Gaussian read noise whatever the level, but a heavy-tailed one
    (whose standard deviation is mostly its tails, so its core is narrow) needs the pixels' levels spread over
    the lattice — which the estimate, a mean over a plane's pixels, has wherever DSNU, dark signal or a
    fractional black level spreads them by ≳ 1 DN. Below about ½ DN no correction holds (the report warns).
    """
    return variance_dn2 - step_dn * step_dn / 12.0


def read_noise(residual_squares_dn2: float, count: int, frames: int, row_pixels: int | None,
               step_dn: float = 1.0) -> tuple[Estimate, float]:
    """The read noise's standard deviation σ_read (DN) from the residuals less their row means.

    σ_Y² = mean((r − m)²) / ((1 − 1/n)(1 − 1/W)) is each pixel's temporal variance without the row noise
    (quantisation included); σ_read² = σ_Y² − Δ²/12 (:func:`sheppard_read_variance_dn2`).

    Parameters
    ----------
    residual_squares_dn2 : float
        Σ (r − m)² over the plane's pixels and frames. Unit: DN².
    count : int
        Number of terms of that sum (pixels × frames).
    frames : int
        n, the frames the per-pixel means were taken over.
    row_pixels : int or None
        W, the pixels of each row mean (None: no row means were subtracted).
    step_dn : float
        The ADC's step Δ (0: values never quantised). Unit: DN.

    Returns
    -------
    (Estimate, float)
        σ_read in DN with its standard error, and σ_Y² in DN².
    """
    factor = (1.0 - 1.0 / frames) * (1.0 - 1.0 / row_pixels if row_pixels else 1.0)
    var_y = residual_squares_dn2 / count / factor
    dof = count * (1.0 - 1.0 / frames)
    var_read = sheppard_read_variance_dn2(var_y, step_dn)
    return sqrt_estimate(Estimate(var_read, var_y * math.sqrt(2.0 / dof))), var_y


def row_noise(row_means_dn: np.ndarray, pixel_variance_dn2: float, row_pixels: int,
              groups: np.ndarray | None = None) -> Estimate:
    """The row noise's standard deviation σ_row (DN) from the row means of the dark residuals.

    Each frame's row means m (of residuals about each pixel's mean: they sum to 0 over the frames) vary as
    σ_row² + σ²/W; so σ_row² = Σ m² / ((n − 1) R) − σ²/W over R rows.

    With ``groups``, each frame's row means first lose their mean over the rows of each group (the rows of one
    colour pattern — a Bayer mosaic's even and odd rows — or of one chip): that removes a per-frame offset of the
    frame's colours (the black-level error, :mod:`camsim.calibration.fixed_pattern`), which every row of a group
    shares; the degrees of freedom become (n − 1)(R − G) for G groups.

    Parameters
    ----------
    row_means_dn : numpy.ndarray, shape (n, R)
        Per frame and row: the mean of the row's residuals. Unit: DN.
    pixel_variance_dn2 : float
        σ², the pixels' temporal variance without the row noise (quantisation included). Unit: DN².
    row_pixels : int
        W, the pixels of each row mean.
    groups : numpy.ndarray of int, shape (R,), optional
        Each row's group (None: no per-frame mean is removed).

    Returns
    -------
    Estimate
        σ_row, 0 where the estimate of its square is negative. Unit: DN.
    """
    m = np.asarray(row_means_dn, np.float64)
    frames, rows = m.shape
    lost = 0
    if groups is not None:
        groups = np.asarray(groups)
        m = m.copy()
        for g in np.unique(groups):
            at = groups == g
            m[:, at] -= m[:, at].mean(axis=1, keepdims=True)
            lost += 1
    dof = (frames - 1) * (rows - lost)
    v_m = float(np.sum(np.square(m))) / dof
    return sqrt_estimate(Estimate(v_m - pixel_variance_dn2 / row_pixels, v_m * math.sqrt(2.0 / dof)))


def dsnu(mean_dn: np.ndarray, temporal_variance: Estimate, frames: int, row_variance_dn2: float = 0.0) -> Estimate:
    """Dark signal non-uniformity: the spatial standard deviation of the per-pixel mean dark level, less the
    temporal noise left in a mean of n frames: √(s²(x̄) − σ²_temporal / n). Unit: DN.

    The square's standard error adds three parts: the sample variance's over N pixels, 2 s⁴/N; the row noise left in
    the mean, σ_row²/n, which only H rows sample, 2 (σ_row²/n)²/H; and the temporal variance's own, SE(σ²)/n.

    Parameters
    ----------
    mean_dn : numpy.ndarray
        Per-pixel mean over the dark frames (one plane, (H, W)). Unit: DN.
    temporal_variance : Estimate
        The dark temporal variance (:func:`temporal_variance`). Unit: DN².
    frames : int
    row_variance_dn2 : float
        σ_row². Unit: DN².
    """
    spatial = float(np.var(mean_dn, ddof=1))
    rows = mean_dn.shape[0] if mean_dn.ndim > 1 else mean_dn.size
    se2 = (2 * spatial**2 / mean_dn.size + 2 * (max(row_variance_dn2, 0.0) / frames) ** 2 / rows
           + ((temporal_variance.standard_error or 0.0) / frames) ** 2)
    return sqrt_estimate(Estimate(spatial - temporal_variance.value / frames, math.sqrt(se2)))


def row_power_spectrum(row_means_dn: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The power spectrum of the row means, averaged over frames: |FFT(m)|² / R at frequencies 0 … ½ cycle/row.

    White row noise gives a flat spectrum at (1 − 1/n)(σ_row² + σ²/W) (the residuals' means lose 1/n of it);
    a peak shows a periodic row pattern (a banding frequency).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Frequencies (cycles / row) and power (DN² per frequency bin, normalised so that a white sequence of
        variance v gives v).
    """
    frames, rows = row_means_dn.shape
    power = np.mean(np.abs(np.fft.rfft(row_means_dn, axis=1)) ** 2, axis=0) / rows
    return np.fft.rfftfreq(rows), power
