"""Chromaticity ellipses by PCA of a patch's xy samples (the paper's Ref. 29)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MIN_SAMPLES = 3
RANK1_RATIO = 1e-12
"""λ2 ≤ RANK1_RATIO · λ1 counts as rank 1 (all samples on a line)."""


@dataclass(frozen=True)
class Ellipse:
    """A PCA ellipse of 2-D samples.

    Attributes
    ----------
    center_x, center_y : float or None
        Sample mean (same unit as the samples, e.g. xy). None only when there are no samples.
    semi_major, semi_minor : float or None
        a = k √λ1 ≥ b = k √λ2: λ1 ≥ λ2 the eigenvalues of the sample covariance (ddof = 1), k the confidence
        in σ (``confidence_sigma``).
    angle_deg : float or None
        Inclination of the major axis to the x axis, in degrees, in (−90, 90].
    size : float or None
        √(a² + b²).
    n_samples : int
    status : str
        ``"ok"``; or a degenerate case: ``"too-few-samples"`` (< 3; only the centre is given, if n ≥ 1),
        ``"constant"`` (all samples equal: a = b = size = 0, angle None), ``"rank-1"`` (samples on a line:
        b = 0, a, angle and size = a are given).
    """

    center_x: float | None
    center_y: float | None
    semi_major: float | None
    semi_minor: float | None
    angle_deg: float | None
    size: float | None
    n_samples: int
    status: str


def _major_axis_angle_deg(vector) -> float:
    """Angle of an axis direction to the x axis, folded into (−90, 90] degrees."""
    angle = float(np.degrees(np.arctan2(vector[1], vector[0])))
    while angle <= -90.0:
        angle += 180.0
    while angle > 90.0:
        angle -= 180.0
    return angle


def _covariance_eigen(xy, weights=None):
    """Eigenvalues λ1 ≥ λ2 (clipped at 0) and the unit major-axis vector of the sample covariance."""
    values, vectors = np.linalg.eigh(np.cov(xy, rowvar=False, ddof=1, fweights=weights))
    values = np.clip(values, 0.0, None)
    return values[1], values[0], vectors[:, 1]


def fit_ellipse(xy, confidence_sigma=1.0, weights=None) -> Ellipse:
    """Fit the PCA ellipse of a set of 2-D samples.

    Parameters
    ----------
    xy : array_like, shape (n, 2)
        Samples as rows (e.g. xy chromaticities from :func:`camsim.colour.colorimetry.chromaticity_xy`).
        Must be finite: exclude undefined samples first.
    confidence_sigma : float
        k: the semi-axes are k standard deviations along the principal axes (k = 1: the 1 σ ellipse).
    weights : array_like of int, shape (n,), optional
        Frequency of each row (distinct samples with their counts): the same fit as on the repeated samples.

    Returns
    -------
    Ellipse
        Degenerate sample sets are reported by ``status``, with undefined fields None (never NaN).
    """
    xy = np.asarray(xy, dtype=np.float64)
    if xy.ndim != 2 or xy.shape[1] != 2:
        raise ValueError(f"xy must have shape (n, 2), got {xy.shape}")
    if not np.all(np.isfinite(xy)):
        raise ValueError("xy contains NaN or infinite values; exclude undefined samples before fitting")
    if not (np.isfinite(confidence_sigma) and confidence_sigma > 0):
        raise ValueError(f"confidence_sigma must be finite and positive, got {confidence_sigma!r}")
    if weights is not None:
        weights = np.asarray(weights, dtype=np.int64)
        if weights.shape != (xy.shape[0],) or np.any(weights < 1):
            raise ValueError("weights must be one positive count per row")
    n = xy.shape[0] if weights is None else int(weights.sum())
    cx, cy = (float(v) for v in np.average(xy, axis=0, weights=weights)) if n else (None, None)
    if n < MIN_SAMPLES:
        return Ellipse(cx, cy, None, None, None, None, n, "too-few-samples")
    if np.all(xy == xy[0]):
        return Ellipse(float(xy[0, 0]), float(xy[0, 1]), 0.0, 0.0, None, 0.0, n, "constant")
    lam1, lam2, major = _covariance_eigen(xy, weights)
    a = confidence_sigma * float(np.sqrt(lam1))
    angle = _major_axis_angle_deg(major)
    if lam2 <= RANK1_RATIO * lam1:
        return Ellipse(cx, cy, a, 0.0, angle, a, n, "rank-1")
    b = confidence_sigma * float(np.sqrt(lam2))
    return Ellipse(cx, cy, a, b, angle, float(np.hypot(a, b)), n, "ok")
