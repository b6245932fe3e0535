"""One frame of a dataset, rendered (:func:`render_frame`) and written as files (:func:`render_files`), in a worker
process or in this one.

The scene, the camera and the lit scene (radiance, Qe and the DNG colour tags) are cached per process, since
consecutive frames of a spec share them.
"""

from __future__ import annotations

import dataclasses
from functools import lru_cache
from pathlib import Path

from camsim.dataset.spec_parts import FrameSpec
from camsim.io.exr_compression import DEFAULT_EXR_COMPRESSION
from camsim.render.frame_files import write_frame
from camsim.render.pipeline import light_scene, scene_frame
from camsim.scene.scene_file import load_scene
from camsim.sensor.camera import load_camera

__all__ = ["render_frame", "render_files", "render_burst", "render_burst_files"]


@lru_cache(maxsize=16)
def _scene(path: str):
    return load_scene(path)


@lru_cache(maxsize=16)
def _camera(name: str, grid, basis: str, base_dir):
    return load_camera(name, grid, basis, base_dir)


@lru_cache(maxsize=64)
def _lit(path: str, width: int, height: int, illuminant: str, camera: str, source=None):
    """The scene file ``path`` (its source replaced by ``source``, if given) lit and seen by ``camera``."""
    scene = _scene(path).replace(width=width, height=height, camera=camera)
    if source is not None:
        scene = scene.replace(source=source)
    return light_scene(scene, illuminant, _camera(camera, scene.grid, scene.sensitivity_basis, scene.base_dir))


def render_frame(frame: FrameSpec, threads: int = 1):
    """Render one frame of a dataset in memory: its :class:`camsim.render.frame.Frame` and :class:`FrameInfo`.

    :func:`camsim.render.pipeline.scene_frame`, as for ``camsim render``, with the frame's own seed. A frame of an
    ``[images]`` spec has the scene file's source replaced by its crop of an image, lit as a reflectance image;
    its flips mirror the lit scene's label map (every pixel keeps its colour's spectrum).
    """
    scene, lit, camera = _frame_scene(frame)
    return scene_frame(scene, frame.illuminant, frame.intensity_factor, seed=frame.seed, lit=lit, camera=camera,
                       workers=threads)


def _frame_scene(frame: FrameSpec) -> tuple:
    """The frame's scene (its parameters applied), its lit scene and its camera."""
    base = _scene(frame.scene_path)
    image = frame.image
    source = None if image is None else image.source()
    if source is not None:
        base = base.replace(source=source)
    scene = base.replace(width=frame.width, height=frame.height, illuminants=(frame.illuminant,),
                         intensity_factors=(frame.intensity_factor,), **frame.scene_changes)
    if frame.sensor_overrides:
        scene = scene.with_sensor(**frame.sensor_overrides)
    camera = _camera(scene.camera, scene.grid, scene.sensitivity_basis, scene.base_dir)
    lit = _lit(frame.scene_path, frame.width, frame.height, frame.illuminant, scene.camera, source)
    if image is not None and (image.flip_horizontal or image.flip_vertical):
        lit = dataclasses.replace(lit, labels=image.flip(lit.labels))
    return scene, lit, camera


def render_burst(frame: FrameSpec, threads: int = 1):
    """Render a burst item (:attr:`FrameSpec.burst`) in memory, as ``camsim render`` renders a ``[sequence]``
    (:func:`camsim.render.sequence.render_sequence_frames`, with the item's seed: its motion and every frame's
    noise): yield ``(index, name, frame, info, extra)`` for its reference (``index`` ``"ref"``, ``name``
    ``<id>_ref``) and then each frame (``<id>_fNNN``), with its :class:`FrameInfo` and its sequence keys."""
    from camsim.render.pipeline import frame_sensor, scene_frame_info
    from camsim.render.sequence import frame_digits, render_sequence_frames, sequence_frame_info

    scene, lit, camera = _frame_scene(frame)
    scene = scene.replace(seed=frame.seed)
    factor = frame.intensity_factor
    sensor = frame_sensor(scene, lit, factor)
    base = dataclasses.replace(scene_frame_info(scene, lit, camera.name, factor, frame.seed), method="poisson")
    digits = frame_digits(scene.sequence.frames)
    for index, rendered, extra in render_sequence_frames(scene, lit, sensor, factor, workers=threads):
        name, info = sequence_frame_info(frame.id, index, digits, extra, base)
        yield index, name, rendered, info, extra


