"""
Signal-to-noise ratio against the light level
=============================================

The SNR of a patch is a power ratio, signal² / variance in DN (the paper's Eq. 14). ``camsim analyze`` reports it
twice for every patch and channel: measured on the pixels — (patch mean − black level)² / the pixels' variance —
and from the model terms recorded in the frame's sidecar (Eqs. 13–14: k² (S + D + σ²_read) plus the 1/12 DN² a
quantiser adds). This example renders the ColorChecker under D65 at eight intensity factors F, measures the SNR of
four neutral patches with :func:`camsim.analyse_paths` (points), and draws the model's SNR as a continuous line
in F.

What to notice: the points lie on the lines from F = 1 down to F = 0.003. At high F the SNR of a bright patch grows
nearly in proportion to F (shot noise: SNR = S for S electrons); as the light falls, Table I's dark current (195–230
electrons a pixel in one second, the same at every F) dominates the variance and the SNR falls as F², twice as
steeply on the log axes. Where the SNR falls below about 0.01 (the black patch at the lowest F), the measurement
scatters about the line: with n pixels a patch, the measured SNR's own spread is about 2 √(SNR / n) + 1 / n.
"""

# %%
# Render and measure
# ------------------
# Eight frames at F from 1 down to 0.003, written to a temporary folder and analysed from the files.
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import camsim
from camsim.analysis.snr import snr_model  # the one import from below camsim's top level

scene = camsim.load_scene("macbeth_26").replace(width=480, height=320)
factors = np.geomspace(1.0, 0.003, 8)
with tempfile.TemporaryDirectory() as folder:
    for factor in factors:
        frame, info = camsim.scene_frame(scene, "D65", float(factor), seed=5)
        camsim.write_frame(Path(folder), f"d65_{factor:.4g}", frame, info)
    results = camsim.analyse_paths([Path(folder)], progress=False)

patches = ["white 9.5 (.05 D)", "neutral 6.5 (.44 D)", "neutral 3.5 (1.05 D)", "black 2 (1.5 D)"]
channel = 1  # G
measured = {name: [] for name in patches}
for result in results:
    for patch in result["patches"]:
        if patch["name"] in measured:
            snr = patch["channels"][channel]["snr_empirical"]
            measured[patch["name"]].append((result["intensity_factor"], snr))
print("pixels measured per patch:", results[0]["patches"][0]["channels"][channel]["n_pixels"])

# %%
# The model as a line
# -------------------
# The same Eqs. 13–14 that the analysis evaluates for each frame, here at 200 values of F: the expected signal S
# and dark charge D of each patch come from the scene lit by D65 (:func:`camsim.light_scene`), the read noise and
# gain from the sensor.
sensor = scene.sensor
lit = camsim.light_scene(scene, "D65")
names = lit.radiance.patch_names
dense = np.geomspace(1.0, 0.002, 200)
model = {name: [] for name in patches}
for factor in dense:
    expected = lit.expected(sensor, float(factor), "pixel")
    for name in patches:
        i = names.index(name)
        terms = snr_model(expected.signal_e[i, channel], expected.dark_e[channel], expected.signal_var_e2[i, channel],
                          sensor.read_noise_e, sensor.dn_per_electron, quantisation=True)
        model[name].append(float(terms.snr))

# %%
# Draw them
# ---------
fig, ax = plt.subplots(figsize=(7.5, 5.5), layout="constrained")
for name, colour in zip(patches, ["0.0", "tab:blue", "tab:orange", "tab:red"]):
    ax.plot(dense, model[name], "-", color=colour, lw=1.2, label=f"{name}: model (Eqs. 13–14)")
    f, snr = zip(*[(f, s) for f, s in measured[name] if s is not None and s > 0])
    ax.plot(f, snr, "o", color=colour, ms=6, mfc="none", mew=1.5, label=f"{name}: measured on the pixels")
ax.set(xscale="log", yscale="log", xlabel="intensity factor F (light level relative to the scene's 100 cd/m² white)",
       ylabel="SNR, G channel (signal² / variance, power ratio)",
       title="SNR against F: macbeth_26 under D65, Table I sensor, 480 × 320")
ax.grid(alpha=0.3, which="both")
ax.legend(fontsize=8, loc="lower right")
plt.show()
