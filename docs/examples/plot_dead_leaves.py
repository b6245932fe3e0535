"""
A dead-leaves crop as the light falls
=====================================

The built-in ``dead_leaves`` scene is the texture target of camera-noise and denoiser evaluation: opaque disks of
radius density ∝ r⁻³ (2–100 pixels), each a ColorChecker reflectance or one of two greys, under D65, seen by the
``emva-12bit`` sensor (12 bits, 0.4 DN/e⁻, read noise 3 e⁻). This example renders it at four intensity factors F,
from full light down to F = 0.003, and shows the same crop of each frame, developed to sRGB with a gain of
1 / F so that every frame is shown as bright as F = 1.

What to notice: at F = 1 the texture is clean down to the smallest disks; at F = 0.01 the small disks and the
edges between similar colours are lost in the noise, and at F = 0.003 only the largest disks remain. Above each
crop are the frame's mean signal in the G channel (DN above the black level) and the noise that
:func:`camsim.analyse_paths` measured in the whole frame — the standard deviation of noisy − clean, from the
frame's EXR, which stores each pixel's expected value beside it — with the noise the model predicts for that frame
from its sidecar alone. In DN the noise falls with F, but far more slowly than the signal: shot noise falls as √F,
and below it lie the read noise and the dark current, which do not fall at all.
"""

# %%
# Render, write and measure
# -------------------------
# A 400 × 300 frame per F (the disks keep their sizes in pixels, so a smaller frame is a smaller field of view,
# not a coarser texture), written to a temporary folder, analysed from the files, and developed to sRGB.
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import camsim
from camsim.render.preview import preview_srgb  # the one import from below camsim's top level

scene = camsim.load_scene("dead_leaves").replace(width=400, height=300)
factors = [1.0, 0.1, 0.01, 0.003]
crop = np.s_[60:240, 80:320]  # rows, columns: 180 × 240 pixels from the middle of the frame
previews = {}
with tempfile.TemporaryDirectory() as folder:
    for factor in factors:
        frame, info = camsim.scene_frame(scene, "D65", factor, seed=2)
        camsim.write_frame(Path(folder), f"dead_leaves_f{factor:g}", frame, info)
        previews[factor] = preview_srgb(frame, info, exposure="auto")[crop]
    results = camsim.analyse_paths([Path(folder)], progress=False)

# %%
# The frame statistics of each frame: per channel, the residual noisy − clean, its variance measured
# (``residual_var_dn2``) and predicted by the model (``predicted_var_dn2``), in DN².
noise = {}
for result in sorted(results, key=lambda r: -r["intensity_factor"]):
    green = result["frame_statistics"][1]
    noise[result["intensity_factor"]] = (np.sqrt(green["residual_var_dn2"]), np.sqrt(green["predicted_var_dn2"]),
                                         green["mean_dn"])
    print(f"F = {result['intensity_factor']:g}: G mean {green['mean_dn']:.1f} DN above black, noise σ "
          f"{noise[result['intensity_factor']][0]:.2f} DN measured, {noise[result['intensity_factor']][1]:.2f} DN "
          "predicted")

# %%
# Show the crops
# --------------
fig, axes = plt.subplots(1, len(factors), figsize=(13, 3.6), layout="constrained")
for ax, factor in zip(axes, factors):
    measured, predicted, mean = noise[factor]
    ax.imshow(previews[factor], interpolation="nearest")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(f"F = {factor:g}\nG: mean {mean:.0f} DN above black,\nnoise σ {measured:.1f} DN "
                 f"(model {predicted:.1f} DN)", fontsize=10)
fig.suptitle("dead_leaves under D65, emva-12bit sensor: a 240 × 180 crop, sRGB with gain 1 / F")
plt.show()
