"""Colour preservation per patch: the chromaticity of the patch mean and of every pixel through the camera → XYZ
matrix, the bias of the mean against the clean patch, the PCA noise ellipse of the pixels' xy, and ΔE_ab by the
paper's 5-step procedure against the clean patch of the F = 1 frame. Undefined quantities are None, never NaN.
"""

from __future__ import annotations

import math

import numpy as np

from camsim.analysis.delta_e import delta_e_5step, reference_lab
from camsim.analysis.ellipse import fit_ellipse
from camsim.analysis.patches import patch_samples
from camsim.colour.colorimetry import chromaticity_xy, xyz_from_camera
from camsim.core.optional_numbers import finite_or_none


def _xy_of_mean(xyz: np.ndarray):
    """xy of the mean of XYZ samples, or None (no sample, or X + Y + Z ≤ 0)."""
    if xyz.shape[0] == 0:
        return None
    xy, _ = chromaticity_xy(xyz.mean(axis=0)[None, :])
    return (float(xy[0, 0]), float(xy[0, 1])) if xy.shape[0] else None


def patch_colour(samples_dn: np.ndarray, matrix: np.ndarray, ref_lab) -> dict:
    """Colour quantities of one patch's samples (n, 3), black already subtracted. Unit of samples: DN."""
    xyz = xyz_from_camera(samples_dn, matrix)
    xy, n_undefined = chromaticity_xy(xyz)
    ellipse = fit_ellipse(xy)
    out = {"mean_xy": _xy_of_mean(xyz), "n_xy_undefined": int(n_undefined), "ellipse_status": ellipse.status,
           "ellipse_size": finite_or_none(ellipse.size), "center_x": finite_or_none(ellipse.center_x),
           "center_y": finite_or_none(ellipse.center_y), "delta_e": None, "n_y_nonpositive": None}
    if ref_lab is not None:
        de = delta_e_5step(xyz, ref_lab)
        out.update(delta_e=finite_or_none(de.mean), n_y_nonpositive=int(de.n_undefined))
    return out


def _bias(xy, truth):
    if xy is None or truth is None:
        return None
    return float(math.hypot(xy[0] - truth[0], xy[1] - truth[1]))


def _ratio(after, before):
    if after is None or before is None or not before > 0:
        return None
    return float(after / before)


def reference_labs(frame, clean: np.ndarray, black: np.ndarray, matrix, border: int) -> list:
    """Per patch the mean Lab (5-step, Y = 100) of the clean layer: the ΔE reference of the F = 1 frame."""
    labs = []
    for patch in frame.meta["patches"]:
        samples = patch_samples(clean, patch["rect_xywh"], border).astype(np.float64) - black
        lab = reference_lab(xyz_from_camera(samples, matrix))[0] if samples.shape[0] else None
        labs.append(lab)
    return labs


def patch_row(index, patch, ref, truth, before, after) -> dict:
    """One row of ``patches.csv``: the clean truth and the colour before (noisy) and after (denoised)."""
    truth_xy = truth["mean_xy"]
    row = {"patch_index": index, "patch_name": patch["name"],
           "clean_x": None if truth_xy is None else truth_xy[0], "clean_y": None if truth_xy is None else truth_xy[1]}
    for label, colour in (("noisy", before), ("denoised", after)):
        xy = colour["mean_xy"]
        row.update({
            f"{label}_mean_x": None if xy is None else xy[0],
            f"{label}_mean_y": None if xy is None else xy[1],
            f"bias_{label}_xy": _bias(xy, truth_xy),
            f"{label}_center_x": colour["center_x"],
            f"{label}_center_y": colour["center_y"],
            f"ellipse_size_{label}": colour["ellipse_size"],
            f"ellipse_status_{label}": colour["ellipse_status"],
            f"n_xy_undefined_{label}": colour["n_xy_undefined"],
        })
    row["ellipse_size_ratio"] = _ratio(after["ellipse_size"], before["ellipse_size"])
    row.update({"delta_e_clean": truth["delta_e"], "delta_e_noisy": before["delta_e"],
                "delta_e_denoised": after["delta_e"], "n_y_nonpositive_noisy": before["n_y_nonpositive"],
                "n_y_nonpositive_denoised": after["n_y_nonpositive"],
                "delta_e_status": "no-reference" if ref is None else (
                    "ok" if after["delta_e"] is not None else "no-valid-sample")})
    return row
