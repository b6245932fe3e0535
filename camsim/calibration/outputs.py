"""The outputs of ``camsim calibrate``: ``preset.toml``, ``calibration.json``, ``report.md`` and three plots.

``preset.toml`` is an interface (read by ``camsim.sensor.presets`` for ``--preset PATH.toml``); its keys are:

* ``[preset]``: ``name``, ``source``, ``bits``, ``pedestal_dn``, ``cfa`` (absent for a 3-colour stack or a
  monochrome sensor), ``read_noise_model`` (``"gaussian"`` or ``"tukey-lambda"``);
* one ``[[iso]]`` table: ``iso``, ``k_dn_per_e``, ``tukey_lambda``, ``tukey_scale_dn`` (the Tukey scale, not the
  standard deviation), ``gaussian_sigma_dn`` (the read noise's standard deviation), ``row_sigma_dn``, ``dsnu_dn``,
  ``prnu_percent``; and the effects of issue 28 (:func:`effect_values`): ``column_fpn_e``,
  ``black_level_error_dn``, and where they apply ``dark_shading_map`` and ``hot_pixel_map``, the files
  ``dark_shading.npy`` (e⁻) and ``hot_pixels.npy`` (e⁻/s) written beside it (paths relative to the preset file).

Every file is written atomically (:mod:`camsim.io.atomic`); the plots need matplotlib, imported when they are drawn
(:mod:`camsim.io.figures`: no pyplot, no backend change).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from camsim.calibration.estimate import Estimate, ratio
from camsim.calibration.measure import GAUSSIAN_LAMBDA_TOLERANCE, Calibration
from camsim.calibration.ptc import FIT_FRACTION
from camsim.calibration.tukey import GAUSSIAN_LAMBDA
from camsim.core.optional_numbers import finite_or_none
from camsim.io.atomic import atomic_path, write_json_atomic, write_text_atomic

FILES = {
    "preset": "preset.toml",
    "dark_shading": "dark_shading.npy",
    "hot_pixels": "hot_pixels.npy",
    "json": "calibration.json",
    "report": "report.md",
    "ptc": "ptc.png",
    "probability": "probability_plot.png",
    "rows": "row_spectrum.png",
}


def _number(value: float, digits: int = 6) -> str:
    """A TOML float: ``digits`` significant digits, always with a decimal point or an exponent."""
    text = f"{float(value):.{digits}g}"
    return text if any(c in text for c in ".e") else text + ".0"


def _string(text: str) -> str:
    """A TOML basic string (JSON's escapes are TOML's)."""
    return json.dumps(str(text), ensure_ascii=False)


#: The dark-shading map is named where its pattern's variance lies more than this many standard errors above 0.
MAP_MIN_Z = 5.0


def _significant(e: Estimate) -> bool:
    """Whether a spread's 95 % interval excludes 0 (a standard deviation from :func:`sqrt_estimate`)."""
    return e.ci95 is not None and e.ci95[0] > 0


