"""Rendering a whole scene: every illuminant × intensity factor, into frame files and a manifest."""

from __future__ import annotations

from pathlib import Path

from tqdm import tqdm

from camsim.core.errors import CamsimError
from camsim.io.dng import MIN_SIZE
from camsim.io.exr import DEFAULT_EXR_COMPRESSION, check_exr_compression
from camsim.io.output_folder import output_folder
from camsim.light.spectra import illuminant_spd
from camsim.methods import get_method
from camsim.render.frame_files import frame_stem, write_frame
from camsim.render.frame_manifest import MANIFEST_NAME, FrameManifest
from camsim.render.pipeline import light_scene, scene_frame
from camsim.scene.scene_file import Scene
from camsim.sensor.camera import load_camera


def check_scene(scene: Scene) -> None:
    """Fail early, before any frame is written, on names that do not resolve (or make unsafe file names:
    :mod:`camsim.core.names`) and sizes that cannot be written. A raw scene is checked by
    :func:`camsim.render.raw_render.check_raw_scene`."""
    if scene.optics is not None:  # an [optics] table: pixel statistics, no raw scene (camsim.render.optics)
        from camsim.render.optics import check_optics_scene

        check_optics_scene(scene)
    check_map_files(scene)
    if scene.source.table == "raw":
        from camsim.render.raw_render import check_raw_scene

        return check_raw_scene(scene)
    get_method(scene.method)
    for name in scene.illuminants:
        illuminant_spd(name, scene.grid)
        for factor in scene.intensity_factors:  # every file name the frames will have
            frame_stem(scene.name, name, factor)
    reference = getattr(scene.scale, "reference_illuminant", None)  # the anchor's light (AnchorScale)
    if reference is not None:
        illuminant_spd(reference, scene.grid)
    if scene.sensor.quantisation:  # a DNG will be written: an image's or a cube's size is its own (its header's)
        own = scene.source.has_own_size
        width, height = scene.source.own_size() if own else (scene.width, scene.height)
        if min(width, height) < MIN_SIZE:
            where = f"{scene.source.table} scene's frame" if own else "frame"
            raise CamsimError(f"{where} {width}x{height} is smaller than {MIN_SIZE}x{MIN_SIZE} pixels, which raw "
                              "readers (LibRaw) refuse")


def check_map_files(scene: Scene) -> None:
    """Load the sensor's map files (cached for the frames) and check them, their shape against the frame's and
    their values against their parameters' bounds, before a frame's warning is said: a bad map is then the one line
    a render prints."""
    from camsim.sensor.fixed_pattern import load_pixel_map
    from camsim.sensor.params import MAP_FILE_PARAMS

    paths = {name: getattr(scene.sensor, name) for name in MAP_FILE_PARAMS}
    if not any(paths.values()):
        return
    size = scene.source.own_size() if scene.source.has_own_size else (scene.width, scene.height)
    for name, path in paths.items():
        if path is not None:
            load_pixel_map(path, scene.sensor, (size[1], size[0]), name)


def scene_warnings(scene: Scene) -> list[str]:
    """Refuse a scene with a frame that cannot be drawn, before anything is drawn or written, and return its warnings
    (one line each): :func:`camsim.render.pipeline.check_frames` of a spectral scene,
    :func:`camsim.render.raw_render.raw_frame_warnings` of a raw scene (no spectra, no light: the file's electrons)."""
    if scene.source.table == "raw":
        from camsim.render.raw_render import raw_frame_warnings

        if scene.sequence is None:
            return raw_frame_warnings(scene)
        from camsim.render.raw_sequence import check_raw_sequence, raw_sequence_warnings

        warnings = raw_frame_warnings(scene)
        check_raw_sequence(scene)
        return warnings + raw_sequence_warnings(scene)
    from camsim.render.pipeline import check_frames  # (looked up now: the tests replace it)

    return check_frames(scene)


