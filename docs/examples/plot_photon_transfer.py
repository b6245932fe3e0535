"""
Photon transfer curve of a simulated Sony A7S II
================================================

The photon transfer curve is the basic measurement of a camera's noise (EMVA 1288): uniformly lit frames at a
series of exposures, and for each the mean of the digital numbers against their temporal variance (from the
difference of two frames). Below saturation a linear camera gives a straight line, σ²_y = K (μ_y − μ_y.dark) +
σ²_y.dark, whose slope is the overall system gain K (DN per electron) and whose intercept is the dark noise.

This example simulates the measurement of camsim's ``sony-a7s2`` camera preset at ISO 3200 (a 14-bit Bayer sensor
with the published figures of that camera: read noise, gain and full well, and its black level of 512 DN), with
``camsim.emva.run``, the function behind ``camsim emva``, at a small size, and analyses it with the reference
implementation of the standard (the ``emva1288`` package). The measured points are drawn against the closed form
of the configured camera.

What to notice: the points lie on the line over three decades of signal, from about 20 DN (a few electrons) to
saturation, on the shot-noise slope (variance ∝ mean); below them the line levels off at the dark noise, which the
dark frames measure. The gain K that the standard fits agrees with the configured one to within 1 % (printed
below). At ISO 3200 the ADC's top, not the full well (166 000 e⁻), is where the curve ends:
14 bits at 3.06 DN/e⁻ hold about 5 200 e⁻, and past it the variance collapses.
"""

# %%
# Simulate and analyse the measurement
# ------------------------------------
# ``camsim.sensor_preset`` gives the camera's sensor at an ISO. ``camsim.emva.EmvaSetup`` sets the size of the
# measurement: a 192 × 192 region (its 96 × 96 first-G sites are analysed), 30 exposure steps from dark to 1.2 × the
# predicted saturation plus 40 in its lowest 5 % (down to 1/800 of saturation), two frames each, and 8-frame stacks
# for the spatial non-uniformities (the command's defaults are 256 × 256, 50 + 10 steps and 100-frame stacks).
import matplotlib.pyplot as plt
import numpy as np

import camsim
from camsim.emva import EmvaSetup, run  # the one import from below camsim's top level

sensor = camsim.sensor_preset("sony-a7s2", 3200)
setup = EmvaSetup(size=192, steps=30, low_steps=40, stack_frames=8, seed=0)
# The preset has no PRNU: the reference's PRNU is then the square root of a difference of two variances that the
# noise can make negative (it reports NaN, with a numpy warning, silenced here).
with np.errstate(invalid="ignore"):
    result = run(sensor=sensor, setup=setup)
for key, row in result.comparison().items():
    if key in ("K_dn_per_e", "dark_noise_e", "qe"):
        print(f"{key}: configured {row['configured']:.4g}, recovered {row['recovered']:.4g} "
              f"({100 * row['relative_error']:+.2f} %)")

# %%
# The measured points and the closed form
# ---------------------------------------
# The reference implementation's temporal data: per exposure the mean ``u_y`` and temporal variance ``s2_y`` of
# the digital numbers, and those of the dark frames. The line is the standard's linear model with the configured
# camera's K and dark noise σ_d (read noise and row noise, in electrons), plus the 1/12 DN² of quantisation,
# up to the predicted saturation.
temporal = result.results.temporal
mean = temporal["u_y"] - temporal["u_ydark"]
variance = temporal["s2_y"]
k, dark_noise_e = result.configured["K_dn_per_e"], result.configured["dark_noise_e"]
saturation_dn = k * result.measurement.predicted_saturation_e
line_mean = np.geomspace(1.0, saturation_dn, 300)
line_variance = k * line_mean + (k * dark_noise_e) ** 2 + 1 / 12
fit_k = result.recovered["K_dn_per_e"]
low, high = result.details["fit_indices"]

fig, axes = plt.subplots(1, 2, figsize=(12, 5), layout="constrained")
for ax, scale in zip(axes, ("linear", "log")):
    ax.plot(line_mean, line_variance, "-", color="0.2", lw=1.2,
            label=f"configured camera: K = {k:.3g} DN/e⁻, σ_d = {dark_noise_e:.2f} e⁻")
    ax.plot(mean, variance, "o", ms=5, mfc="none", color="tab:blue", label="measured (EMVA 1288 pairs)")
    ax.plot(mean[low:high + 1], variance[low:high + 1], "o", ms=5, color="tab:blue",
            label=f"points of the standard's fit: K = {fit_k:.3g} DN/e⁻")
    ax.axvline(saturation_dn, color="tab:red", ls=":", label="predicted saturation (top of the 14-bit ADC)")
    ax.set(xscale=scale, yscale=scale, xlabel="mean signal μ_y − μ_y.dark (DN)",
           ylabel="temporal variance σ²_y (DN²)")
    ax.grid(alpha=0.3, which="both")
axes[0].set_title("Photon transfer, linear axes")
axes[1].set_title("The same, log axes: dark-noise floor and shot-noise slope")
axes[1].axhline(temporal["s2_ydark"][0], color="tab:green", ls="--", lw=1,
                label=f"dark frames: σ²_y.dark = {temporal['s2_ydark'][0]:.1f} DN² (measured)")
axes[1].set_xlim(left=1)
axes[0].legend(fontsize=8, loc="upper left")
axes[1].legend(handles=axes[1].get_lines()[-1:], fontsize=8, loc="upper left")
fig.suptitle("sony-a7s2 at ISO 3200 (first G sites of a 192 × 192 region, 550 nm light)")
plt.show()