def effect_values(cal: Calibration, maps: bool = True) -> dict:
    """The preset's values of the dark fixed pattern and the black-level error, with a comment each.

    With ``maps`` the preset names ``dark_shading.npy`` where the map holds a fixed pattern — its variance, the
    temporal noise removed, more than :data:`MAP_MIN_Z` standard errors above 0, and its RMS above the map's own
    per-pixel noise √(σ²/n), which a render with the map adds to the pattern (more darks lower it) — and
    ``hot_pixels.npy`` where hot pixels were found. The map is the
    whole fixed offset of each pixel (DSNU, columns, rows, shading): where it is named, ``dsnu_dn`` and
    ``column_fpn_e`` are 0, so that nothing is counted twice. Without the map, ``dsnu_dn`` is the pixels' DSNU less
    the column FPN's share, √(DSNU² − σ_c²), and ``column_fpn_e`` the column FPN. ``column_fpn_e`` and
    ``black_level_error_dn`` are 0 where their 95 % interval holds 0 (an estimate of a spread is biased upwards
    there).

    Returns
    -------
    dict
        ``{key: (value, comment)}``, keys ``dsnu_dn``, ``column_fpn_e``, ``black_level_error_dn`` and, where they
        apply, ``dark_shading_map``, ``hot_pixel_map`` (file names, relative to the preset).
    """
    fx = cal.effects
    out = {}
    column = ratio(fx.column_fpn_dn, cal.k_dn_per_e)
    rms = fx.shading_rms_e
    z = rms.value / (2 * rms.standard_error) if rms.standard_error else 0.0  # of the variance: v / (2 √v SE(√v))
    shading = maps and z > MAP_MIN_Z and rms.value > fx.shading_se_e
    if shading:
        out["dark_shading_map"] = (FILES["dark_shading"], f"fixed dark pattern of RMS {fx.shading_rms_e.value:.4g} e⁻ "
                                   f"(± {fx.shading_se_e:.2g} e⁻ per pixel, from {len(cal.dark_files)} darks)")
    if maps and fx.hot_e_per_s is not None and fx.hot_count:
        out["hot_pixel_map"] = (FILES["hot_pixels"], f"{fx.hot_count} hot pixels ({100 * fx.hot_fraction.value:.3g} %)")
    if shading:
        out["dsnu_dn"] = (0.0, f"in dark_shading_map (measured {cal.dsnu_dn.value:.4g} DN)")
        out["column_fpn_e"] = (0.0, f"in dark_shading_map (measured {column.value:.4g} e⁻)")
    else:
        dsnu = math.sqrt(max(cal.dsnu_dn.value**2 - (fx.column_fpn_dn.value**2 if _significant(column) else 0), 0))
        out["dsnu_dn"] = (dsnu, "the pixels' DSNU, column FPN apart")
        out["column_fpn_e"] = (column.value if _significant(column) else 0.0,
                               f"σ of the column offsets (measured {column.value:.3g} ± {column.standard_error:.2g})")
    b = fx.black_level_error_dn
    out["black_level_error_dn"] = (b.value if _significant(b) else 0.0,
                                   f"σ of the per-frame colour offset (measured {b.value:.3g} ± "
                                   f"{b.standard_error:.2g})")
    return out


def preset_toml(cal: Calibration, maps: bool = True) -> str:
    """The text of ``preset.toml`` (``maps``: :func:`effect_values`)."""
    lines = [
        "# A camera preset measured by camsim calibrate (see calibration.json and report.md beside it).",
        "[preset]",
        f"name = {_string(cal.name)}",
        f"source = {_string(cal.source)}",
        f"bits = {cal.layout.bits}",
        f"pedestal_dn = {cal.pedestal_dn}                    # the black level, rounded (the ADC adds P + ½)",
    ]
    if cal.layout.cfa:
        lines.append(f"cfa = {_string(cal.layout.cfa)}")
    dsnu = [f"dsnu_dn = {_number(cal.dsnu_dn.value)}"]
    effects = []
    if cal.effects is not None:
        values = effect_values(cal, maps)
        dsnu = []
        for key, (value, comment) in values.items():
            text = _string(value) if isinstance(value, str) else _number(value)
            effects.append(f"{key} = {text}   # {comment}")
    lines += [
        f"read_noise_model = {_string(cal.read_noise_model)}   # \"gaussian\" when λ is within "
        f"{GAUSSIAN_LAMBDA_TOLERANCE} of {GAUSSIAN_LAMBDA}",
        "",
        "[[iso]]",
        f"iso = {cal.iso}",
        f"k_dn_per_e = {_number(cal.k_dn_per_e.value)}",
        f"tukey_lambda = {_number(cal.tukey_lambda.value, 4)}",
        f"tukey_scale_dn = {_number(cal.tukey_scale_dn.value)}   # the Tukey scale (not the standard deviation)",
        f"gaussian_sigma_dn = {_number(cal.read_dn.value)}   # the read noise's standard deviation",
        f"row_sigma_dn = {_number(cal.row_dn.value)}",
        *dsnu,
        f"prnu_percent = {_number(cal.prnu_percent.value)}",
        *effects,
        "",
    ]
    return "\n".join(lines)


