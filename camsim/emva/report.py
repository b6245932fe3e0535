"""The outputs of ``camsim emva``: ``emva.json``, ``report.md`` and its plots, each written atomically.

``emva.json`` is an interface: ``{key: {"configured", "recovered", "relative_error"}}`` for the keys of
:data:`camsim.emva.simulate.QUANTITIES` (K_dn_per_e, dark_noise_e, qe, saturation_e, dsnu_e, prnu_percent), then,
where the dark stack was also taken at a second exposure time, of
:data:`camsim.emva.simulate.SPLIT_QUANTITIES` (dsnu_offset_e, dsnu_dark_current_e_per_s), then, where the dark
current was measured at several temperatures, of :data:`camsim.emva.simulate.TEMPERATURE_QUANTITIES`
(dark_current_doubling_c), with null where a value is undefined (a relative error of a quantity configured as 0, a
negative variance).

The plots are the reference implementation's own (``emva1288.process.plotting``) drawn headless, each with the
configured camera overlaid.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from camsim.emva.simulate import (
    CHANNEL,
    S2_YDARK_FLOOR_DN2,
    EmvaResult,
    emva1288_numpy_shims,
    emva1288_process,
    model_dark_temporal_dn,
)
from camsim.io.atomic import write_json_atomic, write_text_atomic
from camsim.io.figures import new_figure, save_png
from camsim.io.output_folder import make_folder

PLOTS = {
    "photon_transfer": "photon_transfer.png",
    "snr": "snr.png",
    "nonuniformity": "nonuniformity.png",
}
_NAMES = {
    "K_dn_per_e": "System gain K",
    "dark_noise_e": "Temporal dark noise σ_d",
    "qe": "Quantum efficiency η",
    "saturation_e": "Saturation capacity μ_e,sat",
    "dsnu_e": "DSNU₁₂₈₈",
    "prnu_percent": "PRNU₁₂₈₈",
    "dsnu_offset_e": "DSNU, offset part σ_o",
    "dsnu_dark_current_e_per_s": "DSNU, dark-current part c (∝ T)",
    "dark_current_doubling_c": "Doubling temperature T_d of the dark current",
}
_CONFIGURED_AS = {
    "K_dn_per_e": "G · G_Ve⁻",
    "dark_noise_e": "√(σ²_read + μ_dark + σ²_row)",
    "qe": "η_G(λ) of the camera",
    "saturation_e": "full well",
    "dsnu_e": "dsnu_e",
    "prnu_percent": "prnu_percent",
    "dsnu_offset_e": "dsnu_e",
    "dsnu_dark_current_e_per_s": "p/100 · σ²_dark (G)",
    "dark_current_doubling_c": "dark_current_doubling_c",
}
#: The DSNU configured with both kinds on: the total at the measured exposure time T.
_DSNU_BOTH = "√(dsnu_e² + (p/100 · σ²_dark · T)²)"


def _plots(result: EmvaResult, out: Path) -> dict:
    """Draw the reference implementation's plots with the configuration overlaid; returns {key: file name}."""
    emva1288_process()
    from emva1288.process import plotting

    res, conf = result.results, result.configured
    k, eta = conf["K_dn_per_e"], conf["qe"]

    fig = new_figure(figsize=(11, 4.4), layout="constrained")
    left, right = fig.subfigures(1, 2)
    ptc = plotting.PlotPTC(left)
    ptc.plot(res)
    x = res.temporal["u_y"] - res.temporal["u_ydark"]
    ptc.ax.plot(x, k * x, ":", color="k", label=f"configured K = {k:.4g} DN/e⁻")
    ptc.ax.set_title(f"Photon transfer (fit K = {res.K:.4g} DN/e⁻)")
    ptc.set_legend(ptc.ax)
    sens = plotting.PlotSensitivity(right)
    sens.plot(res)
    p = res.temporal["u_p"]
    sens.ax.plot(p, eta * k * p, ":", color="k", label=f"configured η K = {eta * k:.4g} DN/p")
    sens.ax.set_title(f"Sensitivity (fit R = {res.R:.4g} DN/p, η = {res.QE:.2f} %)")
    sens.ax.ticklabel_format(axis="x", style="sci", scilimits=(1, 4))
    sens.set_legend(sens.ax)
    save_png(fig, out / PLOTS["photon_transfer"])

    fig = new_figure(figsize=(7.5, 5.2), layout="constrained")
    snr = plotting.PlotSNR(fig)
    snr.plot(res)
    mu_p = np.geomspace(max(1.0, float(p[0]) / 4), float(p[-1]), 200)
    mu_e = eta * mu_p
    temporal = mu_e / np.sqrt(conf["dark_noise_e"] ** 2 + (1 / 12) / k**2 + mu_e)
    temporal[mu_e > result.measurement.predicted_saturation_e] = np.nan
    snr.ax.plot(mu_p, temporal, color="k", lw=0.8, label="configured camera (temporal SNR)")
    snr.ax.set_title("Signal-to-noise ratio")
    snr.set_legend(snr.ax)
    save_png(fig, out / PLOTS["snr"])

    fig = new_figure(figsize=(11, 4.2), layout="constrained")
    left, right = fig.subfigures(1, 2)
    dsnu = plotting.PlotLogarithmicHistogramDSNU(left)
    dsnu.plot(res)
    dsnu.ax.set_title(f"DSNU histogram (averaged dark stack, DSNU₁₂₈₈ = {_fmt(result.recovered['dsnu_e'])} e⁻)",
                      fontsize="medium")
    prnu = plotting.PlotLogarithmicHistogramPRNU(right)
    prnu.plot(res)
    prnu_value = _fmt(result.recovered["prnu_percent"])
    prnu.ax.set_title(f"PRNU histogram (high-pass filtered, PRNU₁₂₈₈ = {prnu_value} %)", fontsize="medium")
    save_png(fig, out / PLOTS["nonuniformity"])
    return dict(PLOTS)


