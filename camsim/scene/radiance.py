"""From a scene and one illuminant to spectral radiance: a label map plus K spectra.

The scene's source gives its spectra (:mod:`camsim.scene.sources`): a chart K = patches + 1 (the surround), a synthetic
target its K (:mod:`camsim.scene.sources.target`), a cube one per pixel, so the renderer has a single path; but nothing
per pixel is spectral for a chart or a target. Reflectances are
lit by the illuminant and scaled to the scene's luminance; an emissive source keeps its own radiance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError
from camsim.light.photons import scale_to_luminance
from camsim.light.rates import FactoredSpectra
from camsim.light.spectra import cmfs_on_grid, illuminant_spd
from camsim.scene.regions import check_regions, region_weights
from camsim.scene.scene_file import Scene


@dataclass(frozen=True)
class SceneRadiance:
    """Spectral radiance of a scene under one illuminant at F = 1.

    Attributes
    ----------
    labels : numpy.ndarray, shape (H, W), unsigned integer
        Index into ``radiance`` for every pixel.
    radiance : numpy.ndarray or camsim.light.rates.FactoredSpectra, shape (K, N)
        Spectral radiance of each distinct spectrum (factored for an image's colours). Unit: W / (m² sr nm).
    white_radiance : numpy.ndarray, shape (N,)
        Radiance of the perfect white (reflectance 1) under the illuminant at the scene's luminance, the absolute
        scale's reference. Unit: W / (m² sr nm).
    patch_names : list of str
        Names of the chart patches (empty for a cube).
    patch_rects : list of (x, y, w, h)
        Patch rectangles in pixels (empty for a cube).
    reflectance_set : str
        Name of the reflectance set or cube file.
    surround : bool
        Whether the spectrum after the patches is a chart's surround.
    target : dict or None
        A synthetic target's geometry (:class:`camsim.scene.sources.SourceSpectra`), for the sidecar.
    patch_weights : tuple or None
        For patches that are the scene file's regions (:mod:`camsim.scene.regions`): per patch ``(indices, counts)``,
        the spectra inside its rectangle and their pixel counts. None: patch i is spectrum i (a chart's patches).
    recovery : dict or None
        An image's RGB → spectrum recovery and what fell outside its gamut
        (:class:`camsim.scene.sources.SourceSpectra`), for the sidecar.
    """

    labels: np.ndarray
    radiance: np.ndarray
    white_radiance: np.ndarray
    patch_names: list
    patch_rects: list
    reflectance_set: str
    surround: bool = True
    target: dict | None = None
    patch_weights: tuple | None = None
    recovery: dict | None = None


def scene_radiance(scene: Scene, illuminant: str) -> SceneRadiance:
    """Spectral radiance of ``scene`` under ``illuminant`` (a colour-science name), at F = 1."""
    grid = scene.grid
    ybar = cmfs_on_grid(grid)[1]
    spd = illuminant_spd(illuminant, grid)
    white = scale_to_luminance(spd, ybar, grid.step_nm, scene.luminance_cd_m2)
    source = scene.source.spectra(grid, scene.width, scene.height)
    refl = source.spectra
    if source.kind == "radiance":  # emissive: its own absolute scale
        radiance = refl
    elif scene.normalisation == "chart":
        radiance = refl * white
    elif isinstance(refl, FactoredSpectra) and scene.source.table == "image":
        raise CamsimError("normalisation 'per-spectrum' scales each spectrum to the luminance: it applies to charts "
                          "and cubes, not to an image, whose pixels keep their relative brightness")
    else:  # each spectrum its own scale: dense rows (a cube's too: H · W · N values)
        refl = np.asarray(refl, dtype=np.float64)
        radiance = np.empty_like(refl)
        for k, row in enumerate(refl):
            lit = row * spd
            if not np.any(lit > 0):
                raise CamsimError(f"spectrum {k} is black under {illuminant}: it cannot be scaled to a luminance")
            radiance[k] = scale_to_luminance(lit, ybar, grid.step_nm, scene.luminance_cd_m2)
    if not scene.regions:
        return SceneRadiance(source.labels, radiance, white, source.patch_names, source.patch_rects, source.name,
                             source.surround, source.target, recovery=source.recovery)
    if source.patch_names:
        raise CamsimError(f"[[region]] is for scenes without patches of their own (an image, a cube, dead leaves): "
                          f"this scene's source already has {len(source.patch_names)} patches, which analyze measures")
    height, width = source.labels.shape
    check_regions(scene.regions, width, height, "scene")
    weights = tuple(region_weights(source.labels, region.rect) for region in scene.regions)
    return SceneRadiance(source.labels, radiance, white, [r.name for r in scene.regions],
                         [r.rect for r in scene.regions], source.name, False, source.target, weights,
                         recovery=source.recovery)
