"""Summaries of ``camsim denoise-eval``: per denoiser and intensity factor the means over frames and patches, the
counts of undefined values, whether colour is preserved by the :class:`Criterion`, and down to which light level
(:func:`verdict`); per half-decade band of F (:func:`f_band`) the chart-free verdicts on detail (SSIM against the
clean layer) and colour (mean ΔE00 against the clean layer) (:func:`summarise_bands`, :func:`band_verdicts`)."""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass

from camsim.core.errors import CamsimError
from camsim.core.optional_numbers import mean_of_defined, median_of_defined

NOISY = "noisy"  # the name of the no-denoising baseline in summaries


@dataclass(frozen=True)
class Criterion:
    """When a denoiser is said to preserve colour at a light level (over all patches of the frames at that F).

    Colour is preserved when the mean ΔE_ab (5-step, against F = 1) ≤ ``max_delta_e``, the mean chromaticity bias
    ≤ ``max_bias_xy``, and no patch's denoised colour is undefined (its mean with X + Y + Z ≤ 0, or not one
    sample with Y > 0 for ΔE).

    Chart-free (every frame): detail is preserved in a band of F when the mean SSIM of the denoised frames
    against their clean layer is ≥ ``min_ssim``; colour when their mean ΔE00 against the clean layer (per pixel,
    :mod:`camsim.denoise.colour_fidelity`) is ≤ ``max_delta_e00``.
    """

    max_delta_e: float = 3.0
    max_bias_xy: float = 0.005
    min_ssim: float = 0.8
    max_delta_e00: float = 5.0

    def __post_init__(self):
        if not (isinstance(self.min_ssim, (int, float)) and 0 < self.min_ssim <= 1):
            raise CamsimError(f"criterion min_ssim must lie in (0, 1], got {self.min_ssim!r}")
        for name in ("max_delta_e", "max_bias_xy", "max_delta_e00"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise CamsimError(f"criterion {name} must be a positive finite number, got {value!r}")

    def text(self) -> str:
        return (f"mean ΔE_ab ≤ {self.max_delta_e:g} and mean chromaticity bias ≤ {self.max_bias_xy:g} (xy), "
                "with no patch's colour undefined")

    def band_text(self) -> str:
        return (f"detail: mean SSIM against the clean layer ≥ {self.min_ssim:g}; colour: mean ΔE00 against the "
                f"clean layer ≤ {self.max_delta_e00:g}")


def f_band(factor: float) -> tuple[float, float]:
    """The half-decade band [10^(k/2), 10^((k+1)/2)) of F that holds ``factor`` (k an integer), e.g. (0.1, 0.316).

    Random light levels (a dataset's log-uniform F) are grouped by band; a grid's F = 1, 0.1, 0.01 fall one to a
    band.
    """
    if not (math.isfinite(factor) and factor > 0):
        raise CamsimError(f"intensity factor must be a positive finite number, got {factor!r}")
    k = math.floor(2.0 * math.log10(factor) + 1e-9)
    return 10.0 ** (k / 2.0), 10.0 ** ((k + 1) / 2.0)


def band_label(band) -> str:
    """``0.1–0.316`` for the band (0.1, 0.316...)."""
    return f"{band[0]:.3g}–{band[1]:.3g}"


def _judge(value, threshold, at_least: bool) -> str:
    if value is None:
        return "undetermined"
    return "yes" if (value >= threshold if at_least else value <= threshold) else "no"


def summarise_bands(frame_rows, names, criterion: Criterion) -> list[dict]:
    """One row per denoiser × band of F (:func:`f_band`): means over its frames of SSIM, PSNR gain and ΔE00 (noisy
    and denoised), run time, and whether detail and colour are preserved (denoised and noisy) by ``criterion``."""
    by = defaultdict(list)
    for r in frame_rows:
        by[(r["denoiser"], f_band(r["intensity_factor"]))].append(r)
    rows = []
    for name in names:
        for band in sorted({k[1] for k in by if k[0] == name}, reverse=True):
            fr = by[(name, band)]
            factors = [r["intensity_factor"] for r in fr]
            row = {"denoiser": name, "band": band_label(band), "f_band_low": band[0], "f_band_high": band[1],
                   "f_min": min(factors), "f_max": max(factors), "n_frames": len(fr)}
            for key in ("ssim_noisy", "ssim_denoised", "ssim_gain", "psnr_gain_db", "delta_e00_noisy",
                        "delta_e00_denoised", "seconds"):
                row[key] = mean_of_defined(r.get(key) for r in fr)
            row.update({
                "detail_preserved": _judge(row["ssim_denoised"], criterion.min_ssim, True),
                "colour_preserved_e00": _judge(row["delta_e00_denoised"], criterion.max_delta_e00, False),
                "detail_preserved_noisy": _judge(row["ssim_noisy"], criterion.min_ssim, True),
                "colour_preserved_e00_noisy": _judge(row["delta_e00_noisy"], criterion.max_delta_e00, False),
            })
            rows.append(row)
    return rows


def band_verdicts(band_rows, names) -> dict:
    """Per denoiser (and :data:`NOISY`, from the first denoiser's rows) the :func:`verdict` on detail and on colour
    over the bands of F, each band standing at the lowest F tested in it (``f_min``): ``preserved_down_to`` is
    then the lowest F of the last band, from the top, where the criterion holds in every band above."""
    out = {}
    for name, suffix in [*((n, "") for n in names), *(((names[0], "_noisy"),) if names else ())]:
        rows = [{**r, "intensity_factor": r["f_min"]} for r in band_rows if r["denoiser"] == name]
        out[NOISY if suffix else name] = {"detail": verdict(rows, "detail_preserved" + suffix),
                                          "colour": verdict(rows, "colour_preserved_e00" + suffix)}
    return out


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
            has_ref = any(p["delta_e_status"] != "no-reference" for p in pr)  # no patches: nothing to judge
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
