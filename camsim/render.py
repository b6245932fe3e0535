"""The block scheduler: per-pixel noise on top of the per-spectrum expected charge, in row blocks.

A frame is split into row blocks whose size depends on the frame width only; block *b* draws from its own
generator, child *b* of the frame's ``SeedSequence``. So the output for a seed is the same whatever the number
of worker threads, and memory for temporaries grows with the block, not with the frame.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from camsim.errors import CamsimError
from camsim.expected import ExpectedSignal
from camsim.fixed_pattern import FixedPattern, fixed_pattern
from camsim.methods import get_method
from camsim.seeding import block_generators
from camsim.sensor import SensorParams
from camsim.stages import dn_dtype

if TYPE_CHECKING:  # the plan's module imports scipy: only its type is needed here
    from camsim.methods.plan import DrawPlan

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
    plan: DrawPlan | None = None  # how each spectrum and channel was drawn (None for spectral)
    maps: FixedPattern | None = None  # the sensor's DSNU / PRNU maps, if any

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


def default_workers() -> int:
    """Worker threads to use by default: the machine's cores."""
    return max(1, os.cpu_count() or 1)


@dataclass(frozen=True)
class FrameJob:
    """One frame being drawn: what every block of it needs, shared by the threads (read-only but the outputs).

    Attributes
    ----------
    labels : numpy.ndarray, shape (H, W)
    expected : ExpectedSignal
    sensor : SensorParams
    statistics : {'pixel', 'paper'}
    plan : DrawPlan or None
        The method's per-spectrum plan.
    maps : FixedPattern or None
        The sensor's DSNU / PRNU maps.
    noisy : numpy.ndarray, shape (planes, H, W), float32
        Output: DN before quantisation.
    digital : numpy.ndarray or None, shape (planes, H, W)
        Output: quantised DN (None when quantisation is off).
    """

    labels: np.ndarray
    expected: ExpectedSignal
    sensor: SensorParams
    statistics: str
    plan: DrawPlan | None
    maps: FixedPattern | None
    noisy: np.ndarray
    digital: np.ndarray | None

    def maps_rows(self, r0: int, r1: int):
        """(DSNU offset, PRNU gain) of rows ``r0:r1``, shape (3, r1 − r0, W) each, or None where off."""
        if self.maps is None:
            return None, None
        offset = None if self.maps.offset_e is None else self.maps.offset_e[:, r0:r1]
        gain = None if self.maps.gain is None else self.maps.gain[:, r0:r1]
        return offset, gain


@dataclass
class _Scratch:
    """A thread's reusable buffers: fresh pages cost more than the maths."""

    plane: np.ndarray  # (rows, W) float32: one block plane
    work: np.ndarray  # float32, half a block plane: Box–Muller's scratch


def block_rows(shape, cfa: str | None) -> int:
    """Rows per block of a frame of ``shape`` (H, W): a function of the width (and the CFA) only."""
    height, width = shape
    rows = max(1, BLOCK_PIXELS // width)
    if cfa is not None:
        if height % 2 or width % 2:
            raise CamsimError(f"a {cfa} colour filter array needs an even frame size, got {width}x{height}")
        rows = max(2, rows - rows % 2)  # blocks start on the pattern's even rows
    return rows


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

    A block scheduler: the frame is cut into row blocks (:func:`block_rows`), block *b* draws from generator
    *b* (:func:`camsim.seeding.block_generators`) with the method's ``draw_block``
    (:mod:`camsim.methods`), on a pool of threads.

    Parameters
    ----------
    labels : numpy.ndarray, shape (H, W), unsigned integer
        Spectrum index per pixel.
    expected : ExpectedSignal
        From :meth:`camsim.pipeline.LitScene.expected` or :func:`camsim.expected.expected_signal`.
    sensor : SensorParams
    statistics : {'pixel', 'paper'}
    method : str
        A name of :data:`camsim.methods.METHODS`.
    rng : numpy.random.Generator, numpy.random.SeedSequence or int, optional
        Seed of the frame. Each row block draws from its own child (``SeedSequence.spawn`` or
        ``Generator.spawn``), so the output does not depend on the number of threads.
    workers : int, optional
        Threads (default: the number of cores). The output does not depend on it.
    tolerance : float, optional
        ``auto``'s KS tolerance (default :data:`camsim.methods.DEFAULT_TOLERANCE`).
    """
    impl = get_method(method)
    height, width = labels.shape
    rows = block_rows(labels.shape, sensor.cfa)
    starts = list(range(0, height, rows))
    generators = block_generators(rng, len(starts))
    maps = fixed_pattern(sensor, labels.shape)
    if maps is not None and maps.gain is not None and not impl.per_pixel_mean:
        raise CamsimError(f"PRNU needs a per-pixel mean: use method poisson, gaussian or auto, not {method}")
    plan = impl.plan(expected, sensor, statistics, tolerance)
    planes = 3 if sensor.cfa is None else 1  # a colour filter array keeps one value per pixel
    noisy = np.empty((planes, height, width), dtype=np.float32)
    digital = np.empty((planes, height, width), dtype=dn_dtype(sensor.bits)) if sensor.quantisation else None
    job = FrameJob(labels, expected, sensor, statistics, plan, maps, noisy, digital)
    per_thread = threading.local()

    def run_block(index: int) -> None:
        if getattr(per_thread, "scratch", None) is None:
            per_thread.scratch = _Scratch(np.empty((rows, width), dtype=np.float32),
                                          np.empty(rows * width // 2 + 1, dtype=np.float32))
        r0 = starts[index]
        impl.draw_block(job, r0, min(height, r0 + rows), generators[index], per_thread.scratch)

    workers = default_workers() if workers is None else max(1, int(workers))
    if workers == 1 or len(starts) == 1:
        for index in range(len(starts)):
            run_block(index)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(run_block, range(len(starts))))
    return Frame(noisy, digital, labels, expected, sensor, plan, maps)
