"""The outputs of ``camsim calibrate``: ``preset.toml``, ``calibration.json``, ``report.md`` and three plots.

``preset.toml`` is an interface (read by ``camsim.sensor.presets`` for ``--preset PATH.toml``); its keys are:

* ``[preset]``: ``name``, ``source``, ``bits``, ``pedestal_dn``, ``cfa`` (absent for a 3-colour stack or a
  monochrome sensor), ``read_noise_model`` (``"gaussian"`` or ``"tukey-lambda"``);
* one ``[[iso]]`` table: ``iso``, ``k_dn_per_e``, ``tukey_lambda``, ``tukey_scale_dn`` (the Tukey scale, not the
  standard deviation), ``gaussian_sigma_dn`` (the read noise's standard deviation), ``row_sigma_dn``, ``dsnu_dn``,
  ``prnu_percent``.

Every file is written atomically (:mod:`camsim.io.atomic`); the plots need matplotlib, imported when they are drawn
(:mod:`camsim.io.figures`: no pyplot, no backend change).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from camsim.calibration.estimate import Estimate, ratio
from camsim.calibration.measure import GAUSSIAN_LAMBDA_TOLERANCE, Calibration
from camsim.calibration.ptc import FIT_FRACTION
from camsim.calibration.tukey import GAUSSIAN_LAMBDA
from camsim.io.atomic import write_json_atomic, write_text_atomic
from camsim.core.optional_numbers import finite_or_none

FILES = {
    "preset": "preset.toml",
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


def preset_toml(cal: Calibration) -> str:
    """The text of ``preset.toml``."""
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
        f"dsnu_dn = {_number(cal.dsnu_dn.value)}",
        f"prnu_percent = {_number(cal.prnu_percent.value)}",
        "",
    ]
    return "\n".join(lines)


def _fit_record(fit) -> dict:
    return {"lambda": round(fit.lam, 5), "ppcc": finite_or_none(round(fit.ppcc, 7)),
            "scale_dn": finite_or_none(f"{fit.scale_dn:.6g}"), "std_dn": finite_or_none(f"{fit.std_dn:.6g}"),
            "samples": fit.samples}


def calibration_record(cal: Calibration) -> dict:
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
    return "\n".join(lines)


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


def write_outputs(cal: Calibration, out) -> dict:
    """Write ``preset.toml``, ``calibration.json``, ``report.md`` and the plots into ``out`` (which must exist),
    each atomically; returns {key: path}. The preset is written last: the other files explain it."""
    out = Path(out)
    paths = {key: out / name for key, name in FILES.items()}
    _plot_ptc(cal, paths["ptc"])
    _plot_probability(cal, paths["probability"])
    _plot_rows(cal, paths["rows"])
    write_json_atomic(paths["json"], calibration_record(cal))
    write_text_atomic(paths["report"], report_markdown(cal))
    write_text_atomic(paths["preset"], preset_toml(cal))
    return paths

