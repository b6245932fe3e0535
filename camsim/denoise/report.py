"""The outputs of ``camsim denoise-eval``: CSV tables, plots, ``report.md`` and ``summary.json``, each atomic.

* ``frames.csv`` — one row per denoiser × frame: PSNR / SSIM of the noisy and the denoised frame against the clean
  layer, the data range used, the estimated and the true noise σ per channel.
* ``patches.csv`` — one row per denoiser × frame × patch: xy of the patch mean (clean, noisy, denoised), the
  chromaticity bias, the ellipse centre and size before and after, their ratio, ΔE (clean, noisy, denoised).
* ``summary.csv`` — one row per denoiser × intensity factor: the means, the undefined counts and whether colour is
  preserved by the criterion.
* ``bands.csv`` — one row per denoiser × half-decade band of F: mean SSIM, PSNR gain, chart-free ΔE00 (noisy and
  denoised), run time, and whether detail and colour are preserved.
* ``psnr_ssim.png``, ``chromaticity_bias.png``, ``delta_e.png``, ``ellipse_size.png`` (each against F, noisy
  baseline and denoised), ``delta_e00.png`` (chart-free ΔE00 against F), ``examples.png`` (crops: clean, noisy,
  denoised), ``crops_by_band.png`` (a centre crop per band of F: clean, noisy, each denoiser).
* ``report.md`` and ``summary.json`` (settings, criterion, verdicts, undefined counts, skipped frames).

Empty CSV cells are undefined values (counted in ``summary.csv`` and ``summary.json``); no file holds NaN.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from camsim.denoise.bayer import BAYER_PLANES, GAIN_WHY, isp_text
from camsim.denoise.colour_fidelity import WHITE_CLEAN_MAX
from camsim.denoise.denoisers import MODEL_SIGMA_TEXT, SIGMA_ESTIMATOR, SIGMA_MODEL, WAVELET_IMPLEMENTATION
from camsim.denoise.evaluate import Evaluation
from camsim.denoise.summary import NOISY, band_label, f_band
from camsim.io.atomic import write_json_atomic, write_text_atomic
from camsim.io.figures import new_figure, save_png
from camsim.io.output_folder import make_folder

#: The columns of ``frames.csv`` for Bayer frames (empty for three-chip frames): raw scores on the normalised packed
#: planes (overall, then per plane R, G1, G2, B), the noise σ per plane (normalised), and the scores after the ISP.
BAYER_FRAME_COLUMNS = (
    "raw_psnr_noisy_db", "raw_psnr_denoised_db", "raw_psnr_gain_db", "raw_ssim_noisy", "raw_ssim_denoised",
    "raw_ssim_gain",
    *(f"raw_psnr_{p}_{label}_db" for p in BAYER_PLANES for label in ("noisy", "denoised")),
    *(f"raw_ssim_{p}_{label}" for p in BAYER_PLANES for label in ("noisy", "denoised")),
    *(f"raw_sigma_est_{p}" for p in BAYER_PLANES), *(f"raw_sigma_model_{p}" for p in BAYER_PLANES),
    *(f"raw_noise_std_{p}" for p in BAYER_PLANES),
    "isp_gain", "srgb_psnr_noisy_db", "srgb_psnr_denoised_db", "srgb_ssim_noisy", "srgb_ssim_denoised",
    "srgb_delta_e00_noisy", "srgb_delta_e00_denoised")
FRAME_COLUMNS = ("denoiser", "file", "scene", "illuminant", "intensity_factor", "width_px", "height_px",
                 "data_range_dn", "data_range_source", "sigma_est_R_dn", "sigma_est_G_dn", "sigma_est_B_dn",
                 "sigma_model_R_dn", "sigma_model_G_dn", "sigma_model_B_dn", "sigma_given",
                 "noise_std_R_dn", "noise_std_G_dn", "noise_std_B_dn", "psnr_noisy_db", "psnr_denoised_db",
                 "psnr_gain_db", "ssim_noisy", "ssim_denoised", "ssim_gain", "white_source", "delta_e00_noisy",
                 "delta_e00_denoised", "seconds", "frame_kind", "scored_as", "bayer_input",
                 *BAYER_FRAME_COLUMNS)
BAND_COLUMNS = ("denoiser", "band", "f_band_low", "f_band_high", "f_min", "f_max", "n_frames", "ssim_noisy",
                "ssim_denoised", "ssim_gain", "psnr_gain_db", "delta_e00_noisy", "delta_e00_denoised", "seconds",
                "detail_preserved", "colour_preserved_e00", "detail_preserved_noisy", "colour_preserved_e00_noisy")
PATCH_COLUMNS = ("denoiser", "file", "illuminant", "intensity_factor", "patch_index", "patch_name", "clean_x",
                 "clean_y", "noisy_mean_x", "noisy_mean_y", "denoised_mean_x", "denoised_mean_y", "bias_noisy_xy",
                 "bias_denoised_xy", "noisy_center_x", "noisy_center_y", "denoised_center_x", "denoised_center_y",
                 "ellipse_size_noisy", "ellipse_status_noisy", "ellipse_size_denoised", "ellipse_status_denoised",
                 "ellipse_size_ratio", "n_xy_undefined_noisy", "n_xy_undefined_denoised", "delta_e_clean",
                 "delta_e_noisy", "delta_e_denoised", "n_y_nonpositive_noisy", "n_y_nonpositive_denoised",
                 "delta_e_status")
SUMMARY_COLUMNS = ("denoiser", "intensity_factor", "n_frames", "n_patches", "psnr_noisy_db", "psnr_denoised_db",
                   "psnr_gain_db", "ssim_noisy", "ssim_denoised", "ssim_gain", "bias_noisy_xy", "bias_denoised_xy",
                   "ellipse_size_noisy", "ellipse_size_denoised", "ellipse_size_ratio", "delta_e_clean",
                   "delta_e_noisy", "delta_e_denoised", "delta_e_noisy_median", "delta_e_denoised_median",
                   "n_bias_undefined", "n_ellipse_ratio_undefined", "n_delta_e_undefined", "n_psnr_undefined",
                   "colour_preserved", "colour_preserved_noisy")
PLOTS = {"psnr_ssim": "psnr_ssim.png", "bias": "chromaticity_bias.png", "delta_e": "delta_e.png",
         "ellipse": "ellipse_size.png", "delta_e00": "delta_e00.png", "examples": "examples.png",
         "crops": "crops_by_band.png"}
NOISY_LABEL = "noisy (no denoising)"


def _cell(value):
    if value is None:
        return ""
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"non-finite value {value!r} in an output table (a bug: undefined values must be None)")
    return value


def csv_text(rows, columns) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n", extrasaction="ignore")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: _cell(row.get(k)) for k in columns})
    return buffer.getvalue()


def _fmt(value, spec=".3g") -> str:
    return "—" if value is None else format(value, spec)


def _f(factor) -> str:
    return f"{factor:g}"


# ------------------------------------------------------------------------------------------------------ plots

def _series(ev: Evaluation, name: str, key: str):
    rows = sorted((r for r in ev.summary_rows if r["denoiser"] == name), key=lambda r: r["intensity_factor"])
    pts = [(r["intensity_factor"], r[key]) for r in rows if r[key] is not None]
    return [p[0] for p in pts], [p[1] for p in pts]


def _colours(ev: Evaluation) -> dict:
    import matplotlib

    cycle = matplotlib.rcParams["axes.prop_cycle"].by_key()["color"]
    return {d.name: cycle[i % len(cycle)] for i, d in enumerate(ev.denoisers)}


def _against_f(ax, ev: Evaluation, key_noisy: str, key_denoised: str, ylabel: str, log_y=False, threshold=None):
    colours = _colours(ev)
    first = ev.denoisers[0].name
    x, y = _series(ev, first, key_noisy)
    if x:
        ax.plot(x, y, "k--", marker="o", mfc="none", ms=8, zorder=4, label=NOISY_LABEL)  # on top of identity
    for d in ev.denoisers:
        x, y = _series(ev, d.name, key_denoised)
        if x:
            ax.plot(x, y, "-", marker="o", color=colours[d.name], label=d.name)
    if threshold is not None:
        ax.axhline(threshold, color="crimson", lw=1, ls=":", label=f"criterion ≤ {threshold:g}")
    ax.set_xscale("log")
    if log_y:
        ax.set_yscale("log")
    ax.set_xlabel("intensity factor F (light level)")
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8)


def _plots(ev: Evaluation, out: Path) -> dict:
    crit = ev.settings.criterion
    fig = new_figure(figsize=(11, 4.2), layout="constrained")
    axes = fig.subplots(1, 2)
    _against_f(axes[0], ev, "psnr_noisy_db", "psnr_denoised_db", "PSNR against the clean layer (dB)")
    _against_f(axes[1], ev, "ssim_noisy", "ssim_denoised", "SSIM against the clean layer")
    fig.suptitle("PSNR and SSIM (mean over frames) — data range: each frame's clean range"
                 + ("; Bayer frames: after the ISP, data range 1" if _bayer_rows(ev) else ""))
    save_png(fig, out / PLOTS["psnr_ssim"])

    fig = new_figure(figsize=(6.5, 4.4), layout="constrained")
    ax = fig.subplots()
    _against_f(ax, ev, "bias_noisy_xy", "bias_denoised_xy", "mean chromaticity bias |Δxy| of patch means",
               log_y=True, threshold=crit.max_bias_xy)
    ax.set_title("Chromaticity bias against the clean patch mean")
    save_png(fig, out / PLOTS["bias"])

    fig = new_figure(figsize=(6.5, 4.4), layout="constrained")
    ax = fig.subplots()
    _against_f(ax, ev, "delta_e_noisy", "delta_e_denoised", "mean ΔE_ab (5-step, vs clean F = 1)", log_y=True,
               threshold=crit.max_delta_e)
    x, y = _series(ev, ev.denoisers[0].name, "delta_e_clean")
    if x and max(y) > 0.01 * crit.max_delta_e:  # the floor a perfect denoiser reaches; omitted when ~0
        ax.plot(x, y, color="grey", ls="-.", label="clean layer (perfect denoiser)")
        ax.legend(fontsize=8)
    ax.set_title("ΔE against F = 1")
    save_png(fig, out / PLOTS["delta_e"])

    fig = new_figure(figsize=(11, 4.2), layout="constrained")
    axes = fig.subplots(1, 2)
    _against_f(axes[0], ev, "ellipse_size_noisy", "ellipse_size_denoised", "mean ellipse size √(a² + b²) (xy, 1 σ)",
               log_y=True)
    colours = _colours(ev)
    for d in ev.denoisers:
        x, y = _series(ev, d.name, "ellipse_size_ratio")
        if x:
            axes[1].plot(x, y, "-", marker="o", color=colours[d.name], label=d.name)
    axes[1].axhline(1.0, color="k", ls="--", lw=1, label="no change")
    axes[1].set_xscale("log")
    axes[1].set_xlabel("intensity factor F (light level)")
    axes[1].set_ylabel("mean ellipse-size ratio, denoised / noisy")
    axes[1].grid(True, which="both", alpha=0.3)
    axes[1].legend(fontsize=8)
    fig.suptitle("Chromaticity noise ellipses before (noisy) and after (denoised)")
    save_png(fig, out / PLOTS["ellipse"])

    fig = new_figure(figsize=(6.5, 4.4), layout="constrained")
    ax = fig.subplots()
    _against_f_frames(ax, ev, "delta_e00_noisy", "delta_e00_denoised", "mean ΔE00 against the clean layer",
                      threshold=crit.max_delta_e00)
    ax.set_title("Chart-free colour fidelity (every pixel, vs clean)")
    save_png(fig, out / PLOTS["delta_e00"])

    if ev.examples:
        _example_plot(ev, out / PLOTS["examples"])
    if ev.band_crops:
        crops_by_band_figure(ev, out / PLOTS["crops"])
    return {k: v for k, v in PLOTS.items() if (out / v).exists() and (k != "examples" or ev.examples)
            and (k != "crops" or ev.band_crops)}


def _against_f_frames(ax, ev: Evaluation, key_noisy: str, key_denoised: str, ylabel: str, threshold=None):
    """Per-frame values against F (one point per frame, log-log): the noisy baseline and each denoiser."""
    colours = _colours(ev)
    first = ev.denoisers[0].name
    pts = sorted((r["intensity_factor"], r[key_noisy]) for r in ev.frame_rows
                 if r["denoiser"] == first and r[key_noisy] is not None)
    if pts:
        ax.plot(*zip(*pts), "ko", mfc="none", ms=6, label=NOISY_LABEL)
    for d in ev.denoisers:
        if d.name == "identity":
            continue  # the same points as the noisy baseline
        pts = sorted((r["intensity_factor"], r[key_denoised]) for r in ev.frame_rows
                     if r["denoiser"] == d.name and r[key_denoised] is not None)
        if pts:
            ax.plot(*zip(*pts), ".", color=colours[d.name], ms=7, label=d.name)
    if threshold is not None:
        ax.axhline(threshold, color="crimson", lw=1, ls=":", label=f"criterion ≤ {threshold:g}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("intensity factor F (light level)")
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)


def crops_by_band_figure(ev: Evaluation, path: Path) -> Path:
    """The crops figure: per half-decade band of F (rows, brightest first) a centre crop of one frame in the band
    (the one closest to the band's centre in log F) — noisy, then each denoiser, then clean (columns). Three-chip
    frames: black level subtracted, each row scaled to its clean crop's maximum, γ 1/2.2; Bayer frames: developed
    by :func:`camsim.isp.develop` (:func:`camsim.denoise.bayer.isp_settings`, the run's ``isp_gain``). Written as a PNG
    with matplotlib's Agg canvas, chosen here for this figure alone (no process-wide backend)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    bands = sorted(ev.band_crops, reverse=True)
    columns = ["noisy", *[d.name for d in ev.denoisers if d.name != "identity"], "clean"]
    fig = new_figure(figsize=(2.2 * len(columns), 1.8 * len(bands) + 0.6), layout="constrained")
    FigureCanvasAgg(fig)
    _crop_grid(fig, [ev.band_crops[band] for band in bands], columns,
               [f"F {band_label(band)}\n(F = {ev.band_crops[band]['intensity_factor']:.3g})" for band in bands], 8)
    fig.suptitle("Noisy / denoised / clean per band of F (centre crop)\n"
                 + _crop_note([ev.band_crops[band] for band in bands], _gain_word(ev.settings.isp_gain)), fontsize=9)
    return save_png(fig, path)


def _crop_grid(fig, rows: list, columns: list, row_labels: list, label_size: int) -> None:
    """Rows of crops (each a dict: column name → crop, plus ``black``) as an image grid on ``fig``: black level
    subtracted, each row scaled to its clean crop's maximum, γ 1/2.2; column titles on the first row, ``row_labels``
    on the first column."""
    axes = fig.subplots(len(rows), len(columns), squeeze=False)
    for i, crops in enumerate(rows):
        black = crops["black"]
        scale = float(np.max(crops["clean"] - black)) or 1.0
        for j, col in enumerate(columns):
            ax = axes[i, j]
            # a Bayer frame's crops are developed already (camsim.isp, sRGB in [0, 1]): shown as they are
            shown = np.clip(crops[col], 0.0, 1.0) if crops.get("developed") else _display(crops[col], black, scale)
            ax.imshow(shown, interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            if i == 0:
                ax.set_title(col, fontsize=9)
            if j == 0:
                ax.set_ylabel(row_labels[i], fontsize=label_size)


def _crop_note(rows: list, gain="white") -> str:
    """How the crops of ``rows`` are shown, for a figure's title (one line per kind of frame among them)."""
    notes = []
    if any(not r.get("developed") for r in rows):
        notes.append("three-chip: black subtracted, row scaled to its clean maximum, γ 1/2.2")
    if any(r.get("developed") for r in rows):
        notes.append(f"Bayer: developed by camsim.isp (as shot, camera matrix, gain {gain}, sRGB)")
    return "\n".join(notes)


def _gain_word(gain) -> str:
    return {"white": "white", "auto": "1/F"}.get(gain, f"{gain:g}" if isinstance(gain, (int, float)) else str(gain))


def _display(img, black, scale):
    v = np.clip((img.astype(np.float64) - black) / scale, 0.0, 1.0)
    return v ** (1 / 2.2)


def _example_plot(ev: Evaluation, path: Path) -> None:
    factors = sorted(ev.examples, reverse=True)
    columns = ["clean", "noisy", *[d.name for d in ev.denoisers]]
    fig = new_figure(figsize=(2.3 * len(columns), 1.9 * len(factors) + 0.5), layout="constrained")
    _crop_grid(fig, [ev.examples[factor] for factor in factors], columns, [f"F = {_f(f)}" for f in factors], 9)
    fig.suptitle("Clean, noisy and denoised\n"
                 + _crop_note([ev.examples[factor] for factor in factors], _gain_word(ev.settings.isp_gain)),
                 fontsize=9)
    save_png(fig, path)


# ------------------------------------------------------------------------------------------------------ report

def _row(ev: Evaluation, name: str, factor: float) -> dict | None:
    for r in ev.summary_rows:
        if r["denoiser"] == name and r["intensity_factor"] == factor:
            return r
    return None


def _why(row: dict, crit, noisy: bool) -> str:
    label = "noisy" if noisy else "denoised"
    de, bias = row[f"delta_e_{label}"], row[f"bias_{label}_xy"]
    reasons = []
    if de is None or de > crit.max_delta_e:
        reasons.append(f"mean ΔE {_fmt(de, '.3g')} > {crit.max_delta_e:g}" if de is not None else "ΔE undefined")
    if bias is None or bias > crit.max_bias_xy:
        reasons.append(f"bias {_fmt(bias, '.2g')} > {crit.max_bias_xy:g}" if bias is not None else "bias undefined")
    if not reasons:
        reasons.append("a patch's colour is undefined")
    return ", ".join(reasons)


def verdict_sentence(ev: Evaluation, name: str) -> str:
    v = ev.verdicts[name]
    noisy = name == NOISY
    source = ev.denoisers[0].name if noisy else name
    label = NOISY_LABEL if noisy else name
    factors = sorted(v["by_factor"], reverse=True)
    if v["status"] == "undetermined":
        return f"**{label}**: cannot be judged — no F = 1 frame gives the ΔE reference."
    if v["status"] == "all-preserved":
        text = (f"**{label}** preserves colour at every tested light level, down to F = {_f(factors[-1])} (the "
                "lowest tested); where it stops lies below the tested range.")
    elif v["status"] == "never-preserved":
        row = _row(ev, source, v["stops_at"])
        text = (f"**{label}** does not preserve colour even at the highest tested light level, F = "
                f"{_f(v['stops_at'])} ({_why(row, ev.settings.criterion, noisy)}).")
    else:
        row = _row(ev, source, v["stops_at"])
        text = (f"**{label}** preserves colour down to F = {_f(v['preserved_down_to'])} and stops at F = "
                f"{_f(v['stops_at'])} ({_why(row, ev.settings.criterion, noisy)}).")
    if v["recovers_below"]:
        text += (f" It passes again at F = {', '.join(_f(f) for f in v['recovers_below'])}, below its stop (not "
                 "monotone: look at the table).")
    return text


def _down_to(v) -> str:
    if v["status"] == "undetermined":
        return "undetermined"
    if v["status"] == "never-preserved":
        return "none (fails at every tested F)" if not v["recovers_below"] else "none at the top"
    return _f(v["preserved_down_to"]) + (" (lowest tested)" if v["status"] == "all-preserved" else "")


def _stops(v) -> str:
    if v["status"] == "undetermined":
        return "undetermined"
    return "below the tested range" if v["stops_at"] is None else _f(v["stops_at"])


def _mark(value: str) -> str:
    return {"yes": "✓", "no": "✗"}.get(value, "—")


def _chart_judged(ev: Evaluation) -> bool:
    """Whether the chart's ΔE verdicts could be formed (a chart in view and an F = 1 frame as the reference)."""
    return any(v["status"] != "undetermined" for v in ev.verdicts.values()) and bool(ev.patch_rows)


ASPECTS = {"detail": ("detail", "ssim_denoised", "mean SSIM", "<", "min_ssim"),
           "colour": ("colour", "delta_e00_denoised", "mean ΔE00", ">", "max_delta_e00")}


def _band_row(ev: Evaluation, name: str, f_min: float) -> dict | None:
    source = ev.denoisers[0].name if name == NOISY else name
    for r in ev.band_rows:
        if r["denoiser"] == source and r["f_min"] == f_min:
            return r
    return None


def band_verdict_sentence(ev: Evaluation, name: str, aspect: str) -> str:
    """One sentence: down to which light level ``name`` preserves ``aspect`` ("detail" or "colour")."""
    word, key, label, cmp, limit_name = ASPECTS[aspect]
    if name == NOISY:
        key = key.replace("_denoised", "_noisy")
    limit = getattr(ev.settings.criterion, limit_name)
    v = ev.band_verdicts[name][aspect]
    who = NOISY_LABEL if name == NOISY else name
    if v["status"] == "undetermined":
        return f"**{who}**: {word} cannot be judged ({label} undefined in every band)."
    if v["status"] == "all-preserved":
        return (f"**{who}** preserves {word} in every tested band, down to F = {v['preserved_down_to']:.3g} (the "
                "lowest tested).")
    row = _band_row(ev, name, v["stops_at"])
    value = row[key] if row else None
    why = (f"in band {row['band']} (F = {row['f_min']:.3g}…{row['f_max']:.3g}, {row['n_frames']} frame"
           f"{'s' if row['n_frames'] != 1 else ''}) the {label} is {_fmt(value, '.3g')} {cmp} {limit:g}"
           if row else "")
    if v["status"] == "never-preserved":
        text = f"**{who}** does not preserve {word} even in the brightest tested band: {why}."
    else:
        text = (f"**{who}** preserves {word} down to F = {v['preserved_down_to']:.3g} and stops below it: {why}.")
    if v["recovers_below"]:
        text += f" It passes again in lower bands (F = {', '.join(f'{f:.3g}' for f in v['recovers_below'])})."
    return text


def _band_down_to(v) -> str:
    if v["status"] == "undetermined":
        return "undetermined"
    if v["status"] == "never-preserved":
        return "none"
    return f"{v['preserved_down_to']:.3g}" + (" (lowest tested)" if v["status"] == "all-preserved" else "")


def _seconds_per_frame(ev: Evaluation, name: str) -> float | None:
    n = len(ev.dataset.frames)
    return ev.seconds.get(name, 0.0) / n if n else None


def _band_lines(ev: Evaluation) -> list[str]:
    crit = ev.settings.criterion
    names = [d.name for d in ev.denoisers]
    first = names[0]
    bands = [r for r in ev.band_rows if r["denoiser"] == first]
    lines = ["## Detail and colour per light level (every frame, no chart needed)", "",
             "Frames are grouped in half-decade bands of the intensity factor F (10^(k/2) ≤ F < 10^((k+1)/2)). In a "
             "band, a denoiser:", "",
             f"* **preserves detail** when the mean SSIM of its output against the clean layer is **≥ "
             f"{crit.min_ssim:g}**;",
             f"* **preserves colour** when the mean ΔE00 (CIEDE2000, per pixel, against the clean layer; see *How it "
             f"was measured*) is **≤ {crit.max_delta_e00:g}**.", "",
             *(["For Bayer frames the SSIM and ΔE00 are those after the ISP: the developed denoised (or noisy) "
                "frame against the developed clean one (see *Bayer frames* below)"
                + ("; this dataset mixes them with three-chip frames, scored in camera DN, in the same bands and "
                   "means — score the two kinds in separate runs for comparable numbers." if
                   len(_bayer_rows(ev)) != len(ev.frame_rows) else "."), ""] if _bayer_rows(ev) else []),
             "It preserves an aspect *down to* the lowest F tested in the last band, from the brightest down, in "
             "which the criterion holds in that band and every brighter one; below it, it stops. The noisy frames "
             "(no denoising) are judged by the same rule: a denoiser is worth running where it passes and they "
             "fail.", ""]
    for name in [*names, NOISY]:
        lines.append(f"* {band_verdict_sentence(ev, name, 'detail')} {band_verdict_sentence(ev, name, 'colour')}")
    lines += ["", "| denoiser | detail down to F | colour down to F | s/frame | "
              + " | ".join(f"F {r['band']}" for r in bands) + " |", "|---|---|---|---|" + "---|" * len(bands)]
    for name in [*names, NOISY]:
        v = ev.band_verdicts[name]
        suffix = "_noisy" if name == NOISY else ""
        source = first if name == NOISY else name
        marks = []
        for b in bands:
            r = next(x for x in ev.band_rows if x["denoiser"] == source and x["band"] == b["band"])
            marks.append(f"{_mark(r['detail_preserved' + suffix])} {_mark(r['colour_preserved_e00' + suffix])}")
        spf = None if name == NOISY else _seconds_per_frame(ev, name)
        lines.append(f"| {NOISY_LABEL if name == NOISY else name} | {_band_down_to(v['detail'])} | "
                     f"{_band_down_to(v['colour'])} | {_fmt(spf, '.3g')} | " + " | ".join(marks) + " |")
    lines += ["", "Each band's cell: detail, then colour — ✓ preserved, ✗ not, — undetermined. s/frame: the "
              "denoiser's mean run time per frame on this machine (this run).", "",
              "Mean SSIM / mean ΔE00 against the clean layer per band (noisy first):", "",
              "| F band (frames) | " + " | ".join([NOISY_LABEL, *names]) + " |", "|---|" + "---|" * (len(names) + 1)]
    for b in bands:
        cells = [f"{_fmt(b['ssim_noisy'], '.3f')} / {_fmt(b['delta_e00_noisy'], '.3g')}"]
        for name in names:
            r = next(x for x in ev.band_rows if x["denoiser"] == name and x["band"] == b["band"])
            cells.append(f"{_fmt(r['ssim_denoised'], '.3f')} / {_fmt(r['delta_e00_denoised'], '.3g')}")
        lines.append(f"| {b['band']} ({b['n_frames']}) | " + " | ".join(cells) + " |")
    lines.append("")
    if "crops" in ev.plot_files:
        lines += [f"Crops per band: [{ev.plot_files['crops']}]({ev.plot_files['crops']}).", "",
                  f"![noisy, denoised and clean crops per band of F]({ev.plot_files['crops']})", ""]
    return lines


def _bayer_rows(ev: Evaluation) -> list[dict]:
    return [r for r in ev.frame_rows if r.get("frame_kind", "three-chip") != "three-chip"]


def _mean(rows, key):
    values = [r[key] for r in rows if r.get(key) is not None]
    return float(np.mean(values)) if values else None


def bayer_input_text(bayer_input: str) -> str:
    """What a user's denoiser gets for a Bayer frame (for the report)."""
    if bayer_input == "mosaic":
        return ("the (H, W) float32 mosaic in the frame's own pattern, black subtracted and divided by white − black "
                "(0 = black, 1 = the white level; not clipped: noise goes below 0)")
    return ("the (H/2, W/2, 4) float32 planes R, G1, G2, B (G1 the green on R's row; channels last), black "
            "subtracted and divided by white − black (0 = black, 1 = the white level; not clipped: noise goes below "
            "0)")


def _gain_fallbacks(ev: Evaluation) -> list[str]:
    """The Bayer frames developed with gain auto because their sidecar gives no perfect white (gain white asked)."""
    if ev.settings.isp_gain != "white":
        return []
    return sorted({r["file"] for r in _bayer_rows(ev) if r.get("isp_gain") == "auto"})


def _gain_note(ev: Evaluation) -> str:
    gain = ev.settings.isp_gain
    note = ""
    if gain == "white":
        note = f" (the default: {GAIN_WHY}; `--isp-gain auto` gives 1 / F)"
    fallbacks = _gain_fallbacks(ev)
    if fallbacks:
        note += (f"; {len(fallbacks)} frame(s) whose sidecar gives no perfect white (`white_signal_e`) with gain auto "
                 f"instead: {', '.join(fallbacks[:5])}{' …' if len(fallbacks) > 5 else ''}")
    return note


def _bayer_lines(ev: Evaluation) -> list[str]:
    rows = _bayer_rows(ev)
    if not rows:
        return []
    names = [d.name for d in ev.denoisers]
    first = names[0]
    n = len({r["file"] for r in rows})
    patterns = sorted({r["frame_kind"].split()[-1] for r in rows})
    lines = ["## Bayer frames: raw and after the ISP", "",
             f"{n} Bayer frame{'s' if n != 1 else ''} (CFA {', '.join(patterns)}). Each denoiser got "
             f"{bayer_input_text('packed')}"
             + ("" if ev.settings.bayer_input == "packed" else
                f" — the built-ins; a user's denoiser got {bayer_input_text('mosaic')}")
             + ", and the noise σ per plane in that unit. Scores:", "",
             "* **raw**: PSNR and SSIM (scikit-image) on the normalised packed planes R, G1, G2, B against the clean "
             "mosaic normalised alike, `data_range` = 1 (the white level); overall PSNR from the mean squared error "
             "over all four planes, overall SSIM the mean of the four. At low light the signal spans a small part of "
             "the white level, so raw PSNR is high and raw SSIM near 1 for every result: compare denoisers within a "
             "light level, or after the ISP;",
             f"* **after the ISP**: the noisy, denoised and clean mosaics each developed by "
             f"{isp_text(ev.settings.isp_gain)}{_gain_note(ev)}; PSNR and "
             "SSIM (`data_range` = 1) and the mean CIEDE2000 of every pixel (sRGB → CIELAB, D65) against the "
             "developed clean frame. These are the `psnr_*`, `ssim_*` and `delta_e00_*` of these frames in "
             "`frames.csv` (column `scored_as`) and in the bands above.", "",
             "Means over the Bayer frames in each half-decade band of F (`a → b`: noisy → denoised; per frame in "
             "`frames.csv`):", "",
             "| denoiser | F band (frames) | raw PSNR (dB) | raw SSIM | sRGB PSNR (dB) | sRGB SSIM | sRGB ΔE00 |",
             "|---|---|---|---|---|---|---|"]
    bands = sorted({f_band(r["intensity_factor"]) for r in rows}, reverse=True)

    def in_band(name, band):
        return [r for r in rows if r["denoiser"] == name and f_band(r["intensity_factor"]) == band]

    for name in names:
        for band in bands:
            fr = in_band(name, band)
            if not fr:
                continue
            lines.append(
                f"| {name} | {band_label(band)} ({len(fr)}) | {_fmt(_mean(fr, 'raw_psnr_noisy_db'), '.2f')} → "
                f"{_fmt(_mean(fr, 'raw_psnr_denoised_db'), '.2f')} | {_fmt(_mean(fr, 'raw_ssim_noisy'), '.3f')} → "
                f"{_fmt(_mean(fr, 'raw_ssim_denoised'), '.3f')} | {_fmt(_mean(fr, 'srgb_psnr_noisy_db'), '.2f')} → "
                f"{_fmt(_mean(fr, 'srgb_psnr_denoised_db'), '.2f')} | {_fmt(_mean(fr, 'srgb_ssim_noisy'), '.3f')} → "
                f"{_fmt(_mean(fr, 'srgb_ssim_denoised'), '.3f')} | "
                f"{_fmt(_mean(fr, 'srgb_delta_e00_noisy'), '.3g')} → "
                f"{_fmt(_mean(fr, 'srgb_delta_e00_denoised'), '.3g')} |")
    lines += ["", "Raw PSNR per plane R / G1 / G2 / B (dB, mean over the Bayer frames in each band of F; noisy first):",
              "",
              "| F band | " + " | ".join(f"{NOISY_LABEL if k == 0 else names[k - 1]}"
                                   for k in range(len(names) + 1)) + " |",
              "|---|" + "---|" * (len(names) + 1)]
    for band in bands:
        cells = []
        for k, name in enumerate([first, *names]):
            label = "noisy" if k == 0 else "denoised"
            fr = in_band(name, band)
            cells.append(" / ".join(_fmt(_mean(fr, f"raw_psnr_{p}_{label}_db"), ".1f") for p in BAYER_PLANES))
        lines.append(f"| {band_label(band)} | " + " | ".join(cells) + " |")
    lines += ["", "Per frame and plane (PSNR and SSIM), the noise σ per plane (the blind estimate, the sensor "
              "model's and the true one, in the normalised unit): the `raw_*` and `srgb_*` columns of `frames.csv`.",
              ""]
    return lines


def report_text(ev: Evaluation) -> str:
    crit = ev.settings.criterion
    names = [d.name for d in ev.denoisers]
    frames = ev.dataset.frames
    factors = sorted({float(f.meta["intensity_factor"]) for f in frames}, reverse=True)
    illuminants = sorted({str(f.meta.get("illuminant")) for f in frames})
    scenes = sorted({str(f.meta.get("scene")) for f in frames})
    n_frames = len(frames)
    shown = factors if len(factors) <= 8 else [factors[0], factors[-1]]
    f_text = (", ".join(_f(f) for f in shown) if len(factors) <= 8
              else f"{len(factors)} levels from {factors[0]:.3g} down to {factors[-1]:.3g}")
    lines = [f"# Denoiser evaluation: {', '.join(names)}", ""]
    lines += [f"Dataset: {', '.join(f'`{r}`' for r in ev.dataset.roots)} — {n_frames} frame"
              f"{'s' if n_frames != 1 else ''} scored (scene {', '.join(scenes)}; illuminant"
              f"{'s' if len(illuminants) != 1 else ''} {', '.join(illuminants)}; F = {f_text})"
              + (f"; {len(ev.dataset.skipped)} file(s) skipped (see the end)." if ev.dataset.skipped else "."), ""]

    lines += _band_lines(ev)
    lines += _bayer_lines(ev)

    chart = _chart_judged(ev)
    lines += ["## Chart colour (ColorChecker patches, against F = 1)", ""]
    if not ev.patch_rows and _bayer_rows(ev) and len(_bayer_rows(ev)) == len(ev.frame_rows):
        lines += ["The chart metrics (patch bias, noise ellipses, 5-step ΔE_ab) are computed for three-chip frames "
                  "only, and every frame here is a Bayer mosaic: colour is judged by the ΔE00 after the ISP above.",
                  ""]
    elif not ev.patch_rows:
        lines += ["No chart in view: the chart metrics (patch bias, noise ellipses, 5-step ΔE_ab) do not apply; "
                  "colour is judged by the chart-free ΔE00 above.", ""]
    elif not chart:
        lines += ["A chart is in view but no F = 1 frame of the same measurement gives the 5-step ΔE_ab reference, so "
                  "the chart verdict is not formed; the patch bias and noise ellipses are in the tables below and in "
                  "`patches.csv`, and colour is judged by the chart-free ΔE00 above.", ""]
    if chart:
        lines += ["Colour is **preserved** on the chart at a light level (intensity factor F) when, over every patch "
                  "of every frame at that F, after denoising:", "",
                  f"* the mean ΔE_ab (the paper's 5-step procedure: each pixel scaled to Y = 100, CIELAB against D65, "
                  f"ΔE to the same patch at F = 1) is **≤ {crit.max_delta_e:g}**, and",
                  f"* the mean chromaticity bias |xy(mean of the denoised patch) − xy(mean of the clean patch)| is "
                  f"**≤ {crit.max_bias_xy:g}**, and",
                  "* no patch's denoised colour is undefined (a patch mean with X + Y + Z ≤ 0, or no pixel with "
                  "Y > 0).", "",
                  "ΔE is averaged over the pixels of a patch, so it judges each pixel's colour, noise included; the "
                  "bias judges the patch mean alone (a denoiser that averages noise away but shifts colours fails on "
                  "it).", "",
                  "A denoiser preserves colour *down to* the lowest F at which the criterion holds there and at every "
                  "higher tested F; it *stops* at the next lower tested F. The noisy frames themselves (no denoising; "
                  "`identity` gives exactly the same) are judged by the same rule.", ""]

    if chart:
        lines += ["### Where colour stops being preserved on the chart", ""]
        lines += [f"* {verdict_sentence(ev, name)}" for name in [*names, NOISY]]
        lines += ["", "| denoiser | colour preserved down to F | stops at F | " + " | ".join(
            f"F = {_f(f)}" for f in factors) + " |", "|---|---|---|" + "---|" * len(factors)]
        for name in [*names, NOISY]:
            v = ev.verdicts[name]
            label = NOISY_LABEL if name == NOISY else name
            marks = " | ".join(_mark(v["by_factor"].get(f, "")) for f in factors)
            lines.append(f"| {label} | {_down_to(v)} | {_stops(v)} | {marks} |")
        lines += ["", "✓ preserved, ✗ not, — undetermined.", ""]

    if chart and len(names) > 1:
        lines += ["### Comparison per light level", "",
                  "Mean ΔE_ab / mean chromaticity bias / PSNR gain (dB) of each denoiser; the noisy baseline first.",
                  "", "| F | " + " | ".join([NOISY_LABEL, *names]) + " |", "|---|" + "---|" * (len(names) + 1)]
        for f in factors:
            cells = []
            base = _row(ev, names[0], f)
            cells.append(f"{_fmt(base['delta_e_noisy'], '.3g')} / {_fmt(base['bias_noisy_xy'], '.2g')} "
                         f"{_mark(base['colour_preserved_noisy'])}")
            for name in names:
                r = _row(ev, name, f)
                cells.append(f"{_fmt(r['delta_e_denoised'], '.3g')} / {_fmt(r['bias_denoised_xy'], '.2g')} / "
                             f"{_fmt(r['psnr_gain_db'], '+.1f')} {_mark(r['colour_preserved'])}")
            lines.append(f"| {_f(f)} | " + " | ".join(cells) + " |")
        lines.append("")

    lines += ["## Per denoiser and light level", "",
              "Means over frames (PSNR, SSIM) and over patches (the rest); `a → b` is noisy → denoised. The ellipse "
              "ratio is the mean over patches of size(denoised) / size(noisy); ΔE floor is the clean layer's own ΔE "
              "(what a perfect denoiser reaches).", ""]
    for d in ev.denoisers:
        lines += [f"### {d.name}", "", f"{d.description}.", "",
                  "| F | PSNR (dB) | SSIM | bias xy | ellipse size ratio | ΔE mean (median) | ΔE floor | preserved |",
                  "|---|---|---|---|---|---|---|---|"]
        for f in factors:
            r = _row(ev, d.name, f)
            if r is None:
                continue
            lines.append(
                f"| {_f(f)} | {_fmt(r['psnr_noisy_db'], '.2f')} → {_fmt(r['psnr_denoised_db'], '.2f')} | "
                f"{_fmt(r['ssim_noisy'], '.3f')} → {_fmt(r['ssim_denoised'], '.3f')} | "
                f"{_fmt(r['bias_noisy_xy'], '.2g')} → {_fmt(r['bias_denoised_xy'], '.2g')} | "
                f"{_fmt(r['ellipse_size_ratio'], '.3g')} | "
                f"{_fmt(r['delta_e_noisy'], '.3g')} ({_fmt(r['delta_e_noisy_median'], '.3g')}) → "
                f"{_fmt(r['delta_e_denoised'], '.3g')} ({_fmt(r['delta_e_denoised_median'], '.3g')}) | "
                f"{_fmt(r['delta_e_clean'], '.2g')} | {_mark(r['colour_preserved'])} |")
        lines.append("")

    lines += ["## Figures", ""]
    captions = {"psnr_ssim": "PSNR and SSIM against F", "bias": "chromaticity bias against F",
                "delta_e": "ΔE against F", "ellipse": "ellipse size before and after, and their ratio",
                "delta_e00": "chart-free ΔE00 against the clean layer, per frame",
                "examples": "clean, noisy and denoised crops",
                "crops": "noisy, denoised and clean crops per band of F"}
    for key, file in ev.plot_files.items():
        lines.append(f"![{captions[key]}]({file})")
    lines.append("")

    s = ev.settings
    lines += ["## How it was measured", "",
              f"* **Noise level given to the denoisers**: estimated blindly from each noisy frame — "
              f"{SIGMA_ESTIMATOR}. The sidecar's noise model (signal variance, dark and read noise) is not used: "
              "a real denoiser does not know it"
              + ("" if not any(d.sigma_source == SIGMA_MODEL for d in ev.denoisers) else
                 f" — except {', '.join(d.name for d in ev.denoisers if d.sigma_source == SIGMA_MODEL)}, which has "
                 f"no blind mode and is given {MODEL_SIGMA_TEXT}")
              + ". `frames.csv` lists the blind estimate, the model's σ and the true σ (std of noisy − clean, for "
              "comparison only).",
              "* **Chart-free colour (ΔE00)**: per frame, the mean over its pixels of CIEDE2000 "
              "(`colour.delta_E(..., method=\"CIE 2000\")`) between the test frame (noisy or denoised) and the clean "
              "layer, both black-level subtracted (always, `--keep-black` or not) and taken through the same camera "
              "→ XYZ matrix M as the chart, then to CIELAB against one white: the perfect white (reflectance 1) "
              "under the frame's light at the frame's F and exposure (the sidecar's `white_signal_e` through M; L* "
              "= 100 there), the white a viewer of the frame exposed for its light would see. Noise is thus judged "
              "relative to the scene's white at that light level, lightness included"
              + (" (older sidecars without `white_signal_e`: " + WHITE_CLEAN_MAX + ")"
                 if any(r.get("white_source") == WHITE_CLEAN_MAX for r in ev.frame_rows) else "") + ".",
              "* **Run time**: " + "; ".join(f"{d.name} {_fmt(_seconds_per_frame(ev, d.name), '.3g')} s/frame"
                                             for d in ev.denoisers) + " (mean per frame, this run, this machine).",
              "* **PSNR and SSIM** (scikit-image): against the clean layer, with `data_range` = the clean layer's "
              "range in the frame (max − min over pixels and channels, DN; the white level only if that range is "
              "0). At low light the signal spans a few DN of the 8-bit white level, and a white-level range would "
              "make SSIM's stabilising constants swamp the image and rate every frame ≈ 1. The PSNR *gain* does not "
              "depend on the range.",
              f"* **Patches**: the sidecar's `rect_xywh` less {s.border_px} px on each side. Black level: "
              + ("the sidecar's black level subtracted before every colour quantity, so that they measure the "
                 "denoiser and not the dark current's drag toward the camera black point (the paper subtracts "
                 "nothing; `--keep-black` does the same)." if s.subtract_black else
                 "not subtracted (as the paper): the colour quantities include the dark current's drag toward the "
                 "camera black point, which no denoiser removes — see the ΔE floor."),
              "* **Colour**: camera DN → XYZ by the paper's M = (T Tᵗ)(C Tᵗ)⁻¹ (Eq. 15) from the sidecar's Qe; xy "
              "per pixel and of the patch mean; the bias is against the clean patch mean of the same frame; the "
              "ellipse is the PCA 1 σ ellipse of the pixels' xy (size √(a² + b²)). The noisy frame's bias is the "
              "sampling error of a patch mean (σ/√n, large for dark patches at low light); a denoiser that keeps "
              "local means cannot remove it, so a denoised bias close to the noisy one means the denoiser adds no "
              "shift of its own, and the bias limit then marks where the light itself no longer suffices.",
              "* **ΔE reference**: the mean Lab (5-step) of the same patch in the *clean* layer of the F = 1 frame "
              "of the same measurement (same scene, illuminant, camera, sensor settings and size — "
              "`camsim.analysis.grouping.group_key`), so that it is noise-free and the same for every denoiser.",
              *([f"* **Bayer frames**: a user's denoiser got {bayer_input_text(s.bayer_input)} "
                 f"(`--bayer-input {s.bayer_input}`), the built-ins the packed planes; developed for the scores after "
                 f"the ISP by {isp_text(s.isp_gain)}{_gain_note(ev)}. The PSNR/SSIM bullet below is for three-chip "
                 "frames; a Bayer frame's "
                 "frame-level PSNR, SSIM and ΔE00 are those after the ISP (data range 1)."] if _bayer_rows(ev) else []),
              "* **Denoisers**: " + "; ".join(f"`{d.target}` — {d.description}" for d in ev.denoisers) + ".",
              ]
    if any(d.target == "wavelet" for d in ev.denoisers):
        lines.append(f"* **wavelet implementation**: {WAVELET_IMPLEMENTATION}.")
    lines.append("")

    lines += ["## Undefined values", "",
              "Counted, never averaged in (no not-a-number anywhere): these cells are empty in the CSV files.", "",
              "| count | " + " | ".join(names) + " |", "|---|" + "---|" * len(names)]
    keys = list(next(iter(ev.counts.values())).keys()) if ev.counts else []
    for key in keys:
        lines.append(f"| {key} | " + " | ".join(str(ev.counts[n][key]) for n in names) + " |")
    lines.append("")
    if ev.dataset.skipped:
        lines += ["## Skipped files", "", "These files were not scored, each for the reason given:", ""]
        lines += [f"* `{s['file']}` — {s['reason']}" for s in ev.dataset.skipped]
        lines.append("")
    lines += ["Files: `frames.csv` (per frame), `patches.csv` (per frame × patch), `summary.csv` (per denoiser × F), "
              "`summary.json` (settings, verdicts, counts).", ""]
    return "\n".join(lines)


def summary_json(ev: Evaluation) -> dict:
    s = ev.settings
    return {
        "dataset": ev.dataset.roots,
        "frames_scored": len(ev.dataset.frames),
        "skipped": ev.dataset.skipped,
        "frames_scored_bayer": len({r["file"] for r in _bayer_rows(ev)}),
        "bayer": {"denoiser_input": bayer_input_text(s.bayer_input), "builtin_input": bayer_input_text("packed"),
                  "bayer_input": s.bayer_input, "planes": list(BAYER_PLANES), "isp": isp_text(s.isp_gain),
                  "isp_gain": s.isp_gain, "isp_gain_auto_fallback": _gain_fallbacks(ev),
                  "raw_data_range": 1.0, "srgb_data_range": 1.0},
        "settings": {"border_px": s.border_px, "black_subtraction": "sidecar" if s.subtract_black else "none",
                     "camera_to_xyz": s.matrix, "data_range": "clean layer range per frame",
                     "sigma_estimator": SIGMA_ESTIMATOR, "sigma_model": MODEL_SIGMA_TEXT,
                     "delta_e00": "mean CIEDE2000 per pixel against the clean layer, CIELAB against the perfect "
                                  "white at the frame's F (sidecar white_signal_e) through the camera → XYZ matrix",
                     "delta_e_reference": "clean layer of the F = 1 frame of the same measurement"},
        "criterion": {"max_delta_e": s.criterion.max_delta_e, "max_bias_xy": s.criterion.max_bias_xy,
                      "text": s.criterion.text()},
        "denoisers": [{"name": d.name, "target": d.target, "kind": d.kind, "description": d.description,
                       "verdict": _json_verdict(ev.verdicts[d.name])} for d in ev.denoisers],
        "noisy_baseline_verdict": _json_verdict(ev.verdicts[NOISY]),
        "band_criterion": {"min_ssim": s.criterion.min_ssim, "max_delta_e00": s.criterion.max_delta_e00,
                           "text": s.criterion.band_text()},
        "band_verdicts": {name: {aspect: _json_verdict(v) for aspect, v in vs.items()}
                          for name, vs in ev.band_verdicts.items()},
        "seconds_per_frame": {d.name: _seconds_per_frame(ev, d.name) for d in ev.denoisers},
        "bands": ev.band_rows,
        "summary": ev.summary_rows,
        "undefined": ev.counts,
    }


def _json_verdict(v: dict) -> dict:
    return {**v, "by_factor": [{"intensity_factor": f, "colour_preserved": p} for f, p in v["by_factor"].items()]}


def write_outputs(ev: Evaluation, out_dir: Path) -> dict:
    """Write every output into ``out_dir`` (created); returns {kind: path}."""
    out_dir = Path(out_dir)
    make_folder(out_dir)
    paths = {"frames": out_dir / "frames.csv", "patches": out_dir / "patches.csv",
             "summary": out_dir / "summary.csv", "report": out_dir / "report.md", "json": out_dir / "summary.json"}
    write_text_atomic(paths["frames"], csv_text(ev.frame_rows, FRAME_COLUMNS))
    write_text_atomic(paths["patches"], csv_text(ev.patch_rows, PATCH_COLUMNS))
    write_text_atomic(paths["summary"], csv_text(ev.summary_rows, SUMMARY_COLUMNS))
    paths["bands"] = out_dir / "bands.csv"
    write_text_atomic(paths["bands"], csv_text(ev.band_rows, BAND_COLUMNS))
    ev.plot_files = _plots(ev, out_dir)
    paths.update({k: out_dir / v for k, v in ev.plot_files.items()})
    write_text_atomic(paths["report"], report_text(ev))
    write_json_atomic(paths["json"], summary_json(ev))
    return paths