def _effects_record(cal: Calibration, maps: bool) -> dict:
    """``calibration.json``'s ``dark_effects``: the figures of :mod:`camsim.calibration.fixed_pattern`."""
    from camsim.calibration import fixed_pattern as fp

    fx = cal.effects
    named = effect_values(cal, maps)
    k = cal.k_dn_per_e
    return {
        "dark_shading": {"file": FILES["dark_shading"], "in_preset": "dark_shading_map" in named,
                         "unit": "e-", "shape": list(fx.shading_e.shape),
                         "fixed_pattern_rms_e": fx.shading_rms_e.record(),
                         "per_pixel_standard_error_e": float(f"{fx.shading_se_e:.6g}"),
                         "how": "mean of the darks less each plane's black level (hot pixels: the 5x5 median), / K"},
        "hot_pixels": {"file": FILES["hot_pixels"] if fx.hot_e_per_s is not None else None,
                       "in_preset": "hot_pixel_map" in named, "unit": "e-/s", "count": fx.hot_count,
                       "fraction": fx.hot_fraction.record(), "exposure_s": fx.exposure_s,
                       "threshold_dn": [float(f"{t:.6g}") for t in fx.hot_threshold_dn],
                       "threshold_sigmas": fp.HOT_THRESHOLD_SIGMAS, "window": fp.LOCAL_WINDOW,
                       "how": "mean dark above its 5x5 median by more than m robust sigma (1.4826 MAD, at least the "
                              "mean's temporal noise); extra dark current = excess / K / exposure"},
        "column_fpn_dn": fx.column_fpn_dn.record(),
        "column_fpn_e": ratio(fx.column_fpn_dn, k).record(),
        "black_level_error_dn": fx.black_level_error_dn.record(),
        "preset_values": {key: value for key, (value, _) in named.items()},
    }


def _fit_record(fit) -> dict:
    return {"lambda": round(fit.lam, 5), "ppcc": finite_or_none(round(fit.ppcc, 7)),
            "scale_dn": finite_or_none(f"{fit.scale_dn:.6g}"), "std_dn": finite_or_none(f"{fit.std_dn:.6g}"),
            "samples": fit.samples}


