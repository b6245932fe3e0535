"""
The ColorChecker under four lights, clean and noisy
===================================================

camsim's reference scene, ``macbeth_26``, is the 24-patch ColorChecker (N. Ohta's spectra) seen by a Nikon 5100
through the paper's Table I sensor (8 bits). Here it is rendered under four of its 26 named illuminants — daylight
D65, tungsten A, the cool-white fluorescent FL2 and the high-pressure discharge lamp HP1 — and developed into sRGB
previews: on top the frame's clean layer (each pixel's expected value, no noise) at F = 0.01, below it the noisy
frames at F = 0.1 and F = 0.01 (a tenth and a hundredth of the scene's light).

What to notice: the previews are white-balanced, as a camera's auto white balance would do, so the clean chart
looks nearly the same under every light, although the electrons it gives differ from light to light: the camera
is anchored once, on D65. Every preview is scaled up by 1 / F to the brightness of F = 1, which amplifies the
noise with the signal. At F = 0.01 the white patch gives 41, 71 and 60 electrons a pixel in R, G and B under D65
(8.5 in B under HP1), while Table I's dark current adds 195–230 electrons a pixel in one second under every light:
the preview subtracts its mean, but its shot noise (about 15 electrons) stays, and the colours dissolve into it —
first the dark patches, and most under HP1, whose weak blue channel white balance multiplies the most.
"""

# %%
# Render the frames
# -----------------
# ``camsim.load_scene`` reads a built-in scene by name; ``replace`` makes the frame small (240 × 160 pixels), so
# that the twelve frames take about a second. ``camsim.scene_frame`` draws one frame under one light at one
# intensity factor F, with a fixed seed: the same call gives the same frame.
import dataclasses

import matplotlib.pyplot as plt

import camsim
from camsim.render.preview import preview_srgb  # the one import from below camsim's top level

scene = camsim.load_scene("macbeth_26").replace(width=240, height=160)
illuminants = ["D65", "A", "FL2", "HP1"]
rows = ["clean, F = 0.01", "noisy, F = 0.1", "noisy, F = 0.01"]

previews = {}
for light in illuminants:
    for factor in (0.1, 0.01):
        frame, info = camsim.scene_frame(scene, light, factor, seed=1)
        # exposure="auto" is a gain of 1 / F: every F is shown as bright as F = 1, its noise amplified with it
        previews[light, f"noisy, F = {factor:g}"] = preview_srgb(frame, info, exposure="auto")
        if factor == 0.01:
            # the clean layer (what the EXR stores as clean.R, G, B): each pixel's expected value, unquantised
            clean = dataclasses.replace(frame, noisy_dn=frame.clean_dn(), digital_dn=None)
            previews[light, "clean, F = 0.01"] = preview_srgb(clean, info, exposure="auto")

# %%
# Show them side by side
# ----------------------
# One column per light. A preview subtracts the black level from the digital numbers, maps camera RGB to XYZ by
# a least-squares fit on the chart's patches, white-balances to D65 and encodes sRGB; ``camsim render --preview``
# writes the same pictures (without the 1 / F gain).
fig, axes = plt.subplots(len(rows), len(illuminants), figsize=(10, 6.6), layout="constrained")
for column, light in enumerate(illuminants):
    for row, name in enumerate(rows):
        ax = axes[row, column]
        ax.imshow(previews[light, name], interpolation="nearest")
        ax.set_xticks([])
        ax.set_yticks([])
        if row == 0:
            ax.set_title(light)
        if column == 0:
            ax.set_ylabel(name)
fig.suptitle("macbeth_26 (Table I sensor, 240 × 160) under four lights: sRGB previews, gain 1 / F")
plt.show()
