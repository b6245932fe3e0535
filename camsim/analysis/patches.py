"""Per-patch measurements of one frame: pixel statistics, chromaticity ellipse, ΔE and SNR."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camsim.analysis.colorimetry import camera_to_xyz_matrix, chromaticity_xy, xyz_from_camera
from camsim.analysis.delta_e import delta_e_5step, reference_lab
from camsim.analysis.ellipse import fit_ellipse
from camsim.analysis.frames import LoadedFrame
from camsim.analysis.snr import snr_empirical, snr_model
from camsim.errors import CamsimError

CHANNELS = ("R", "G", "B")
BLACK_MODES = ("none", "sidecar", "dark-frame")


@dataclass(frozen=True)
class AnalysisSettings:
    """How frames are measured.

    Attributes
    ----------
    border_px : int
        Pixels excluded along each edge of every patch rectangle.
    black : {'none', 'sidecar', 'dark-frame'}
        Black-level subtraction: none (as in the paper), the sidecar's mean dark level, or a dark frame's mean.
    matrix : str
        Camera → XYZ method (``camsim.analysis.colorimetry.CAMERA_TO_XYZ_METHODS``).
    """

    border_px: int = 3
    black: str = "none"
    matrix: str = "paper"

    def __post_init__(self):
        if self.black not in BLACK_MODES:
            raise CamsimError(f"black-level mode must be one of {BLACK_MODES}, got {self.black!r}")
        if not (isinstance(self.border_px, int) and self.border_px >= 0):
            raise CamsimError(f"border must be a non-negative number of pixels, got {self.border_px!r}")


def _finite_or_none(value):
    """A float for JSON and CSV, None where the value is infinite (e.g. SNR in dB of a zero signal)."""
    value = float(value)
    return value if np.isfinite(value) else None


def frame_matrix(frame: LoadedFrame, method: str) -> np.ndarray:
    """Camera DN → XYZ matrix of a frame, from the Qe and gain in its metadata."""
    meta = frame.meta
    training = None
    if method == "least-squares":
        patches = meta["patches"]
        if not patches or any(p.get("xyz_cd_m2") is None for p in patches):
            raise CamsimError(f"{frame.path}: the least-squares matrix needs patch XYZ values in the sidecar")
        camera = np.array([p["signal_e"] for p in patches]) * meta["dn_per_electron"]
        training = (camera, np.array([p["xyz_cd_m2"] for p in patches]))
    try:
        return camera_to_xyz_matrix(np.asarray(meta["qe_e_m2_sr_per_photon"]), np.asarray(meta["wavelengths_nm"]),
                                    meta["dn_per_electron"], method=method, training=training)
    except ValueError as exc:
        raise CamsimError(f"{frame.path}: {exc}") from None


def saturation_threshold_dn(frame: LoadedFrame) -> float:
    """Smallest value counted as saturated: the ADC full scale, or the full well less 3 σ of read noise."""
    meta = frame.meta
    stages = meta["stages"]
    threshold = float(meta["white_level_dn"]) if stages.get("quantisation") else np.inf
    if stages.get("saturation"):
        read = meta["read_noise_e"] if stages.get("read_noise") else 0.0
        at_full_well = meta["dn_per_electron"] * (meta["full_well_e"] - 3.0 * read)
        threshold = min(threshold, np.floor(at_full_well) if frame.quantised else at_full_well)
    return threshold


def patch_samples(pixels: np.ndarray, rect, border: int) -> np.ndarray:
    """Pixels of a patch rectangle less a border, as samples (n, 3)."""
    x, y, w, h = rect
    if 2 * border >= min(w, h):  # nothing left (and a negative slice end would wrap around)
        return np.empty((0, pixels.shape[0]), dtype=pixels.dtype)
    block = pixels[:, y + border : y + h - border, x + border : x + w - border]
    return block.reshape(3, -1).T


def patch_colour_samples(frame: LoadedFrame, settings: AnalysisSettings, black_dn, matrix):
    """XYZ samples of every patch, (n, 3) each, after the chosen black subtraction."""
    return [xyz_from_camera(patch_samples(frame.pixels_dn, p["rect_xywh"], settings.border_px) - black_dn, matrix)
            for p in frame.meta["patches"]]


def reference_labs(frame: LoadedFrame, settings: AnalysisSettings, black_dn, matrix) -> list:
    """Mean Lab of every patch of an F = 1 frame (the ΔE reference), or None where no sample is valid."""
    labs = []
    for xyz in patch_colour_samples(frame, settings, black_dn, matrix):
        lab, _ = reference_lab(xyz)
        labs.append(lab)
    return labs


def fraction_within(xy: np.ndarray, k_sigma: float) -> float:
    """Fraction of samples inside the k-σ ellipse of their own covariance (Mahalanobis distance ≤ k).

    For a bivariate Gaussian cloud this is 1 − exp(−k²/2): 0.865 at k = 2. Unit: fraction.
    """
    d = xy - xy.mean(axis=0)
    inverse = np.linalg.inv(np.cov(d.T))
    return float(np.mean(np.einsum("ni,ij,nj->n", d, inverse, d) <= k_sigma**2))


def distinct_values(raw: np.ndarray) -> int:
    """Number of distinct (R, G, B) digital-number triplets among integer samples (n, 3)."""
    codes = raw.astype(np.int64)
    return int(np.unique((codes[:, 0] << 32) | (codes[:, 1] << 16) | codes[:, 2]).size)


def analyse_frame(frame: LoadedFrame, settings: AnalysisSettings, black_dn, matrix, ref_labs=None):
    """Measure every patch of a frame.

    Parameters
    ----------
    black_dn : numpy.ndarray, shape (3,)
        Subtracted from every pixel before the colour quantities and the DN/electron statistics. Unit: DN.
    matrix : numpy.ndarray, shape (3, 3)
        Camera DN → XYZ.
    ref_labs : list, optional
        Per patch the reference Lab (from the F = 1 frame), for ΔE; None leaves ΔE out.

    Returns
    -------
    list of dict
        One record per patch: ``name``, ``channels`` (a list of 3 per-channel dicts) and the patch-level
        colour quantities; undefined cases are counted (``n_xy_undefined``, ``n_y_nonpositive``) or named
        (``ellipse_status``, ``delta_e_status``, per channel ``snr_status``), never NaN.
    """
    meta = frame.meta
    k = meta["dn_per_electron"]
    stages = meta["stages"]
    expected_black = frame.expected_black_dn()
    threshold = saturation_threshold_dn(frame)
    records = []
    for index, patch in enumerate(meta["patches"]):
        raw = patch_samples(frame.pixels_dn, patch["rect_xywh"], settings.border_px)
        samples = raw - black_dn
        terms = (np.asarray(patch["signal_e"]), np.asarray(patch["dark_e"]) if stages["dark_current"] else 0.0,
                 np.asarray(patch["signal_var_e2"]), meta["read_noise_e"] if stages["read_noise"] else 0.0, k,
                 bool(stages["quantisation"]) and frame.quantised)  # an EXR holds the values before the ADC
        model = snr_model(*terms)  # quantisation as the variance it adds: comparable with the pixels' SNR
        model_eq13 = snr_model(*terms, quantisation_term="mean-square")  # Eq. 13 literally
        channels = []
        for c, name in enumerate(CHANNELS):
            values = samples[:, c]
            n = values.size
            var = float(values.var(ddof=1)) if n > 1 else None
            snr, snr_db, snr_status = snr_empirical(raw[:, c], expected_black[c])
            channels.append({
                "channel": name,
                "n_pixels": n,
                "black_dn": float(black_dn[c]),
                "mean_dn": float(values.mean()) if n else None,
                "var_dn2": var,
                "std_dn": None if var is None else float(np.sqrt(var)),
                "mean_e": float(values.mean()) / k if n else None,
                "var_e2": None if var is None else var / k**2,
                "std_e": None if var is None else float(np.sqrt(var)) / k,
                "saturated_pixels": int(np.count_nonzero(raw[:, c] >= threshold)),
                "constant": bool(n > 0 and np.all(values == values[0])),
                "snr_model": _finite_or_none(model.snr[c]),
                "snr_model_db": _finite_or_none(model.snr_db[c]),
                "snr_model_eq13": _finite_or_none(model_eq13.snr[c]),
                "snr_model_eq13_db": _finite_or_none(model_eq13.snr_db[c]),
                "snr_empirical": snr,
                "snr_empirical_db": snr_db,
                "snr_status": snr_status,
            })
        xyz = xyz_from_camera(samples, matrix)
        xy, n_undefined = chromaticity_xy(xyz)
        ellipse = fit_ellipse(xy)
        within = fraction_within(xy, 2.0) if ellipse.status == "ok" else None
        record = {
            "index": index,
            "name": patch["name"],
            "channels": channels,
            "n_xy_valid": int(xy.shape[0]),
            "n_xy_undefined": int(n_undefined),
            "ellipse_status": ellipse.status,
            "center_x": ellipse.center_x,
            "center_y": ellipse.center_y,
            "semi_major_xy": ellipse.semi_major,
            "semi_minor_xy": ellipse.semi_minor,
            "angle_deg": ellipse.angle_deg,
            "size_xy": ellipse.size,
            "frac_in_2sigma": within,
            "n_distinct_values": distinct_values(raw) if frame.quantised else None,
        }
        if ref_labs is None or ref_labs[index] is None:
            record.update(delta_e_ab_mean=None, delta_e_ab_std=None, n_y_nonpositive=None,
                          delta_e_status="no-reference")
        else:
            de = delta_e_5step(xyz, ref_labs[index])
            record.update(delta_e_ab_mean=de.mean, delta_e_ab_std=de.std, n_y_nonpositive=int(de.n_undefined),
                          delta_e_status="ok" if de.mean is not None else "no-valid-sample")
        records.append(record)
    return records