def calibration_record(cal: Calibration, maps: bool = True) -> dict:
    """The content of ``calibration.json``: every estimate with its standard error and 95 % interval, combined and
    per plane, the photon transfer points and the files."""
    planes = {}
    for p, pl in enumerate(cal.planes):
        fit = pl.ptc
        planes[pl.name] = {
            "colour": pl.colour,
            "pixels": pl.pixels,
            "black_level_dn": pl.black_dn.record(),
            "dark_temporal_variance_dn2": pl.dark_variance_dn2.record(),
            "pixel_variance_without_rows_dn2": float(f"{pl.pixel_variance_dn2:.6g}"),
            "read_noise_dn": pl.read_dn.record(),
            "read_noise_e": ratio(pl.read_dn, fit.k_dn_per_e).record(),
            "row_noise_dn": pl.row_dn.record(),
            "dsnu_dn": pl.dsnu_dn.record(),
            "k_dn_per_e": {**fit.k_dn_per_e.record(), "r_squared": round(fit.r_squared, 7),
                           "chi2_per_dof": None if fit.chi2_per_dof is None else float(f"{fit.chi2_per_dof:.4g}"),
                           "intercept_dn2": fit.intercept_dn2.record(),
                           "pairs_used": int(np.count_nonzero(fit.used))},
            "tukey": {"matched_ppcc": _fit_record(pl.tukey), "plain_ppcc": _fit_record(pl.tukey_plain)},
            "prnu_percent": {**pl.prnu_percent.record(), "pair": pl.prnu_pair},
        }
    pairs = []
    for i, pair in enumerate(cal.pairs):
        pairs.append({
            "files": list(pair.files), "level": pair.level,
            "mean_signal_dn": {pl.name: float(f"{pair.mean_dn[p]:.7g}") for p, pl in enumerate(cal.planes)},
            "temporal_variance_dn2": {pl.name: float(f"{pair.variance_dn2[p]:.7g}") for p, pl in enumerate(cal.planes)},
            "used_in_fit": {pl.name: bool(pl.ptc.used[i]) for pl in cal.planes},
            "prnu_percent": {pl.name: pair.prnu_percent[p].record() for p, pl in enumerate(cal.planes)},
        })
    return {
        "name": cal.name,
        "iso": cal.iso,
        "date": cal.date,
        "source": cal.source,
        "sensor": {"layout": cal.layout.kind, "cfa": cal.layout.cfa, "width": cal.layout.shape[1],
                   "height": cal.layout.shape[0], "white_level_dn": cal.layout.white_level_dn,
                   "bits": cal.layout.bits, "planes": list(cal.layout.plane_names)},
        "files": {"dark": list(cal.dark_files), "flat": list(cal.flat_files)},
        "preset": {"pedestal_dn": cal.pedestal_dn, "read_noise_model": cal.read_noise_model},
        "black_level_dn": cal.black_dn.record(),
        "k_dn_per_e": cal.k_dn_per_e.record(),
        "read_noise_dn": cal.read_dn.record(),
        "read_noise_e": cal.read_e.record(),
        "tukey_lambda": cal.tukey_lambda.record(),
        "tukey_scale_dn": cal.tukey_scale_dn.record(),
        "row_noise_dn": cal.row_dn.record(),
        "row_noise_e": cal.row_e.record(),
        "dsnu_dn": cal.dsnu_dn.record(),
        "dsnu_e": cal.dsnu_e.record(),
        "prnu_percent": cal.prnu_percent.record(),
        "planes": planes,
        "flat_pairs": pairs,
        **({"dark_effects": _effects_record(cal, maps)} if cal.effects is not None else {}),
        "warnings": list(cal.warnings),
    }


def _fmt(e: Estimate, digits: int = 4) -> str:
    if e.standard_error is None:
        return f"{e.value:.{digits}g}"
    return f"{e.value:.{digits}g} ± {e.standard_error:.2g}"


