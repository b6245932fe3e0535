"""
Speed against accuracy of the sampling methods
==============================================

camsim draws each pixel's charge by one of five methods (``--method``): ``poisson`` (one exact Poisson draw per
pixel and channel, the default), ``table`` (exact too: each spectrum's law as an alias table), ``spectral`` (one
draw per wavelength bin, 101 times the work), ``gaussian`` (one moment-matched normal: fast, wrong at low counts)
and ``auto`` (the Gaussian only where its distance to the exact law is within a tolerance). This example renders
the ColorChecker under D65 with each method at intensity factors F from 1 down to 10⁻⁵, for the paper's Table I
sensor and for the ideal sensor (photon noise only, whose counts fall below one electron at low F), and puts each
method's speed against its error.

The error is measured against the exact law of the digital numbers, computed analytically: per patch and channel
the pmf of the pixel's value (``camsim.sensor.dn_law.dn_pmf``: Poisson charge, full well, read noise, gain, ADC), its
total variation (TV) distance to the frame's histogram, divided by the TV that an exact sampler with as many
pixels shows on average (``camsim.sensor.dn_law.expected_tv``), averaged over the 72 patch-channels. An exact sampler
sits at 1 whatever the frame size.

What to notice: with the ideal sensor ``gaussian`` leaves the exact law by orders of magnitude as the counts
fall, while ``auto`` switches to exact draws there and stays at 1. With Table I every method sits near 1 at this
size: the Gaussian's error there (a KS distance of at most 0.0065 per pixel) is smaller than what a small frame
can resolve. **The frames here are small** (400 × 300 pixels, 2 438 a patch; ``spectral`` 160 × 120, 255 a
patch), so that the example runs in a few seconds: the speeds of so small a frame include fixed costs (and vary
with the machine that builds these pages), and the errors are resolved far less finely than at the full sizes of
camsim's benchmarks — with Table I the Gaussian's mean TV is 1.1–1.3 times its floor at 1000 × 700 and 2 to 5
times at 4000 × 3000, where χ² tests reject it in most patch-channels (see :doc:`../benchmarks`).
"""

# %%
# Render each method at each F and measure it
# -------------------------------------------
import time

import matplotlib.pyplot as plt
import numpy as np

import camsim
from camsim.sensor.dn_law import dn_pmf, expected_tv, sample_distances  # the one import from below camsim's top level

FACTORS = (1.0, 0.1, 0.01, 1e-3, 1e-4, 1e-5)
METHODS = ("poisson", "table", "gaussian", "auto", "spectral")
SIZES = {"spectral": (160, 120)}  # the others: 400 × 300
SPECTRAL_FACTORS = (1.0, 1e-4)  # spectral is slow: two F only
BORDER = 3  # pixels left out at each patch's edge, as camsim analyze does


def patch_values(frame, rect, channel):
    """A patch's integer values in one channel: its digital numbers, or (unquantised) its values floored to 1 e⁻."""
    x, y, w, h = rect
    window = np.s_[channel, y + BORDER : y + h - BORDER, x + BORDER : x + w - BORDER]
    if frame.digital_dn is not None:
        return frame.digital_dn[window].ravel()
    return np.floor(frame.noisy_dn[window]).ravel()


LAWS = {}  # the exact laws depend on the sensor, F, the patch and the channel, not on the method: computed once


def error_ratio(frame, rects, preset, factor):
    """Mean over patches × channels of TV to the exact law, over the mean of an exact sampler's E[TV]."""
    ex, sensor, tv, floor = frame.expected, frame.sensor, [], []
    quantised = frame.digital_dn is not None
    for index, rect in enumerate(rects):
        for c in range(3):
            values = patch_values(frame, rect, c)
            key = (preset, factor, index, c)
            if key not in LAWS:
                LAWS[key] = dn_pmf(ex.signal_e[index, c] + ex.dark_e[c], sensor.dn_per_electron,
                                   sensor.read_noise_e if sensor.read_noise else 0.0,
                                   sensor.full_well_e if sensor.saturation else None,
                                   sensor.bits if quantised else None, sensor.pedestal_dn if quantised else 0)
            law = LAWS[key]
            tv.append(sample_distances(law, values)[0])
            floor.append(expected_tv(law, values.size))
    return float(np.mean(tv) / np.mean(floor))