def _fmt(value, digits: int = 4) -> str:
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    return f"{value:.{digits}g}"


def _percent(value) -> str:
    return "—" if value is None else f"{100 * value:+.2f} %"


def _verdict(result: EmvaResult, key: str) -> str:
    target = result.quantities[key][1]
    ok = result.within_target(key)
    if target is None:
        return "no target (see below)"
    if not result.configured[key]:
        return "off (configured 0)"
    return f"✓ within {target * 100:g} %" if ok else f"✗ outside {target * 100:g} %"


def _summary(result: EmvaResult) -> list:
    """Title and the comparison table."""
    import emva1288

    rows = result.comparison()
    lines = [
        f"# EMVA 1288 measurement of the simulated camera — preset `{result.measurement.preset_name}`",
        "",
        "camsim simulated the EMVA 1288 (Release 4.0 Linear) photon-transfer measurement of its camera model and "
        f"analysed it with the reference implementation, `emva1288` {emva1288.__version__} (standard "
        f"{emva1288.__standard_version__}), through its in-memory entry points `Data1288` and `Results1288`.",
        "",
        "## What the standard recovers against what was configured",
        "",
        "| quantity | unit | configured as | configured | recovered (EMVA 1288) | relative error | target |",
        "|---|---|---|---|---|---|---|",
    ]
    for key, (unit, _target) in result.quantities.items():
        r = rows[key]
        configured_as = _DSNU_BOTH if key == "dsnu_e" and result.measurement.sensor.dsnu_dark_current_percent > 0 \
            else _CONFIGURED_AS[key]
        lines.append(f"| {_NAMES[key]} (`{key}`) | {unit} | {configured_as} | {_fmt(r['configured'])} | "
                     f"{_fmt(r['recovered'])} | {_percent(r['relative_error'])} | {_verdict(result, key)} |")
    checked = [key for key in result.quantities if result.within_target(key) is not None]
    failed = [key for key in checked if not result.within_target(key)]
    verdict = (f"All {len(checked)} quantities with a target ({', '.join(checked)}) are within it." if not failed
               else f"Outside their target: {', '.join(failed)} (of {', '.join(checked)}); see below.")
    return lines + [
        "",
        verdict,
        "",
        "The QE is a fraction (e⁻ per photon; the standard prints it in %). Saturation has no target: the standard's "
        "μ_e,sat is not the full well (see below). `emva.json` holds the same numbers.",
        "",
    ]


