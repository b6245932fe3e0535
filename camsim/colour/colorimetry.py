"""Camera RGB → CIE XYZ → xy chromaticity (the paper's Eqs. 15–16).

A core module (it imports only :mod:`camsim.light.photons` and :mod:`camsim.light.spectra`): the preview, the analysis
and its consumers (experiments, denoise-eval) all take their colorimetry from here.

Conventions
-----------
Samples are rows: camera DN vectors and XYZ vectors have shape (..., 3), with the last axis (R, G, B) or
(X, Y, Z). A 3×3 matrix ``M`` maps them as ``xyz = dn @ M.T``.
"""

from __future__ import annotations

import numpy as np

from camsim.light.photons import LIGHT_SPEED_M_S, PLANCK_J_S
from camsim.light.spectra import cmfs_at

CHANNELS = ("R", "G", "B")
"""The camera's channels, in the order of the last axis of DN samples (and of a frame's first axis)."""
MAX_CONDITION = 1e12
"""Largest condition number of the matrix inverted before a camera is called singular."""


def matrix_condition(matrix) -> float:
    """2-norm condition number of a square matrix (``inf`` if singular), never NaN.

    ``matrix`` has shape (K, L); the result is σ_max / σ_min of its singular values, ``inf`` when σ_min is 0 or
    the matrix is not finite.
    """
    matrix = np.asarray(matrix, dtype=np.float64)
    if not np.all(np.isfinite(matrix)):
        return float("inf")
    sv = np.linalg.svd(matrix, compute_uv=False)
    if sv.size == 0 or sv[-1] <= 0.0:
        return float("inf")
    return float(sv[0] / sv[-1])


def _radiance_sensitivity(qe, wl, dn_per_electron):
    """C_i = k · Qe_i · λ_i · δ_i / (h c): DN per unit spectral radiance in bin i (λ in m, δ in nm)."""
    return dn_per_electron * qe * (wl * 1e-9) * np.gradient(wl) / (PLANCK_J_S * LIGHT_SPEED_M_S)


def _literal_sensitivity(qe, wl, dn_per_electron):
    """C_i = k · (h c / λ_i) · Qe_i, as Eq. 16 prints it."""
    return dn_per_electron * (PLANCK_J_S * LIGHT_SPEED_M_S / (wl * 1e-9)) * qe


def _check_camera(qe, wavelengths_nm, dn_per_electron):
    qe = np.asarray(qe, dtype=np.float64)
    wl = np.asarray(wavelengths_nm, dtype=np.float64)
    if wl.ndim != 1 or wl.size < 3 or qe.shape != (3, wl.size):
        raise ValueError(f"qe must have shape (3, N) for N ≥ 3 wavelengths, got {qe.shape} and {wl.shape}")
    if not (np.all(np.isfinite(qe)) and np.all(np.isfinite(wl)) and np.all(wl > 0)):
        raise ValueError("qe and wavelengths must be finite, and wavelengths positive")
    if not (np.isfinite(dn_per_electron) and dn_per_electron > 0):
        raise ValueError(f"dn_per_electron must be finite and positive, got {dn_per_electron!r}")
    return qe, wl


def _cmf_projection_matrix(sensitivity, wl):
    """M = (T Tᵗ)(C Tᵗ)⁻¹ and cond(C Tᵗ)."""
    t = cmfs_at(wl)  # CIE 1931 2° CMFs at the frame's wavelengths, shape (3, N)
    ctt = sensitivity @ t.T
    cond = matrix_condition(ctt)
    if cond > MAX_CONDITION:
        raise ValueError(
            f"camera is (near) singular: the 3×3 matrix C·Tᵗ of camera sensitivities against the CIE 1931 "
            f"colour-matching functions has condition number {cond:.3g} > {MAX_CONDITION:.0e}; the channels are "
            "(nearly) linearly dependent, so no camera → XYZ matrix exists"
        )
    try:
        m_t = np.linalg.solve(ctt.T, (t @ t.T).T)  # Mᵗ from (C Tᵗ)ᵗ Mᵗ = (T Tᵗ)ᵗ
    except np.linalg.LinAlgError as exc:
        raise ValueError(f"camera is singular: C·Tᵗ cannot be inverted ({exc})") from exc
    return m_t.T, cond


def _projection_method(sensitivity):
    def method(qe, wavelengths_nm, dn_per_electron, training):
        qe, wl = _check_camera(qe, wavelengths_nm, dn_per_electron)
        return _cmf_projection_matrix(sensitivity(qe, wl, dn_per_electron), wl)

    return method


def _least_squares(qe, wavelengths_nm, dn_per_electron, training):
    if training is None:
        raise ValueError('method "least-squares" needs training=(camera_dn (K, 3), xyz (K, 3))')
    dn, xyz = (np.asarray(a, dtype=np.float64) for a in training)
    if dn.ndim != 2 or dn.shape[1] != 3 or xyz.shape != dn.shape:
        raise ValueError(f"training arrays must both have shape (K, 3), got {dn.shape} and {xyz.shape}")
    if not (np.all(np.isfinite(dn)) and np.all(np.isfinite(xyz))):
        raise ValueError("training data contain NaN or infinite values")
    cond = matrix_condition(dn)
    if dn.shape[0] < 3 or cond > MAX_CONDITION:
        raise ValueError(
            f"least-squares training camera DN (K = {dn.shape[0]}) are rank-deficient (condition number "
            f"{cond:.3g}): need at least 3 samples spanning all three channels"
        )
    m_t, _, _, _ = np.linalg.lstsq(dn, xyz, rcond=None)
    return m_t.T, cond


