"""The SNR sensitivity analysis (the paper's Figs. 7–9; Eqs. 13, 14 and 17) under two protocols.

Protocols (``protocol`` column of the numbers CSV):

- ``one-at-a-time``: the paper's stated protocol, "only one noise is considered at a time (the other noises are
  deactivated in the model)". Photon noise stays on: it is the signal's own noise (Eq. 13's V·G² term), not one
  of the three noises analysed. Read noise: photon + read noise, σ_read 4 → 4.4 e⁻. Dark current: photon + dark
  current, σ²_dark × 1.1. Quantisation: photon noise only, without and with the nb-bit ADC.
- ``all-on``: Table I with every stage on and one parameter changed. Quantisation: Table I without and with the ADC.

Saturation stays on (Table I) in both; it does not act at the analysis's F ≤ 0.1. "Without quantisation" is the
same frame before the ADC (its EXR), "with" its DNG: they share every random draw.

SNR₁ is the SNR with the smaller noise (Table I's parameter, or no ADC), SNR₂ with the larger one, so that
ΔSNR = 100 (SNR₁ − SNR₂) / SNR₁ > 0, as the paper expects (Eq. 17).

Model forms (columns), each under both quantisation terms (rows: ``quantisation_term`` ``mean-square``, Eq. 12's
error squared, 1/3 DN², Eq. 13 literally; ``variance``, the 1/12 DN² the quantiser adds to the pixel values):

- ``eq13``: Eqs. 13–14 as printed. Eq. 13, Var = V·G² + σ_read²·G² + σ_ADC², in DN²: V·G² is the shot-noise
  variance of V = G_Ve (S + D), Poisson in electrons, so k² (S + D) with k = G · G_Ve; σ_read·G_Ve·G = k σ_read.
  Eq. 14's numerator is the quantised noise-free signal [k S]_nb where the sensor quantises (0 where k S < 1 DN),
  k S where it does not.
- ``eq13_unquantised_numerator``: the same with the numerator k S everywhere.
- ``statistics_variance``: Eq. 13 with the photon statistics' own Var S in place of S (the sidecar's
  ``signal_var_e2``: S in ``pixel`` statistics, Σ F g Qe² ≈ 1e-14 S in ``paper`` statistics, which leaves only the
  dark, read and quantisation terms: ΔSNR then does not depend on F).

The empirical ΔSNR is measured on the pixels (:func:`camsim.analysis.snr.snr_empirical`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camsim.analysis.snr import delta_snr_percent, quantised_signal_dn, snr_model
from camsim.colour.colorimetry import CHANNELS
from camsim.core.optional_numbers import finite_or_none
from camsim.experiments import findings as fd
from camsim.experiments.report import Finding, write_csv, write_report
from camsim.experiments.runner import STATISTICS_METHODS, Setup, analyse_series, prepare, run_conditions
from camsim.render.frame_files import read_frame_meta
from camsim.sensor.params import PRESETS, SensorParams

SNR_FACTORS = (0.1, 0.05, 0.01, 0.005, 0.001)
#: The paper's SNR analysis uses the boundary data points 1–13.
N_POINTS = 13
PROTOCOLS = ("one-at-a-time", "all-on")
NOISES = ("read+10%", "dark+10%", "quantisation")
QUANTISATION_TERMS = {"mean-square": "σ²_ADC = 1/3 DN²", "variance": "σ²_ADC = 1/12 DN²"}
FORMS = ("eq13", "eq13_unquantised_numerator", "statistics_variance")
STATISTICS = tuple(STATISTICS_METHODS)
#: The CSV column of the verdicts: Eqs. 13–14 as printed.
VERDICT_COLUMN = "delta_snr_eq13_pct"


@dataclass(frozen=True)
class Comparison:
    """One ΔSNR of Eq. 17: the series (and file kind) of SNR₁ and of SNR₂ under a protocol.

    ``first`` and ``second`` are ``(series name, source)``; source ``dng`` reads the frames as rendered (the EXR
    where nothing is quantised), ``exr`` the values before the ADC.
    """

    protocol: str
    noise: str
    first: tuple
    second: tuple


def _more_read(sensor: SensorParams) -> SensorParams:
    return dataclasses.replace(sensor, read_noise_e=1.1 * sensor.read_noise_e)


def _more_dark(sensor: SensorParams) -> SensorParams:
    return dataclasses.replace(sensor, dark_current_e_per_s=tuple(1.1 * d for d in sensor.dark_current_e_per_s))


def protocol_series(base: SensorParams) -> tuple[dict, list]:
    """The sensors to render ({series name: sensor}) and the comparisons of both protocols against ``base``."""
    read = base.with_stages(dark_current=False, quantisation=False)
    dark = base.with_stages(read_noise=False, quantisation=False)
    adc = base.with_stages(dark_current=False, read_noise=False)
    series = {
        "one-at-a-time-read": read, "one-at-a-time-read+10%": _more_read(read),
        "one-at-a-time-dark": dark, "one-at-a-time-dark+10%": _more_dark(dark),
        "one-at-a-time-quantisation": adc,
        "all-on": base, "all-on-read+10%": _more_read(base), "all-on-dark+10%": _more_dark(base),
    }
    comparisons = [
        Comparison("one-at-a-time", "read+10%", ("one-at-a-time-read", "dng"), ("one-at-a-time-read+10%", "dng")),
        Comparison("one-at-a-time", "dark+10%", ("one-at-a-time-dark", "dng"), ("one-at-a-time-dark+10%", "dng")),
        Comparison("one-at-a-time", "quantisation", ("one-at-a-time-quantisation", "exr"),
                   ("one-at-a-time-quantisation", "dng")),
        Comparison("all-on", "read+10%", ("all-on", "dng"), ("all-on-read+10%", "dng")),
        Comparison("all-on", "dark+10%", ("all-on", "dng"), ("all-on-dark+10%", "dng")),
        Comparison("all-on", "quantisation", ("all-on", "exr"), ("all-on", "dng")),
    ]
    return series, comparisons


def model_snr(meta: dict, index: int, source: str, form: str, quantisation_term: str) -> np.ndarray:
    """Model SNR (Eq. 14) of patch ``index`` of a frame, per channel, from the frame's sidecar ``meta``.

    Parameters
    ----------
    meta : dict
        The frame's sidecar (:func:`camsim.render.frame_files.read_frame_meta`).
    index : int
        Patch index.
    source : {'dng', 'exr'}
        The file analysed: an EXR holds the values before the ADC, so nothing is quantised there.
    form : {'eq13', 'eq13_unquantised_numerator', 'statistics_variance'}
        See the module's docstring.
    quantisation_term : {'mean-square', 'variance'}

    Returns
    -------
    numpy.ndarray, shape (3,)
        SNR as a power ratio.
    """
    if form not in FORMS:
        raise ValueError(f"form must be one of {FORMS}, got {form!r}")
    stages, patch = meta["stages"], meta["patches"][index]
    signal = np.asarray(patch["signal_e"], dtype=np.float64)
    dark = np.asarray(patch["dark_e"], dtype=np.float64) if stages["dark_current"] else 0.0
    if form == "statistics_variance":
        signal_var = np.asarray(patch["signal_var_e2"], dtype=np.float64)
    else:  # Eq. 13's V·G²: Poisson in electrons
        signal_var = signal if stages["photon_noise"] else np.zeros(3)
    read = meta["read_noise_e"] if stages["read_noise"] else 0.0
    quantising = bool(stages["quantisation"]) and source == "dng" and meta.get("bits") is not None
    bits = meta["bits"] if quantising and form != "eq13_unquantised_numerator" else None
    return snr_model(signal, dark, signal_var, read, meta["dn_per_electron"], quantising, quantisation_term,
                     numerator_bits=bits).snr


def snr_rows(results: dict, comparisons, statistics_list=STATISTICS) -> list[dict]:
    """ΔSNR (%) of each comparison per statistics, quantisation term, F, point and channel (Eq. 17).

    Parameters
    ----------
    results : dict
        ``{(statistics-series, source): analysis results}`` (one result per F, from
        :func:`camsim.experiments.runner.analyse_series`).
    comparisons : list of Comparison

    Returns
    -------
    list of dict
        The rows of the numbers CSV: the model forms' SNR₁, SNR₂ and ΔSNR (``delta_snr_<form>_pct``; None where
        SNR₁ is 0, e.g. a quantised numerator of 0 DN), the empirical ones, and the baseline's signal k S and
        [k S]_nb in DN.
    """
    metas: dict = {}

    def meta_of(result):
        path = result["frame_file"]
        if path not in metas:
            metas[path] = read_frame_meta(path)
        return metas[path]

    rows = []
    for statistics in statistics_list:
        for comp in comparisons:
            firsts = {r["intensity_factor"]: r for r in results[(f"{statistics}-{comp.first[0]}", comp.first[1])]}
            seconds = results[(f"{statistics}-{comp.second[0]}", comp.second[1])]
            for term in QUANTISATION_TERMS:
                for two in sorted(seconds, key=lambda r: -r["intensity_factor"]):
                    f = two["intensity_factor"]
                    one = firsts[f]
                    meta_1, meta_2 = meta_of(one), meta_of(two)
                    k, bits = meta_1["dn_per_electron"], meta_1["bits"]
                    for p1, p2 in zip(one["patches"], two["patches"]):
                        i = p1["index"]
                        snr = {form: (model_snr(meta_1, i, comp.first[1], form, term),
                                      model_snr(meta_2, i, comp.second[1], form, term)) for form in FORMS}
                        signal_dn = k * np.asarray(meta_1["patches"][i]["signal_e"], dtype=np.float64)
                        for c, channel in enumerate(CHANNELS):
                            e1, e2 = p1["channels"][c]["snr_empirical"], p2["channels"][c]["snr_empirical"]
                            row = {"statistics": statistics, "protocol": comp.protocol, "variant": comp.noise,
                                   "quantisation_term": term, "intensity_factor": f, "point": i + 1,
                                   "channel": channel, "signal_dn": float(signal_dn[c]),
                                   "signal_quantised_dn": float(quantised_signal_dn(signal_dn[c], bits)),
                                   "snr_1_eq13": finite_or_none(snr["eq13"][0][c]),
                                   "snr_2_eq13": finite_or_none(snr["eq13"][1][c])}
                            for form, (s1, s2) in snr.items():
                                row[f"delta_snr_{form}_pct"] = delta_snr_percent(finite_or_none(s1[c]),
                                                                                 finite_or_none(s2[c]))
                            row.update(snr_1_empirical=e1, snr_2_empirical=e2,
                                       delta_snr_empirical_pct=delta_snr_percent(e1, e2))
                            rows.append(row)
    return rows


TEXTS = {
    "read+10%": ("S.1", "Read noise +10 % changes the SNR by less than 1 %", "read"),
    "dark+10%": ("S.2", "Dark current +10 % changes the SNR by 1–9 %", "dark"),
    "quantisation": ("S.3", "Quantisation changes the SNR the most", "quantisation"),
}


def figure_key(noise: str, protocol: str) -> str:
    """The figure of a noise under a protocol, e.g. ``snr_read_one_at_a_time``."""
    return f"snr_{TEXTS[noise][2]}_{protocol.replace('-', '_')}"


def snr_findings(rows) -> list[Finding]:
    """S.1–S.3 for each protocol and quantisation term, a verdict per statistics (Eqs. 13–14 as printed)."""
    found = []
    for protocol in PROTOCOLS:
        for term, label in QUANTISATION_TERMS.items():
            verdicts = {}
            for statistics in STATISTICS:
                mine = [r for r in rows if r["statistics"] == statistics and r["protocol"] == protocol
                        and r["quantisation_term"] == term]
                verdicts[statistics] = {
                    "read+10%": fd.snr_average_within(mine, "read+10%", below=1.0),
                    "dark+10%": fd.snr_average_within(mine, "dark+10%", low=1.0, high=9.0),
                    "quantisation": fd.snr_largest(mine, "quantisation", ("read+10%", "dark+10%")),
                }
            for noise, (key, text, _) in TEXTS.items():
                off = protocol == "one-at-a-time" and noise != "quantisation"
                note = (f"{protocol}: the ADC is off in this comparison, so the quantisation term does not enter "
                        "(the same numbers under both terms)." if off else "")
                found.append(Finding(f"{key} [{protocol}, {label}]", text,
                                     {s: verdicts[s][noise] for s in STATISTICS}, figure_key(noise, protocol),
                                     note=note))
    return found


PROTOCOL_TEXT = [
    "## Protocols and model forms", "",
    "- `one-at-a-time` (the paper's stated protocol: \"only one noise is considered at a time (the other noises are "
    "deactivated in the model)\"): photon noise stays on (it is the signal's own noise, Eq. 13's V·G² term); read "
    "noise: photon + read noise, σ_read 4 → 4.4 e⁻; dark current: photon + dark current, σ²_dark × 1.1; "
    "quantisation: photon noise only, without and with the ADC.",
    "- `all-on`: Table I with every stage on, one parameter changed; quantisation: Table I without and with the ADC.",
    "- \"Without quantisation\" is the same frame before the ADC (its EXR), \"with\" its DNG; the other "
    "comparisons share their random draws too (frames are seeded by statistics and F only), so that the empirical "
    "ΔSNR is not swamped by sampling noise. SNR₁ is always the SNR with the smaller noise, so that "
    "ΔSNR = 100 (SNR₁ − SNR₂) / SNR₁ > 0 (Eq. 17).",
    "- Verdicts use Eqs. 13–14 as printed (CSV column `delta_snr_eq13_pct`): Var = k² (S + D) + k² σ²_read + "
    "σ²_ADC in DN² (Eq. 13's V·G² is the shot noise of V = G_Ve (S + D), Poisson in electrons; k = G · G_Ve), "
    "numerator [k S]_nb (Eq. 14: the integer part of the noise-free signal, 0 where k S < 1 DN, so the SNR is 0 "
    "and a ΔSNR against it undefined) where the sensor quantises. Beside it: the numerator k S "
    "(`delta_snr_eq13_unquantised_numerator_pct`), and the photon statistics' own Var S in place of S "
    "(`delta_snr_statistics_variance_pct`: in `paper` statistics Σ F g Qe², about 1e-14 S, which drops the photon "
    "term and makes every ΔSNR the same at every F), and the pixels' own ΔSNR (`delta_snr_empirical_pct`, quoted "
    "as a median: where the signal is near the black level the measured SNR₁ is near 0 and the ratio explodes).",
    "- Each verdict is given under both quantisation terms: σ²_ADC = 1/3 DN² (the mean square of Eq. 12's error "
    "I − G·Ṽ, Eq. 13 literally) and 1/12 DN² (the variance the quantiser adds to the pixel values).",
    "- As the paper does (\"comparing the average SNR sensitivities\"), a finding is judged on the average curves: "
    "per channel and F, the mean ΔSNR over the 13 points; undefined values are left out and counted.", "",
]


def run_snr_sensitivity(out_dir: Path, setup: Setup, progress: bool = True) -> list[Finding]:
    """ΔSNR (%) for read noise +10 %, dark current +10 % and quantisation, under both protocols (Eq. 17)."""
    from camsim.experiments.figures import snr_figures

    setup = dataclasses.replace(setup, n_points=min(setup.n_points, N_POINTS))
    prep = prepare(setup)
    base = PRESETS["paper-table1"]
    series, comparisons = protocol_series(base)
    conditions = [(f"{s}-{name}", sensor, SNR_FACTORS, s) for s in STATISTICS for name, sensor in series.items()]
    rendered = run_conditions(prep, conditions, out_dir, setup.seed, progress)
    results = {(key, "dng"): value for key, value in rendered.items()}
    for key, sensor, _, _ in conditions:
        if sensor.quantisation:  # the same frames before the ADC
            results[(key, "exr")] = analyse_series(out_dir / "frames" / key, source="exr")
    rows = snr_rows(results, comparisons)
    numbers = write_csv(out_dir / "snr_sensitivity_numbers.csv", rows)
    findings = snr_findings(rows)
    figures = snr_figures(rows, out_dir)
    write_report(out_dir / "report.md", "SNR sensitivity to the noise parameters (Eq. 17)", setup, prep, base,
                 SNR_FACTORS, findings, figures, numbers, "paper-table1", preamble=PROTOCOL_TEXT)
    return findings