def _dark_current_text(s) -> str:
    """The G channel's dark current as measured: at the sensor's temperature where it has one (EMVA 1288 states
    the dark current at the temperature of the measurement)."""
    rate = s.dark_current_e_per_s[CHANNEL]
    if s.temperature_c is None:
        return f"{rate:g} e⁻/s"
    return (f"{s.dark_current_effective_e_per_s[CHANNEL]:g} e⁻/s at the sensor's {s.temperature_c:g} °C "
            f"({rate:g} e⁻/s at {s.dark_current_reference_c:g} °C, doubling every {s.dark_current_doubling_c:g} °C)")


def _dark_notes(result: EmvaResult) -> list:
    """Dark noise (quantisation), K and η (the quantisation offset of the PTC), the −½ DN, the black level."""
    s, d = result.measurement.sensor, result.details
    k, dark_e = s.dn_per_electron, s.dark_mean_e[CHANNEL]
    conf, rec = result.configured["dark_noise_e"], result.recovered["dark_noise_e"]
    dark_mean, dark_var = model_dark_temporal_dn(s)
    expected = math.sqrt(max(dark_var, S2_YDARK_FLOOR_DN2) - 1 / 12) / k  # what the standard's formula gives
    q_dark = dark_var - (k * conf) ** 2  # the quantiser's share of the dark variance, exactly
    delta = 1 / 12 - q_dark  # the PTC's offset at the origin
    lo, hi = d["fit_indices"]
    x = (result.results.temporal["u_y"] - result.results.temporal["u_ydark"])[lo:hi + 1]
    k_bias = delta * np.sum(x) / np.sum(x * x) / k  # least squares through the origin, shifted by delta
    spread = k * math.hypot(conf, result.configured["dsnu_e"])  # temporal and spatial (both kinds of DSNU)
    read = s.read_noise_e if s.read_noise else 0.0
    if abs(expected / conf - 1) > 0.01:
        cause = ("The difference from the configuration is therefore the standard's 1/12 DN² assumption, not the "
                 "simulation: below about 0.5 DN of noise the quantisation error depends on where the dark level "
                 "falls between two codes.")
    else:
        cause = "The 1/12 DN² assumption holds at this noise level."
    if d["dark_floor_applied"]:
        cause += f" The reference implementation raised σ²_y.dark to its floor of {S2_YDARK_FLOOR_DN2} DN²."
    if dark_e > 0:
        clipping = "negligible." if s.dark_level_dn[CHANNEL] > 3.5 * spread else \
            "**not** negligible: the dark statistics are biased."
        black = (f"{dark_e:g} e⁻ = {s.dark_level_dn[CHANNEL]:.3g} DN against a dark noise of {spread:.3g} DN"
                 f"{' (with DSNU)' if result.configured['dsnu_e'] > 0 else ''}, so clipping is {clipping}")
    else:
        black = "none: the dark signal is clipped at 0 DN and its statistics are biased."
    return [
        f"* **Dark noise.** EMVA's σ_d is all the temporal noise in the dark at the measured exposure "
        f"({s.exposure_s:g} s): read noise and the shot noise of the {dark_e:g} dark electrons (and row noise, "
        f"{s.row_noise_e:g} e⁻ here), hence the configured √(σ²_read + μ_dark + σ²_row) = {_fmt(conf)} e⁻ (the "
        f"read noise alone is {read:g} e⁻). The standard takes σ_d = √(σ²_y.dark − σ²_q) / K with σ²_q = 1/12 DN², "
        "which assumes the quantiser's error is uniform and independent of the signal — true when the noise before "
        f"the ADC is well above 1 DN. Here that noise is {k * conf:.3g} DN. camsim's model gives, exactly, a "
        f"quantised dark variance of {dark_var:.4g} DN² (measured: {d['s2_ydark_dn2']:.4g} DN²), so the standard's "
        f"formula should return {expected:.4g} e⁻; it returned {_fmt(rec)} e⁻. {cause}",
        "* **System gain and QE.** K is the slope of the photon transfer curve, fitted through the origin. The "
        "standard assumes the same quantisation variance (1/12 DN²) in the bright and in the dark; in camsim's model "
        f"the dark's is {q_dark:.4g} DN², so the curve starts {delta:+.3g} DN² off the origin, which shifts K by "
        f"about {100 * k_bias:+.2f} % over the fit range (measured "
        f"{_percent(result.comparison()['K_dn_per_e']['relative_error'])}); η = R / K inherits it with the opposite "
        "sign (R, a fit of means, is unbiased).",
        "* **The −½ DN of the integer part.** camsim's ADC keeps the integer part (Eq. 11), so every mean reads "
        f"½ DN low: the dark level is {d['u_ydark_dn']:.4g} DN (model: {dark_mean:.4g} DN) for {dark_e:g} e⁻ × K = "
        f"{s.dark_level_dn[CHANNEL]:.4g} DN. The standard only uses μ_y − μ_y.dark, so the bias cancels from K, R "
        "and η; a rounding ADC would change nothing here.",
        "* **Black level.** EMVA 1288 asks for an offset high enough that no dark pixel reads 0; camsim's ADC has no "
        f"pedestal and clips at 0 DN. The dark electrons are the only offset: {black}",
        _dark_current_note(result),
    ]


