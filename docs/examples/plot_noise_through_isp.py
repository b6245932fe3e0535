"""
Noise through a camera ISP, stage by stage
==========================================

A raw denoiser sees the sensor's noise: independent from pixel to pixel, its variance set by the signal. A
denoiser of sRGB images sees that noise after the camera's image signal processor: scaled by the white balance,
spread over neighbouring pixels by demosaicing, mixed between channels by the colour matrix and bent by the tone
curve. camsim knows each pixel's noise-free value (the frame's clean layer), so the noise at every stage is known
exactly: the clean layer is developed through the same ISP as the noisy frame, and the difference at each stage is
the noise (:func:`camsim.isp.noise.noise_through_isp`, what ``camsim develop --noise-report`` writes).

This example develops two low-light frames of camsim's ``sony-a7s2`` camera preset at ISO 3200 (a 14-bit RGGB
Bayer sensor: 3.06 DN/e⁻, read noise 1.3 e⁻, row noise 0.15 e⁻) with the default ISP (black level,
as-shot white balance, Malvar 2004 demosaicing, camera → sRGB matrix, sRGB tone curve): a flat field at about
16 e⁻ per green pixel, and a ColorChecker at F = 0.01 (80 e⁻ in the strongest channel of the perfect white). Both
are developed with one digital gain, the one that puts the chart's white patch at 0.8.

What to notice: up to the white balance the noise is white — no correlation between neighbours (within the
sampling error) and a flat noise power spectrum; the white balance scales noise and signal alike. Demosaicing
makes each output pixel a weighted sum of its neighbours: the correlation between horizontal neighbours jumps to
about 0.25–0.5, and the spectrum becomes low-pass (several times the white-noise power at low frequencies, less
than half at the highest). The colour matrix, with its negative off-diagonal terms, raises the noise relative to
the signal and the correlation further. The tone curve roughly halves the relative noise: to first order the
noise is f′(μ) times the linear noise, and in the power segment of the sRGB curve f′(μ) μ / f(μ) is 0.44 at white
(μ = 1), 0.46 at μ = 0.2 and 0.51 at μ = 0.05 (camsim's tests check this, and the other stages, against closed
forms). In the darkest patches the noisy values reach below zero, and in the white patch above the white level:
there the curve clips them (the fraction of clipped pixels is printed below).
"""

# %%
# Render the two frames
# ---------------------
# The frames are drawn without the ADC's rounding (``quantisation=False``): their numbers are the signal before
# the ADC, so that noisy − clean is the sensor's noise alone. ``clean_dn()`` is each pixel's expected value (three
# planes); a Bayer frame's clean mosaic (``clean_mosaic``) takes at each site its own colour's plane.
import matplotlib.pyplot as plt
import matplotlib.ticker
import numpy as np

import camsim
from camsim import isp
from camsim.isp.noise import clean_mosaic, noise_through_isp


def mosaic_pair(scene, factor):
    """The frame's noisy mosaic, its clean mosaic, and the ISP's facts about it."""
    frame, info = camsim.scene_frame(scene, "D65", factor, seed=1)
    clean = clean_mosaic(frame.clean_dn(), frame.sensor.cfa)
    return frame.noisy_dn[0], clean, isp.facts_from_info(frame, info), info


camera = dict(preset_name="sony-a7s2", iso=3200)
chart = camsim.load_scene("macbeth_26").replace(width=360, height=240, illuminants=("D65",), **camera)
chart = chart.with_sensor(quantisation=False)
flat = camsim.load_scene("flat").replace(width=256, height=256, **camera).with_sensor(quantisation=False)

chart_noisy, chart_clean, chart_facts, chart_info = mosaic_pair(chart, 0.01)
flat_noisy, flat_clean, flat_facts, _ = mosaic_pair(flat, 0.002)

# one gain for both: the chart's white patch at 0.8 (its clean green, normalised, from the ISP's own stage)
names = list(chart_info.patch_names)
x, y, w, h = chart_info.patch_rects[names.index("white 9.5 (.05 D)")]
normalised = isp.develop_stages(chart_clean, chart_facts, isp.IspSettings(gain=1.0))["srgb_linear"]
settings = isp.IspSettings(gain=0.8 / float(normalised[1, y + 8:y + h - 8, x + 8:x + w - 8].mean()))
print(f"digital gain {settings.gain:.1f}; ISP: {settings.record()}")

# %%
# The noise at each stage
# -----------------------
# The flat field is one region (the whole frame less a 4-pixel margin, where the demosaicing kernels reach past
# the edge); the chart's regions are its six neutral patches. Each row of the result is one region, stage,
# channel and CFA site (``site="all"``: every pixel of the channel).
neutrals = ["white 9.5 (.05 D)", "neutral 8 (.23 D)", "neutral 6.5 (.44 D)", "neutral 5 (.70 D)",
            "neutral 3.5 (1.05 D)", "black 2 (1.5 D)"]
