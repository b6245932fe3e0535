"""Rendering a whole scene: every illuminant × intensity factor, into frame files and a manifest."""

from __future__ import annotations

from pathlib import Path

from tqdm import tqdm

from camsim.camera import load_camera
from camsim.errors import CamsimError
from camsim.frame_files import frame_stem, write_frame
from camsim.io.atomic import write_json_atomic
from camsim.io.dng import MIN_SIZE
from camsim.methods import get_method
from camsim.pipeline import light_scene, scene_frame
from camsim.scene import Scene
from camsim.spectra import illuminant_spd

MANIFEST_NAME = "manifest.json"


def check_scene(scene: Scene) -> None:
    """Fail early, before any frame is written, on names that do not resolve and sizes that cannot be written."""
    get_method(scene.method)
    for name in scene.illuminants:
        illuminant_spd(name, scene.grid)
    if not scene.source.has_own_size and scene.sensor.quantisation and min(scene.width, scene.height) < MIN_SIZE:
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
    frames = []
    jobs = [(ill, f) for ill in scene.illuminants for f in scene.intensity_factors]
    bar = tqdm(total=len(jobs), desc=f"rendering {scene.name}", unit="frame", disable=not progress)
    lit = None
    for illuminant, factor in jobs:
        if lit is None or lit.illuminant != illuminant:  # jobs come grouped by illuminant: lit once each
            lit = light_scene(scene, illuminant, camera)
        frame, info = scene_frame(scene, illuminant, factor, lit=lit, camera=camera, workers=workers)
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