chart = camsim.load_scene("macbeth_26")
lits = {size: camsim.light_scene(chart.replace(width=size[0], height=size[1]), "D65")  # the chart under D65
        for size in {(400, 300), *SIZES.values()}}
rows = []
for preset in ("paper-table1", "ideal"):
    sensor = camsim.PRESETS[preset]
    for method in METHODS:
        width, height = SIZES.get(method, (400, 300))
        lit = lits[width, height]
        if method in ("gaussian", "auto"):  # warm-up, untimed: they tabulate their KS distances once
            camsim.make_frame(lit, sensor, 1.0, method=method, rng=0, workers=2)
        for factor in SPECTRAL_FACTORS if method == "spectral" else FACTORS:
            seconds = []
            for repeat in range(1 if method == "spectral" else 2):  # the faster of 2 renders
                start = time.perf_counter()
                frame = camsim.make_frame(lit, sensor, factor, method=method, rng=1 + repeat, workers=2)
                seconds.append(time.perf_counter() - start)
            rows.append({"preset": preset, "method": method, "F": factor,
                         "mpix_per_s": width * height / 1e6 / min(seconds),
                         "error": error_ratio(frame, lit.radiance.patch_rects, preset, factor)})
for row in rows:
    print(f"{row['preset']:13s} {row['method']:9s} F = {row['F']:<7g} {row['mpix_per_s']:7.2f} MP/s  "
          f"TV / floor {row['error']:.2f}")

# %%
# The chart
# ---------
# One curve per method across F (marker size: F, large at F = 1). Left of the grey band is an exact sampler.
colours = {"spectral": "tab:purple", "poisson": "tab:blue", "table": "tab:orange", "gaussian": "tab:red",
           "auto": "tab:green"}
fig, axes = plt.subplots(1, 2, figsize=(13, 6), sharex=True, sharey=True, layout="constrained")
for ax, preset in zip(axes, ("paper-table1", "ideal")):
    for method in METHODS:
        mine = [r for r in rows if r["preset"] == preset and r["method"] == method]
        xs, ys = [r["error"] for r in mine], [r["mpix_per_s"] for r in mine]
        size = "160 × 120" if method == "spectral" else "400 × 300"
        ax.plot(xs, ys, "-", color=colours[method], lw=2.5 if method == "auto" else 1.2,
                alpha=0.6 if method == "auto" else 1.0, label=f"{method} ({size})")
        ax.scatter(xs, ys, s=[8 + 14 * (np.log10(r["F"]) + 5) for r in mine], color=colours[method], zorder=3)
    ax.axvline(1.0, color="0.4", lw=4, alpha=0.3, label="an exact sampler (TV = its floor)")
    name = {"paper-table1": "Table I sensor (paper-table1)", "ideal": "ideal sensor (photon noise only)"}[preset]
    ax.set(xscale="log", yscale="log", title=f"{name}: error against speed",
           xlabel="error: mean TV to the exact law / an exact sampler's E[TV] (72 patch-channels)",
           ylabel="speed: megapixels per second (2 threads)")
    ax.grid(alpha=0.3, which="both")
axes[0].set_xlim(0.5, 1000)
axes[1].tick_params(labelleft=True)
fig.legend(handles=axes[0].get_legend_handles_labels()[0], loc="outside lower center", ncol=6, fontsize=9,
           frameon=False)
fig.suptitle("Sampling methods on the ColorChecker under D65, pixel statistics, F = 1 … 1e-5 (marker size: F)\n"
             "small frames, so that this example runs in seconds: the benchmarks' chart is at 1000 × 700 and "
             "4000 × 3000")
plt.show()
