"""Rendering a sequence: a scene's ``[sequence]`` frames with camera motion (issue 29, points 1, 3 and 4).

For each illuminant × F the static scene is lit once and its expected signal electrons per pixel and channel
S̄ (3, H, W) are gathered through the label map (so a chart, a target or an image alike becomes a per-pixel image:
that is what motion costs a chart, 12 bytes a pixel and a draw per pixel instead of one plan per spectrum). Frame
i's expectation is the average of S̄ along the camera's path over its exposure, each row over its own under a
rolling shutter, weighted by a flickering light (:func:`moving_expectation`, the motion and the light of
:mod:`camsim.scene.sequence`): at each sub-sample time t, the value at
sensor pixel p is S̄ at q = H(t)⁻¹ p, **bilinear** between pixel centres; a q outside the frame is **clamped** to the
nearest edge pixel (the scene beyond the frame is taken to continue its edge). The frame is then drawn per pixel
from that expectation (:func:`camsim.render.raw_frame.render_expectation_frame`: Poisson(S̄ · g + D̄ · d), the
sensor's every later stage; the fixed pattern is the sensor's, from ``sensor_seed``, the same in every frame; the
temporal noise is each frame's own, from ``frame_seed_sequence(seed, "<illuminant>/f<i>", F)``; the dark charge
is per exposure). Photon statistics ``pixel`` only; the sampling is the exact per-pixel law whatever the scene's
method (the sidecar records ``poisson``).

Files, per illuminant × F with stem STEM (:func:`camsim.render.frame_files.frame_stem`): ``STEM_fNNN.dng/.exr/.json``
(NNN zero-padded to at least 3 digits and to the frame count's), each sidecar with ``frame_index``, ``time_s`` (the
exposure's start, s from the first frame's), ``exposure_s``, ``homography`` (3 × 3, reference pixel → sensor pixel,
at the exposure's middle) and ``sequence`` (the table and the reference's file) — with a rolling shutter or flicker
also the per-row ground truth of :func:`sequence_frame_record` —; and ``STEM_ref.exr/.json``: the
reference frame, the static scene's expectation (no motion, no noise; the fixed pattern in, as every clean layer
has it), its noisy layer equal to its clean one, no DNG. An EXR's clean layer is its frame's own expectation
(:func:`camsim.render.raw_frame.expectation_clean_dn`: every channel at every pixel). The sidecars' per-patch
values (``patches``) are the static scene's.

A raw scene's sequence moves the file's electrons instead (:mod:`camsim.render.raw_sequence`: the same
:func:`moving_expectation`, then the file's CFA and the ``add`` law), where :mod:`camsim.render.run` sends it
(that module imports this one, not the reverse).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.seeding import frame_seed_sequence
from camsim.render.raw_frame import ExpectationFrame, expectation_clean_dn, render_expectation_frame, static_signal_e
from camsim.scene.sequence import Motion, SequenceParams, check_timing
from camsim.sensor.cfa import mosaic_of


def moving_expectation(signal_e: np.ndarray, motion: Motion, frame: int, exposure_s: float,
                       workers: int | None = None, *, pixels: np.ndarray | None = None,
                       out: np.ndarray | None = None) -> np.ndarray:
    """Frame ``frame``'s expected signal electrons (3, H, W) float32: at sensor pixel (x, r), the mean of
    L(t) · S̄(H(t)⁻¹ (x, r)) over row r's exposure — the weighted sum over the sub-samples of
    :meth:`camsim.scene.sequence.Motion.exposure_samples` (each row's own times under a rolling shutter; weights the
    light's exact integral over each part), bilinear, clamped at the edges (:func:`camsim.render.warp.average_warp`,
    on ``workers`` threads; the result does not depend on them). Without motion no warp: S̄ times each row's (or the
    frame's) share of the light (:meth:`~camsim.scene.sequence.Motion.light_factor`), or S̄ itself under a steady
    light. ``pixels``: S̄ channels last, (H, W, 3) float32 C-contiguous (:func:`channels_last`), made once for
    all the frames of a sequence (default: made here); ``out``: a (3, H, W) float32 array to write a warp's result
    into (one for all the frames; default: a new one). Unit: e⁻."""
    from camsim.render.warp import average_warp

    if not motion.params.moves:
        factor = motion.light_factor(frame, exposure_s)
        if factor is None:
            return signal_e
        return (np.asarray(signal_e, dtype=np.float64) * factor[None, :, None]).astype(np.float32)
    times, weights = motion.exposure_samples(frame, exposure_s)
    inverses = np.linalg.inv(motion.homographies(times, frame)).reshape(times.shape + (3, 3))
    pixels = channels_last(signal_e) if pixels is None else pixels
    return average_warp(pixels, inverses, weights, workers=workers, planar=True, out=out)


def channels_last(signal_e: np.ndarray) -> np.ndarray:
    """S̄ (3, H, W) as the warp reads it: (H, W, 3) float32, C-contiguous (a copy)."""
    return np.ascontiguousarray(np.moveaxis(signal_e, 0, -1), dtype=np.float32)


def sequence_frame_record(motion: Motion, frame: int, exposure_s: float) -> dict:
    """Frame ``frame``'s ground truth for its sidecar: ``frame_index``, ``time_s`` (row 0's exposure start),
    ``homography`` (at row 0's exposure middle), ``blur_subsamples_used``; with a rolling shutter
    ``rolling_shutter_row_s`` (Δ: row r starts at time_s + r · Δ) and ``row_homographies`` (one 3 × 3 per row, at
    its exposure's middle time_s + r · Δ + T/2); with flicker ``flicker_factor`` (a global shutter: the frame's share
    of the light, (1/T) ∫ L dt over its exposure) or ``flicker_row_factor`` (a rolling shutter: one per row)."""
    seq = motion.params
    out = {"frame_index": frame, "time_s": motion.start_s(frame),
           "homography": motion.mid_homography(frame, exposure_s).tolist(),
           "homography_time": "the exposure's middle, time_s + exposure_s / 2",
           "blur_subsamples_used": motion.subsample_count(frame, exposure_s) if seq.moves else 1}
    if seq.rolling:
        out["homography_time"] = "row 0's exposure middle, time_s + exposure_s / 2"
        out["rolling_shutter_row_s"] = seq.rolling_shutter_row_s
        out["row_homographies"] = motion.row_homographies(frame, exposure_s).tolist()
        out["row_homographies_time"] = "row r's exposure middle, time_s + r · rolling_shutter_row_s + exposure_s / 2"
    factor = motion.light_factor(frame, exposure_s)
    if factor is not None:
        if seq.rolling:
            out["flicker_row_factor"] = factor.tolist()
        else:
            out["flicker_factor"] = float(factor[0])
    return out


def frame_digits(frames: int) -> int:
    """The zero-padded width of a frame's index in its stem: at least 3, the count's digits."""
    return max(3, len(str(frames - 1)))


def sequence_frame_info(stem: str, index, digits: int, extra: dict, base):
    """A sequence frame's file stem (``STEM_fNNN``, or ``STEM_ref`` for ``index`` ``"ref"``) and its
    :class:`camsim.render.frame_files.FrameInfo`: ``base`` with the frame's sidecar keys ``extra``
    (:func:`render_sequence_frames`), whose ``sequence`` record gains ``stem`` and ``reference`` (its file)."""
    name = f"{stem}_ref" if index == "ref" else f"{stem}_f{index:0{digits}d}"
    extra = {**extra, "sequence": {**extra["sequence"], "stem": stem, "reference": f"{stem}_ref.exr"}}
    return name, dataclasses.replace(base, sequence=extra)


def check_sequence_scene(scene) -> None:
    """Refuse, before any work, what a sequence cannot render (one line each)."""
    if scene.source.table == "raw":  # (camsim.render.run dispatches a raw scene's to camsim.render.raw_sequence)
        raise CamsimError("a raw scene's [sequence] is rendered from its file's electrons (camsim render), not here")
    own = scene.source.has_own_size
    height = (scene.source.own_size() if own else (scene.width, scene.height))[1]
    if scene.exposure == "fixed":  # (auto: each frame's T is checked when it is known)
        check_timing(scene.sequence, scene.sensor.exposure_s, height)
    else:
        check_timing(scene.sequence, 0.0, height)
    if scene.statistics != "pixel":
        raise CamsimError("a [sequence] draws pixel statistics (its frames are drawn per pixel); set "
                          "statistics = 'pixel'")


def render_sequence_frames(scene, lit, sensor, intensity_factor: float, *, workers=None):
    """Yield ``("ref", frame, extra)`` and then ``(i, frame, extra)`` for every frame of ``scene.sequence`` under
    ``lit`` at F: :class:`camsim.render.raw_frame.ExpectationFrame` objects and the sidecar keys of each (``extra``)."""
    seq: SequenceParams = scene.sequence
    expected = lit.expected(sensor, intensity_factor, scene.statistics)
    labels = lit.labels
    height, width = labels.shape
    check_timing(seq, sensor.exposure_s, height)
    static = static_signal_e(labels, expected.signal_e)
    optics = None
    if getattr(scene, "optics", None) is not None:  # the lens in front of the static scene (camsim.render.optics)
        from camsim.render.optics import optics_signal

        static, record = optics_signal(lit, expected.signal_e, scene.optics, static=static, workers=workers)
        optics = {"optics": record}
    motion = Motion.of(seq, width, height, scene.seed)
    record = seq.record()
    from camsim.sensor.fixed_pattern import fixed_pattern

    maps = fixed_pattern(sensor, labels.shape)
    ref_clean = expectation_clean_dn(static, sensor, maps, workers)
    ref_noisy = ref_clean if sensor.cfa is None else mosaic_of(ref_clean, sensor.cfa)[None]
    yield "ref", ExpectationFrame(np.ascontiguousarray(ref_noisy), None, labels, expected, sensor, None, maps, None,
                               ref_clean), {
        "sequence_reference": True, "homography": np.eye(3).tolist(), "sequence": record, **(optics or {})}
    # once for every frame: S̄ channels last, and the buffer of each frame's expectation (no frame keeps it)
    pixels, buffer = (channels_last(static), np.empty_like(static)) if seq.moves else (None, None)
    for i in range(seq.frames):
        moving = moving_expectation(static, motion, i, sensor.exposure_s, workers, pixels=pixels, out=buffer)
        source = moving if sensor.cfa is None else mosaic_of(moving, sensor.cfa)[None]
        rng = frame_seed_sequence(scene.seed, f"{lit.illuminant}/f{i}", intensity_factor)
        draw = render_expectation_frame(source, sensor, rng=rng, workers=workers, clean=sensor.cfa is None)
        clean = draw.clean_dn if sensor.cfa is None else expectation_clean_dn(moving, sensor, draw.maps, workers)
        frame = ExpectationFrame(draw.noisy_dn, draw.digital_dn, labels, expected, sensor, None, draw.maps,
                              draw.black_level_error_dn, clean)
        extra = {**sequence_frame_record(motion, i, sensor.exposure_s), "sequence": record, **(optics or {})}
        yield i, frame, extra


def sequence_jobs(scene, camera):
    """Yield ``(F, lit, sensor, stem, base)`` for each illuminant × F of a sequence scene, in order: the lit scene
    (:func:`camsim.render.pipeline.light_scene`, once per illuminant), the frame's sensor, the stem
    (:func:`camsim.render.frame_files.frame_stem`) and the frames' :class:`camsim.render.frame_files.FrameInfo` (method
    ``poisson``: a sequence draws per pixel) — for the files (:func:`render_sequence`) and the Zarr store
    (:mod:`camsim.dataset.sequence_store`) alike."""
    from camsim.render.frame_files import frame_stem
    from camsim.render.pipeline import frame_sensor, light_scene, scene_frame_info

    for illuminant in scene.illuminants:
        lit = light_scene(scene, illuminant, camera)
        for factor in scene.intensity_factors:
            sensor = frame_sensor(scene, lit, factor)
            base = dataclasses.replace(scene_frame_info(scene, lit, camera.name, factor, scene.seed),
                                       method="poisson")
            yield factor, lit, sensor, frame_stem(scene.name, illuminant, factor), base


def render_sequence(scene, out_dir, *, workers=None, progress=True, exr_compression=None, warn=None) -> dict:
    """Render every illuminant × F of a scene with a ``[sequence]``: its reference and frames (module docstring),
    each committed by its sidecar, the manifest listing them (a frame's entry with ``frame_index`` and ``time_s``,
    the reference's with ``sequence_reference``). :func:`camsim.render.run.render_scene`'s
    contract."""
    from tqdm import tqdm

    from camsim.io.exr import DEFAULT_EXR_COMPRESSION, check_exr_compression
    from camsim.io.output_folder import output_folder
    from camsim.render.frame_files import write_frame
    from camsim.render.frame_manifest import MANIFEST_NAME, FrameManifest
    from camsim.sensor.camera import load_camera

    exr_compression = exr_compression or DEFAULT_EXR_COMPRESSION
    check_sequence_scene(scene)
    check_exr_compression(exr_compression)
    seq = scene.sequence
    with output_folder(out_dir) as out_dir:
        out_dir = Path(out_dir)
        camera = load_camera(scene.camera, scene.grid, scene.sensitivity_basis, scene.base_dir)
        manifest = FrameManifest(out_dir, scene.name)
        if manifest.frames or (out_dir / MANIFEST_NAME).exists():
            manifest.write()
        bar = tqdm(total=len(scene.illuminants) * len(scene.intensity_factors) * (seq.frames + 1),
                   desc=f"rendering {scene.name}", unit="frame", disable=not progress)
        digits = frame_digits(seq.frames)
        with bar, manifest.kept_on_failure():
            for factor, lit, sensor, stem, base in sequence_jobs(scene, camera):
                for index, frame, extra in render_sequence_frames(scene, lit, sensor, factor, workers=workers):
                    name, info = sequence_frame_info(stem, index, digits, extra, base)
                    manifest.withdraw(name)
                    files = write_frame(out_dir, name, frame, info, exr_compression=exr_compression)
                    manifest.commit(info, files)
                    bar.update()
    return manifest.as_dict()
