"""From a scene and one illuminant to spectral radiance: a label map plus K spectra.

A chart gives K = patches + 1 (the surround) spectra. A cube is held the same way, with one label per pixel,
so the renderer has a single path; but nothing per pixel is spectral for a chart.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camsim.errors import CamsimError
from camsim.photons import scale_to_luminance
from camsim.scene import Scene
from camsim.spectra import cmfs_on_grid, illuminant_spd, reflectance_set


@dataclass(frozen=True)
class SceneRadiance:
    """Spectral radiance of a scene under one illuminant at F = 1.

    Attributes
    ----------
    labels : numpy.ndarray, shape (H, W), unsigned integer
        Index into ``radiance`` for every pixel.
    radiance : numpy.ndarray, shape (K, N)
        Spectral radiance of each distinct spectrum. Unit: W / (m² sr nm).
    white_radiance : numpy.ndarray, shape (N,)
        Radiance of the perfect white (reflectance 1) under the illuminant at the scene's luminance, the absolute
        scale's reference. Unit: W / (m² sr nm).
    patch_names : list of str
        Names of the chart patches (empty for a cube).
    patch_rects : list of (x, y, w, h)
        Patch rectangles in pixels (empty for a cube).
    reflectance_set : str
        Name of the reflectance set or cube file.
    """

    labels: np.ndarray
    radiance: np.ndarray
    white_radiance: np.ndarray
    patch_names: list
    patch_rects: list
    reflectance_set: str


def scene_radiance(scene: Scene, illuminant: str) -> SceneRadiance:
    """Spectral radiance of ``scene`` under ``illuminant`` (a colour-science name), at F = 1."""
    grid = scene.grid
    ybar = cmfs_on_grid(grid)[1]
    spd = illuminant_spd(illuminant, grid)
    white = scale_to_luminance(spd, ybar, grid.step_nm, scene.luminance_cd_m2)
    if scene.chart is not None:
        names, refl = reflectance_set(scene.chart.reflectances, grid, scene.base_dir)
        geometry = scene.chart.geometry
        if len(names) != geometry.n_patches:
            raise CamsimError(
                f"reflectance set {scene.chart.reflectances!r} has {len(names)} spectra but the chart is "
                f"{geometry.columns} × {geometry.rows}"
            )
        refl = np.vstack([refl, np.full((1, grid.size), scene.chart.surround_reflectance)])
        labels = geometry.label_map(scene.width, scene.height)
        rects = geometry.rects(scene.width, scene.height)
        label = scene.chart.reflectances
    else:
        cube = load_cube(scene.cube.path, grid.size)
        height, width = cube.shape[:2]
        labels = np.arange(height * width, dtype=np.uint32).reshape(height, width)
        refl, names, rects = cube.reshape(-1, grid.size), [], []
        label = scene.cube.path.name
        if scene.cube.kind == "radiance":
            return SceneRadiance(labels, refl, white, names, rects, label)
    if scene.normalisation == "chart":
        radiance = refl * white
    else:
        radiance = np.empty_like(refl)
        for k, row in enumerate(refl):
            lit = row * spd
            if not np.any(lit > 0):
                raise CamsimError(f"spectrum {k} is black under {illuminant}: it cannot be scaled to a luminance")
            radiance[k] = scale_to_luminance(lit, ybar, grid.step_nm, scene.luminance_cd_m2)
    return SceneRadiance(labels, radiance, white, names, rects, label)


def load_cube(path, n_bins: int) -> np.ndarray:
    """Load a hyperspectral cube (``.npy``, H × W × N, float) and check it against the scene grid."""
    try:
        cube = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise CamsimError(f"cube file not found: {path}") from None
    except (OSError, ValueError, EOFError) as exc:
        raise CamsimError(f"cannot read cube file {path}: {exc}") from None
    if cube.ndim != 3:
        raise CamsimError(f"cube {path} must be H × W × N, got shape {cube.shape}")
    if cube.shape[2] != n_bins:
        raise CamsimError(
            f"cube {path} has {cube.shape[2]} wavelength bins but the scene's grid has {n_bins}: "
            "set [spectral] to the cube's grid"
        )
    cube = np.asarray(cube, dtype=np.float64)
    if not np.all(np.isfinite(cube)):
        raise CamsimError(f"cube {path} contains NaN or infinite values")
    if np.any(cube < 0):
        raise CamsimError(f"cube {path} has negative values")
    return cube
