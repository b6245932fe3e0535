"""Per-patch measurements of one frame: pixel statistics, chromaticity ellipse, ΔE and SNR."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camsim.analysis.delta_e import delta_e_5step, reference_lab
from camsim.analysis.ellipse import fit_ellipse
from camsim.analysis.snr import snr_from_moments, snr_model
from camsim.colour.colorimetry import CHANNELS, camera_to_xyz_matrix, chromaticity_xy, xyz_from_camera
from camsim.core.errors import CamsimError
from camsim.core.optional_numbers import finite_or_none
from camsim.render.frame_files import LoadedFrame

BLACK_MODES = ("none", "sidecar", "dark-frame")


@dataclass(frozen=True)
class AnalysisSettings:
    """How frames are measured.

    Attributes
    ----------
    border_px : int
        Pixels excluded along each edge of every patch rectangle.
    black : {'none', 'sidecar', 'dark-frame'}
        Black-level subtraction: none (as in the paper), the sidecar's (the mean of an unlit pixel's numbers), or a
        dark frame's mean.
    matrix : str
        Camera → XYZ method (``camsim.colour.colorimetry.CAMERA_TO_XYZ_METHODS``).
    edge_region : tuple of int or None
        (x, y, w, h) pixels of a slanted edge whose SFR every frame gets (:mod:`camsim.analysis.mtf`); None: only
        frames whose sidecar records a slanted-edge target, in the target's region.
    """

    border_px: int = 3
    black: str = "none"
    matrix: str = "paper"
    edge_region: tuple | None = None

    def __post_init__(self):
        if self.black not in BLACK_MODES:
            raise CamsimError(f"black-level mode must be one of {BLACK_MODES}, got {self.black!r}")
        if not (isinstance(self.border_px, int) and self.border_px >= 0):
            raise CamsimError(f"border must be a non-negative number of pixels, got {self.border_px!r}")


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


def fraction_within(xy: np.ndarray, k_sigma: float, weights=None) -> float | None:
    """Fraction of samples inside the k-σ ellipse of their own covariance (Mahalanobis distance ≤ k).

    For a bivariate Gaussian cloud this is 1 − exp(−k²/2): 0.865 at k = 2. ``weights``: counts per row.
    """
    d = xy - np.average(xy, axis=0, weights=weights)
    values, vectors = np.linalg.eigh(np.cov(d.T, fweights=weights))
    if not values.min() > 0:  # numerically singular (e.g. a few distinct float32 values): no 2-D shape to test
        return None
    projected = d @ vectors
    inside = np.sum(projected**2 / values, axis=1) <= k_sigma**2
    return float(np.average(inside, weights=weights))


def site_values(mosaic: np.ndarray, rect, border: int, pattern: str, channel: int) -> np.ndarray:
    """A Bayer frame's values of one channel inside a patch rectangle less a border, shape (n,).

    ``mosaic`` is (1, H, W); a pixel's channel follows from its absolute row and column parity.
    """
    from camsim.sensor.cfa import cfa_sites

    x, y, w, h = rect
    if 2 * border >= min(w, h):
        return np.empty(0, dtype=mosaic.dtype)
    block = mosaic[0, y + border : y + h - border, x + border : x + w - border]
    parts = [block[(dy - y - border) % 2 :: 2, (dx - x - border) % 2 :: 2].ravel()
             for dy, dx, c in cfa_sites(pattern) if c == channel]
    return np.concatenate(parts)


def demosaiced_samples(frame: LoadedFrame, rect, border: int) -> np.ndarray:
    """RGB of a Bayer frame's patch rectangle less a border, by bilinear demosaicing (colour-demosaicing), as
    samples (n, 3) of float64. Unit: DN.

    Used only for the quantities that need all three channels at one pixel (xy, ellipses, ΔE); the per-channel
    statistics come from the sites themselves. Only a window around the patch is demosaiced, not the frame: the
    bilinear kernels are 3 × 3, so a margin of one pixel (two, to start on a whole 2 × 2 cell and keep the
    pattern) gives exactly the values the whole frame would (at the frame's edges the window's edges are the
    frame's, with the same reflection), in float64 of the window's size instead of several times the frame's.
    """
    from colour_demosaicing import demosaicing_CFA_Bayer_bilinear

    x, y, w, h = rect
    if 2 * border >= min(w, h):
        return np.empty((0, 3))
    mosaic = frame.pixels_dn[0]
    top, left = max(y + border - 2, 0) & ~1, max(x + border - 2, 0) & ~1  # even: the window keeps the pattern
    bottom, right = min(y + h - border + 1, mosaic.shape[0]), min(x + w - border + 1, mosaic.shape[1])
    window = demosaicing_CFA_Bayer_bilinear(mosaic[top:bottom, left:right].astype(np.float64), frame.cfa_pattern)
    inner = np.asarray(window)[y + border - top : y + h - border - top, x + border - left : x + w - border - left]
    return inner.reshape(-1, 3)


def distinct_samples(raw: np.ndarray):
    """Distinct (R, G, B) rows of integer samples and their counts: ``(rows (m, 3), counts (m,))``.

    A quantised patch of a few hundred thousand pixels takes a few hundred to a few thousand distinct values;
    every per-sample quantity (xy, Lab, ΔE) is then computed once per distinct value and weighted by its count,
    which gives exactly the same statistics as the repeated samples.
    """
    if raw.shape[0] == 0:
        return np.empty((0, 3)), np.empty(0, dtype=np.int64)
    low = raw.min(axis=0).astype(np.int64)
    span = raw.max(axis=0).astype(np.int64) - low + 1
    codes = (raw - low).astype(np.int64)
    codes = (codes[:, 0] * span[1] + codes[:, 1]) * span[2] + codes[:, 2]
    if span.prod() <= 4 * raw.shape[0] + 2**16:  # a dense code range: count in one pass instead of sorting
        counts = np.bincount(codes, minlength=int(span.prod()))
        unique = np.flatnonzero(counts)
        counts = counts[unique]
    else:
        unique, counts = np.unique(codes, return_counts=True)
    r, rest = np.divmod(unique, span[1] * span[2])
    g, b = np.divmod(rest, span[2])
    return np.stack([r, g, b], axis=1).astype(np.float64) + low, counts


def _channel_record(name, values, counts, black, expected_black, threshold, k, model, model_eq13, c):
    """Per-channel statistics of a patch, from its (distinct) values less ``black`` and their counts."""
    n = int(counts.sum()) if counts is not None else values.size
    mean = float(np.average(values, weights=counts)) if n else None
    var = float(np.sum((counts if counts is not None else 1) * (values - mean) ** 2) / (n - 1)) if n > 1 else None
    saturated = values >= threshold - black
    snr, snr_db, snr_status = snr_from_moments(mean + black if n else 0.0, var or 0.0, n, expected_black)
    return {
        "channel": name,
        "n_pixels": n,
        "black_dn": float(black),
        "mean_dn": mean,
        "var_dn2": var,
        "std_dn": None if var is None else float(np.sqrt(var)),
        "mean_e": None if mean is None else mean / k,
        "var_e2": None if var is None else var / k**2,
        "std_e": None if var is None else float(np.sqrt(var)) / k,
        "saturated_pixels": int(np.sum(counts[saturated]) if counts is not None else np.count_nonzero(saturated)),
        "constant": bool(n > 0 and np.all(values == values[0])),
        "snr_model": finite_or_none(model.snr[c]),
        "snr_model_db": finite_or_none(model.snr_db[c]),
        "snr_model_eq13": finite_or_none(model_eq13.snr[c]),
        "snr_model_eq13_db": finite_or_none(model_eq13.snr_db[c]),
        "snr_empirical": snr,
        "snr_empirical_db": snr_db,
        "snr_status": snr_status,
    }


def analyse_frame(frame: LoadedFrame, settings: AnalysisSettings, black_dn, matrix, ref_labs=None):
    """Measure every patch of a frame.

    Parameters
    ----------
    black_dn : numpy.ndarray, shape (3,)
        Subtracted from every pixel before the colour quantities and the DN/electron statistics. Unit: DN.
    matrix : numpy.ndarray, shape (3, 3)
        Camera DN → XYZ.
    ref_labs : list or "self", optional
        Per patch the reference Lab (from the F = 1 frame), for ΔE; ``"self"``: this frame is the reference;
        None leaves ΔE out.

    Returns
    -------
    records : list of dict
        One record per patch: ``name``, ``channels`` (a list of 3 per-channel dicts) and the patch-level
        colour quantities; undefined cases are counted (``n_xy_undefined``, ``n_y_nonpositive``) or named
        (``ellipse_status``, ``delta_e_status``, per channel ``snr_status``), never NaN.
    labs : list
        Per patch the mean Lab of this frame's samples (the ΔE reference when this is an F = 1 frame).
    """
    meta = frame.meta
    k = meta["dn_per_electron"]
    stages = meta["stages"]
    expected_black = frame.expected_black_dn()
    threshold = saturation_threshold_dn(frame)
    pattern = frame.cfa_pattern
    records, labs = [], []
    for index, patch in enumerate(meta["patches"]):
        if pattern:  # Bayer: statistics per site; colour from the demosaiced RGB
            rows, counts = demosaiced_samples(frame, patch["rect_xywh"], settings.border_px), None
            sites = [site_values(frame.pixels_dn, patch["rect_xywh"], settings.border_px, pattern, c).astype(float)
                     - black_dn[c] for c in range(3)]
        else:
            raw = patch_samples(frame.pixels_dn, patch["rect_xywh"], settings.border_px)
            rows, counts = distinct_samples(raw) if frame.quantised else (raw.astype(np.float64), None)
        samples = rows - black_dn
        terms = (np.asarray(patch["signal_e"]), np.asarray(patch["dark_e"]) if stages["dark_current"] else 0.0,
                 np.asarray(patch["signal_var_e2"]), meta["read_noise_e"] if stages["read_noise"] else 0.0, k,
                 bool(stages["quantisation"]) and frame.quantised)  # an EXR holds the values before the ADC
        model = snr_model(*terms)  # quantisation as the variance it adds: comparable with the pixels' SNR
        # Eqs. 13–14 as printed: photon term V·G² = k² S (whatever the statistics' own Var S), σ²_ADC = 1/3 DN²
        # (Eq. 12's mean square), numerator the quantised noise-free signal [k S]_nb
        printed = (terms[0], terms[1], terms[0], *terms[3:])
        model_eq13 = snr_model(*printed, quantisation_term="mean-square",
                               numerator_bits=int(meta["bits"]) if terms[5] else None)
        channels = [_channel_record(name, sites[c] if pattern else samples[:, c], None if pattern else counts,
                                    black_dn[c], expected_black[c], threshold, k, model, model_eq13, c)
                    for c, name in enumerate(CHANNELS)]
        xyz = xyz_from_camera(samples, matrix)
        xy, n_undefined, valid = chromaticity_xy(xyz, weights=counts, return_valid=True)
        weights = None if counts is None else counts[valid]
        ellipse = fit_ellipse(xy, weights=weights)
        lab, _ = reference_lab(xyz, weights=counts) if xyz.shape[0] else (None, 0)
        labs.append(lab)
        record = {
            "index": index,
            "name": patch["name"],
            "channels": channels,
            "n_xy_valid": int(ellipse.n_samples),
            "n_xy_undefined": int(n_undefined),
            "ellipse_status": ellipse.status,
            "center_x": ellipse.center_x,
            "center_y": ellipse.center_y,
            "semi_major_xy": ellipse.semi_major,
            "semi_minor_xy": ellipse.semi_minor,
            "angle_deg": ellipse.angle_deg,
            "size_xy": ellipse.size,
            "frac_in_2sigma": fraction_within(xy, 2.0, weights) if ellipse.status == "ok" else None,
            "n_distinct_values": int(rows.shape[0]) if frame.quantised and not pattern else None,
        }
        reference = lab if ref_labs == "self" else (None if ref_labs is None else ref_labs[index])
        if reference is None:
            record.update(delta_e_ab_mean=None, delta_e_ab_std=None, n_y_nonpositive=None,
                          delta_e_status="no-reference")
        else:
            de = delta_e_5step(xyz, reference, weights=counts)
            record.update(delta_e_ab_mean=de.mean, delta_e_ab_std=de.std, n_y_nonpositive=int(de.n_undefined),
                          delta_e_status="ok" if de.mean is not None else "no-valid-sample")
        records.append(record)
    return records, labs