def render_burst_files(frame: FrameSpec, directory: Path, threads: int = 1,
                       exr_compression: str = DEFAULT_EXR_COMPRESSION,
                       srgb: str = "none") -> tuple[dict, dict, dict | None]:
    """Render a burst item (:func:`render_burst`) and write its files into ``directory``, as ``camsim render``
    writes a ``[sequence]``'s: ``<id>_ref.exr/.json`` (the clean reference: the static scene), then
    ``<id>_fNNN.dng/.exr/.json`` per frame, each atomically. With ``srgb`` (``png``, ``png16``) also
    ``<id>_ref_srgb_clean.png`` and per frame ``<id>_fNNN_srgb_noisy.png`` and ``<id>_fNNN_srgb_clean.png``, all
    developed with one development, the reference's (:func:`camsim.dataset.srgb.burst_development`: the same white
    balance, matrix, gain and tone curve for every frame, whose light, flicker included, shows as it is).

    Returns
    -------
    names : dict
        File names by kind ``<frame>.<kind>``: ``ref.exr``, ``ref.json``, ``f000.dng`` (None without
        quantisation), ``f000.exr``, ``f000.json`` (and ``f000.xmp`` beside a three-chip DNG) …; with ``srgb``
        ``ref.srgb_clean``, ``f000.srgb_noisy``, ``f000.srgb_clean`` …
    burst : dict
        The manifest's ``burst``: ``frames`` (the frames' suffixes, ``f000`` …, in order) and ``reference``
        (``ref``); a frame's files are ``<id>_<suffix>.<kind>``.
    srgb_record : dict or None
        What the sRGB files hold (:func:`camsim.dataset.srgb.burst_srgb_record`), None without them.
    """
    names, suffixes, development, record = {}, [], None, None
    for index, name, rendered, info, _ in render_burst(frame, threads):
        suffix = name[len(frame.id) + 1:]
        written = write_frame(Path(directory), name, rendered, info, exr_compression=exr_compression)
        names.update({f"{suffix}.{kind}": value for kind, value in written.items()})
        if index != "ref":
            suffixes.append(suffix)
        if srgb == "none":
            continue
        from camsim.dataset.srgb import burst_development, burst_srgb_record, develop_burst_reference, develop_frame

        if index == "ref":
            development = burst_development(rendered, info)
            images, record = develop_burst_reference(rendered, srgb, development)
            own = record
        else:  # (its record, the one it carries, is the reference's: one development)
            images, own = develop_frame(rendered, info, srgb, development.settings, development.facts)
        written = _write_srgb(name, Path(directory), {}, images, own)
        names.update({f"{suffix}.{layer}": value for layer, value in written.items()})
    return names, {"frames": suffixes, "reference": "ref"}, None if record is None else burst_srgb_record(record)


def render_files(frame: FrameSpec, directory: Path, threads: int = 1,
                 exr_compression: str = DEFAULT_EXR_COMPRESSION, srgb: str = "none") -> tuple[dict, dict | None]:
    """Render one frame (:func:`render_frame`) and write ``<id>.dng`` (if quantised), ``<id>.exr`` (with
    ``exr_compression``) and ``<id>.json`` into ``directory``; with ``srgb`` (``png``, ``png16``) also
    ``<id>_srgb_noisy.png`` and ``<id>_srgb_clean.png`` (:mod:`camsim.dataset.srgb`), each written atomically.
    A frame of a ``[raws]`` spec is a raw scene's (:func:`camsim.dataset.raws.render_raw_files`: its DNG, EXR,
    sidecar and, where the source has saturated sites, ``<id>_mask.png``).

    Returns
    -------
    names : dict
        The file names by kind (``dng`` None without quantisation; ``srgb_noisy``, ``srgb_clean`` with ``srgb``).
    srgb_record : dict or None
        What the sRGB files hold (:func:`camsim.dataset.srgb.develop_frame`), None without them.
    """
    if frame.raw is not None and frame.burst is not None:  # a burst of a [raws] crop (no sRGB: refused when planned)
        from camsim.dataset.raws import render_raw_burst_files

        names, burst = render_raw_burst_files(frame, Path(directory), threads, exr_compression)
        return {**names, "burst": burst}, None
    if frame.raw is not None:  # a crop of a raw file of a [raws] folder
        from camsim.dataset.raws import render_raw_files

        names, (draw, meta) = render_raw_files(frame, Path(directory), threads, exr_compression)
        if srgb == "none":
            return names, None
        from camsim.dataset.srgb import develop_raw_frame

        images, record = develop_raw_frame(draw, meta, srgb)
        return _write_srgb(frame.id, Path(directory), names, images, record), record
    if frame.burst is not None:  # a burst: its frames and reference (and their sRGB outputs, one development)
        names, burst, record = render_burst_files(frame, Path(directory), threads, exr_compression, srgb)
        return {**names, "burst": burst}, record
    rendered, info = render_frame(frame, threads)
    names = write_frame(Path(directory), frame.id, rendered, info, exr_compression=exr_compression)
    if srgb == "none":
        return names, None
    from camsim.dataset.srgb import develop_frame

    images, record = develop_frame(rendered, info, srgb)
    return _write_srgb(frame.id, Path(directory), names, images, record), record


def _write_srgb(stem: str, directory: Path, names: dict, images: dict, record: dict) -> dict:
    """Write the developed ``images`` (by layer) as ``<stem>_<layer>.png``; ``names`` with them."""
    from camsim.isp import write_png

    for layer, image in images.items():
        names[layer] = f"{stem}_{layer}.png"
        write_png(Path(directory) / names[layer], image, bits=record["bits"],
                  record={"layer": layer, "frame": stem, **record})
    return names
