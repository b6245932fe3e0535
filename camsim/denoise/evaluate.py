"""Scoring denoisers on a dataset of camsim frames against their clean layer.

A dataset is any set of folders (searched recursively) and files holding camsim EXR frames: channels R, G, B =
the noisy DN before quantisation, layer ``clean.R/G/B`` = their expected value, header ``camsim:metadata`` = the
sidecar. Every denoiser sees each noisy frame as a (H, W, 3) float32 DN array; it is scored

* per frame: PSNR and SSIM (:mod:`skimage.metrics`) of the denoised and of the noisy frame against the clean
  layer, with ``data_range`` = the clean layer's range (max − min over the frame's pixels and channels);
* per patch (``meta["patches"]`` rectangles less a border): the chromaticity of the patch mean and of every
  pixel through the paper's camera → XYZ matrix M (Eq. 15, from the sidecar's Qe), the chromaticity bias
  |xy(mean of the patch) − xy(mean of the clean patch)|, the PCA noise ellipse of the pixels' xy before
  (noisy) and after (denoised), and ΔE_ab by the paper's 5-step procedure against the same patch in the clean
  layer of the F = 1 frame of the same measurement (:func:`camsim.analysis.analyze.group_key`).

Undefined quantities (no chromaticity where X + Y + Z ≤ 0, degenerate ellipses, no F = 1 reference, an
infinite PSNR of a perfect result) are None and counted, never NaN.
"""

from __future__ import annotations

import math
import time
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camsim.analysis.analyze import group_key
from camsim.colorimetry import CHANNELS, chromaticity_xy, xyz_from_camera
from camsim.analysis.delta_e import delta_e_5step, reference_lab
from camsim.analysis.ellipse import fit_ellipse
from camsim.analysis.frames import load_frame
from camsim.analysis.patches import frame_matrix, patch_samples
from camsim.errors import CamsimError
from camsim.optional_numbers import finite_or_none, mean_of_defined, median_of_defined

from camsim.denoise.denoisers import Denoiser, estimate_noise_sigma

NOISY = "noisy"  # the name of the no-denoising baseline in summaries
SSIM_MIN_SIDE = 7  # scikit-image's default SSIM window


