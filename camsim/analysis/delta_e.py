"""The paper's 5-step ΔE_ab procedure.

1. White: CIE 1931 2° D65 at Y = 100.
2. Each sample's XYZ is scaled to Y = 100 (samples with Y ≤ 0 or non-finite cannot be: counted and excluded).
3. CIELAB of every sample against that white.
4. ΔE_ab (CIE 1976) of each sample to a reference Lab: the mean Lab of the same patch at F = 1.
5. The mean over samples.

Because every sample is scaled to Y = 100 = Y_n, L* is always 100: the procedure compares chromaticity only.
Samples are rows, shape (..., 3).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from camsim.light.spectra import CMFS_NAME, import_colour


def d65_white_xy() -> np.ndarray:
    """xy of the CIE 1931 2° D65 white point (``colour.CCS_ILLUMINANTS``), shape (2,)."""
    return np.asarray(import_colour().CCS_ILLUMINANTS[CMFS_NAME]["D65"], dtype=np.float64)


def d65_white_xyz_y100() -> np.ndarray:
    """XYZ of the D65 white point with Y = 100, shape (3,) (step 1)."""
    x, y = d65_white_xy()
    return np.array([x / y, 1.0, (1.0 - x - y) / y]) * 100.0


def _rows(xyz) -> np.ndarray:
    xyz = np.asarray(xyz, dtype=np.float64)
    if xyz.shape[-1:] != (3,):
        raise ValueError(f"xyz must have shape (..., 3), got {xyz.shape}")
    return xyz.reshape(-1, 3)


def lab_scaled_to_y100(xyz, return_valid=False):
    """CIELAB of samples scaled to Y = 100, against D65 at Y = 100 (steps 2–3).

    Parameters
    ----------
    xyz : array_like, shape (..., 3)
        XYZ samples as rows, any common scale; leading axes are flattened.

    Returns
    -------
    lab : numpy.ndarray, shape (m, 3)
        L*, a*, b* of the m valid samples, in input order (L* = 100 for all of them).
    n_undefined : int
        Samples excluded because Y ≤ 0 or a component is not finite.
    valid : numpy.ndarray of bool, shape (n,)
        Only with ``return_valid``: which input rows the Lab values belong to.
    """
    colour = import_colour()
    xyz = _rows(xyz)
    y = xyz[:, 1]
    valid = np.all(np.isfinite(xyz), axis=1) & (y > 0)
    scaled = xyz[valid] * (100.0 / y[valid, None])
    scaled[:, 1] = 100.0  # exactly, not up to rounding
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        lab = colour.XYZ_to_Lab(scaled / 100.0, illuminant=d65_white_xy())
    lab = np.asarray(lab, dtype=np.float64).reshape(-1, 3)
    n_undefined = int(xyz.shape[0] - lab.shape[0])
    finite = np.all(np.isfinite(lab), axis=1)  # overflow of huge ratios X/Y: counted, never NaN
    if return_valid:
        valid[np.flatnonzero(valid)[~finite]] = False
        return lab[finite], n_undefined + int(np.count_nonzero(~finite)), valid
    return lab[finite], n_undefined + int(np.count_nonzero(~finite))


def reference_lab(xyz_at_f1, weights=None):
    """Reference Lab of a patch: the mean Lab of its F = 1 samples after scaling to Y = 100.

    Parameters
    ----------
    xyz_at_f1 : array_like, shape (..., 3)

    Returns
    -------
    lab : numpy.ndarray, shape (3,), or None
        None when no sample is valid (no reference can be formed).
    n_undefined : int
        Samples excluded (Y ≤ 0 or non-finite).
    """
    lab, _, valid = lab_scaled_to_y100(xyz_at_f1, return_valid=True)
    w = None if weights is None else np.asarray(weights)[valid]
    n_undefined = int(np.count_nonzero(~valid)) if weights is None else int(np.sum(np.asarray(weights)[~valid]))
    return (np.average(lab, axis=0, weights=w) if lab.shape[0] else None), n_undefined


@dataclass(frozen=True)
class DeltaE:
    """ΔE_ab of a patch's samples to its reference.

    Attributes
    ----------
    mean : float or None
        Mean ΔE_ab (CIE 1976) over the valid samples; None when there is none.
    std : float or None
        Sample standard deviation (ddof = 1) of ΔE_ab; None when fewer than 2 samples are valid.
    n_samples : int
        Valid samples used.
    n_undefined : int
        Samples excluded (Y ≤ 0 or non-finite).
    """

    mean: float | None
    std: float | None
    n_samples: int
    n_undefined: int


def delta_e_5step(xyz, reference_lab, weights=None) -> DeltaE:
    """The paper's 5-step ΔE_ab of XYZ samples to a reference Lab.

    Parameters
    ----------
    xyz : array_like, shape (..., 3)
        XYZ samples of one patch at one F, any common scale.
    reference_lab : array_like, shape (3,)
        From :func:`reference_lab` (the same patch at F = 1).
    weights : array_like of int, optional
        Frequency of each row (distinct samples with their counts).

    Returns
    -------
    DeltaE
    """
    colour = import_colour()
    ref = np.asarray(reference_lab, dtype=np.float64)
    if ref.shape != (3,) or not np.all(np.isfinite(ref)):
        raise ValueError(f"reference_lab must be 3 finite numbers, got {reference_lab!r}")
    lab, _, valid = lab_scaled_to_y100(xyz, return_valid=True)
    w = np.ones(lab.shape[0], dtype=np.int64) if weights is None else np.asarray(weights, dtype=np.int64)[valid]
    n_undefined = int(np.count_nonzero(~valid)) if weights is None else int(np.sum(np.asarray(weights)[~valid]))
    n = int(w.sum())
    if n == 0:
        return DeltaE(None, None, 0, n_undefined)
    de = np.asarray(colour.delta_E(lab, np.broadcast_to(ref, lab.shape), method="CIE 1976"), dtype=np.float64)
    de = de.reshape(-1)
    mean = float(np.average(de, weights=w))
    std = float(np.sqrt(np.sum(w * (de - mean) ** 2) / (n - 1))) if n >= 2 else None
    return DeltaE(mean, std, n, n_undefined)
