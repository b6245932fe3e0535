"""Photons: spectral radiance to mean photon rates (the paper's Eqs. 1–5).

All functions are pure and work on K spectra at once (K × N arrays), never per pixel.
"""

from __future__ import annotations

import numpy as np

from camsim.core.errors import CamsimError

#: Planck constant as in the paper. Unit: J s.
PLANCK_J_S = 6.626176e-34
#: Speed of light as in the paper. Unit: m/s.
LIGHT_SPEED_M_S = 2.997925e8
#: Maximum luminous efficacy used for luminance, Y = 683 Σ L ȳ δ. Unit: lm/W.
KM_LM_PER_W = 683.0


def luminance_cd_m2(radiance: np.ndarray, ybar: np.ndarray, step_nm: float) -> np.ndarray:
    """Luminance of spectral radiances, Y = 683 · Σ L(λ) ȳ(λ) δ.

    Parameters
    ----------
    radiance : numpy.ndarray, shape (..., N)
        Spectral radiance. Unit: W / (m² sr nm).
    ybar : numpy.ndarray, shape (N,)
        CIE 1931 ȳ on the same grid.
    step_nm : float
        Bin width δ. Unit: nm.

    Returns
    -------
    numpy.ndarray, shape (...)
        Unit: cd / m².
    """
    return KM_LM_PER_W * (np.asarray(radiance) @ ybar) * step_nm


def scale_to_luminance(spd: np.ndarray, ybar: np.ndarray, step_nm: float, luminance: float) -> np.ndarray:
    """Scale a relative spectral power distribution so that its luminance is ``luminance``.

    Parameters
    ----------
    spd : numpy.ndarray, shape (N,)
        Relative spectral power (any scale).
    luminance : float
        Target luminance. Unit: cd / m².

    Returns
    -------
    numpy.ndarray, shape (N,)
        Spectral radiance. Unit: W / (m² sr nm).
    """
    y = luminance_cd_m2(spd, ybar, step_nm)
    if not y > 0:
        raise CamsimError("a spectrum with zero luminance on the scene's grid cannot be scaled to a luminance")
    return spd * (luminance / y)


def photon_radiance(radiance: np.ndarray, wavelengths_nm: np.ndarray, step_nm: float) -> np.ndarray:
    """Mean photon radiance per bin, g(λi) = λi · L(λi) · δ / (h c) (Eq. 3).

    Parameters
    ----------
    radiance : numpy.ndarray, shape (..., N)
        Spectral radiance. Unit: W / (m² sr nm).
    wavelengths_nm : numpy.ndarray, shape (N,)
        Bin centres. Unit: nm.
    step_nm : float
        Bin width δ. Unit: nm.

    Returns
    -------
    numpy.ndarray, shape (..., N)
        Unit: photons / (s m² sr) per bin.
    """
    wavelengths_m = np.asarray(wavelengths_nm) * 1e-9
    # a radiance beyond ~1e289 W / (m² sr nm) (a luminance_cd_m2 of 1e300) overflows to inf: expected, and refused
    # with its reason before any frame is drawn (camsim.sensor.expected.expected_signal checks that the rates are
    # finite)
    with np.errstate(over="ignore"):
        return np.asarray(radiance) * (wavelengths_m * step_nm / (PLANCK_J_S * LIGHT_SPEED_M_S))