@dataclass(frozen=True)
class Criterion:
    """When a denoiser is said to preserve colour at a light level (over all patches of the frames at that F).

    Colour is preserved when the mean ΔE_ab (5-step, against F = 1) ≤ ``max_delta_e``, the mean chromaticity bias
    ≤ ``max_bias_xy``, and no patch's denoised colour is undefined (its mean with X + Y + Z ≤ 0, or not one
    sample with Y > 0 for ΔE).
    """

    max_delta_e: float = 3.0
    max_bias_xy: float = 0.005

    def __post_init__(self):
        for name in ("max_delta_e", "max_bias_xy"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise CamsimError(f"criterion {name} must be a positive finite number, got {value!r}")

    def text(self) -> str:
        return (f"mean ΔE_ab ≤ {self.max_delta_e:g} and mean chromaticity bias ≤ {self.max_bias_xy:g} (xy), "
                "with no patch's colour undefined")


@dataclass(frozen=True)
class EvalSettings:
    """How frames are scored.

    Attributes
    ----------
    border_px : int
        Pixels left out along each edge of a patch rectangle.
    subtract_black : bool
        Subtract the sidecar's mean dark level (exact for EXR numbers) before the colour quantities, so that they
        measure the denoiser rather than the dark current's drag toward the camera black point (which the paper,
        subtracting nothing, reports). False measures as the paper does.
    criterion : Criterion
    matrix : str
        Camera → XYZ method; the paper's M by default.
    """

    border_px: int = 3
    subtract_black: bool = True
    criterion: Criterion = field(default_factory=Criterion)
    matrix: str = "paper"

    def __post_init__(self):
        if not (isinstance(self.border_px, int) and self.border_px >= 0):
            raise CamsimError(f"border must be a non-negative number of pixels, got {self.border_px!r}")


@dataclass
class DatasetFrame:
    """A usable frame of a dataset: its path, its path relative to the dataset folder, and its sidecar."""

    path: Path
    name: str
    meta: dict


@dataclass
class Dataset:
    frames: list[DatasetFrame]
    skipped: list[dict]  # {"file", "reason"}
    roots: list[str]


def _relative(path: Path, root: Path) -> str:
    try:
        return str(path.relative_to(root))
    except ValueError:
        return str(path)


def find_dataset(paths) -> Dataset:
    """The EXR frames under ``paths`` (folders searched recursively, or files) that can be scored.

    Bayer (CFA) frames, EXRs without a clean layer and files that are not camsim frames are skipped, each with
    its reason.

    Raises
    ------
    CamsimError
        A path that does not exist, or no usable frame at all.
    """
    from camsim.io.exr import read_exr

    frames, skipped, roots = [], [], []
    for entry in paths:
        entry = Path(entry)
        if entry.is_dir():
            candidates, root = sorted(p for p in entry.rglob("*.exr") if p.is_file()), entry
        elif entry.is_file():
            candidates, root = [entry], entry.parent
        else:
            raise CamsimError(f"no such file or folder: {entry}")
        roots.append(str(entry))
        for path in candidates:
            name = _relative(path, root)
            try:
                frame = load_frame(path)
            except CamsimError as exc:
                skipped.append({"file": name, "reason": f"not a readable camsim frame: {exc}"})
                continue
            if frame.cfa_pattern or frame.pixels_dn.shape[0] != 3:
                skipped.append({"file": name, "reason": f"Bayer (CFA {frame.cfa_pattern}) mosaic: denoise-eval "
                                                        "scores three-chip (R, G, B at every pixel) frames only"})
                continue
            _, clean, _ = read_exr(path)
            if clean is None:
                skipped.append({"file": name, "reason": "no clean layer (clean.R/G/B) to score against"})
                continue
            frames.append(DatasetFrame(path, name, frame.meta))
    if not frames:
        reasons = "; ".join(f"{s['file']}: {s['reason']}" for s in skipped[:3])
        raise CamsimError(f"no scorable frames (three-chip camsim EXR with a clean layer) in "
                          f"{', '.join(str(p) for p in paths)}" + (f" — skipped {reasons}" if reasons else ""))
    return Dataset(frames, skipped, roots)


def image_scores(clean: np.ndarray, test: np.ndarray, data_range: float) -> tuple[float | None, float | None]:
    """PSNR (dB) and SSIM of ``test`` against ``clean``, both (H, W, 3); None where undefined.

    PSNR is undefined (infinite) for a perfect result; SSIM for frames smaller than its 7 × 7 window.
    """
    from skimage.metrics import mean_squared_error, peak_signal_noise_ratio, structural_similarity

    clean = clean.astype(np.float64)
    test = test.astype(np.float64)
    psnr = None
    if mean_squared_error(clean, test) > 0:
        psnr = finite_or_none(peak_signal_noise_ratio(clean, test, data_range=data_range))
    ssim = None
    if min(clean.shape[:2]) >= SSIM_MIN_SIDE:
        ssim = finite_or_none(structural_similarity(clean, test, data_range=data_range, channel_axis=-1))
    return psnr, ssim


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


def _reference_labs(frame, clean: np.ndarray, black: np.ndarray, matrix, border: int) -> list:
    """Per patch the mean Lab (5-step, Y = 100) of the clean layer: the ΔE reference of the F = 1 frame."""
    labs = []
    for patch in frame.meta["patches"]:
        samples = patch_samples(clean, patch["rect_xywh"], border).astype(np.float64) - black
        lab = reference_lab(xyz_from_camera(samples, matrix))[0] if samples.shape[0] else None
        labs.append(lab)
    return labs


@dataclass
class FrameResult:
    """Scores of one frame: the noisy baseline and per denoiser."""

    frame_row: dict  # the frame's fields common to every denoiser (file, F, ..., noisy scores)
    denoised_rows: dict  # denoiser name -> frame-level scores of the denoised frame
    patch_rows: dict  # denoiser name -> list of per-patch dicts
    examples: dict = field(default_factory=dict)  # denoiser name -> (H', W', 3) crop; plus "noisy", "clean"
    seconds: dict = field(default_factory=dict)  # denoiser name -> run time on this frame


EXAMPLE_CROP = (240, 320)  # rows, columns of the crop kept for the example figure


def _frame_fields(frame: DatasetFrame) -> dict:
    meta = frame.meta
    return {"file": frame.name, "scene": meta.get("scene"), "illuminant": meta.get("illuminant"),
            "intensity_factor": float(meta["intensity_factor"]), "width_px": meta.get("width_px"),
            "height_px": meta.get("height_px")}


def evaluate_frame(frame: DatasetFrame, denoisers: list[Denoiser], settings: EvalSettings, ref_labs,
                   keep_example: bool = False) -> tuple[FrameResult, list | None]:
    """Score every denoiser on one frame. Returns the result and, for an F = 1 frame, its reference Labs."""
    from camsim.io.exr import read_exr

    loaded = load_frame(frame.path)
    _, clean, _ = read_exr(frame.path)
    noisy_chw = loaded.pixels_dn.astype(np.float32, copy=False)
    noisy = np.ascontiguousarray(np.moveaxis(noisy_chw, 0, -1))
    clean_hw3 = np.ascontiguousarray(np.moveaxis(clean, 0, -1))
    black = loaded.expected_black_dn() if settings.subtract_black else np.zeros(3)
    matrix = frame_matrix(loaded, settings.matrix)
    border = settings.border_px
    own_refs = None
    if ref_labs == "self":
        own_refs = _reference_labs(loaded, clean, black, matrix, border)
        ref_labs = own_refs

    data_range = float(clean.max() - clean.min())
    data_range_source = "clean range"
    if not data_range > 0:
        data_range, data_range_source = float(loaded.meta.get("white_level_dn") or 1.0), "white level"
    sigma = estimate_noise_sigma(noisy)
    true_sigma = (noisy.astype(np.float64) - clean_hw3).std(axis=(0, 1))
    psnr_noisy, ssim_noisy = image_scores(clean_hw3, noisy, data_range)
    row = _frame_fields(frame)
    row.update({"data_range_dn": data_range, "data_range_source": data_range_source,
                **{f"sigma_est_{c}_dn": float(s) for c, s in zip(CHANNELS, sigma)},
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
    if keep_example:
        result.examples.update(noisy=noisy[crop].copy(), clean=clean_hw3[crop].copy(), black=np.asarray(black))
    for denoiser in denoisers:
        start = time.perf_counter()
        denoised = denoiser(noisy, sigma)
        result.seconds[denoiser.name] = time.perf_counter() - start
        psnr, ssim = image_scores(clean_hw3, denoised, data_range)
        result.denoised_rows[denoiser.name] = {
            "psnr_denoised_db": psnr, "ssim_denoised": ssim,
            "psnr_gain_db": None if psnr is None or psnr_noisy is None else psnr - psnr_noisy,
            "ssim_gain": None if ssim is None or ssim_noisy is None else ssim - ssim_noisy,
        }
        if keep_example:
            result.examples[denoiser.name] = denoised[crop].copy()
        denoised_chw = np.moveaxis(denoised, -1, 0)
        rows = []
        for index, patch, ref, truth, before in base:
            samples = patch_samples(denoised_chw, patch["rect_xywh"], border).astype(np.float64) - black
            after = patch_colour(samples, matrix, ref)
            rows.append(_patch_row(index, patch, ref, truth, before, after))
        result.patch_rows[denoiser.name] = rows
    return result, own_refs


def _patch_row(index, patch, ref, truth, before, after) -> dict:
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
    seconds: dict = field(default_factory=dict)  # denoiser name -> total run time (printed, never written)
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
    references: dict[str, list] = {}
    frame_rows, patch_rows, examples = [], [], {}
    seconds = dict.fromkeys(names, 0.0)
    for frame in tqdm(order, desc="denoising", unit="frame", disable=not progress):
        key = group_key(frame.meta)
        factor = float(frame.meta["intensity_factor"])
        is_ref = factor == 1.0 and key not in references
        keep = key == example_group and factor in example_factors and factor not in examples
        result, own = evaluate_frame(frame, denoisers, settings, "self" if is_ref else references.get(key), keep)
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
    return Evaluation(dataset, denoisers, settings, frame_rows, patch_rows, summary_rows, verdicts, examples, counts,
                      seconds)


def _preserved(delta_e, bias, n_undefined_colour, has_reference, criterion: Criterion) -> str:
    if not has_reference:
        return "undetermined"
    if n_undefined_colour or delta_e is None or bias is None:
        return "no"
    return "yes" if delta_e <= criterion.max_delta_e and bias <= criterion.max_bias_xy else "no"


def summarise(frame_rows, patch_rows, names, criterion: Criterion) -> list[dict]:
    """One row per denoiser × intensity factor: means over frames and patches, counts of undefined values and
    whether colour is preserved (for the denoised frames, and for the noisy baseline)."""
    frames_by = defaultdict(list)
    patches_by = defaultdict(list)
    for r in frame_rows:
        frames_by[(r["denoiser"], r["intensity_factor"])].append(r)
    for r in patch_rows:
        patches_by[(r["denoiser"], r["intensity_factor"])].append(r)
    rows = []
    for name in names:
        for factor in sorted({k[1] for k in frames_by if k[0] == name}, reverse=True):
            fr, pr = frames_by[(name, factor)], patches_by[(name, factor)]
            has_ref = any(p["delta_e_status"] != "no-reference" for p in pr) or not pr
            row = {"denoiser": name, "intensity_factor": factor, "n_frames": len(fr), "n_patches": len(pr)}
            for key in ("psnr_noisy_db", "psnr_denoised_db", "psnr_gain_db", "ssim_noisy", "ssim_denoised",
                        "ssim_gain"):
                row[key] = mean_of_defined(r[key] for r in fr)
            for key in ("bias_noisy_xy", "bias_denoised_xy", "ellipse_size_noisy", "ellipse_size_denoised",
                        "ellipse_size_ratio", "delta_e_clean", "delta_e_noisy", "delta_e_denoised"):
                row[key] = mean_of_defined(p[key] for p in pr)
            for key in ("delta_e_noisy", "delta_e_denoised"):  # ΔE is heavy-tailed at low light: also the median
                row[f"{key}_median"] = median_of_defined(p[key] for p in pr)
            undefined = {}
            for label in ("noisy", "denoised"):
                undefined[label] = sum((p[f"bias_{label}_xy"] is None and p["clean_x"] is not None)
                                       + (p[f"delta_e_{label}"] is None and p["delta_e_status"] != "no-reference")
                                       for p in pr)
            row.update({
                "n_bias_undefined": sum(p["bias_denoised_xy"] is None for p in pr),
                "n_ellipse_ratio_undefined": sum(p["ellipse_size_ratio"] is None for p in pr),
                "n_delta_e_undefined": sum(p["delta_e_denoised"] is None for p in pr),
                "n_psnr_undefined": sum(r["psnr_denoised_db"] is None for r in fr),
                "colour_preserved": _preserved(row["delta_e_denoised"], row["bias_denoised_xy"], undefined["denoised"],
                                               has_ref, criterion),
                "colour_preserved_noisy": _preserved(row["delta_e_noisy"], row["bias_noisy_xy"], undefined["noisy"],
                                                     has_ref, criterion),
            })
            rows.append(row)
    return rows


def verdict(rows, column: str) -> dict:
    """Where colour stops being preserved, from summary rows of one denoiser (any order).

    Returns ``{"preserved_down_to": F or None, "stops_at": F or None, "status": ..., "by_factor": {F: yes/no/...},
    "recovers_below": [F...]}``; status is ``all-preserved`` (the stop lies below the tested range), ``stops``,
    ``never-preserved`` (fails at the highest tested F) or ``undetermined`` (no F = 1 reference).
    """
    rows = sorted(rows, key=lambda r: -r["intensity_factor"])
    by_factor = {r["intensity_factor"]: r[column] for r in rows}
    if rows and all(v == "undetermined" for v in by_factor.values()):
        return {"status": "undetermined", "preserved_down_to": None, "stops_at": None, "by_factor": by_factor,
                "recovers_below": []}
    down_to, stops = None, None
    for r in rows:
        if r[column] == "yes":
            down_to = r["intensity_factor"]
        else:
            stops = r["intensity_factor"]
            break
    recovers = [] if stops is None else [f for f, v in by_factor.items() if f < stops and v == "yes"]
    status = "all-preserved" if stops is None else ("never-preserved" if down_to is None else "stops")
    return {"status": status, "preserved_down_to": down_to, "stops_at": stops, "by_factor": by_factor,
            "recovers_below": recovers}


def undefined_counts(frame_rows, patch_rows, names) -> dict:
    """Per denoiser, how many values were undefined (None in the CSV files) and why."""
    out = {}
    for name in names:
        fr = [r for r in frame_rows if r["denoiser"] == name]
        pr = [r for r in patch_rows if r["denoiser"] == name]
        out[name] = {
            "frames": len(fr),
            "patches": len(pr),
            "psnr_infinite_denoised": sum(r["psnr_denoised_db"] is None for r in fr),
            "psnr_infinite_noisy": sum(r["psnr_noisy_db"] is None for r in fr),
            "ssim_undefined": sum(r["ssim_denoised"] is None for r in fr),
            "patch_mean_xy_undefined_clean": sum(r["clean_x"] is None for r in pr),
            "patch_mean_xy_undefined_noisy": sum(r["noisy_mean_x"] is None for r in pr),
            "patch_mean_xy_undefined_denoised": sum(r["denoised_mean_x"] is None for r in pr),
            "xy_undefined_samples_noisy": sum(r["n_xy_undefined_noisy"] for r in pr),
            "xy_undefined_samples_denoised": sum(r["n_xy_undefined_denoised"] for r in pr),
            "degenerate_ellipses_noisy": sum(r["ellipse_status_noisy"] != "ok" for r in pr),
            "degenerate_ellipses_denoised": sum(r["ellipse_status_denoised"] != "ok" for r in pr),
            "ellipse_ratio_undefined": sum(r["ellipse_size_ratio"] is None for r in pr),
            "delta_e_no_reference": sum(r["delta_e_status"] == "no-reference" for r in pr),
            "delta_e_no_valid_sample": sum(r["delta_e_status"] == "no-valid-sample" for r in pr),
            "y_nonpositive_samples_noisy": sum(r["n_y_nonpositive_noisy"] or 0 for r in pr),
            "y_nonpositive_samples_denoised": sum(r["n_y_nonpositive_denoised"] or 0 for r in pr),
        }
    return out