regions = {name: chart_info.patch_rects[names.index(name)] for name in neutrals}
flat_rows = noise_through_isp(flat_noisy, flat_clean, flat_facts, settings)
chart_rows = noise_through_isp(chart_noisy, chart_clean, chart_facts, settings, regions=regions)
stages = list(isp.STAGE_NAMES)


def series(rows, key, region, channel="G"):
    picked = {r["stage"]: r[key] for r in rows if r["region"] == region and r["channel"] == channel
              and r["site"] == "all"}
    return np.array([np.nan if picked[s] is None else picked[s] for s in stages], dtype=float)


print(f"{'stage':>15}  flat G: noise std ({'unit':>11}), std / signal, corr. with the right neighbour")
for stage in stages:
    row = next(r for r in flat_rows if r["stage"] == stage and r["channel"] == "G" and r["site"] == "all")
    print(f"{stage:>15}  {row['std']:10.4g} ({row['unit']:>11}), {100 * row['std'] / row['signal']:5.1f} %, "
          f"{row['corr_h']:+.3f}")

for name in neutrals:
    row = next(r for r in chart_rows if r["region"] == name and r["stage"] == "toned" and r["channel"] == "G"
               and r["site"] == "all")
    print(f"{name:>20}: sRGB value {row['signal']:.3f}, noise std {row['std']:.4f}, "
          f"{100 * row['clipped_fraction']:.1f} % of the noisy pixels clipped")

# %%
# One figure
# ----------
# Left: the green channel's noise relative to its clean signal at each stage (in the mosaic stages, over the
# green sites; the raw signal counted above the black level), for the flat field and the six neutral patches.
# Middle: the correlation between horizontal neighbours. Right: the flat field's noise power spectrum (radial
# profile, relative to white noise of the same variance) before the ISP (the normalised mosaic, each channel's
# sites) and after it (the sRGB image).
fig, (ax_std, ax_corr, ax_nps) = plt.subplots(1, 3, figsize=(15, 4.8), layout="constrained")
index = np.arange(len(stages))
greys = plt.cm.copper(np.linspace(0.95, 0.05, len(neutrals)))
for name, colour in zip(neutrals, greys):
    rel = series(chart_rows, "std", name) / series(chart_rows, "signal", name)
    ax_std.plot(index, 100 * rel, "o-", color=colour, ms=4, lw=1, label=f"chart: {name}")
    ax_corr.plot(index, series(chart_rows, "corr_h", name), "o-", color=colour, ms=4, lw=1)
ax_std.plot(index, 100 * series(flat_rows, "std", "frame") / series(flat_rows, "signal", "frame"), "s-",
            color="tab:green", lw=2.5, label="flat field")
for channel, colour in (("R", "tab:red"), ("G", "tab:green"), ("B", "tab:blue")):
    ax_corr.plot(index, series(flat_rows, "corr_h", "frame", channel), "s-", color=colour, lw=2.5,
                 label=f"flat field, {channel}")
for ax in (ax_std, ax_corr):
    ax.set_xticks(index, stages, rotation=30, ha="right")
    ax.grid(alpha=0.3)
ax_std.set(yscale="log", ylabel="noise std / clean signal (%), green", title="Relative noise per stage")
ax_std.yaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
ax_std.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
ax_std.set_yticks([2, 5, 10, 20, 50, 100])
ax_std.set_ylim(2, 120)
ax_std.legend(fontsize=7, ncol=2, loc="lower left")
ax_corr.axhline(0, color="0.3", lw=0.8)
ax_corr.set(ylabel="correlation with the right neighbour", title="Correlation between neighbours per stage")
ax_corr.plot([], [], "o-", color=greys[2], ms=4, lw=1, label="chart patches, G (colours as on the left)")
ax_corr.legend(fontsize=7, loc="upper left")
for stage, style in (("normalised", ":"), ("toned", "-")):
    for channel, colour in (("R", "tab:red"), ("G", "tab:green"), ("B", "tab:blue")):
        row = next(r for r in flat_rows if r["stage"] == stage and r["channel"] == channel and r["site"] == "all")
        ax_nps.plot(row["nps_frequency"], row["nps"], style, marker="o", ms=3, color=colour,
                    label=f"{channel}, {'raw (normalised mosaic)' if stage == 'normalised' else 'sRGB (toned)'}")
ax_nps.axhline(1, color="0.3", lw=0.8)
ax_nps.set(xlabel="radial frequency (cycles per pixel)", ylabel="NPS / white noise of the same variance",
           title="Flat field: noise power spectrum, raw vs sRGB", xlim=(0, 0.5), ylim=(0, None))
ax_nps.grid(alpha=0.3)
ax_nps.legend(fontsize=7)
fig.suptitle("sony-a7s2 at ISO 3200, low light: noise through the ISP (noise = developed noisy − developed clean)")
plt.show()