def _dark_current_note(result: EmvaResult) -> str:
    """What the one exposure time says of the dark current, and of its spatial non-uniformity."""
    s = result.measurement.sensor
    note = ("* **Dark current.** One exposure time is measured (the standard's dark-current section needs several), "
            "so the dark electrons appear only through σ_d. camsim's dark current is a rate σ²_dark in e⁻/s with "
            "Poisson noise and ")
    if s.dsnu_dark_current_percent == 0:
        note += "no spatial non-uniformity of its own"
    else:
        note += (f"a spatial non-uniformity of its own, {s.dsnu_dark_current_percent:g} % (each pixel's rate is "
                 "σ²_dark · d, d a fixed log-normal map of mean 1), whose DSNU grows ∝ T: see the DSNU at two "
                 "exposure times")
    note += "; EMVA's μ_I would be the same rate"
    if s.temperature_c is not None:
        note += (f", at the sensor's {s.temperature_c:g} °C: {s.dark_current_effective_e_per_s[CHANNEL]:g} e⁻/s "
                 f"(μ_I,ref · 2^((ϑ − ϑ_ref)/T_d) with {s.dark_current_e_per_s[CHANNEL]:g} e⁻/s at "
                 f"{s.dark_current_reference_c:g} °C, T_d = {s.dark_current_doubling_c:g} °C)")
    if result.measurement.dark_vs_temperature:
        note += "; it is measured against the temperature below"
    return note + "."


