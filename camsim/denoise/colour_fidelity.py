"""Chart-free colour fidelity of a frame: the mean CIEDE2000 difference of every pixel to the clean layer.

Needs no chart and no F = 1 frame, so every frame of every dataset is judged for colour. For a frame:

1. **Camera → XYZ.** The black level (the sidecar's, :meth:`camsim.render.frame_files.LoadedFrame.expected_black_dn`) is
   subtracted from the test image (noisy or denoised) and from the clean layer, and both are mapped to XYZ by the
   same camera → XYZ matrix M that the chart metrics use (the paper's Eq. 15 from the sidecar's Qe,
   :func:`camsim.analysis.patches.frame_matrix`). M's overall scale is immaterial: the white below goes through it
   too.
2. **White.** The reference white of CIELAB is the *perfect white* (a reflectance-1 diffuser) under the frame's own
   light at the frame's own F and exposure: its expected signal is the sidecar's ``white_signal_e`` (× the gain
   ``dn_per_electron``, in DN), taken through the same M. It is the same for the test image and the clean layer,
   and it is what a viewer of the frame, exposed and white-balanced for its light, calls white (L* = 100), so that
   the noise is judged relative to the scene's white at that light level — a dark frame's noise is as visible as
   it would be once the frame is brightened. Sidecars of older camsim, without ``white_signal_e``, fall back to a
   white with the chromaticity of the sidecar's ``as_shot_neutral`` (the camera's response to the perfect white
   under the frame's light) through M, and the luminance of the clean layer's brightest pixel (a chart's white
   patch, 90 % of the perfect white); which one was used is reported (:data:`WHITE_SIDECAR`,
   :data:`WHITE_CLEAN_MAX`).
3. **Lab and ΔE00.** CIELAB of every pixel (``colour.XYZ_to_Lab`` with XYZ / Y_white and the white's xy), then
   ``colour.delta_E(..., method="CIE 2000")`` pixel by pixel against the clean layer's Lab; the score is the mean
   over the frame's pixels. Negative XYZ (noise below the black level) fall on CIELAB's linear segment and stay
   finite; the score is None only where it is not finite.

Unlike the chart's 5-step ΔE_ab (which scales every pixel to Y = 100 and compares chromaticity only), this score
keeps lightness: noise in L* counts.
"""

from __future__ import annotations

import warnings

import numpy as np

from camsim.colour.colorimetry import xyz_from_camera
from camsim.core.optional_numbers import finite_or_none
from camsim.light.spectra import import_colour

__all__ = ["WHITE_SIDECAR", "WHITE_CLEAN_MAX", "frame_white_xyz", "lab_against_white", "mean_delta_e00"]

WHITE_SIDECAR = "perfect white at F (sidecar white_signal_e)"
"""White source: the sidecar's perfect white under the frame's light at its F."""
WHITE_CLEAN_MAX = "as_shot_neutral chromaticity, clean maximum Y"
"""White source of older sidecars: as_shot_neutral's chromaticity, the clean layer's largest Y."""


def frame_white_xyz(meta: dict, matrix: np.ndarray, clean_hw3_dn: np.ndarray | None = None):
    """The CIELAB reference white of a frame, in the XYZ scale of ``matrix``.

    Parameters
    ----------
    meta : dict
        The frame's sidecar.
    matrix : numpy.ndarray, shape (3, 3)
        Camera DN → XYZ (``xyz = dn @ matrix.T``).
    clean_hw3_dn : numpy.ndarray, shape (H, W, 3), optional
        The clean layer, black level subtracted (DN); needed only for sidecars without ``white_signal_e``.

    Returns
    -------
    white : numpy.ndarray, shape (3,) or None
        XYZ of the white (None when it cannot be formed: Y ≤ 0).
    source : str
        :data:`WHITE_SIDECAR` or :data:`WHITE_CLEAN_MAX`.
    """
    matrix = np.asarray(matrix, dtype=np.float64)
    if meta.get("white_signal_e") is not None:
        white_dn = np.asarray(meta["white_signal_e"], dtype=np.float64) * float(meta["dn_per_electron"])
        white = xyz_from_camera(white_dn, matrix)
        source = WHITE_SIDECAR
    else:
        neutral = xyz_from_camera(np.asarray(meta["as_shot_neutral"], dtype=np.float64), matrix)
        y_max = float(np.max(xyz_from_camera(clean_hw3_dn, matrix)[..., 1])) if clean_hw3_dn is not None else 0.0
        white = neutral * (y_max / neutral[1]) if neutral[1] > 0 else np.full(3, np.nan)
        source = WHITE_CLEAN_MAX
    if not (np.all(np.isfinite(white)) and white[1] > 0):
        return None, source
    return white, source


def lab_against_white(xyz: np.ndarray, white_xyz: np.ndarray) -> np.ndarray:
    """CIELAB of XYZ samples (..., 3) against a white (3,) in the same scale (colour-science's ``XYZ_to_Lab``)."""
    colour = import_colour()
    white_xyz = np.asarray(white_xyz, dtype=np.float64)
    xy = white_xyz[:2] / white_xyz.sum()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return np.asarray(colour.XYZ_to_Lab(np.asarray(xyz, dtype=np.float64) / white_xyz[1], illuminant=xy),
                          dtype=np.float64)


def mean_delta_e00(test_hw3_dn: np.ndarray, clean_hw3_dn: np.ndarray, matrix: np.ndarray,
                   white_xyz: np.ndarray | None) -> float | None:
    """Mean CIEDE2000 of every pixel of ``test`` to the same pixel of ``clean`` (see the module docstring).

    Parameters
    ----------
    test_hw3_dn, clean_hw3_dn : numpy.ndarray, shape (H, W, 3)
        Camera R, G, B with the black level subtracted. Unit: DN.
    matrix : numpy.ndarray, shape (3, 3)
        Camera DN → XYZ.
    white_xyz : numpy.ndarray, shape (3,) or None
        The reference white (:func:`frame_white_xyz`); None gives None.

    Returns
    -------
    float or None
        Mean ΔE00 over the pixels (unitless, 1 ≈ a just-noticeable difference); None if undefined.
    """
    if white_xyz is None or np.asarray(test_hw3_dn).size == 0:
        return None
    colour = import_colour()
    lab_test = lab_against_white(xyz_from_camera(test_hw3_dn, matrix), white_xyz).reshape(-1, 3)
    lab_clean = lab_against_white(xyz_from_camera(clean_hw3_dn, matrix), white_xyz).reshape(-1, 3)
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        de = np.asarray(colour.delta_E(lab_test, lab_clean, method="CIE 2000"), dtype=np.float64)
    return finite_or_none(float(np.mean(de)))
