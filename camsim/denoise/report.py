"""The outputs of ``camsim denoise-eval``: CSV tables, plots, ``report.md`` and ``summary.json``, each atomic.

* ``frames.csv`` — one row per denoiser × frame: PSNR / SSIM of the noisy and the denoised frame against the clean
  layer, the data range used, the estimated and the true noise σ per channel.
* ``patches.csv`` — one row per denoiser × frame × patch: xy of the patch mean (clean, noisy, denoised), the
  chromaticity bias, the ellipse centre and size before and after, their ratio, ΔE (clean, noisy, denoised).
* ``summary.csv`` — one row per denoiser × intensity factor: the means, the undefined counts and whether colour is
  preserved by the criterion.
* ``psnr_ssim.png``, ``chromaticity_bias.png``, ``delta_e.png``, ``ellipse_size.png`` (each against F, noisy
  baseline and denoised), ``examples.png`` (crops: clean, noisy, denoised).
* ``report.md`` and ``summary.json`` (settings, criterion, verdicts, undefined counts, skipped frames).

Empty CSV cells are undefined values (counted in ``summary.csv`` and ``summary.json``); no file holds NaN.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from camsim.denoise.denoisers import SIGMA_ESTIMATOR, WAVELET_IMPLEMENTATION
from camsim.denoise.evaluate import Evaluation
from camsim.denoise.summary import NOISY
from camsim.io.atomic import write_json_atomic, write_text_atomic
from camsim.plotting import new_figure, save_png
from camsim.io.output_folder import make_folder

FRAME_COLUMNS = ("denoiser", "file", "scene", "illuminant", "intensity_factor", "width_px", "height_px",
                 "data_range_dn", "data_range_source", "sigma_est_R_dn", "sigma_est_G_dn", "sigma_est_B_dn",
                 "noise_std_R_dn", "noise_std_G_dn", "noise_std_B_dn", "psnr_noisy_db", "psnr_denoised_db",
                 "psnr_gain_db", "ssim_noisy", "ssim_denoised", "ssim_gain")
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
         "ellipse": "ellipse_size.png", "examples": "examples.png"}
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
    ax.legend(fontsize=8)


def _plots(ev: Evaluation, out: Path) -> dict:
    crit = ev.settings.criterion
    fig = new_figure(figsize=(11, 4.2), layout="constrained")
    axes = fig.subplots(1, 2)
    _against_f(axes[0], ev, "psnr_noisy_db", "psnr_denoised_db", "PSNR against the clean layer (dB)")
    _against_f(axes[1], ev, "ssim_noisy", "ssim_denoised", "SSIM against the clean layer")
    fig.suptitle("PSNR and SSIM (mean over frames) — data range: each frame's clean range")
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

    if ev.examples:
        _example_plot(ev, out / PLOTS["examples"])
    return {k: v for k, v in PLOTS.items() if (out / v).exists() and (k != "examples" or ev.examples)}


def _display(img, black, scale):
    v = np.clip((img.astype(np.float64) - black) / scale, 0.0, 1.0)
    return v ** (1 / 2.2)


def _example_plot(ev: Evaluation, path: Path) -> None:
    factors = sorted(ev.examples, reverse=True)
    columns = ["clean", "noisy", *[d.name for d in ev.denoisers]]
    fig = new_figure(figsize=(2.3 * len(columns), 1.9 * len(factors) + 0.5), layout="constrained")
    axes = fig.subplots(len(factors), len(columns), squeeze=False)
    for i, factor in enumerate(factors):
        crops = ev.examples[factor]
        black = crops["black"]
        scale = float(np.max(crops["clean"] - black)) or 1.0
        for j, col in enumerate(columns):
            ax = axes[i, j]
            ax.imshow(_display(crops[col], black, scale), interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            if i == 0:
                ax.set_title(col, fontsize=9)
            if j == 0:
                ax.set_ylabel(f"F = {_f(factor)}", fontsize=9)
    fig.suptitle("Clean, noisy and denoised (black subtracted, each row scaled to its clean maximum, γ 1/2.2)",
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
    return {"yes": "✓", "no": "✗"}.get(value, "?")


def report_text(ev: Evaluation) -> str:
    crit = ev.settings.criterion
    names = [d.name for d in ev.denoisers]
    frames = ev.dataset.frames
    factors = sorted({float(f.meta["intensity_factor"]) for f in frames}, reverse=True)
    illuminants = sorted({str(f.meta.get("illuminant")) for f in frames})
    scenes = sorted({str(f.meta.get("scene")) for f in frames})
    n_frames = len(frames)
    lines = [f"# Denoiser evaluation: {', '.join(names)}", ""]
    lines += [f"Dataset: {', '.join(f'`{r}`' for r in ev.dataset.roots)} — {n_frames} frame"
              f"{'s' if n_frames != 1 else ''} scored (scene {', '.join(scenes)}; illuminant"
              f"{'s' if len(illuminants) != 1 else ''} {', '.join(illuminants)}; F = "
              f"{', '.join(_f(f) for f in factors)})"
              + (f"; {len(ev.dataset.skipped)} file(s) skipped (see the end)." if ev.dataset.skipped else "."), ""]

    lines += ["## Criterion", "",
              "Colour is **preserved** at a light level (intensity factor F) when, over every patch of every frame at "
              "that F, after denoising:", "",
              f"* the mean ΔE_ab (the paper's 5-step procedure: each pixel scaled to Y = 100, CIELAB against D65, "
              f"ΔE to the same patch at F = 1) is **≤ {crit.max_delta_e:g}**, and",
              f"* the mean chromaticity bias |xy(mean of the denoised patch) − xy(mean of the clean patch)| is "
              f"**≤ {crit.max_bias_xy:g}**, and",
              "* no patch's denoised colour is undefined (a patch mean with X + Y + Z ≤ 0, or no pixel with Y > 0).",
              "",
              "ΔE is averaged over the pixels of a patch, so it judges each pixel's colour, noise included; the bias "
              "judges the patch mean alone (a denoiser that averages noise away but shifts colours fails on it).",
              "",
              "A denoiser preserves colour *down to* the lowest F at which the criterion holds there and at every "
              "higher tested F; it *stops* at the next lower tested F. The noisy frames themselves (no denoising; "
              "`identity` gives exactly the same) are judged by the same rule.", ""]

    lines += ["## Where colour stops being preserved", ""]
    lines += [f"* {verdict_sentence(ev, name)}" for name in [*names, NOISY]]
    lines += ["", "| denoiser | colour preserved down to F | stops at F | " + " | ".join(
        f"F = {_f(f)}" for f in factors) + " |", "|---|---|---|" + "---|" * len(factors)]
    for name in [*names, NOISY]:
        v = ev.verdicts[name]
        label = NOISY_LABEL if name == NOISY else name
        marks = " | ".join(_mark(v["by_factor"].get(f, "")) for f in factors)
        lines.append(f"| {label} | {_down_to(v)} | {_stops(v)} | {marks} |")
    lines += ["", "✓ preserved, ✗ not, ? undetermined.", ""]

    if len(names) > 1:
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
                "examples": "clean, noisy and denoised crops"}
    for key, file in ev.plot_files.items():
        lines.append(f"![{captions[key]}]({file})")
    lines.append("")

    s = ev.settings
    lines += ["## How it was measured", "",
              f"* **Noise level given to the denoisers**: estimated blindly from each noisy frame — "
              f"{SIGMA_ESTIMATOR}. The sidecar's noise model (signal variance, dark and read noise) is not used: "
              "a real denoiser does not know it. `frames.csv` also lists the true σ (std of noisy − clean) for "
              "comparison only.",
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
              "`camsim.analysis.analyze.group_key`), so that it is noise-free and the same for every denoiser.",
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
        lines += ["## Skipped files", "",
                  "Bayer (CFA) frames are not supported: a denoiser here takes R, G and B at every pixel, and a "
                  "mosaic would have to be demosaiced first, which would mix the demosaicing's errors into the "
                  "score. They are listed here and left out.", ""]
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
        "settings": {"border_px": s.border_px, "black_subtraction": "sidecar" if s.subtract_black else "none",
                     "camera_to_xyz": s.matrix, "data_range": "clean layer range per frame",
                     "sigma_estimator": SIGMA_ESTIMATOR,
                     "delta_e_reference": "clean layer of the F = 1 frame of the same measurement"},
        "criterion": {"max_delta_e": s.criterion.max_delta_e, "max_bias_xy": s.criterion.max_bias_xy,
                      "text": s.criterion.text()},
        "denoisers": [{"name": d.name, "target": d.target, "kind": d.kind, "description": d.description,
                       "verdict": _json_verdict(ev.verdicts[d.name])} for d in ev.denoisers],
        "noisy_baseline_verdict": _json_verdict(ev.verdicts[NOISY]),
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
    ev.plot_files = _plots(ev, out_dir)
    paths.update({k: out_dir / v for k, v in ev.plot_files.items()})
    write_text_atomic(paths["report"], report_text(ev))
    write_json_atomic(paths["json"], summary_json(ev))
    return paths