def _saturation_and_pattern_notes(result: EmvaResult) -> list:
    """Saturation (the variance peak against the clip), DSNU / PRNU (the realised maps), the QE's photon count."""
    m, s, d = result.measurement, result.measurement.sensor, result.details
    k, sat = s.dn_per_electron, m.predicted_saturation_e
    recovered = result.recovered["saturation_e"]
    tail = float(result.results.temporal["s2_y"][-1])
    prnu = f" and the PRNU ({s.prnu_percent:g} % ≈ {s.prnu_percent / 100 * sat:.0f} e⁻)" if s.prnu_percent else ""
    if d["index_u_ysat_automatic"] != d["index_u_ysat"]:
        search = ("The reference implementation's own search for the peak (walking back from the brightest step) "
                  f"stopped at step {d['index_u_ysat_automatic']} (μ_p = {d['u_p_sat_automatic']:.6g}), a wiggle of "
                  f"the plateau past saturation, whose variance is not 0 but about {tail:.3g} DN² (the read noise "
                  "after the charge clips); camsim passes it the maximum of the variance (`index_u_ysat` = "
                  f"{d['index_u_ysat']}, μ_p,sat = {_fmt(d['u_p_sat'], 6)}).")
    else:
        search = f"The reference implementation's own search for the peak finds the same step ({d['index_u_ysat']})."
    if s.fixed_pattern:
        drawn = [f"{v:.4g} {unit} ({name})" for v, unit, name in
                 ((m.realised_dsnu_e, "e⁻", "DSNU"), (m.realised_prnu_percent, "%", "PRNU"),
                  (m.realised_dark_dsnu_e_per_s, "e⁻/s", "the dark-current rates")) if v is not None]
        listed = drawn[0] if len(drawn) == 1 else ", ".join(drawn[:-1]) + " and " + drawn[-1]
        maps = (f"; over the {m.data['width']} × {m.data['height']} analysed pixels the maps actually drawn (sensor "
                f"seed {s.sensor_seed}) have {listed}.")
    else:
        maps = " (both off here, so the standard should find about 0: what it finds is the estimators' noise)."
    kind = "Gaussian" if s.dsnu_dark_current_percent == 0 else "Gaussian (offset, PRNU) and log-normal (dark current)"
    dark_map = ("" if s.dsnu_dark_current_percent == 0 else
                " The dark-current DSNU is a log-normal factor (mean 1, σ "
                f"{s.dsnu_dark_current_percent:g} %) on the dark-current rate: the dark electrons of a pixel are "
                "Poisson(σ²_dark · T · d), so in the averaged dark image it adds p/100 · σ²_dark · T to the offset's σ "
                "in quadrature, and it cancels from the PRNU's bright minus dark.")
    return [
        "* **Saturation.** The standard defines saturation as the step where the temporal variance peaks, and "
        "μ_e,sat = η μ_p,sat counts the photo-electrons there (the dark electrons are subtracted). camsim clips the "
        f"charge at the full well ({s.full_well_e:g} e⁻) and the ADC at {s.max_dn} DN = "
        f"{(s.max_dn - s.pedestal_dn) / k:.5g} e⁻{' above its pedestal' if s.pedestal_dn else ''}; "
        f"whichever comes first, less the dark electrons, the signal clips at {sat:.5g} e⁻. The variance peaks "
        f"before that, when the temporal noise (√μ_e ≈ {math.sqrt(sat):.0f} e⁻){prnu} can carry some pixels to the "
        f"clip, and the steps ({(m.photons[-1] - m.photons[-2]) * m.eta:.0f} e⁻ apart near the top) quantise where: "
        f"the standard finds {_fmt(recovered)} e⁻, {_percent(recovered / sat - 1 if recovered else None)} from the "
        f"clip. {search}",
        f"* **DSNU and PRNU.** Configured: the standard deviations of camsim's per-pixel {kind} maps{maps} camsim "
        "applies the PRNU gain to the photo-signal only (not to the dark electrons), which is what EMVA's PRNU "
        "measures (bright minus dark). Neither map has row or column structure, so the standard's row / column "
        f"components should be near 0.{dark_map}",
        "* **Quantum efficiency.** The light is monochromatic and the photon count μ_p is per pixel area in the "
        "exposure; camsim's photon statistics are exact Poisson electrons per pixel (`pixel` statistics), the "
        "standard's model.",
    ]


