"""Rendering a sequence: a scene's ``[sequence]`` frames with camera motion (issue 29, points 1, 3 and 4).

For each illuminant × F the static scene is lit once and its expected signal electrons per pixel and channel
S̄ (3, H, W) are gathered through the label map (so a chart, a target or an image alike becomes a per-pixel image:
that is what motion costs a chart, 12 bytes a pixel and a draw per pixel instead of one plan per spectrum). Frame
i's expectation is the average of S̄ along the camera's path over its exposure
(:func:`moving_expectation`, the motion of :mod:`camsim.scene.sequence`): at each sub-sample time t, the value at
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
at the exposure's middle) and ``sequence`` (the table and the reference's file); and ``STEM_ref.exr/.json``: the
reference frame, the static scene's expectation (no motion, no noise; the fixed pattern in, as every clean layer
has it), its noisy layer equal to its clean one, no DNG. An EXR's clean layer is its frame's own expectation
(:func:`camsim.render.raw_frame.expectation_clean_dn`: every channel at every pixel). The sidecars' per-patch
values (``patches``) are the static scene's.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.seeding import frame_seed_sequence
from camsim.render.frame import Frame
from camsim.render.raw_frame import expectation_clean_dn, render_expectation_frame
from camsim.scene.sequence import Motion, SequenceParams, check_timing
from camsim.sensor.cfa import mosaic_of


@dataclass(frozen=True)
class SequenceFrame(Frame):
    """A frame whose clean layer is per pixel (a moving scene's), not one value per spectrum."""

    clean: np.ndarray | None = None  # (3, H, W) float32, DN

    def clean_dn(self) -> np.ndarray:
        return self.clean


def static_signal_e(labels: np.ndarray, signal_e: np.ndarray) -> np.ndarray:
    """S̄ per pixel and channel, (3, H, W) float32, from the per-spectrum ``signal_e`` (K, 3) through ``labels``.
    Unit: e⁻."""
    table = np.asarray(signal_e, dtype=np.float32)
    out = np.empty((3,) + labels.shape, dtype=np.float32)
    for c in range(3):
        out[c] = table[:, c][labels]
    return out


#: Rows of a warp block: a block's temporaries stay small (in cache, no fresh pages) and blocks run on threads.
WARP_BLOCK_PIXELS = 2**16


def warp_bilinear(pixels: np.ndarray, inverse: np.ndarray, out: np.ndarray, weight: float = 1.0,
                  rows: tuple[int, int] | None = None) -> None:
    """``out += weight · pixels(H⁻¹ p)`` at every pixel p: bilinear between pixel centres, clamped at the edges.

    Parameters
    ----------
    pixels : numpy.ndarray, shape (H, W, C), float32, C-contiguous
        The image, channels last (one gather fetches a pixel's C values together).
    inverse : numpy.ndarray, shape (3, 3)
        H⁻¹: sensor pixel (x, y, 1) → reference pixel (homogeneous); an affine one (last row 0, 0, 1) skips the
        division.
    out : numpy.ndarray, shape (H, W, C) (or (r1 − r0, W, C) with ``rows``), float32
        Accumulated in place.
    rows : (r0, r1), optional
        Only the sensor rows r0:r1 (``out`` holds just them).

    Coordinates are float32 (at 4000 px, steps of 2.4e-4 px).
    """
    height, width, channels = pixels.shape
    r0, r1 = (0, height) if rows is None else rows
    inv = np.asarray(inverse, dtype=np.float64)
    x = np.arange(width, dtype=np.float32)[None, :]
    y = np.arange(r0, r1, dtype=np.float32)[:, None]
    f32 = np.float32
    qx = f32(inv[0, 0]) * x + (f32(inv[0, 1]) * y + f32(inv[0, 2]))
    qy = f32(inv[1, 0]) * x + (f32(inv[1, 1]) * y + f32(inv[1, 2]))
    if not (inv[2, 0] == 0 and inv[2, 1] == 0 and inv[2, 2] == 1):
        w = f32(inv[2, 0]) * x + (f32(inv[2, 1]) * y + f32(inv[2, 2]))
        qx /= w
        qy /= w
    np.clip(qx, 0, width - 1, out=qx)
    np.clip(qy, 0, height - 1, out=qy)
    x0 = np.floor(qx)
    y0 = np.floor(qy)
    np.minimum(x0, max(width - 2, 0), out=x0)
    np.minimum(y0, max(height - 2, 0), out=y0)
    qx -= x0  # the fractions
    qy -= y0
    index = y0.astype(np.int64)
    index *= width
    index += x0.astype(np.int64)
    index = index.ravel()
    dx = 1 if width > 1 else 0
    dy = width if height > 1 else 0
    fx, fy = qx.reshape(-1, 1), qy.reshape(-1, 1)
    flat = pixels.reshape(-1, channels)
    acc = out.reshape(-1, channels)
    take = lambda i: np.take(flat, i, axis=0)  # noqa: E731 (rows of C values: far faster than flat[i])
    top = take(index)  # (1 − fx) a + fx b, rows y0 and y0 + 1, then (1 − fy) top + fy bottom
    top += (take(index + dx) - top) * fx
    bottom = take(index + dy)
    bottom += (take(index + dx + dy) - bottom) * fx
    bottom -= top
    bottom *= fy
    top += bottom
    if weight != 1:
        top *= f32(weight)
    acc += top


def moving_expectation(signal_e: np.ndarray, motion: Motion, frame: int, exposure_s: float,
                       workers: int | None = None) -> np.ndarray:
    """Frame ``frame``'s expected signal electrons (3, H, W) float32: the mean of S̄(H(t)⁻¹ p) over the
    sub-sample times of its exposure (:meth:`camsim.scene.sequence.Motion.subsample_times`), bilinear, clamped at
    the edges (:func:`warp_bilinear`), in row blocks on ``workers`` threads (default: every core; the result does
    not depend on it: each block sums its sub-samples in order). Unit: e⁻."""
    from concurrent.futures import ThreadPoolExecutor

    from camsim.render.frame import default_workers

    times = motion.subsample_times(frame, exposure_s)
    weight = 1 / len(times)
    pixels = np.ascontiguousarray(np.moveaxis(signal_e, 0, -1), dtype=np.float32)
    out = np.zeros_like(pixels)
    inverses = []
    for t in times:
        h = motion.homography(float(t), frame)
        inverses.append(None if np.allclose(h, np.eye(3), rtol=0, atol=1e-12) else np.linalg.inv(h))
    height, width = pixels.shape[:2]
    rows = max(1, WARP_BLOCK_PIXELS // width)

    def block(r0: int) -> None:
        r1 = min(height, r0 + rows)
        for inverse in inverses:
            if inverse is None:
                out[r0:r1] += pixels[r0:r1] * np.float32(weight)
            else:
                warp_bilinear(pixels, inverse, out[r0:r1], weight, rows=(r0, r1))

    starts = range(0, height, rows)
    workers = default_workers() if workers is None else max(1, int(workers))
    if workers == 1:
        for r0 in starts:
            block(r0)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(block, starts))
    return np.ascontiguousarray(np.moveaxis(out, -1, 0))


def frame_digits(frames: int) -> int:
    """The zero-padded width of a frame's index in its stem: at least 3, the count's digits."""
    return max(3, len(str(frames - 1)))


def check_sequence_scene(scene) -> None:
    """Refuse, before any work, what a sequence cannot render (one line each)."""
    if scene.source.table == "raw":
        raise CamsimError("a [sequence] is not available for a raw scene yet")
    if scene.exposure == "fixed":  # (auto: each frame's T is checked when it is known)
        check_timing(scene.sequence, scene.sensor.exposure_s)
    if scene.statistics != "pixel":
        raise CamsimError("a [sequence] draws pixel statistics (its frames are drawn per pixel); set "
                          "statistics = 'pixel'")


def render_sequence_frames(scene, lit, sensor, intensity_factor: float, *, workers=None):
    """Yield ``("ref", frame, extra)`` and then ``(i, frame, extra)`` for every frame of ``scene.sequence`` under
    ``lit`` at F: :class:`SequenceFrame` objects and the sidecar keys of each (``extra``)."""
    seq: SequenceParams = scene.sequence
    check_timing(seq, sensor.exposure_s)
    expected = lit.expected(sensor, intensity_factor, scene.statistics)
    labels = lit.labels
    height, width = labels.shape
    static = static_signal_e(labels, expected.signal_e)
    motion = Motion.of(seq, width, height, scene.seed)
    record = seq.record()
    from camsim.sensor.fixed_pattern import fixed_pattern

    maps = fixed_pattern(sensor, labels.shape)
    ref_clean = expectation_clean_dn(static, sensor, maps, workers)
    ref_noisy = ref_clean if sensor.cfa is None else mosaic_of(ref_clean, sensor.cfa)[None]
    yield "ref", SequenceFrame(np.ascontiguousarray(ref_noisy), None, labels, expected, sensor, None, maps, None,
                               ref_clean), {
        "sequence_reference": True, "homography": np.eye(3).tolist(), "sequence": record}
    for i in range(seq.frames):
        moving = moving_expectation(static, motion, i, sensor.exposure_s, workers) if seq.moves else static
        source = moving if sensor.cfa is None else mosaic_of(moving, sensor.cfa)[None]
        rng = frame_seed_sequence(scene.seed, f"{lit.illuminant}/f{i}", intensity_factor)
        draw = render_expectation_frame(source, sensor, rng=rng, workers=workers)
        clean = draw.clean_dn if sensor.cfa is None else expectation_clean_dn(moving, sensor, draw.maps, workers)
        frame = SequenceFrame(draw.noisy_dn, draw.digital_dn, labels, expected, sensor, None, draw.maps,
                              draw.black_level_error_dn, clean)
        extra = {"frame_index": i, "time_s": motion.start_s(i),
                 "homography": motion.mid_homography(i, sensor.exposure_s).tolist(),
                 "homography_time": "the exposure's middle, time_s + exposure_s / 2",
                 "blur_subsamples_used": int(len(motion.subsample_times(i, sensor.exposure_s))) if seq.moves else 1,
                 "sequence": record}
        yield i, frame, extra


def render_sequence(scene, out_dir, *, workers=None, progress=True, exr_compression=None, warn=None) -> dict:
    """Render every illuminant × F of a scene with a ``[sequence]``: its reference and frames (module docstring),
    each committed by its sidecar, the manifest listing them (a frame's entry with ``frame_index`` and ``time_s``,
    the reference's with ``sequence_reference``). :func:`camsim.render.run.render_scene`'s
    contract."""
    from tqdm import tqdm

    from camsim.io.exr import DEFAULT_EXR_COMPRESSION, check_exr_compression
    from camsim.io.output_folder import output_folder
    from camsim.render.frame_files import frame_stem, write_frame
    from camsim.render.frame_manifest import MANIFEST_NAME, FrameManifest
    from camsim.render.pipeline import frame_sensor, light_scene, scene_frame_info
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
        jobs = [(ill, f) for ill in scene.illuminants for f in scene.intensity_factors]
        bar = tqdm(total=len(jobs) * (seq.frames + 1), desc=f"rendering {scene.name}", unit="frame",
                   disable=not progress)
        digits = frame_digits(seq.frames)
        with bar, manifest.kept_on_failure():
            for illuminant, factor in jobs:
                lit = light_scene(scene, illuminant, camera)
                sensor = frame_sensor(scene, lit, factor)
                base = dataclasses.replace(scene_frame_info(scene, lit, camera.name, factor, scene.seed),
                                           method="poisson")
                stem = frame_stem(scene.name, illuminant, factor)
                for index, frame, extra in render_sequence_frames(scene, lit, sensor, factor, workers=workers):
                    name = f"{stem}_ref" if index == "ref" else f"{stem}_f{index:0{digits}d}"
                    extra = {**extra, "sequence": {**extra["sequence"], "stem": stem,
                                                   "reference": f"{stem}_ref.exr"}}
                    info = dataclasses.replace(base, sequence=extra)
                    manifest.withdraw(name)
                    files = write_frame(out_dir, name, frame, info, exr_compression=exr_compression)
                    manifest.commit(info, files)
                    bar.update()
    return manifest.as_dict()
