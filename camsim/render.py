"""The rendering pipeline: expected charge per spectrum, then per-pixel noise in row blocks.

A frame is split into row blocks whose size depends on the frame width only; block *b* draws from its own
generator, child *b* of the frame's ``SeedSequence``. So the output for a seed is the same whatever the number
of worker threads, and memory for temporaries grows with the block, not with the frame.
"""

from __future__ import annotations

import os
import threading
import zlib
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from camsim.camera import Camera, absolute_qe
from camsim.expected import ExpectedSignal, expected_signal
from camsim.photons import photon_radiance
from camsim.radiance import SceneRadiance
from camsim.errors import CamsimError
from camsim.gaussian import DEFAULT_TOLERANCE, fill_channel, plan_methods
from camsim.sampling import METHODS, draw_electrons

#: Methods drawn in one pass per channel straight to DN (camsim.gaussian.fill_channel), and every method.
FUSED_METHODS = ("poisson", "gaussian", "auto")
ALL_METHODS = ("poisson", "spectral", "gaussian", "auto")
from camsim.fixed_pattern import fixed_pattern
from camsim.sensor import (
    SensorParams,
    cfa_sites,
    add_read_noise_e,
    add_row_noise_e,
    dn_dtype,
    electrons_to_dn,
    quantise_dn,
    saturate_e,
)

#: Pixels per row block (the block has max(1, BLOCK_PIXELS // width) rows).
BLOCK_PIXELS = 2**18


@dataclass(frozen=True)
class Frame:
    """A rendered frame.

    Attributes
    ----------
    noisy_dn : numpy.ndarray, shape (3, H, W), float32
        G · G_Ve⁻ · (f_sat(S + D) + read noise): the signal before quantisation. Unit: DN.
    digital_dn : numpy.ndarray or None, shape (3, H, W), uint8 (nb ≤ 8) or uint16
        The quantised output I (Eq. 11); None when quantisation is off. Unit: DN.
    labels : numpy.ndarray, shape (H, W)
        Spectrum index of each pixel.
    expected : ExpectedSignal
        Per-spectrum model moments for this frame.
    sensor : SensorParams
    """

    noisy_dn: np.ndarray
    digital_dn: np.ndarray | None
    labels: np.ndarray
    expected: ExpectedSignal
    sensor: SensorParams
    plan: object = None  # camsim.gaussian.GaussianPlan: how each spectrum and channel was drawn (not spectral)
    maps: object = None  # camsim.fixed_pattern.FixedPattern: the sensor's DSNU / PRNU maps, if any

    def clean_dn(self) -> np.ndarray:
        """Expected value of ``noisy_dn`` per pixel: G · G_Ve⁻ · E[f_sat(S + D)], shape (3, H, W), float32."""
        k = self.sensor.dn_per_electron
        table = (self.expected.clean_e * k).astype(np.float32)
        out = np.empty((3,) + self.labels.shape, dtype=np.float32)
        for c in range(3):
            out[c] = table[:, c][self.labels]  # fancy indexing: ~4× faster than np.take with small ints
            # fixed-pattern maps are part of the sensor, so of the expectation (exact below saturation)
            if self.maps is not None and self.maps.gain is not None:
                out[c] += (self.maps.gain[c] - 1) * (k * self.expected.signal_e[:, c]).astype(np.float32)[self.labels]
            if self.maps is not None and self.maps.offset_e is not None:
                out[c] += np.float32(k) * self.maps.offset_e[c]
            if self.maps is not None and self.sensor.saturation:
                np.minimum(out[c], np.float32(k * self.sensor.full_well_e), out=out[c])
        return out


def frame_seed_sequence(seed: int, illuminant: str, intensity_factor: float) -> np.random.SeedSequence:
    """The seed sequence of one frame: a function of the run seed, the illuminant and F only.

    So a frame is the same whether it is rendered alone or as part of a longer run.
    """
    key = (zlib.crc32(illuminant.encode("utf-8")), zlib.crc32(repr(float(intensity_factor)).encode("ascii")))
    return np.random.SeedSequence(entropy=seed, spawn_key=key)