def _method(result: EmvaResult) -> list:
    """How the measurement was simulated and analysed."""
    m, s, d = result.measurement, result.measurement.sensor, result.details
    setup = m.setup
    stages = ", ".join(f"{stage} {'on' if getattr(s, stage) else 'off'}" for stage in
                       ("photon_noise", "dark_current", "saturation", "read_noise", "quantisation"))
    p = s.dsnu_dark_current_percent
    dark_dsnu = "" if p == 0 else f" (offset) and {p:g} % (dark current)"
    long_stack = "" if m.dark_stack_long is None else (
        f" L more dark frames at {m.dsnu_exposure_s:g} s ({m.dsnu_exposure_s / s.exposure_s:g} × the exposure time) "
        "give the DSNU at a second exposure time.")
    return [
        "## How the measurement was simulated",
        "",
        f"* **Sensor:** preset `{m.preset_name}`: K = {s.dn_per_electron:.4g} DN/e⁻ ({s.conversion_gain_v_per_e:g} "
        f"V/e⁻ × {s.analog_gain_dn_per_v:g} DN/V), {s.bits}-bit ADC, full well {s.full_well_e:g} e⁻, read noise "
        f"{s.read_noise_e:g} e⁻, dark current {_dark_current_text(s)} (G), exposure "
        f"{s.exposure_s:g} s, DSNU {s.dsnu_e:g} e⁻{dark_dsnu}, PRNU {s.prnu_percent:g} %, row noise "
        f"{s.row_noise_e:g} e⁻, "
        f"{s.read_noise_model} read noise, sensor seed {s.sensor_seed}; stages {stages}.",
        f"* **Light and QE:** monochromatic {setup.wavelength_nm:g} nm; the camera is `{m.camera}` at camsim's "
        f"physical scale (peak QE 0.5, 4.65 µm pixels), whose G channel has η = {m.eta:.4g} e⁻/photon there. A "
        "pixel collects η μ_p electrons on average (Poisson), μ_p being the photons on the pixel in the exposure.",
        f"* **Photon transfer series:** one exposure time, the irradiation varied in {len(m.photons)} steps: "
        f"{setup.steps} equally spaced up to {setup.overshoot:g} × the predicted saturation "
        f"(μ_p = {m.photons[-1]:.6g}) plus {setup.low_steps} in its lowest 5 %; two frames per step and two dark "
        "frames (the temporal variance comes from each pair's difference, so the fixed pattern cancels).",
        f"* **Spatial non-uniformity:** L = {setup.stack_frames} dark frames and L frames at "
        f"{setup.spatial_level * 100:g} % of saturation (μ_p = {m.photons_spatial:.6g}), averaged; the standard "
        f"subtracts the temporal variance left in the average (σ²_y.stack / L).{long_stack}",
        f"* **Frames:** {m.frames} frames of {setup.size} × {setup.size} pixels, G channel (`frame.digital_dn`, "
        f"in memory), method `poisson`, `pixel` statistics; temporal noise from seed {setup.seed} "
        "(`SeedSequence(seed, spawn_key=(kind, step, frame))`), the same sensor for every frame.",
        "* **Analysis:** `Data1288` on the loader's reduction (sum, pseudo-variance and mean difference of each pair "
        "or stack), then `Results1288`. K and R are fitted through the origin from the darkest step to 70 % of "
        f"saturation (μ_p {d['fit_photons'][0]:.6g} to {d['fit_photons'][1]:.6g}).",
        "",
    ]


def _dsnu_exposures(result: EmvaResult) -> list:
    """The DSNU at two exposure times and its split into the offset and the dark-current part (if measured)."""
    m, d = result.measurement, result.details
    if m.dark_stack_long is None:
        return []
    s, conf, rec = m.sensor, result.configured, result.recovered
    offset, rate = conf["dsnu_offset_e"], conf["dsnu_dark_current_e_per_s"]
    t1, t2 = d["dsnu_exposures_s"]
    rows = [(t1, rec["dsnu_e"], d["DSNU1288_DN"]), (t2, d["dsnu_long_e"], d["dsnu_long_dn"])]
    ratio = None if rec["dsnu_e"] is None or d["dsnu_long_e"] is None else d["dsnu_long_e"] / rec["dsnu_e"]
    realised = [f"{v:.4g} {unit} ({name})" for v, unit, name in
                ((m.realised_dsnu_e, "e⁻", "offset"), (m.realised_dark_dsnu_e_per_s, "e⁻/s", "dark-current rate"))
                if v is not None]
    lines = [
        "## DSNU at two exposure times: the offset and the dark-current part",
        "",
        "An offset DSNU (`dsnu_e`, a fixed charge per pixel) is the same at every exposure time; a DSNU of the "
        "dark-current rate (`dsnu_dark_current_percent` = p: each pixel collects Poisson(σ²_dark · T · d) dark "
        "electrons, d a fixed log-normal factor of mean 1 and σ p/100) grows ∝ T. Independent maps add in "
        "variance, so DSNU²(T) = σ_o² + (c T)² with σ_o = `dsnu_e` and c = p/100 · σ²_dark. The dark stack was "
        f"taken at two exposure times, {t1:g} s and {t2:g} s (L = {m.setup.stack_frames} frames each). At "
        f"{t1:g} s the DSNU is the reference implementation's DSNU₁₂₈₈; at {t2:g} s the standard's spatial data "
        "take no second exposure time, so it is the standard's own formula on that stack (the averaged image's "
        "spatial variance less the temporal variance left in it, σ²_y.stack / L, over the reference's K).",
        "",
        "| exposure time | configured √(σ_o² + (c T)²) | measured DSNU | measured DSNU in DN |",
        "|---|---|---|---|",
    ]
    lines += [f"| {t:g} s | {_fmt(math.hypot(offset, rate * t))} e⁻ | {_fmt(e)} e⁻ | {_fmt(dn)} DN |"
              for t, e, dn in rows]
    lines += [
        "",
        f"DSNU({t2:g} s) / DSNU({t1:g} s) = {_fmt(ratio)} (an offset DSNU alone: 1; a dark-current DSNU alone: "
        f"{t2 / t1:g}). Through the two points, the offset part is σ_o = {_fmt(rec['dsnu_offset_e'])} e⁻ (configured "
        f"{_fmt(offset)} e⁻) and the dark-current part c = {_fmt(rec['dsnu_dark_current_e_per_s'])} e⁻/s "
        f"(configured {_fmt(rate)} e⁻/s, i.e. {s.dsnu_dark_current_percent:g} % of "
        f"{s.dark_current_effective_e_per_s[CHANNEL] if s.dark_current else 0:g} e⁻/s, the dark current at the "
        "sensor's temperature)."
        + (" — : the estimate of that part's square came out negative, i.e. the part is below the estimators' "
           "noise." if rec["dsnu_offset_e"] is None or rec["dsnu_dark_current_e_per_s"] is None else "")
        + (f" The maps actually drawn have {' and '.join(realised)} over the analysed pixels." if realised else ""),
        "",
    ]
    return lines