def report_markdown(cal: Calibration) -> str:
    """The text of ``report.md``."""
    names = [pl.name for pl in cal.planes]
    levels = len({pair.level for pair in cal.pairs})
    lines = [
        f"# Camera calibration — {cal.name}, ISO {cal.iso:g}",
        "",
        f"{cal.source}. Sensor: {cal.layout.describe()} ({cal.layout.bits}-bit), planes {', '.join(names)}.",
        "",
        "## The preset's values",
        "",
        "| quantity | value ± standard error | 95 % interval | how |",
        "|---|---|---|---|",
    ]

    def row(label, e: Estimate, how, digits=4):
        ci = "—" if e.ci95 is None else f"{e.ci95[0]:.{digits}g} … {e.ci95[1]:.{digits}g}"
        lines.append(f"| {label} | {_fmt(e, digits)} | {ci} | {how} |")

    row("black level (DN)", cal.black_dn, f"mean of the darks; pedestal_dn = round(black) = {cal.pedestal_dn}",
        7)
    row("K (DN/e⁻)", cal.k_dn_per_e, "photon transfer: slope of var(A − B)/2 − σ²_dark against μ, weighted least "
        f"squares up to {100 * FIT_FRACTION:g} % of saturation; planes combined by inverse variance")
    row("read noise σ (DN)", cal.read_dn, "residuals about each pixel's mean, row means removed, − 1/12 DN² (Sheppard)")
    row("read noise σ (e⁻)", cal.read_e, "σ_DN / K")
    row("Tukey λ", cal.tukey_lambda, "matched PPCC (the law of the residuals: read noise ∗ ADC box ∗ the mean's "
        "Gaussian); mean of the planes")
    row("Tukey scale (DN)", cal.tukey_scale_dn, "the probability plot's slope")
    row("row noise σ (DN)", cal.row_dn, "variance of whole rows' means of the residuals − σ²/W")
    row("row noise σ (e⁻)", cal.row_e, "σ_row / K")
    row("DSNU (DN)", cal.dsnu_dn, "spatial σ of the per-pixel dark mean, − σ²_temporal / n")
    row("DSNU (e⁻)", cal.dsnu_e, "DSNU / K")
    row("PRNU (%)", cal.prnu_percent, "spatial σ of the brightest fitted pair's mean − the darks' mean (detrended), "
        "temporal parts removed, / μ")
    lines += ["", f"Read noise model: **{cal.read_noise_model}** (Gaussian when λ is within "
              f"{GAUSSIAN_LAMBDA_TOLERANCE} — or two standard errors — of {GAUSSIAN_LAMBDA}, the Tukey law closest "
              "to the normal).", ""]
    if cal.warnings:
        lines += ["## Warnings", ""] + [f"* {w}" for w in cal.warnings] + [""]
    lines += ["## Per plane", "",
              "| plane | black (DN) | K (DN/e⁻) | R² | read σ (DN) | λ matched | λ plain PPCC | row σ (DN) | "
              "DSNU (DN) | PRNU (%) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for pl in cal.planes:
        lines.append(f"| {pl.name} | {_fmt(pl.black_dn, 6)} | {_fmt(pl.ptc.k_dn_per_e)} | {pl.ptc.r_squared:.5f} | "
                     f"{_fmt(pl.read_dn)} | {pl.tukey.lam:+.4f} | {pl.tukey_plain.lam:+.4f} | {_fmt(pl.row_dn)} | "
                     f"{_fmt(pl.dsnu_dn)} | {_fmt(pl.prnu_percent)} |")
    lines += ["", f"Row noise over whole rows: {_fmt(cal.row_dn)} DN (the preset's); per plane, over each plane's "
              "sites of a row.", "", "## Photon transfer", "",
              f"{len(cal.pairs)} pairs at {levels} levels (mean signal per plane, DN; temporal variance, DN²; "
              "* = not fitted).", "",
              "| level | files | " + " | ".join(f"μ {n} | var {n}" for n in names) + " |",
              "|---|---|" + "---|---|" * len(names)]
    for i, pair in enumerate(cal.pairs):
        cells = []
        for p, pl in enumerate(cal.planes):
            star = "" if pl.ptc.used[i] else "*"
            cells.append(f"{pair.mean_dn[p]:.1f}{star} | {pair.variance_dn2[p]:.2f}")
        files = ", ".join(Path(f).name for f in pair.files)
        lines.append(f"| {pair.level} | {files} | " + " | ".join(cells) + " |")
    lines += ["", "![photon transfer](ptc.png)", "", "## Read noise: its law", "",
              "The samples are the dark frames' residuals about each pixel's mean over the n frames, less each "
              "row's mean (one per frame and plane row). ELD's plain PPCC correlates their order statistics with "
              "Tukey-λ quantiles; but a residual is the read noise blurred by the ADC's step (a uniform error of "
              "width 1 DN) and by the mean it was taken from (a Gaussian of variance σ²/(n − 1)), which pulls the "
              "plain λ towards the Gaussian-like 0.14. The matched PPCC correlates them with the quantiles of that "
              "blurred law, computed exactly for each λ, and is the preset's λ.", "",
              "![PPCC and probability plot](probability_plot.png)", "", "## Row noise", "",
              "![row-mean power spectrum](row_spectrum.png)", "",
              f"White row noise is flat at (1 − 1/n)(σ_row² + σ²/W) = {cal.row_white_level_dn2:.4g} DN²; a peak is a "
              "periodic row pattern (banding).", ""]
    if cal.effects is not None:
        lines += _report_effects(cal)
    return "\n".join(lines)


def _report_effects(cal: Calibration) -> list:
    """The report's section on the dark fixed pattern and the black-level error."""
    fx = cal.effects
    column_e = ratio(fx.column_fpn_dn, cal.k_dn_per_e)
    hot = ("no exposure in the files: no map" if fx.hot_e_per_s is None else
           f"{fx.hot_count} pixels ({100 * fx.hot_fraction.value:.3g} ± {100 * fx.hot_fraction.standard_error:.2g} %)"
           + (f", extra dark current median {float(np.median(fx.hot_e_per_s[fx.hot_e_per_s > 0])):.4g} e⁻/s"
              if fx.hot_count else ""))
    return ["## Dark fixed pattern and black-level error", "",
            "| quantity | value ± standard error | how |", "|---|---|---|",
            f"| dark-shading map RMS (e⁻) | {_fmt(fx.shading_rms_e)} | the mean of the darks less each plane's black "
            f"level, ÷ K (`dark_shading.npy`), its temporal noise removed; per pixel ± {fx.shading_se_e:.3g} e⁻ |",
            f"| hot pixels | {hot} | mean dark above its 5 × 5 median by more than 5 robust σ "
            "(`hot_pixels.npy`, e⁻/s) |",
            f"| column FPN σ (DN) | {_fmt(fx.column_fpn_dn)} | column means of the map about a cubic trend, less the "
            "pixels' share / H |",
            f"| column FPN σ (e⁻) | {_fmt(column_e)} | ÷ K |",
            f"| black-level error σ (DN) | {_fmt(fx.black_level_error_dn)} | per-frame colour means' spread, less "
            "σ²/N and σ²_row/R |", ""]


def _plot_ptc(cal: Calibration, path: Path) -> None:
    from camsim.io.figures import new_figure, save_png

    fig = new_figure(figsize=(7.5, 5.0), layout="constrained")
    ax = fig.add_subplot()
    colours = {"R": "tab:red", "G": "tab:green", "B": "tab:blue", "Y": "k"}
    top = max(float(np.max(pair.mean_dn)) for pair in cal.pairs)
    xs = np.linspace(0, top, 50)
    for p, pl in enumerate(cal.planes):
        mu = np.array([pair.mean_dn[p] for pair in cal.pairs])
        var = np.array([pair.variance_dn2[p] for pair in cal.pairs]) - pl.dark_variance_dn2.value
        colour = colours.get(pl.colour, "k")
        marker = "os^vd"[p % 5]
        used = pl.ptc.used
        ax.plot(mu[used], var[used], marker, color=colour, ms=5, label=f"{pl.name}: K = {_fmt(pl.ptc.k_dn_per_e)}")
        if np.any(~used):
            ax.plot(mu[~used], var[~used], marker, color=colour, mfc="none", ms=5)
        ax.plot(xs, pl.ptc.k_dn_per_e.value * xs + pl.ptc.intercept_dn2.value, "-", color=colour, lw=0.8)
    ax.set_xlabel("mean signal μ − black (DN)")
    ax.set_ylabel("temporal variance var(A − B)/2 − σ²_dark (DN²)")
    ax.set_title(f"Photon transfer: K = {_fmt(cal.k_dn_per_e)} DN/e⁻ (hollow: not fitted)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    save_png(fig, path)


def _plot_probability(cal: Calibration, path: Path) -> None:
    from camsim.io.figures import new_figure, save_png

    fig = new_figure(figsize=(11, 4.4), layout="constrained")
    left, right = fig.subplots(1, 2)
    for pl in cal.planes:
        plain = pl.tukey_plain
        line, = left.plot(plain.lambda_grid, plain.ppcc_curve, "-", lw=0.8, label=f"{pl.name} plain")
        left.plot(pl.tukey.lambda_grid, pl.tukey.ppcc_curve, "o", ms=3, color=line.get_color(),
                  label=f"{pl.name} matched, λ = {pl.tukey.lam:+.3f}")
    left.axvline(cal.tukey_lambda.value, color="k", lw=0.8, ls=":")
    best = max(float(np.max(pl.tukey_plain.ppcc_curve)) for pl in cal.planes)
    left.set_ylim(best - 0.004, best + 0.0005)
    left.set_xlabel("Tukey λ")
    left.set_ylabel("probability-plot correlation")
    left.set_title("PPCC against λ")
    left.grid(alpha=0.3)
    left.legend(fontsize="x-small", ncol=2)
    pl = cal.planes[0]
    q, x = pl.probability_plot
    right.plot(q, x, ".", ms=2, label="sorted residuals")
    right.plot(q, q, "-", color="k", lw=0.8, label="the fitted law")
    right.set_xlabel(f"quantiles of the blurred Tukey law, λ = {pl.tukey.lam:+.3f} (DN)")
    right.set_ylabel("residual (DN)")
    right.set_title(f"Probability plot, plane {pl.name} (r = {pl.tukey.ppcc:.6f})")
    right.grid(alpha=0.3)
    right.legend(fontsize="small")
    save_png(fig, path)


def _plot_rows(cal: Calibration, path: Path) -> None:
    from camsim.io.figures import new_figure, save_png

    freq, power = cal.row_spectrum
    fig = new_figure(figsize=(7.5, 4.4), layout="constrained")
    ax = fig.add_subplot()
    ax.semilogy(freq[1:], power[1:], "-", lw=0.6, label="row means' power (mean over the dark frames)")
    ax.axhline(cal.row_white_level_dn2, color="k", ls="--", lw=0.8,
               label=f"white row noise σ_row = {cal.row_dn.value:.3g} DN")
    floor = cal.row_white_level_dn2 - (1 - 1 / len(cal.dark_files)) * cal.row_dn.value**2
    ax.axhline(floor, color="tab:gray", ls=":", lw=0.8, label="no row noise (pixel noise / W)")
    ax.set_xlabel("frequency (cycles per row)")
    ax.set_ylabel("power (DN²)")
    ax.set_title("Power spectrum of the row means of the dark residuals")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize="small")
    save_png(fig, path)


def _write_npy_atomic(path: Path, array: np.ndarray) -> None:
    """``numpy.save`` through :func:`camsim.io.atomic.atomic_path` (no pickle)."""
    with atomic_path(path) as partial:
        with open(partial, "wb") as handle:
            np.save(handle, np.ascontiguousarray(array), allow_pickle=False)


def write_outputs(cal: Calibration, out, maps: bool = True) -> dict:
    """Write ``preset.toml``, ``calibration.json``, ``report.md``, the plots and the maps (``dark_shading.npy``,
    ``hot_pixels.npy``) into ``out`` (which must exist), each atomically; returns {key: path}. The preset is written
    last: the other files explain it. ``maps``: whether the preset names the maps (:func:`effect_values`)."""
    out = Path(out)
    paths = {key: out / name for key, name in FILES.items()}
    _plot_ptc(cal, paths["ptc"])
    _plot_probability(cal, paths["probability"])
    _plot_rows(cal, paths["rows"])
    if cal.effects is not None:
        _write_npy_atomic(paths["dark_shading"], cal.effects.shading_e)
        if cal.effects.hot_e_per_s is not None:
            _write_npy_atomic(paths["hot_pixels"], cal.effects.hot_e_per_s)
        else:
            paths.pop("hot_pixels")
    else:
        paths.pop("dark_shading")
        paths.pop("hot_pixels")
    write_json_atomic(paths["json"], calibration_record(cal, maps))
    write_text_atomic(paths["report"], report_markdown(cal))
    write_text_atomic(paths["preset"], preset_toml(cal, maps))
    return paths