CAMERA_TO_XYZ_METHODS = {
    "paper": _projection_method(_radiance_sensitivity),
    "paper-literal": _projection_method(_literal_sensitivity),
    "least-squares": _least_squares,
}
"""Methods of :func:`camera_to_xyz_matrix`; each returns (M, condition number of the matrix inverted)."""


def camera_to_xyz_matrix(qe, wavelengths_nm, dn_per_electron, method="paper", training=None, return_condition=False):
    """3×3 matrix M mapping camera DN (R, G, B) to CIE XYZ: ``xyz = dn @ M.T``.

    Parameters
    ----------
    qe : array_like, shape (3, N)
        Quantum efficiency per channel and wavelength bin. Unit: e⁻·m²·sr/photon (any common scale works: the
        scale of M never matters for chromaticity or for the ΔE procedure, which rescales to Y = 100).
    wavelengths_nm : array_like, shape (N,)
        Bin centres λ_i. Unit: nm.
    dn_per_electron : float
        Overall gain k = G_Ve · G. Unit: DN/e⁻.
    method : {"paper", "paper-literal", "least-squares"}
        * ``"paper"``: Eq. 15, M = (T Tᵗ)(C Tᵗ)⁻¹, T (3, N) the CIE 1931 2° CMFs on the grid and C (3, N) the
          camera's DN per unit spectral radiance in bin i, C_i = k · Qe_i · λ_i · δ_i / (h c) (λ in m, δ the bin
          width in nm, ``np.gradient`` of the bin centres). This is the dimensionally consistent reading of
          Eq. 16, which prints C = G_Ve · G · (h c / λ) · Qe: h c / λ is the energy of a photon (J/photon), so
          it converts photons to joules, the wrong way round for a sensitivity to (energy) radiance.
        * ``"paper-literal"``: as ``"paper"`` with C_i = k · (h c / λ_i) · Qe_i exactly as printed (for
          comparison; it tilts the sensitivities by λ⁻² relative to ``"paper"``).
        * ``"least-squares"``: M minimising ‖xyz − dn @ Mᵗ‖² over ``training``; ``qe`` etc. are not used.
    training : tuple (camera_dn, xyz) of arrays, shape (K, 3) each, optional
        Training pairs for ``"least-squares"`` only; passing it to another method is an error.
    return_condition : bool
        Also return the 2-norm condition number of the matrix inverted: C Tᵗ (3×3) for the paper methods,
        the training DN matrix (K×3) for least squares.

    Returns
    -------
    M : numpy.ndarray, shape (3, 3)
    condition : float
        Only if ``return_condition``.

    Raises
    ------
    ValueError
        Unknown method, bad shapes, or a (near) singular camera or training set (condition number above
        :data:`MAX_CONDITION`, e.g. two identical channels).
    """
    if method not in CAMERA_TO_XYZ_METHODS:
        raise ValueError(f"unknown camera → XYZ method {method!r}; known: {', '.join(CAMERA_TO_XYZ_METHODS)}")
    if training is not None and method != "least-squares":
        raise ValueError(f"training data are only used by method 'least-squares', not {method!r}")
    matrix, cond = CAMERA_TO_XYZ_METHODS[method](qe, wavelengths_nm, dn_per_electron, training)
    return (matrix, cond) if return_condition else matrix


def xyz_from_camera(dn, matrix) -> np.ndarray:
    """Apply a camera → XYZ matrix to DN samples.

    Parameters
    ----------
    dn : array_like, shape (..., 3)
        Camera DN (R, G, B) as the last axis, e.g. (n, 3) samples as rows. Unit: DN (black level removed).
        A (3, n) array of columns should be passed as ``dn.T``.
    matrix : array_like, shape (3, 3)

    Returns
    -------
    numpy.ndarray, shape (..., 3)
        XYZ, in the scale set by ``matrix``.
    """
    dn = np.asarray(dn, dtype=np.float64)
    matrix = np.asarray(matrix, dtype=np.float64)
    if dn.shape[-1:] != (3,) or matrix.shape != (3, 3):
        raise ValueError(f"need dn of shape (..., 3) and a (3, 3) matrix, got {dn.shape} and {matrix.shape}")
    return dn @ matrix.T


def chromaticity_xy(xyz, weights=None, return_valid=False):
    """CIE xy chromaticity x = X / (X + Y + Z), y = Y / (X + Y + Z) of the samples where it is defined.

    Parameters
    ----------
    xyz : array_like, shape (..., 3)
        Samples as rows; leading axes are flattened.

    weights : array_like of int, shape (n,), optional
        Frequency of each row (for distinct samples with counts); ``n_undefined`` then counts samples, not rows.
    return_valid : bool
        Also return the boolean mask of the valid rows.

    Returns
    -------
    xy : numpy.ndarray, shape (m, 2)
        Chromaticity of the m valid samples, in input order; never NaN.
    n_undefined : int
        Samples excluded because X + Y + Z ≤ 0 or a component is not finite.
    valid : numpy.ndarray of bool, shape (n,)
        Only with ``return_valid``.
    """
    xyz = np.asarray(xyz, dtype=np.float64)
    if xyz.shape[-1:] != (3,):
        raise ValueError(f"xyz must have shape (..., 3), got {xyz.shape}")
    xyz = xyz.reshape(-1, 3)
    total = xyz.sum(axis=1)
    valid = np.all(np.isfinite(xyz), axis=1) & np.isfinite(total) & (total > 0)
    xy = xyz[valid, :2] / total[valid, None]
    n_undefined = int(xyz.shape[0] - np.count_nonzero(valid)) if weights is None else int(np.sum(weights[~valid]))
    return (xy, n_undefined, valid) if return_valid else (xy, n_undefined)