def _dark_vs_temperature(result: EmvaResult) -> list:
    """The dark current at several temperatures and its doubling temperature (when measured)."""
    table = result.details.get("dark_current_vs_temperature")
    if not table:
        return []
    m, s = result.measurement, result.measurement.sensor
    t1, t2 = m.dark_vs_temperature[0]["exposures_s"]
    lines = [
        "## Dark current against the temperature",
        "",
        f"At each temperature (the sensor's `temperature_c` set to it) L = {m.setup.stack_frames} dark frames at "
        f"{t1:g} s and L at {t2:g} s; the dark current is the slope of the mean dark value against the exposure "
        "time, over the reference implementation's K (the offsets and the quantiser's half step cancel from the "
        "slope; its standard error is the spread of the frame means). The model: μ_I(ϑ) = μ_I,ref · "
        f"2^((ϑ − ϑ_ref)/T_d), μ_I,ref = {s.dark_current_e_per_s[CHANNEL]:g} e⁻/s at ϑ_ref = "
        f"{s.dark_current_reference_c:g} °C (`dark_current_reference_c`), T_d = {s.dark_current_doubling_c:g} °C "
        "(`dark_current_doubling_c`).",
        "",
        "| temperature | slope | dark current μ_I | configured μ_I |",
        "|---|---|---|---|",
    ]
    lines += [f"| {r['temperature_c']:g} °C | {_fmt(r['slope_dn_per_s'])} ± "
              f"{_fmt(r['slope_standard_error_dn_per_s'], 2)} DN/s | {_fmt(r['dark_current_e_per_s'])} e⁻/s | "
              f"{_fmt(r['configured_e_per_s'])} e⁻/s |"
              for r in table]
    clipped = [r for r in table if r["clip_bias"] is not None and abs(r["clip_bias"]) > 1e-3]
    if clipped:
        lines += ["", "The ADC's clip at 0 DN biases the slope (camsim's exact dark model: "
                  + ", ".join(f"{_percent(r['clip_bias'])} at {r['temperature_c']:g} °C" for r in clipped)
                  + "): the dark level is near 0 DN there; a pedestal (`pedestal_dn`) or a longer exposure keeps it "
                  "clear, as EMVA 1288 asks of the offset."]
    fit = result.recovered["dark_current_doubling_c"]
    lines += ["", f"The straight line log₂ μ_I = a + ϑ / T_d through these points (weighted least squares) gives "
              f"T_d = {_fmt(fit)} °C (configured {s.dark_current_doubling_c:g} °C)."
              + (" Hot pixels add their own dark current to the mean, which the configured μ_I leaves out."
                 if s.hot_pixels else ""), ""]
    return lines


