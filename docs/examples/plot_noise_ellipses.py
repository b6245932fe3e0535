"""
Chromaticity noise ellipses as the light falls
==============================================

``camsim analyze`` measures, for each patch of the ColorChecker, the chromaticity xy of every pixel (camera RGB →
CIE XYZ by the paper's Eq. 15 matrix) and the principal-component ellipse of that cloud: its centre, its 1 σ
semi-axes and its inclination. This example renders the chart under D65 at three intensity factors F, writes the
frames, analyses them from the files with :func:`camsim.analyse_paths`, and draws six patches' ellipses on the
CIE 1931 xy diagram.

What to notice: as F falls, each ellipse grows (about two to three times from F = 1 to F = 0.1 here: the sizes are
printed below), and its centre moves along a straight line towards the camera's black point — the chromaticity
of the dark level. The paper's analysis (and ``camsim analyze`` by default) subtracts no black level, so the dark
current, the same at every F, weighs more and more in each pixel as the light falls and drags every colour
towards it; ``camsim analyze --subtract-black`` removes that drift, not the noise.
"""

# %%
# Render, write and analyse
# -------------------------
# The frames go to a temporary folder; :func:`camsim.analyse_paths` reads them back from the files (DNG and JSON
# sidecar), exactly as the ``camsim analyze`` command does, and returns one record per frame.
import tempfile
from pathlib import Path

import colour  # colour-science, a camsim dependency: the spectral locus of the xy diagram
import matplotlib.pyplot as plt
import numpy as np

import camsim
from camsim.colour.colorimetry import camera_to_xyz_matrix  # the one import from below camsim's top level

scene = camsim.load_scene("macbeth_26").replace(width=360, height=240)
factors = [1.0, 0.3, 0.1]
with tempfile.TemporaryDirectory() as folder:
    for factor in factors:
        frame, info = camsim.scene_frame(scene, "D65", factor, seed=3)
        camsim.write_frame(Path(folder), f"d65_f{factor:g}", frame, info)
    results = camsim.analyse_paths([Path(folder)], progress=False)
results = {r["intensity_factor"]: r for r in sorted(results, key=lambda r: -r["intensity_factor"])}

# %%
# Each frame's record has a list of patches; each patch has its ellipse (``center_x``, ``center_y``,
# ``semi_major_xy``, ``semi_minor_xy``, ``angle_deg``) and ``size_xy`` = √(a² + b²).
chosen = ["blue", "green", "red", "yellow", "magenta", "cyan"]
for factor, result in results.items():
    sizes = {p["name"]: p["size_xy"] for p in result["patches"] if p["name"] in chosen}
    print(f"F = {factor:g}: ellipse size " + ", ".join(f"{n} {s:.4f}" for n, s in sizes.items()))

# %%
# The camera's black point
# ------------------------
# Where the analysis subtracts no black level (the paper's protocol, and ``camsim analyze``'s default), the dark
# level is part of every pixel: its own chromaticity, the frame's expected black level through the same camera →
# XYZ matrix (Eq. 15's, from the camera's absolute Qe, the same in every frame), is where the colours drift to as
# the light falls.
sensor = scene.sensor
matrix = camera_to_xyz_matrix(frame.expected.qe, scene.grid.wavelengths_nm, sensor.dn_per_electron, method="paper")
black_xyz = matrix @ sensor.black_level_dn
black_xy = black_xyz[:2] / black_xyz.sum()


def outline(patch, n=121):
    """The 1 σ ellipse of one patch record, as x and y arrays."""
    t, theta = np.linspace(0, 2 * np.pi, n), np.radians(patch["angle_deg"])
    u, v = patch["semi_major_xy"] * np.cos(t), patch["semi_minor_xy"] * np.sin(t)
    return (patch["center_x"] + u * np.cos(theta) - v * np.sin(theta),
            patch["center_y"] + u * np.sin(theta) + v * np.cos(theta))


# %%
# Draw them
# ---------
cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].values
locus = cmfs[:, :2] / cmfs.sum(axis=1, keepdims=True)
fig, ax = plt.subplots(figsize=(7, 7), layout="constrained")
ax.plot(np.r_[locus[:, 0], locus[0, 0]], np.r_[locus[:, 1], locus[0, 1]], color="0.5", lw=1, label="spectral locus")
styles = {1.0: "-", 0.3: "--", 0.1: ":"}
colours = dict(zip(chosen, ["tab:blue", "tab:green", "tab:red", "goldenrod", "tab:pink", "tab:cyan"]))
for factor, result in results.items():
    for patch in result["patches"]:
        if patch["name"] in colours and patch["ellipse_status"] == "ok":
            ax.plot(*outline(patch), styles[factor], color=colours[patch["name"]], lw=1.5)
            ax.plot(patch["center_x"], patch["center_y"], "o", ms=3, color=colours[patch["name"]])
for name, colour_name in colours.items():  # each patch's centre from F = 1 towards the black point
    start = next(p for p in results[1.0]["patches"] if p["name"] == name)
    ax.plot([start["center_x"], black_xy[0]], [start["center_y"], black_xy[1]], color=colour_name, lw=0.6,
            alpha=0.5)
ax.plot(*black_xy, "kX", ms=10, label="camera black point")
for name, colour_name in colours.items():
    ax.plot([], [], "-", color=colour_name, label=f"patch: {name}")
for factor, style in styles.items():
    ax.plot([], [], style, color="k", label=f"1 σ ellipse at F = {factor:g}")
ax.set(xlim=(0.15, 0.55), ylim=(0.12, 0.52), aspect="equal", xlabel="CIE 1931 x", ylabel="CIE 1931 y",
       title="Noise ellipses of six ColorChecker patches under D65\n(Table I sensor, 360 × 240, no black subtraction)")
ax.grid(alpha=0.3)
ax.legend(fontsize=8, loc="upper left")
plt.show()