def render_scene(scene: Scene, out_dir: str | Path, *, workers: int | None = None, progress: bool = True,
                 preview: bool = False, device: str = "cpu", exr_compression: str = DEFAULT_EXR_COMPRESSION,
                 warn=None) -> dict:
    """Render every frame of ``scene`` into ``out_dir``, keeping ``manifest.json`` there up to date.

    The folder is made ready and held before any work (:func:`camsim.io.output_folder.output_folder`: created,
    checked writable, locked against other camsim runs, swept of temporaries left by killed runs). Each frame
    commits on its own (:func:`camsim.render.frame_files.write_frame`) and the manifest follows each commit, adding to
    the frames of earlier runs in the folder (:class:`camsim.render.frame_manifest.FrameManifest`). With ``preview``,
    each frame also gets an sRGB PNG (:mod:`camsim.render.preview`), listed in its ``files``. ``device`` draws the
    frames on the CPU (default) or a device (:func:`camsim.render.pipeline.make_frame`; checked before the folder is
    touched). ``exr_compression``: a lossless name of :data:`camsim.io.exr.EXR_COMPRESSIONS` (checked before anything is
    written). ``warn``, if given, is called with one line (no prefix) per frame of an image scene whose colours
    fell partly outside the recovery method's gamut (:func:`camsim.scene.sources.image.recovery_warning`: the share of
    the pixels; the sidecar's ``recovery`` records it either way).

    Returns
    -------
    dict
        The manifest: per frame of the folder, scene, illuminant, F, seed and file paths relative to ``out_dir``.
    """
    if scene.optics is not None:  # refused before the folder is touched (camsim.render.optics)
        from camsim.render.optics import check_optics_scene

        check_optics_scene(scene)
    if scene.sequence is not None and scene.source.table == "raw":  # a raw's electrons moved: render.raw_sequence
        from camsim.render.raw_sequence import check_raw_sequence, render_raw_sequence

        check_raw_sequence(scene)
        if preview or device != "cpu":
            raise CamsimError("a sequence's frames are drawn per pixel on the CPU and have no preview")
        return render_raw_sequence(scene, out_dir, workers=workers, progress=progress,
                                   exr_compression=exr_compression)
    if scene.sequence is not None:  # frames with camera motion: camsim.render.sequence
        from camsim.render.sequence import check_sequence_scene, render_sequence

        check_sequence_scene(scene)
        if preview or device != "cpu":
            raise CamsimError("a sequence's frames are drawn per pixel on the CPU and have no preview")
        check_scene(scene)
        return render_sequence(scene, out_dir, workers=workers, progress=progress, exr_compression=exr_compression)
    if scene.source.table == "raw":  # drawn from the file's electrons, not from spectra
        from camsim.render.raw_render import render_raw_scene

        if preview or device != "cpu":
            raise CamsimError("a raw scene's frames are drawn on the CPU and have no preview (develop them with "
                              "camsim develop)")
        return render_raw_scene(scene, out_dir, workers=workers, progress=progress, exr_compression=exr_compression)
    check_scene(scene)
    check_exr_compression(exr_compression)
    if device != "cpu":
        from camsim.render.backends import check_device, device_method

        check_device(device)
        device_method(scene.method, scene.statistics)
    with output_folder(out_dir) as out_dir:
        camera = load_camera(scene.camera, scene.grid, scene.sensitivity_basis, scene.base_dir)
        manifest = FrameManifest(out_dir, scene.name)
        if manifest.frames or (out_dir / MANIFEST_NAME).exists():
            manifest.write()  # from the start, the manifest lists the folder's committed frames (earlier runs')
        jobs = [(ill, f) for ill in scene.illuminants for f in scene.intensity_factors]
        bar = tqdm(total=len(jobs), desc=f"rendering {scene.name}", unit="frame", disable=not progress)
        lit = None
        with bar, manifest.kept_on_failure():
            for illuminant, factor in jobs:
                if lit is None or lit.illuminant != illuminant:  # jobs come grouped by illuminant: lit once each
                    lit = light_scene(scene, illuminant, camera)
                frame, info = scene_frame(scene, illuminant, factor, lit=lit, camera=camera, workers=workers,
                                          device=device)
                stem = frame_stem(scene.name, illuminant, factor)
                manifest.withdraw(stem)
                files = write_frame(out_dir, stem, frame, info, preview=preview, exr_compression=exr_compression)
                manifest.commit(info, files)
                if warn is not None and info.recovery is not None:
                    from camsim.scene.sources.image import recovery_warning

                    line = recovery_warning(info.recovery, info.reflectances)
                    if line is not None:
                        warn(f"{stem}: {line}")
                bar.update()
    return manifest.as_dict()
