"""Scoring denoisers on a dataset of camsim frames against their clean layer: the evaluation loop.

A dataset is any set of folders and files holding camsim EXR frames (:mod:`camsim.denoise.frames`). Every
denoiser sees each noisy frame as a (H, W, 3) float32 DN array; it is scored

* per frame: PSNR and SSIM (:mod:`camsim.denoise.image_scores`) of the denoised and of the noisy frame against the
  clean layer, with ``data_range`` = the clean layer's range (max − min over the frame's pixels and channels);
* per patch (``meta["patches"]`` rectangles less a border; :mod:`camsim.denoise.patch_colour`): the chromaticity
  of the patch mean and of every pixel through the paper's camera → XYZ matrix M (Eq. 15, from the sidecar's Qe),
  the chromaticity bias |xy(mean of the patch) − xy(mean of the clean patch)|, the PCA noise ellipse of the
  pixels' xy before (noisy) and after (denoised), and ΔE_ab by the paper's 5-step procedure against the same
  patch in the clean layer of the F = 1 frame of the same measurement (:func:`camsim.analysis.grouping.group_key`);
* per frame, with no chart and no reference frame needed: the mean CIEDE2000 of every pixel to the clean layer,
  both through M against the perfect white at the frame's F (:mod:`camsim.denoise.colour_fidelity`), of the
  denoised and of the noisy frame;
* per intensity factor: means, undefined counts and the chart's colour-preservation verdicts; per half-decade band
  of F the detail (SSIM) and colour (ΔE00) verdicts (:mod:`camsim.denoise.summary`).

A Bayer (CFA) frame is denoised and scored as :mod:`camsim.denoise.bayer` says: each denoiser gets the mosaic
black-subtracted and normalised to the white level, packed R, G1, G2, B at half resolution (or, for a user's
denoiser with ``bayer_input="mosaic"``, unpacked); it is scored in the raw domain (PSNR and SSIM per packed plane
and overall, data range 1) and after the ISP (the noisy, denoised and clean mosaics developed alike: PSNR, SSIM,
mean ΔE00 against the developed clean). Its frame-level columns ``psnr_*``, ``ssim_*`` and ``delta_e00_*`` (and
so the bands' verdicts) hold the scores after the ISP (``scored_as`` says so); the chart's patch quantities are
three-chip only.

Undefined quantities (no chromaticity where X + Y + Z ≤ 0, degenerate ellipses, no F = 1 reference, an
infinite PSNR of a perfect result) are None and counted, never NaN.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from camsim.analysis.grouping import group_key
from camsim.analysis.patches import frame_matrix, patch_samples
from camsim.colour.colorimetry import CHANNELS
from camsim.core.errors import CamsimError
from camsim.denoise.bayer import (
    BAYER_INPUTS,
    BAYER_PLANES,
    DEFAULT_ISP_GAIN,
    MOSAIC,
    PACKED,
    bayer_frame,
    developed_image,
    from_packed,
    raw_scores,
    srgb_lab,
    srgb_scores,
    to_packed,
)
from camsim.denoise.colour_fidelity import frame_white_xyz, mean_delta_e00
from camsim.denoise.denoisers import SIGMA_MODEL, Denoiser, estimate_noise_sigma, model_noise_sigma
from camsim.denoise.frames import Dataset, DatasetFrame, find_dataset
from camsim.denoise.image_scores import image_scores
from camsim.denoise.patch_colour import patch_colour, patch_row, reference_labs
from camsim.denoise.summary import (
    NOISY,
    Criterion,
    band_verdicts,
    f_band,
    summarise,
    summarise_bands,
    undefined_counts,
    verdict,
)
from camsim.render.frame_files import load_frame

__all__ = ["EvalSettings", "FrameResult", "Evaluation", "evaluate", "evaluate_frame"]


@dataclass(frozen=True)
class EvalSettings:
    """How frames are scored.

    Attributes
    ----------
    border_px : int
        Pixels left out along each edge of a patch rectangle.
    subtract_black : bool
        Subtract the sidecar's black level (the mean of an unlit pixel's numbers) before the colour quantities, so
        that they measure the denoiser rather than the dark current's drag toward the camera black point (which the
        paper, subtracting nothing, reports). False measures as the paper does.
    criterion : Criterion
    matrix : str
        Camera → XYZ method; the paper's M by default.
    bayer_input : {'packed', 'mosaic'}
        What a user's denoiser (``MODULE:FUNCTION``, ``cmd:``) gets for a Bayer frame: the normalised packed planes
        (H/2, W/2, 4) or the normalised mosaic (H, W) (:mod:`camsim.denoise.bayer`). The built-ins always get the
        packed planes.
    isp_gain : {'white', 'auto'} or float
        The gain of the development for a Bayer frame's scores after the ISP (:mod:`camsim.denoise.bayer`):
        ``"white"`` maps the perfect white under the frame's light at its F to 1 (``"auto"`` where a sidecar lacks
        it), ``"auto"`` is 1 / F, a number a fixed gain.
    """

    border_px: int = 3
    subtract_black: bool = True
    criterion: Criterion = field(default_factory=Criterion)
    matrix: str = "paper"
    bayer_input: str = PACKED
    isp_gain: str | float = DEFAULT_ISP_GAIN

    def __post_init__(self):
        if not (isinstance(self.border_px, int) and self.border_px >= 0):
            raise CamsimError(f"border must be a non-negative number of pixels, got {self.border_px!r}")
        if self.bayer_input not in BAYER_INPUTS:
            raise CamsimError(f"unknown Bayer input {self.bayer_input!r}: one of {', '.join(BAYER_INPUTS)}")
        gain = self.isp_gain
        if not (gain in ("white", "auto") or (isinstance(gain, (int, float)) and not isinstance(gain, bool)
                                              and np.isfinite(gain) and gain > 0)):
            raise CamsimError(f"the ISP gain must be 'white', 'auto' or a positive number, got {gain!r}")


@dataclass
class FrameResult:
    """Scores of one frame: the noisy baseline and per denoiser."""

    frame_row: dict  # the frame's fields common to every denoiser (file, F, ..., noisy scores)
    denoised_rows: dict  # denoiser name -> frame-level scores of the denoised frame
    patch_rows: dict  # denoiser name -> list of per-patch dicts
    examples: dict = field(default_factory=dict)  # denoiser name -> (H', W', 3) crop; plus "noisy", "clean"
    band_crops: dict = field(default_factory=dict)  # the same, a centre crop, for the crops-per-band figure
    seconds: dict = field(default_factory=dict)  # denoiser name -> run time on this frame


EXAMPLE_CROP = (240, 320)  # rows, columns of the crop kept for the example figure
BAND_CROP = (96, 128)  # rows, columns of the centre crop kept per F band for the crops figure


#: ``scored_as``: what a frame's ``psnr_*``, ``ssim_*`` and ``delta_e00_*`` columns score.
SCORED_THREE_CHIP = "camera DN"
SCORED_DEVELOPED = "developed sRGB"


def _frame_fields(frame: DatasetFrame) -> dict:
    meta = frame.meta
    pattern = meta.get("cfa_pattern")
    return {"file": frame.name, "scene": meta.get("scene"), "illuminant": meta.get("illuminant"),
            "intensity_factor": float(meta["intensity_factor"]), "width_px": meta.get("width_px"),
            "height_px": meta.get("height_px"), "frame_kind": f"Bayer {pattern}" if pattern else "three-chip",
            "scored_as": SCORED_DEVELOPED if pattern else SCORED_THREE_CHIP}


def _centre_crop(shape) -> tuple:
    h, w = shape[:2]
    ch, cw = min(h, BAND_CROP[0]), min(w, BAND_CROP[1])
    y0, x0 = (h - ch) // 2, (w - cw) // 2
    return slice(y0, y0 + ch), slice(x0, x0 + cw)


def evaluate_frame(frame: DatasetFrame, denoisers: list[Denoiser], settings: EvalSettings, ref_labs,
                   keep_example: bool = False, keep_band_crop: bool = False) -> tuple[FrameResult, list | None]:
    """Score every denoiser on one frame. Returns the result and, for an F = 1 frame, its reference Labs."""
    from camsim.io.exr import read_exr

    loaded = load_frame(frame.path)
    _, clean, _ = read_exr(frame.path)
    if loaded.cfa_pattern:
        return evaluate_bayer_frame(frame, loaded, clean, denoisers, settings, keep_example, keep_band_crop), None
    noisy_chw = loaded.pixels_dn.astype(np.float32, copy=False)
    noisy = np.ascontiguousarray(np.moveaxis(noisy_chw, 0, -1))
    clean_hw3 = np.ascontiguousarray(np.moveaxis(clean, 0, -1))
    black = loaded.expected_black_dn() if settings.subtract_black else np.zeros(3)
    matrix = frame_matrix(loaded, settings.matrix)
    border = settings.border_px
    own_refs = None
    if ref_labs == "self":
        own_refs = reference_labs(loaded, clean, black, matrix, border)
        ref_labs = own_refs

    data_range = float(clean.max() - clean.min())
    data_range_source = "clean range"
    if not data_range > 0:
        data_range, data_range_source = float(loaded.meta.get("white_level_dn") or 1.0), "white level"
    sigma = estimate_noise_sigma(noisy)
    model_black = loaded.expected_black_dn()  # the noise model needs the true dark level, --keep-black or not
    sigma_model = model_noise_sigma(loaded.meta, noisy, model_black)
    true_sigma = (noisy.astype(np.float64) - clean_hw3).std(axis=(0, 1))
    psnr_noisy, ssim_noisy = image_scores(clean_hw3, noisy, data_range)
    clean_signal = clean_hw3.astype(np.float64) - model_black  # ΔE00: always the light's own signal
    white, white_source = frame_white_xyz(loaded.meta, matrix, clean_signal)
    de00_noisy = mean_delta_e00(noisy.astype(np.float64) - model_black, clean_signal, matrix, white)
    row = _frame_fields(frame)
    row.update({"data_range_dn": data_range, "data_range_source": data_range_source,
                **{f"sigma_est_{c}_dn": float(s) for c, s in zip(CHANNELS, sigma)},
                **{f"sigma_model_{c}_dn": float(s) for c, s in zip(CHANNELS, sigma_model)},
                "white_source": white_source, "delta_e00_noisy": de00_noisy,
                **{f"noise_std_{c}_dn": float(s) for c, s in zip(CHANNELS, true_sigma)},
                "psnr_noisy_db": psnr_noisy, "ssim_noisy": ssim_noisy})

    # Per patch: the truth (clean) and the noisy baseline, shared by every denoiser.
    patches = frame.meta["patches"]
    base = []
    for index, patch in enumerate(patches):
        rect = patch["rect_xywh"]
        ref = None if ref_labs is None else ref_labs[index]
        clean_s = patch_samples(clean, rect, border).astype(np.float64) - black
        noisy_s = patch_samples(noisy_chw, rect, border).astype(np.float64) - black
        truth = patch_colour(clean_s, matrix, ref)
        before = patch_colour(noisy_s, matrix, ref)
        base.append((index, patch, ref, truth, before))

    result = FrameResult(row, {}, {})
    h, w = noisy.shape[:2]
    crop = (slice(0, min(h, EXAMPLE_CROP[0])), slice(0, min(w, EXAMPLE_CROP[1])))
    centre = _centre_crop(noisy.shape)
    if keep_example:
        result.examples.update(noisy=noisy[crop].copy(), clean=clean_hw3[crop].copy(), black=np.asarray(black))
    if keep_band_crop:
        result.band_crops.update(noisy=noisy[centre].copy(), clean=clean_hw3[centre].copy(), black=np.asarray(black),
                                 file=frame.name, intensity_factor=float(frame.meta["intensity_factor"]))
    for denoiser in denoisers:
        given = sigma_model if denoiser.sigma_source == SIGMA_MODEL else sigma
        start = time.perf_counter()
        denoised = denoiser(noisy, given)
        result.seconds[denoiser.name] = time.perf_counter() - start
        psnr, ssim = image_scores(clean_hw3, denoised, data_range)
        result.denoised_rows[denoiser.name] = {
            "psnr_denoised_db": psnr, "ssim_denoised": ssim, "sigma_given": denoiser.sigma_source,
            "seconds": result.seconds[denoiser.name],
            "delta_e00_denoised": mean_delta_e00(denoised.astype(np.float64) - model_black, clean_signal, matrix,
                                                 white),
            "psnr_gain_db": None if psnr is None or psnr_noisy is None else psnr - psnr_noisy,
            "ssim_gain": None if ssim is None or ssim_noisy is None else ssim - ssim_noisy,
        }
        if keep_example:
            result.examples[denoiser.name] = denoised[crop].copy()
        if keep_band_crop:
            result.band_crops[denoiser.name] = denoised[centre].copy()
        denoised_chw = np.moveaxis(denoised, -1, 0)
        rows = []
        for index, patch, ref, truth, before in base:
            samples = patch_samples(denoised_chw, patch["rect_xywh"], border).astype(np.float64) - black
            after = patch_colour(samples, matrix, ref)
            rows.append(patch_row(index, patch, ref, truth, before, after))
        result.patch_rows[denoiser.name] = rows
    return result, own_refs


#: The colour (0 = R, 1 = G, 2 = B) of each packed plane R, G1, G2, B.
PLANE_CHANNELS = (0, 1, 1, 2)


def _per_plane(prefix: str, values) -> dict:
    return {f"{prefix}_{p}": (None if v is None else float(v)) for p, v in zip(BAYER_PLANES, values)}


def _raw_columns(scores: dict, label: str) -> dict:
    """raw_psnr_{label}_db, raw_ssim_{label} and per plane raw_psnr_{P}_{label}_db, raw_ssim_{P}_{label}."""
    out = {f"raw_psnr_{label}_db": scores["psnr_db"], f"raw_ssim_{label}": scores["ssim"]}
    for p in BAYER_PLANES:
        out[f"raw_psnr_{p}_{label}_db"] = scores[f"psnr_{p}_db"]
        out[f"raw_ssim_{p}_{label}"] = scores[f"ssim_{p}"]
    return out


def _srgb_columns(scores: dict, label: str) -> dict:
    return {f"srgb_psnr_{label}_db": scores["psnr_db"], f"srgb_ssim_{label}": scores["ssim"],
            f"srgb_delta_e00_{label}": scores["delta_e00"],
            # the generic columns (bands, summary): for a Bayer frame, the scores after the ISP
            f"psnr_{label}_db": scores["psnr_db"], f"ssim_{label}": scores["ssim"],
            f"delta_e00_{label}": scores["delta_e00"]}


def _gain(a, b):
    return None if a is None or b is None else a - b


def evaluate_bayer_frame(frame: DatasetFrame, loaded, clean, denoisers: list[Denoiser], settings: EvalSettings,
                         keep_example: bool = False, keep_band_crop: bool = False) -> FrameResult:
    """Score every denoiser on one Bayer frame (:mod:`camsim.denoise.bayer`): raw scores per packed plane and
    overall, and scores after the ISP. No patch rows (the chart's quantities are three-chip only)."""
    bf = bayer_frame(loaded, clean, settings.isp_gain)
    facts, pattern = bf.facts, bf.pattern
    black4 = np.asarray(facts.black_dn, dtype=np.float64)[list(PLANE_CHANNELS)]
    scale4 = float(facts.white_dn) - black4
    sigma = estimate_noise_sigma(bf.noisy_packed)
    packed_dn = to_packed(loaded.pixels_dn[0].astype(np.float32, copy=False), pattern)
    sigma_model = model_noise_sigma(loaded.meta, packed_dn, black4, PLANE_CHANNELS) / scale4
    true_sigma = (bf.noisy_packed.astype(np.float64) - bf.clean_packed).std(axis=(0, 1))
    clean_dev = developed_image(bf.clean_mosaic, bf)
    noisy_dev = developed_image(bf.noisy_mosaic, bf)
    clean_lab = srgb_lab(clean_dev)
    raw_noisy = raw_scores(bf.clean_packed, bf.noisy_packed)
    srgb_noisy = srgb_scores(clean_dev, noisy_dev, clean_lab)
    row = _frame_fields(frame)
    row.update({"bayer_input": settings.bayer_input, "data_range_source": "1 (developed sRGB; raw: the white level)",
                "isp_gain": bf.gain if isinstance(bf.gain, str) else float(bf.gain),
                **_per_plane("raw_sigma_est", sigma), **_per_plane("raw_sigma_model", sigma_model),
                **_per_plane("raw_noise_std", true_sigma),
                **_raw_columns(raw_noisy, "noisy"), **_srgb_columns(srgb_noisy, "noisy")})
    result = FrameResult(row, {}, {})
    height, width = bf.noisy_mosaic.shape
    crop = (slice(0, min(height, EXAMPLE_CROP[0])), slice(0, min(width, EXAMPLE_CROP[1])))
    centre = _centre_crop((height, width))

    def hw3(image):
        return np.moveaxis(image, 0, -1)

    common = {"developed": True, "black": np.zeros(3)}
    if keep_example:
        result.examples.update(noisy=hw3(noisy_dev)[crop].copy(), clean=hw3(clean_dev)[crop].copy(), **common)
    if keep_band_crop:
        result.band_crops.update(noisy=hw3(noisy_dev)[centre].copy(), clean=hw3(clean_dev)[centre].copy(),
                                 file=frame.name, intensity_factor=float(frame.meta["intensity_factor"]), **common)
    for denoiser in denoisers:
        given = sigma_model if denoiser.sigma_source == SIGMA_MODEL else sigma
        mosaic_in = settings.bayer_input == MOSAIC and denoiser.kind != "builtin"
        start = time.perf_counter()
        out = denoiser(bf.noisy_mosaic if mosaic_in else bf.noisy_packed, given)
        result.seconds[denoiser.name] = time.perf_counter() - start
        packed_out = to_packed(out, pattern) if mosaic_in else out
        mosaic_out = out if mosaic_in else from_packed(out, pattern)
        raw = raw_scores(bf.clean_packed, packed_out)
        dev = developed_image(mosaic_out, bf)
        srgb = srgb_scores(clean_dev, dev, clean_lab)
        result.denoised_rows[denoiser.name] = {
            "sigma_given": denoiser.sigma_source, "seconds": result.seconds[denoiser.name],
            **_raw_columns(raw, "denoised"), **_srgb_columns(srgb, "denoised"),
            "raw_psnr_gain_db": _gain(raw["psnr_db"], raw_noisy["psnr_db"]),
            "raw_ssim_gain": _gain(raw["ssim"], raw_noisy["ssim"]),
            "psnr_gain_db": _gain(srgb["psnr_db"], srgb_noisy["psnr_db"]),
            "ssim_gain": _gain(srgb["ssim"], srgb_noisy["ssim"]),
        }
        result.patch_rows[denoiser.name] = []
        if keep_example:
            result.examples[denoiser.name] = hw3(dev)[crop].copy()
        if keep_band_crop:
            result.band_crops[denoiser.name] = hw3(dev)[centre].copy()
    return result


@dataclass
class Evaluation:
    """Everything ``denoise-eval`` measured."""

    dataset: Dataset
    denoisers: list[Denoiser]
    settings: EvalSettings
    frame_rows: list[dict]  # one per denoiser × frame
    patch_rows: list[dict]  # one per denoiser × frame × patch
    summary_rows: list[dict]  # one per denoiser × F
    verdicts: dict  # denoiser name (and NOISY) -> verdict dict
    examples: dict  # F -> {"noisy", "clean", "black", denoiser name: crop}
    counts: dict  # undefined cases
    seconds: dict = field(default_factory=dict)  # denoiser name -> total run time (printed; s/frame in the report)
    band_rows: list = field(default_factory=list)  # one per denoiser × F band (summarise_bands)
    band_verdicts: dict = field(default_factory=dict)  # denoiser name (and NOISY) -> {"detail": .., "colour": ..}
    band_crops: dict = field(default_factory=dict)  # band (lo, hi) -> crops of one frame in it
    plot_files: dict = field(default_factory=dict)  # filled by report.write_outputs


def evaluate(paths, denoisers: list[Denoiser], settings: EvalSettings | None = None, progress: bool = True,
             on_frame=None) -> Evaluation:
    """Run every denoiser on every scorable frame under ``paths`` and score it (see the module docstring)."""
    from tqdm import tqdm

    settings = settings or EvalSettings()
    names = [d.name for d in denoisers]
    if len(set(names)) != len(names):
        raise CamsimError(f"two denoisers share a name ({', '.join(names)}); give each one once")
    dataset = find_dataset(paths)
    frames = dataset.frames
    groups = {}
    for frame in frames:
        groups.setdefault(group_key(frame.meta), []).append(frame)
    # F = 1 first in each group, so that its clean layer gives the ΔE reference of the others.
    order = sorted(frames, key=lambda f: (group_key(f.meta), f.meta["intensity_factor"] != 1.0,
                                          -float(f.meta["intensity_factor"]), f.name))
    example_group = group_key(order[0].meta)
    factors = sorted({float(f.meta["intensity_factor"]) for f in frames if group_key(f.meta) == example_group},
                     reverse=True)
    example_factors = {factors[0], factors[len(factors) // 2], factors[-1]}
    # Per half-decade band of F, the frame closest (in log F) to the band's centre gives the band's crops.
    band_pick = {}
    for frame in order:
        factor = float(frame.meta["intensity_factor"])
        band = f_band(factor)
        distance = abs(np.log10(factor) - 0.5 * (np.log10(band[0]) + np.log10(band[1])))
        if band not in band_pick or distance < band_pick[band][0]:
            band_pick[band] = (distance, frame.path)
    crop_paths = {path: band for band, (_, path) in band_pick.items()}
    band_crops = {}
    references: dict[str, list] = {}
    frame_rows, patch_rows, examples = [], [], {}
    seconds = dict.fromkeys(names, 0.0)
    for frame in tqdm(order, desc="denoising", unit="frame", disable=not progress):
        key = group_key(frame.meta)
        factor = float(frame.meta["intensity_factor"])
        is_ref = factor == 1.0 and key not in references
        keep = key == example_group and factor in example_factors and factor not in examples
        result, own = evaluate_frame(frame, denoisers, settings, "self" if is_ref else references.get(key), keep,
                                     keep_band_crop=frame.path in crop_paths)
        if frame.path in crop_paths:
            band_crops[crop_paths[frame.path]] = result.band_crops
        if is_ref:
            references[key] = own
        if keep:
            examples[factor] = result.examples
        for name, spent in result.seconds.items():
            seconds[name] += spent
        for d in denoisers:
            common = {"denoiser": d.name, **result.frame_row}
            frame_rows.append({**common, **result.denoised_rows[d.name]})
            for patch in result.patch_rows[d.name]:
                patch_rows.append({"denoiser": d.name, "file": frame.name, "illuminant": frame.meta.get("illuminant"),
                                   "intensity_factor": factor, **patch})
        if on_frame is not None:
            on_frame(frame)
    frame_rows.sort(key=lambda r: (names.index(r["denoiser"]), -r["intensity_factor"], r["file"]))
    patch_rows.sort(key=lambda r: (names.index(r["denoiser"]), -r["intensity_factor"], r["file"], r["patch_index"]))
    summary_rows = summarise(frame_rows, patch_rows, names, settings.criterion)
    verdicts = {name: verdict([r for r in summary_rows if r["denoiser"] == name], "colour_preserved")
                for name in names}
    verdicts[NOISY] = verdict([r for r in summary_rows if r["denoiser"] == names[0]], "colour_preserved_noisy")
    counts = undefined_counts(frame_rows, patch_rows, names)
    band_rows = summarise_bands(frame_rows, names, settings.criterion)
    return Evaluation(dataset, denoisers, settings, frame_rows, patch_rows, summary_rows, verdicts, examples, counts,
                      seconds, band_rows, band_verdicts(band_rows, names), band_crops)
