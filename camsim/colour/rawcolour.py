"""Colour tags for the raw file, derived from the model: ColorMatrix1 and AsShotNeutral.

* ColorMatrix1 (XYZ → camera, DNG convention) is the least-squares fit of the model camera's responses to the
  XYZ of the 24 ColorChecker colour signals under D65 (CalibrationIlluminant1 = 21), scaled so that the D65
  white (Y = 1) maps to a camera neutral whose largest component is 1.
* AsShotNeutral is the camera's response to the perfect white under the frame's own illuminant, divided by its
  largest component: a raw converter then white-balances to the scene light, as a camera's auto white balance
  would.
"""

from __future__ import annotations

import numpy as np

from camsim.light.photons import photon_radiance, scale_to_luminance
from camsim.light.spectra import WavelengthGrid, cmfs_on_grid, illuminant_spd, reflectance_set

#: EXIF LightSource code of D65, the calibration illuminant of ColorMatrix1.
CALIBRATION_ILLUMINANT_D65 = 21
_CALIBRATION_CHART = "ColorChecker N Ohta"


def camera_response(radiance: np.ndarray, qe: np.ndarray, grid: WavelengthGrid) -> np.ndarray:
    """Mean signal electrons per unit exposure and F for radiances, shape (..., 3). Unit: e⁻ / s."""
    return photon_radiance(radiance, grid.wavelengths_nm, grid.step_nm) @ qe.T


def color_matrix_xyz_to_camera(qe: np.ndarray, grid: WavelengthGrid) -> np.ndarray:
    """DNG ColorMatrix1 (3 × 3, XYZ → camera) for D65, normalised so that max(M · XYZ_D65 white) = 1."""
    cmfs = cmfs_on_grid(grid)
    d65 = illuminant_spd("D65", grid)
    _, refl = reflectance_set(_CALIBRATION_CHART, grid)
    radiance = refl * d65
    xyz = radiance @ cmfs.T
    rgb = camera_response(radiance, qe / qe.max(), grid)  # normalised (as the matrix is): no overflow for any Qe
    solution, *_ = np.linalg.lstsq(xyz, rgb, rcond=None)  # rgb ≈ xyz @ solution
    matrix = solution.T
    white_xyz = d65 @ cmfs.T
    white_xyz = white_xyz / white_xyz[1]
    return matrix / (matrix @ white_xyz).max()


def as_shot_neutral(illuminant: str, qe: np.ndarray, grid: WavelengthGrid) -> np.ndarray:
    """Camera response to the perfect white under ``illuminant``, largest component 1, shape (3,)."""
    ybar = cmfs_on_grid(grid)[1]
    white = scale_to_luminance(illuminant_spd(illuminant, grid), ybar, grid.step_nm, 100.0)
    response = camera_response(white, qe / qe.max(), grid)  # normalised (as the result is): no overflow for any Qe
    return response / response.max()