def _other_results(result: EmvaResult) -> list:
    d = result.details
    return [
        "## Other results of the standard",
        "",
        "| quantity | value |",
        "|---|---|",
        f"| responsivity R | {_fmt(d['R_dn_per_photon'])} DN/photon |",
        f"| temporal dark noise σ_y.dark | {_fmt(d['sigma_y_dark_dn'])} DN |",
        f"| absolute sensitivity threshold μ_p,min / μ_e,min | {_fmt(d['u_p_min'])} photons / "
        f"{_fmt(d['u_e_min'])} e⁻ |",
        f"| saturation μ_p,sat | {_fmt(d['u_p_sat'], 6)} photons |",
        f"| SNR_max | {_fmt(d['SNR_max'])} |",
        f"| dynamic range | {_fmt(d['DR_dB'])} dB |",
        f"| linearity error (5–95 %) | {_fmt(d['LE_min_percent'], 3)} % to {_fmt(d['LE_max_percent'], 3)} % |",
        f"| DSNU₁₂₈₈ in DN | {_fmt(d['DSNU1288_DN'])} DN |",
        f"| DSNU₁₂₈₈ row / column / pixel | {_fmt(d['DSNU1288_row'])} / {_fmt(d['DSNU1288_col'])} / "
        f"{_fmt(d['DSNU1288_pixel'])} e⁻ |",
        f"| PRNU₁₂₈₈ row / column / pixel | {_fmt(d['PRNU1288_row'])} / {_fmt(d['PRNU1288_col'])} / "
        f"{_fmt(d['PRNU1288_pixel'])} % |",
        "",
        "— : undefined (the standard's variance estimate came out negative, i.e. the component is below its noise).",
        "",
    ]


def _plot_section(plots: dict) -> list:
    return [
        "## Plots",
        "",
        f"![Photon transfer and sensitivity]({plots['photon_transfer']})",
        "",
        "Left: the photon transfer curve, σ²_y − σ²_y.dark against μ_y − μ_y.dark (slope K); right: the sensitivity, "
        "μ_y − μ_y.dark against μ_p (slope R = η K). Dotted black: the configured camera.",
        "",
        f"![SNR]({plots['snr']})",
        "",
        "The temporal SNR of each step (from its pair of frames), the standard's model curves from the recovered "
        "parameters (temporal: 'Theoretical'; with DSNU and PRNU: 'Total SNR'), and (black) the temporal SNR of the "
        "configured camera, η μ_p / √(σ_d² + σ_q²/K² + η μ_p).",
        "",
        f"![DSNU and PRNU histograms]({plots['nonuniformity']})",
        "",
        "The logarithmic histograms of the averaged dark image (DSNU) and of the high-pass filtered bright − dark "
        "image (PRNU), with the standard's normal model.",
        "",
    ]


def markdown(result: EmvaResult, plots: dict) -> str:
    """The report: the comparison table, where the model and the standard differ, the method, the plots."""
    lines = _summary(result)
    lines += ["## Where camsim's model and the standard's assumptions meet", ""]
    lines += _dark_notes(result) + _saturation_and_pattern_notes(result) + [""] + _dsnu_exposures(result)
    lines += _dark_vs_temperature(result)
    lines += _method(result) + _other_results(result) + _plot_section(plots)
    return "\n".join(lines)


def write_outputs(result: EmvaResult, out) -> dict:
    """Write ``OUT/emva.json``, the plots and ``OUT/report.md``; returns {name: path}."""
    out = Path(out)
    make_folder(out)
    with emva1288_numpy_shims():  # the reference plots call into emva1288's routines
        plots = _plots(result, out)
    write_json_atomic(out / "emva.json", result.comparison())
    write_text_atomic(out / "report.md", markdown(result, plots))
    return {"report": out / "report.md", "json": out / "emva.json", **{k: out / v for k, v in plots.items()}}
