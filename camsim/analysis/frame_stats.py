"""Whole-frame statistics, for every frame and the only measurement of one without patches (an image, a cube, a
dead-leaves target): per channel the black-level-subtracted mean and spread, the clipped fractions, and — with
the EXR's clean layer (each pixel's expected value) — the residual noisy − clean against the noise the model
predicts for it.

The prediction is independent of the renderer: it uses only the clean layer and the sensor record of the sidecar.
Per pixel, in DN²,

    σ² = k² (Var(S + D) + σ_read² + σ_row²) + q,    Var(S + D) = clean / k    (``pixel`` statistics)

(Poisson thinning: the charge's variance is its mean), Var(S + D) = D̄ without photon noise, q = 1/12 DN² for a
DNG's quantised numbers (none for an EXR's). Where it is approximate:

* pixels near a clip are left out of the residual: a DNG pixel whose value in the file, clean + the ADC's offset a
  (:func:`camsim.sensor.stages.adc_offset_dn`: P + ½ with a pedestal P, else 0), lies within 5 σ of 0 or of the white
  level, and (saturation on) any pixel within 5 σ of the full well k · FW — there the clip shrinks the variance and
  moves the mean (their count is ``n_near_clip``);
* the quantised numbers floor (Eq. 11; with a pedestal, floor(x + ½) + P): the residual of a DNG is
  I + ½ − a − clean, and ½ and 1/12 DN² are the floor's mean and variance for a noise much wider than 1 DN (their
  error is below 0.01 DN, resp. DN², for a Gaussian noise of σ ≥ 0.45 DN: it decays as exp(−2π² σ²));
* with a DSNU offset o the clean layer holds S̄ + D̄ + o, so each pixel's Var(S + D) is over- or under-stated by o;
  the offsets' mean over the frame is ~0, so the frame's mean prediction stands;
* ``paper`` statistics (Var S = T² F Σ g Qe², not a function of the clean value): no prediction.

Standard errors are taken over rows (each row's sums, a ratio estimator), so that row noise — one offset per row
— is accounted for, as is the pixels' unequal variance.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from camsim.colour.colorimetry import CHANNELS
from camsim.core.errors import CamsimError
from camsim.core.optional_numbers import finite_or_none
from camsim.io.exr import read_exr_clean
from camsim.render.frame_files import EXR_METADATA_KEY, LoadedFrame
from camsim.sensor.stages import adc_offset_dn

#: A pixel whose clean value lies within this many predicted σ of a clip (0, the white level, the full well) is
#: left out of the residual.
CLIP_MARGIN_SIGMA = 5.0

FRAME_STAT_COLUMNS = ("channel", "n_pixels", "black_dn", "mean_dn", "std_dn", "clip_low_fraction",
                      "clip_high_fraction", "residual_status", "n_residual", "n_near_clip", "residual_mean_dn",
                      "residual_mean_se_dn", "residual_var_dn2", "residual_var_se_dn2", "predicted_var_dn2",
                      "residual_var_ratio")


def load_clean_dn(frame: LoadedFrame, problems: list | None = None) -> tuple[np.ndarray | None, str]:
    """The clean layer (each pixel's expected DN, shape (3, H, W)) of a frame, and why there is none.

    From the frame's own EXR, or for a DNG the EXR of the same stem beside it — taken only when its header holds
    the same metadata as the DNG's sidecar (the same frame). Returns ``(clean, "ok")`` or ``(None, reason)``;
    an EXR that is there but cannot be read gives ``"exr-unreadable"`` and appends why to ``problems`` (a list).
    """
    path = Path(frame.path) if frame.source == "exr" else Path(frame.path).with_suffix(".exr")
    if not path.is_file():
        return None, "no-clean-layer"
    try:
        clean, header = read_exr_clean(path)
    except CamsimError as exc:  # there, but unreadable (truncated, corrupt): told, not dropped without a word
        if problems is not None:
            problems.append(str(exc))
        return None, "exr-unreadable"
    if clean is None:
        return None, "no-clean-layer"
    if frame.source == "dng":
        try:
            same = json.loads(header.get(EXR_METADATA_KEY, "null")) == frame.meta
        except (ValueError, RecursionError):  # not JSON, a too long integer, too deep: not this frame's copy
            same = False
        if not same:
            return None, "exr-of-another-frame"
    if clean.shape[1:] != frame.pixels_dn.shape[1:]:
        return None, "exr-of-another-frame"
    return clean, "ok"


def _planes(frame: LoadedFrame, channel: int):
    """(values (h, w), (row slice, column slice)) of each plane of one channel: the whole plane, or a Bayer
    frame's sites of that colour (one plane per site of the 2 × 2 cell, a strided view: no copy)."""
    if not frame.cfa_pattern:
        return [(frame.pixels_dn[channel], (slice(None), slice(None)))]
    from camsim.sensor.cfa import cfa_sites

    return [(frame.pixels_dn[0][dy::2, dx::2], (slice(dy, None, 2), slice(dx, None, 2)))
            for dy, dx, c in cfa_sites(frame.cfa_pattern) if c == channel]


#: Rows of a plane handled at a time: the float64 work of a block stays a few MiB whatever the frame's size.
BLOCK_ROWS = 64


def _row_mean_se(sums: np.ndarray, counts: np.ndarray) -> tuple[float, float | None]:
    """Mean of values given as per-row ``sums`` and ``counts``, and its standard error over rows (clusters).

    Ratio estimator: m = Σ s_r / Σ n_r, SE² = R / (R − 1) · Σ (s_r − m n_r)² / (Σ n_r)², R rows with values.
    """
    used = counts > 0
    sums, counts = sums[used], counts[used].astype(np.float64)
    total = counts.sum()
    mean = float(sums.sum() / total)
    if sums.size < 2:
        return mean, None
    se = np.sqrt(sums.size / (sums.size - 1) * np.sum((sums - mean * counts) ** 2)) / total
    return mean, float(se)


def predicted_var_dn2(meta: dict, clean_dn: np.ndarray, quantised: bool, channel: int) -> np.ndarray | None:
    """The model's variance of each pixel's value about its clean value, from the sidecar alone. Unit: DN².

    See the module's notes: k² (Var(S + D) + σ_read² + σ_row²) (+ 1/12 for quantised numbers); None under ``paper``
    statistics with photon noise on.
    """
    stages, k = meta["stages"], float(meta["dn_per_electron"])
    if stages.get("photon_noise", True):
        if meta.get("photon_statistics") != "pixel":
            return None
        charge_var = np.maximum(clean_dn.astype(np.float64), 0.0) / k
    else:
        # the dark current at the sensor's temperature where the sidecar records one (issue 28), else as given
        rate = meta.get("dark_current_effective_e_per_s", meta.get("dark_current_e_per_s", [0, 0, 0]))
        dark = np.asarray(rate, dtype=np.float64) * meta["exposure_s"]
        charge_var = np.full(clean_dn.shape, dark[channel] if stages.get("dark_current") else 0.0)
    read = float(meta["read_noise_e"]) if stages.get("read_noise") else 0.0
    row = float(meta.get("row_noise_e") or 0.0)
    return k**2 * (charge_var + read**2 + row**2) + (1.0 / 12.0 if quantised else 0.0)


def _channel_stats(frame: LoadedFrame, channel: int, black: float, clean, clean_status: str) -> dict:
    """One channel's record (:func:`frame_statistics`), block of rows by block of rows."""
    meta = frame.meta
    k, white = float(meta["dn_per_electron"]), float(meta["white_level_dn"])
    adc_offset = adc_offset_dn(int(meta.get("pedestal_dn") or 0))  # what the ADC adds before its floor
    clip_high = frame.quantised or bool(meta["stages"].get("quantisation"))  # an EXR: what the ADC would clip
    residual = clean is not None
    n = low = high = 0
    ref = total = total_sq = 0.0
    row_sums, row_squares, row_counts = [], [], []
    predicted_sum, n_near = 0.0, 0
    for number, (plane, where) in enumerate(_planes(frame, channel)):
        expected_plane = clean[channel][where] if residual else None
        for r0 in range(0, plane.shape[0], BLOCK_ROWS):
            block = plane[r0 : r0 + BLOCK_ROWS].astype(np.float64)
            if n == 0:
                ref = float(block.mean())  # a shift for the sums' precision
            n += block.size
            total += float(np.sum(block - ref))
            total_sq += float(np.sum((block - ref) ** 2))
            low += int(np.count_nonzero(block <= 0))
            high += int(np.count_nonzero(block >= white)) if clip_high else 0
            if not residual:
                continue
            expected = expected_plane[r0 : r0 + BLOCK_ROWS].astype(np.float64)
            var = predicted_var_dn2(meta, expected, frame.quantised, channel)
            if var is None:
                residual, clean_status = False, "paper-statistics"
                continue
            sigma = np.sqrt(var)
            keep = np.ones(block.shape, dtype=bool)
            if frame.quantised:  # the file's value: clean + the ADC's offset, clipped to [0, white]
                keep &= ((expected + adc_offset - CLIP_MARGIN_SIGMA * sigma >= 0)
                         & (expected + adc_offset + CLIP_MARGIN_SIGMA * sigma <= white))
            if meta["stages"].get("saturation"):
                keep &= expected + CLIP_MARGIN_SIGMA * sigma <= k * float(meta["full_well_e"])
            n_near += int(keep.size - np.count_nonzero(keep))
            # Eq. 11: E[floor(x + a)] ≈ x + a − ½ (a the ADC's offset: P + ½ with a pedestal P)
            r = np.where(keep, block + (0.5 - adc_offset if frame.quantised else 0.0) - expected, 0.0)
            row_sums.append(r.sum(axis=1))
            row_squares.append((r * r).sum(axis=1))
            row_counts.append(keep.sum(axis=1))
            predicted_sum += float(np.sum(var, where=keep))
    mean = total / n
    record = {
        "channel": CHANNELS[channel],
        "n_pixels": int(n),
        "black_dn": float(black),
        "mean_dn": ref + mean - black,
        "std_dn": float(np.sqrt(max(total_sq - n * mean**2, 0.0) / (n - 1))) if n > 1 else None,
        "clip_low_fraction": low / n,
        "clip_high_fraction": high / n,
    }
    empty = dict.fromkeys(FRAME_STAT_COLUMNS[8:], None)
    if not residual:
        return record | {"residual_status": clean_status, **empty}
    sums, squares, counts = (np.concatenate(x) for x in (row_sums, row_squares, row_counts))
    n_residual = int(counts.sum())
    if n_residual < 2:
        return record | {"residual_status": "no-pixel-clear-of-clipping", **empty, "n_residual": n_residual,
                         "n_near_clip": n_near}
    bias, bias_se = _row_mean_se(sums, counts)
    square, square_se = _row_mean_se(squares, counts)
    measured = square - bias**2
    prediction = predicted_sum / n_residual
    return record | {
        "residual_status": "ok",
        "n_residual": n_residual,
        "n_near_clip": n_near,
        "residual_mean_dn": bias,
        "residual_mean_se_dn": bias_se,
        "residual_var_dn2": measured,
        "residual_var_se_dn2": square_se,
        "predicted_var_dn2": prediction,
        "residual_var_ratio": finite_or_none(measured / prediction) if prediction > 0 else None,
    }


def frame_statistics(frame: LoadedFrame, black_dn, problems: list | None = None) -> list[dict]:
    """Per channel (a Bayer frame: that colour's sites) statistics of the whole frame.

    Parameters
    ----------
    frame : LoadedFrame
    black_dn : numpy.ndarray, shape (3,)
        Subtracted from the mean. Unit: DN.
    problems : list, optional
        Gets one line per EXR that is there but unreadable (its residual is then ``exr-unreadable``).

    Returns
    -------
    list of dict
        One record per channel with the keys :data:`FRAME_STAT_COLUMNS`: ``n_pixels``; ``mean_dn`` (black-level
        subtracted) and ``std_dn``; ``clip_low_fraction`` (values ≤ 0) and ``clip_high_fraction`` (values ≥ the
        white level; for an EXR, what the ADC would clip); ``residual_status`` (``ok``, ``no-clean-layer``,
        ``exr-unreadable``, ``exr-of-another-frame``, ``paper-statistics``, ``no-pixel-clear-of-clipping``) and, when
        ``ok``, the residual noisy − clean over the ``n_residual`` pixels clear of clipping: its mean (the bias, ~0
        within ``residual_mean_se_dn``), its variance with standard error, the model's ``predicted_var_dn2`` (the
        mean of each pixel's predicted variance) and their ratio. Unit: DN, DN².
    """
    clean, status = load_clean_dn(frame, problems)
    try:
        return [_channel_stats(frame, c, float(black_dn[c]), clean, status) for c in range(3)]
    finally:
        clean = None