def default_workers() -> int:
    """Worker threads to use by default: the machine's cores."""
    return max(1, os.cpu_count() or 1)


def frame_expected(radiance: SceneRadiance, camera: Camera, scale, sensor, intensity_factor, statistics, grid):
    """Qe and the per-spectrum expected signal of one frame."""
    g = photon_radiance(radiance.radiance, grid.wavelengths_nm, grid.step_nm)
    g_white = photon_radiance(radiance.white_radiance, grid.wavelengths_nm, grid.step_nm)
    qe = absolute_qe(camera, scale, g_white)
    return expected_signal(g, qe, sensor, intensity_factor, statistics)


def render_frame(
    labels: np.ndarray,
    expected: ExpectedSignal,
    sensor: SensorParams,
    *,
    statistics: str = "pixel",
    method: str = "poisson",
    rng: np.random.Generator | np.random.SeedSequence | int | None = None,
    workers: int | None = None,
    tolerance: float | None = None,
) -> Frame:
    """Render one frame: per-pixel noise on top of the per-spectrum expected signal.

    Parameters
    ----------
    labels : numpy.ndarray, shape (H, W), unsigned integer
        Spectrum index per pixel.
    expected : ExpectedSignal
        From :func:`frame_expected` or :func:`camsim.expected.expected_signal`.
    sensor : SensorParams
    statistics : {'pixel', 'paper'}
    method : {'poisson', 'spectral', 'gaussian', 'auto'}
    rng : numpy.random.Generator, numpy.random.SeedSequence or int, optional
        Seed of the frame. Each row block draws from its own child (``SeedSequence.spawn`` or
        ``Generator.spawn``), so the output does not depend on the number of threads.
    workers : int, optional
        Threads (default: the number of cores). The output does not depend on it.
    tolerance : float, optional
        ``auto``'s KS tolerance (default :data:`camsim.gaussian.DEFAULT_TOLERANCE`).
    """
    height, width = labels.shape
    rows = max(1, BLOCK_PIXELS // width)
    if sensor.cfa is not None:
        if height % 2 or width % 2:
            raise CamsimError(f"a {sensor.cfa} colour filter array needs an even frame size, got {width}x{height}")
        rows = max(2, rows - rows % 2)  # blocks start on the pattern's even rows
    starts = list(range(0, height, rows))
    if isinstance(rng, np.random.Generator):
        generators = rng.spawn(len(starts))
    else:
        seed_seq = rng if isinstance(rng, np.random.SeedSequence) else np.random.SeedSequence(rng)
        generators = [np.random.Generator(np.random.PCG64(child)) for child in seed_seq.spawn(len(starts))]
    planes = 3 if sensor.cfa is None else 1  # a colour filter array keeps one value per pixel
    noisy = np.empty((planes, height, width), dtype=np.float32)
    digital = np.empty((planes, height, width), dtype=dn_dtype(sensor.bits)) if sensor.quantisation else None

    per_thread = threading.local()  # one scratch block per thread, reused: fresh pages cost more than the maths
    read_noise = sensor.read_noise and sensor.read_noise_e > 0
    maps = fixed_pattern(sensor, labels.shape)
    if maps is not None and maps.gain is not None and method == "spectral":
        raise CamsimError("PRNU needs a per-pixel mean: use method poisson, gaussian or auto, not spectral")
    plan = None
    if method in FUSED_METHODS:
        plan = plan_methods(expected, sensor, statistics, method,
                            DEFAULT_TOLERANCE if tolerance is None else tolerance)
    elif method not in METHODS:
        raise CamsimError(f"unknown sampling method {method!r}; methods: {', '.join(ALL_METHODS)}")

    def run_block(index: int) -> None:
        r0 = starts[index]
        r1 = min(height, r0 + rows)
        if getattr(per_thread, "scratch", None) is None:
            per_thread.scratch = np.empty((rows, width), dtype=np.float32)
            per_thread.work = np.empty(rows * width // 2 + 1, dtype=np.float32)
        scratch = per_thread.scratch[: r1 - r0]
        block_rng = generators[index]
        block = noisy[:, r0:r1]  # work in place in the output: electrons first, DN at the end
        offset = None if maps is None or maps.offset_e is None else maps.offset_e[:, r0:r1]
        gain = None if maps is None or maps.gain is None else maps.gain[:, r0:r1]
        if sensor.cfa is not None and plan is not None:  # each site of the 2 × 2 cell: its channel only
            for dy, dx, c in cfa_sites(sensor.cfa):
                site = (slice(dy, None, 2), slice(dx, None, 2))
                sub_labels = np.ascontiguousarray(labels[r0:r1][site])
                value = np.empty(sub_labels.shape, dtype=np.float32)
                fill_channel(value, sub_labels, plan, expected, sensor, statistics, c, block_rng,
                             np.empty_like(value), per_thread.work,
                             None if offset is None else offset[c][site], None if gain is None else gain[c][site])
                block[0][site] = value
            if sensor.row_noise_e > 0:  # a physical row shares its offset, whatever the colour of its pixels
                add_row_noise_e(block[0], sensor.row_noise_e * sensor.dn_per_electron, block_rng)
            if digital is not None:
                quantise_dn(block[0], sensor.bits, out=digital[0, r0:r1])
            return
        if sensor.cfa is not None:  # spectral: draw the three channels, keep each site's own
            rgb = np.empty((3, r1 - r0, width), dtype=np.float32)
            draw_electrons(labels[r0:r1], expected, sensor, statistics, method, block_rng, rgb)
            for dy, dx, c in cfa_sites(sensor.cfa):
                site = (slice(dy, None, 2), slice(dx, None, 2))
                block[0][site] = rgb[c][site]
                if offset is not None:
                    block[0][site] += offset[c][site]
            finish_planes(block, digital, r0, r1, scratch, block_rng)
            return
        if plan is not None:  # poisson / gaussian / auto: every stage in one pass per channel, straight to DN
            for c in range(3):
                fill_channel(block[c], labels[r0:r1], plan, expected, sensor, statistics, c, block_rng, scratch,
                             per_thread.work, None if offset is None else offset[c], None if gain is None else gain[c])
                if sensor.row_noise_e > 0:
                    add_row_noise_e(block[c], sensor.row_noise_e * sensor.dn_per_electron, block_rng)
                if digital is not None:
                    quantise_dn(block[c], sensor.bits, out=digital[c, r0:r1])
            return
        draw_electrons(labels[r0:r1], expected, sensor, statistics, method, block_rng, block)
        if offset is not None:
            block += offset
        finish_planes(block, digital, r0, r1, scratch, block_rng)

    def finish_planes(block, digital, r0, r1, scratch, block_rng):
        """Saturation, read and row noise, gain and ADC on electrons already drawn (the spectral path)."""
        for c in range(block.shape[0]):
            e = block[c]
            if sensor.saturation:
                saturate_e(e, sensor.full_well_e, out=e)
            if read_noise:
                add_read_noise_e(e, sensor.read_noise_e, block_rng, scratch, per_thread.work, sensor.read_noise_model,
                                 sensor.tukey_lambda)
            if sensor.row_noise_e > 0:
                add_row_noise_e(e, sensor.row_noise_e, block_rng)
            electrons_to_dn(e, sensor.dn_per_electron, out=e)
            if digital is not None:
                quantise_dn(e, sensor.bits, out=digital[c, r0:r1])

    workers = default_workers() if workers is None else max(1, int(workers))
    if workers == 1 or len(starts) == 1:
        for index in range(len(starts)):
            run_block(index)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(run_block, range(len(starts))))
    return Frame(noisy, digital, labels, expected, sensor, plan, maps)
