"""One frame of a dataset, rendered and written: :func:`render_files` (in a worker process, or in this one).

The scene, its radiance, the camera and the DNG colour tags are cached per process, since consecutive frames of a
spec share them.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from camsim.camera import load_camera
from camsim.dataset.spec import FrameSpec
from camsim.frame_files import write_frame
from camsim.radiance import scene_radiance
from camsim.rawcolour import as_shot_neutral, color_matrix_xyz_to_camera
from camsim.render import frame_expected, frame_seed_sequence, render_frame
from camsim.run import patch_xyz, scene_frame_info
from camsim.scene import load_scene

__all__ = ["render_files"]


@lru_cache(maxsize=16)
def _scene(path: str):
    return load_scene(path)


@lru_cache(maxsize=64)
def _radiance(path: str, width: int, height: int, illuminant: str):
    return scene_radiance(_scene(path).replace(width=width, height=height), illuminant)


@lru_cache(maxsize=16)
def _camera(name: str, grid, basis: str, base_dir):
    return load_camera(name, grid, basis, base_dir)


_colour_cache: dict = {}


def _colour_tags(illuminant, qe, grid):
    """ColorMatrix1 and AsShotNeutral of a frame (they depend on Qe and the illuminant, not on F)."""
    key = (illuminant, qe.tobytes(), grid)
    if key not in _colour_cache:
        if len(_colour_cache) > 256:
            _colour_cache.clear()
        _colour_cache[key] = (color_matrix_xyz_to_camera(qe, grid), as_shot_neutral(illuminant, qe, grid))
    return _colour_cache[key]


def render_files(frame: FrameSpec, directory: Path, threads: int = 1) -> dict:
    """Render one frame and write ``<id>.dng`` (if quantised), ``<id>.exr`` and ``<id>.json`` into ``directory``.

    The same steps as :func:`camsim.run.render_scene` for one frame, with the frame's own seed. Returns the file
    names by kind (``dng`` None without quantisation).
    """
    base = _scene(frame.scene_path)
    scene = base.replace(width=frame.width, height=frame.height, illuminants=(frame.illuminant,),
                         intensity_factors=(frame.intensity_factor,), **frame.scene_changes)
    if frame.sensor_overrides:
        scene = scene.with_sensor(**frame.sensor_overrides)
    sensor = scene.sensor
    radiance = _radiance(frame.scene_path, frame.width, frame.height, frame.illuminant)
    camera = _camera(scene.camera, scene.grid, scene.sensitivity_basis, scene.base_dir)
    factor = frame.intensity_factor
    expected = frame_expected(radiance, camera, scene.scale, sensor, factor, scene.statistics, scene.grid)
    matrix, neutral = _colour_tags(frame.illuminant, expected.qe, scene.grid)
    rendered = render_frame(
        radiance.labels, expected, sensor, statistics=scene.statistics, method=scene.method,
        rng=frame_seed_sequence(frame.seed, frame.illuminant, factor), workers=threads, tolerance=scene.tolerance,
    )
    info = scene_frame_info(scene, radiance, camera, frame.illuminant, factor, frame.seed, matrix, neutral,
                            patch_xyz(radiance, scene.grid))
    return write_frame(Path(directory), frame.id, rendered, info)
