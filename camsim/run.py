"""Rendering a whole scene: every illuminant × intensity factor, into frame files and a manifest."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
from tqdm import tqdm

from camsim.camera import load_camera
from camsim.errors import CamsimError
from camsim.frame_files import FrameInfo, frame_stem, write_frame
from camsim.io.atomic import write_json_atomic
from camsim.io.dng import MIN_SIZE
from camsim.photons import KM_LM_PER_W
from camsim.radiance import scene_radiance
from camsim.rawcolour import as_shot_neutral, color_matrix_xyz_to_camera
from camsim.render import ALL_METHODS, frame_expected, frame_seed_sequence, render_frame
from camsim.scene import Scene
from camsim.spectra import cmfs_on_grid, illuminant_spd

MANIFEST_NAME = "manifest.json"


def patch_xyz(radiance, grid) -> np.ndarray:
    """CIE 1931 XYZ of each patch's light at F = 1, shape (patches, 3); Y is the luminance in cd/m²."""
    n = len(radiance.patch_names)
    return KM_LM_PER_W * grid.step_nm * (radiance.radiance[:n] @ cmfs_on_grid(grid).T)


def frame_colour_tags(radiance, qe, illuminant: str, grid):
    """ColorMatrix1, AsShotNeutral and the patches' XYZ at F = 1: what a frame's files need besides its pixels."""
    return (color_matrix_xyz_to_camera(qe, grid), as_shot_neutral(illuminant, qe, grid), patch_xyz(radiance, grid))


def scene_frame_info(scene: Scene, radiance, camera, illuminant: str, factor: float, seed: int, matrix, neutral,
                     xyz_at_f1) -> FrameInfo:
    """The :class:`FrameInfo` of one frame of ``scene`` (shared by ``camsim render`` and ``camsim dataset``).

    ``matrix``, ``neutral``: ColorMatrix1 and AsShotNeutral; ``xyz_at_f1``: the patches' XYZ at F = 1.
    """
    return FrameInfo(
        scene=scene.name,
        illuminant=illuminant,
        intensity_factor=factor,
        seed=seed,
        photon_statistics=scene.statistics,
        method=scene.method,
        camera=camera.name,
        sensitivity_basis=camera.sensitivity_basis,
        reflectances=radiance.reflectance_set,
        wavelengths_nm=scene.grid.wavelengths_nm,
        luminance_cd_m2=scene.luminance_cd_m2,
        normalisation=scene.normalisation,
        scale={"kind": scene.scale.kind, **dataclasses.asdict(scene.scale)},
        patch_names=radiance.patch_names,
        patch_rects=radiance.patch_rects,
        color_matrix1=matrix,
        as_shot_neutral=neutral,
        patch_xyz=factor * xyz_at_f1,
    )


def check_scene(scene: Scene) -> None:
    """Fail early, before any frame is written, on names that do not resolve and sizes that cannot be written."""
    if scene.method not in ALL_METHODS:
        raise CamsimError(f"unknown sampling method {scene.method!r}; methods: {', '.join(ALL_METHODS)}")
    for name in scene.illuminants:
        illuminant_spd(name, scene.grid)
    if scene.chart is not None and scene.sensor.quantisation and min(scene.width, scene.height) < MIN_SIZE:
        raise CamsimError(f"frame {scene.width}x{scene.height} is smaller than {MIN_SIZE}x{MIN_SIZE} pixels, "
                          "which raw readers (LibRaw) refuse")


def render_scene(scene: Scene, out_dir: str | Path, *, workers: int | None = None, progress: bool = True,
                 preview: bool = False) -> dict:
    """Render every frame of ``scene`` into ``out_dir`` and write ``manifest.json`` there.

    With ``preview``, each frame also gets an sRGB PNG (:mod:`camsim.preview`), listed in its ``files``.

    Returns
    -------
    dict
        The manifest: the scene name and, per frame, illuminant, F, seed and file paths relative to ``out_dir``.
    """
    check_scene(scene)
    out_dir = Path(out_dir)
    camera = load_camera(scene.camera, scene.grid, scene.sensitivity_basis, scene.base_dir)
    sensor = scene.sensor
    frames = []
    jobs = [(ill, f) for ill in scene.illuminants for f in scene.intensity_factors]
    bar = tqdm(total=len(jobs), desc=f"rendering {scene.name}", unit="frame", disable=not progress)
    current = None
    for illuminant, factor in jobs:
        if current != illuminant:  # jobs come grouped by illuminant: its radiance is computed once
            current, radiance = illuminant, scene_radiance(scene, illuminant)
            colour_tags = None
        expected = frame_expected(radiance, camera, scene.scale, sensor, factor, scene.statistics, scene.grid)
        if colour_tags is None:  # Qe depends on the illuminant (anchor), not on F
            colour_tags = frame_colour_tags(radiance, expected.qe, illuminant, scene.grid)
        frame = render_frame(
            radiance.labels, expected, sensor, statistics=scene.statistics, method=scene.method,
            rng=frame_seed_sequence(scene.seed, illuminant, factor), workers=workers, tolerance=scene.tolerance,
        )
        info = scene_frame_info(scene, radiance, camera, illuminant, factor, scene.seed, *colour_tags)
        files = write_frame(out_dir, frame_stem(scene.name, illuminant, factor), frame, info, preview=preview)
        frames.append({
            "illuminant": illuminant,
            "intensity_factor": factor,
            "seed": scene.seed,
            "photon_statistics": scene.statistics,
            "method": scene.method,
            "files": files,
        })
        bar.update()
    bar.close()
    manifest = {"scene": scene.name, "frames": frames}
    write_json_atomic(out_dir / MANIFEST_NAME, manifest)
    return manifest
