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

from camsim.core.errors import CamsimError
from camsim.core.seeding import block_generators, frame_effect_generator
from camsim.core.xp import namespace_of
from camsim.methods import get_method
from camsim.sensor.expected import ExpectedSignal
from camsim.sensor.fixed_pattern import FixedPattern, dark_gain_at, fixed_pattern
from camsim.sensor.params import SensorParams
from camsim.sensor.stages import (
    dn_dtype,
    draw_black_level_error_dn,
    saturating_mean_e,
    saturation_level_e,
    set_stuck_dn,
    stuck_float_dn,
)

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
    maps: FixedPattern | None = None  # the sensor's DSNU (offset, dark-current) and PRNU maps, if any
    black_level_error_dn: np.ndarray | None = None  # the frame's drawn black-level error (3,), DN, if on

    def clean_dn(self) -> np.ndarray:
        """Expected value of ``noisy_dn`` per pixel: G · G_Ve⁻ · E[f_sat(S + D)], shape (3, H, W), float32.

        :func:`clean_dn` of the frame's labels, expected signal, sensor and fixed-pattern maps.
        """
        return clean_dn(self.labels, self.expected, self.sensor, self.maps)


def clean_dn(labels, expected: ExpectedSignal, sensor: SensorParams, maps: FixedPattern | None = None):
    """The clean layer: the expected DN before quantisation per pixel, G · G_Ve⁻ · E[f_sat(S + D)], shape (3, H, W),
    float32, on the device of ``labels`` (numpy, or CuPy with ``maps`` there too: :mod:`camsim.core.xp`).

    With fixed-pattern maps, each pixel's shift of the mean — (g − 1) S̄ (PRNU), (d − 1) D̄ (dark-current DSNU)
    and its offset o — is added to its spectrum's value and the sum clipped at the full well: exact below
    saturation, and for spectra whose every pixel is saturated (their mean, with the smallest PRNU gain, the
    smallest dark-current factor and the most negative DSNU offset, at or above the saturation cap of
    :func:`camsim.sensor.stages.saturating_mean_e`) the full well itself; an approximation in between. The maps
    carry issue 28's fixed patterns (dark shading, column FPN, hot and dead pixels: their offsets and factors), so
    the clean layer has them; a stuck pixel's clean value is its level (on each plane of a Bayer pixel). The
    black-level error is not in it: it is a per-frame draw, noise about the black level (ELD subtracts it as a
    bias), recorded in the sidecar.
    """
    xp = namespace_of(labels)
    k = sensor.dn_per_electron
    table = xp.asarray((expected.clean_e * k).astype(np.float32))
    out = xp.empty((3,) + labels.shape, dtype=np.float32)
    full = saturated_spectra(expected, sensor, maps) if maps is not None and sensor.saturation else None
    for c in range(3):
        out[c] = table[:, c][labels]  # fancy indexing: ~4× faster than np.take with small ints
        # fixed-pattern maps are part of the sensor, so of the expectation (exact below saturation)
        if maps is not None and maps.gain is not None:
            signal = k * expected.signal_e[:, c]
            if full is not None:  # saturated spectra get the full well below: no shift (and no overflow)
                signal = np.where(full[:, c], 0.0, signal)
            excess = maps.gain[c] - 1 if maps.gain_excess is None else maps.gain_excess[c]  # g − 1, cached per run
            out[c] += excess * xp.asarray(signal.astype(np.float32))[labels]
        dark = expected.dark_e[c]
        if maps is not None and maps.dark_gain is not None and dark > 0 and not (
                full is not None and np.all(full[:, c])):  # (every spectrum saturated: the full well below)
            out[c] += np.float32(k * dark) * (maps.dark_gain[c] - np.float32(1))
        if maps is not None and maps.offset_e is not None:
            out[c] += np.float32(k) * maps.offset_e[c]
        if maps is not None and sensor.dead_pixel_fraction > 0 and maps.gain is not None and \
                maps.dark_gain is not None:  # a dead pixel holds its offset alone, exactly (not the shifted mean)
            dead = (maps.gain[c] == 0) & (maps.dark_gain[c] == 0)
            out[c][dead] = 0 if maps.offset_e is None else np.float32(k) * maps.offset_e[c][dead]
        if maps is not None and sensor.saturation:
            xp.minimum(out[c], np.float32(k * sensor.full_well_e), out=out[c])
            if np.any(full[:, c]):
                out[c][xp.asarray(full[:, c])[labels]] = np.float32(k * sensor.full_well_e)
    if maps is not None and maps.stuck_index is not None:
        level = stuck_float_dn(maps.stuck_level_dn, sensor.pedestal_dn)
        if sensor.cfa is None:
            set_stuck_dn(out, maps.stuck_index, level)
        else:  # a Bayer pixel's three planes
            for c in range(3):
                set_stuck_dn(out[c:c + 1], maps.stuck_index, level)
    return out


def saturated_spectra(expected: ExpectedSignal, sensor: SensorParams, maps: FixedPattern) -> np.ndarray:
    """(K, 3) bool: spectra and channels whose every pixel saturates but with probability ≤ ε (fixed-pattern maps
    on): S̄ · min g + D̄ · min d ≥ M(L, max(1, Var S / S̄)), L the full well minus the most negative offset (g the
    PRNU gains, d the dark-current DSNU factors: a pixel with a larger mean only saturates more).

    The total charge is a sum of scaled Poisson counts whose variance is at most max(1, s) times its mean, so
    :func:`camsim.sensor.stages.saturating_mean_e`'s bound holds with that step. The maps may be on a device.
    """
    ex = expected
    g_min = float(namespace_of(maps.gain).min(maps.gain)) if maps.gain is not None else 1.0
    dark = ex.dark_e if maps.dark_gain is None else ex.dark_e * float(namespace_of(maps.dark_gain).min(maps.dark_gain))
    level = saturation_level_e(sensor.full_well_e, maps.offset_e)
    with np.errstate(divide="ignore", invalid="ignore"):
        step = np.maximum(1.0, np.where(ex.signal_e > 0, ex.signal_var_e2 / ex.signal_e, 0.0))
    return ex.signal_e * max(g_min, 0.0) + dark >= saturating_mean_e(level, step)


#: The largest charge (e⁻) or digital number a frame may hold. Its pixels are float32, which ends at 3.4e38: this
#: leaves room for PRNU gains, offsets and noise on top of the mean.
FRAME_VALUE_MAX = 1e36


def check_frame_values(expected: ExpectedSignal, sensor: SensorParams, maps: FixedPattern | None = None) -> None:
    """Refuse a frame whose values would not fit its float32 pixels, with the reason.

    The largest value a pixel can take, in electrons: with saturation on, the full well plus ten σ of the read and
    row noise; with saturation off, the largest mean charge (S̄ times the largest PRNU gain, 1 + 10 σ, plus D̄ times
    the dark-current DSNU's factor at 10 σ of its normal) plus ten σ of its shot noise, DSNU, read and row noise.
    In DN it is G · G_Ve⁻ times that. Both must stay below :data:`FRAME_VALUE_MAX`: only a light or an exposure
    astronomically beyond any camera's with saturation off (nothing then bounds the charge), or a full well or noise
    of that size, reach it. Means that overflow float64 are refused before, by
    :func:`camsim.sensor.expected.expected_signal`. Issue 28's effects: with ``maps`` (the frame's fixed pattern)
    the largest dark factor (hot pixels) and offset (dark shading, column FPN) are the maps' own; without them, ten
    σ of the column FPN and ten RMS of the dark shading; the black-level error adds ten σ in DN; stuck pixels are
    within the ADC's range.

    Raises
    ------
    CamsimError
    """
    k = sensor.dn_per_electron
    readout = 10 * ((sensor.read_noise_e if sensor.read_noise else 0.0) + sensor.row_noise_e)
    if sensor.saturation:
        peak_e = sensor.full_well_e + readout
    else:
        gain = 1 + 10 * sensor.prnu_percent / 100
        if maps is not None and maps.dark_gain is not None and (sensor.hot_pixels or sensor.dead_pixel_fraction):
            dark = expected.dark_e * max(float(np.max(maps.dark_gain)), dark_gain_at(sensor, 10.0))
            mean = expected.signal_e * gain + dark
            peak_e = float(np.max(mean + 10 * np.sqrt((expected.signal_var_e2 + dark) * gain), initial=0.0))
        elif sensor.dsnu_dark_current_percent > 0:
            dark = expected.dark_e * dark_gain_at(sensor, 10.0)
            mean = expected.signal_e * gain + dark
            peak_e = float(np.max(mean + 10 * np.sqrt((expected.signal_var_e2 + dark) * gain), initial=0.0))
        else:
            mean = expected.signal_e * gain + expected.dark_e
            peak_e = float(np.max(mean + 10 * np.sqrt(expected.total_var_e2 * gain), initial=0.0))
        if sensor.dark_offsets and maps is not None and maps.offset_e is not None:
            peak_e += max(float(np.max(np.abs(maps.offset_e))), 10 * sensor.dsnu_e) + readout
        else:
            peak_e += 10 * (sensor.dsnu_e + sensor.dark_shading_e + sensor.column_fpn_e) + readout
    peak_dn = k * peak_e + 10 * sensor.black_level_error_dn
    if max(peak_e, peak_dn) <= FRAME_VALUE_MAX:
        return
    limit = (f"beyond {FRAME_VALUE_MAX:.0e}, the largest value a frame holds (its pixels are float32, which end at "
             f"{float(np.finfo(np.float32).max):.2g})")
    if 10 * sensor.black_level_error_dn > FRAME_VALUE_MAX / 2:
        raise CamsimError(f"the black-level error (ten σ: {10 * sensor.black_level_error_dn:.3g} DN) is {limit}")
    if sensor.saturation and sensor.full_well_e >= readout:
        raise CamsimError(f"the full well of {sensor.full_well_e:.3g} e⁻ is {k * sensor.full_well_e:.3g} DN, {limit}")
    if sensor.saturation or float(np.max(mean)) < peak_e / 2:
        raise CamsimError(f"the noise and offsets (ten σ) make pixel values of {peak_e:.3g} e⁻ = {k * peak_e:.3g} DN, "
                          f"{limit}")
    spectrum, channel = np.unravel_index(int(np.argmax(mean)), mean.shape)
    top = float(expected.signal_e[spectrum, channel] + expected.dark_e[channel])
    raise CamsimError(f"mean charge {top:.3g} e⁻ per pixel (spectrum {spectrum} of {mean.shape[0]}, channel "
                      f"{'RGB'[channel]}) is {k * top:.3g} DN, {limit}: with saturation off nothing bounds the charge; "
                      f"lower F or the exposure, or switch saturation on")


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
        The sensor's DSNU (offset, dark-current) and PRNU maps.
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
    black_level_error_dn: np.ndarray | None = None  # the frame's (3,), DN: added before the ADC

    def maps_rows(self, r0: int, r1: int):
        """(DSNU offset, PRNU gain, dark-current DSNU factor) of rows ``r0:r1``, shape (3, r1 − r0, W) each, or None
        where off."""
        if self.maps is None:
            return None, None, None
        offset = None if self.maps.offset_e is None else self.maps.offset_e[:, r0:r1]
        gain = None if self.maps.gain is None else self.maps.gain[:, r0:r1]
        dark_gain = None if self.maps.dark_gain is None else self.maps.dark_gain[:, r0:r1]
        return offset, gain, dark_gain


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
    *b* (:func:`camsim.core.seeding.block_generators`) with the method's ``draw_block``
    (:mod:`camsim.methods`), on a pool of threads.

    Parameters
    ----------
    labels : numpy.ndarray, shape (H, W), unsigned integer
        Spectrum index per pixel.
    expected : ExpectedSignal
        From :meth:`camsim.render.pipeline.LitScene.expected` or :func:`camsim.sensor.expected.expected_signal`.
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
        ``auto``'s KS tolerance (default :data:`camsim.methods.tolerance.DEFAULT_TOLERANCE`).

    Raises
    ------
    CamsimError
        A frame whose values would not fit its float32 pixels (:func:`check_frame_values`); PRNU with a method
        that has one mean per spectrum (``spectral``: it draws the dark charge per pixel, so it takes the
        dark-current DSNU, but its per-bin signal draws have one mean per spectrum).
    """
    impl = get_method(method)
    check_frame_values(expected, sensor)
    height, width = labels.shape
    rows = block_rows(labels.shape, sensor.cfa)
    maps = fixed_pattern(sensor, labels.shape)
    if sensor.hot_pixels or sensor.dark_offsets:
        check_frame_values(expected, sensor, maps)  # with the maps' own largest factor and offset
    if maps is not None and maps.gain is not None and not impl.per_pixel_mean:
        what = "PRNU" if sensor.prnu_percent > 0 else "dead pixels (a signal gain of 0)"
        raise CamsimError(f"{what} need{'s' if what == 'PRNU' else ''} a per-pixel mean: use method poisson, "
                          f"gaussian or auto, not {method}")
    plan = impl.plan(expected, sensor, statistics, tolerance)
    planes = 3 if sensor.cfa is None else 1  # a colour filter array keeps one value per pixel
    noisy = np.empty((planes, height, width), dtype=np.float32)
    digital = np.empty((planes, height, width), dtype=dn_dtype(sensor.bits)) if sensor.quantisation else None
    error = black_level_error(sensor, rng)
    job = FrameJob(labels, expected, sensor, statistics, plan, maps, noisy, digital, error)
    run_blocks(height, rows, rng, workers,
               lambda: _Scratch(np.empty((rows, width), dtype=np.float32),
                                np.empty(rows * width // 2 + 1, dtype=np.float32)),
               lambda r0, r1, block_rng, scratch: impl.draw_block(job, r0, r1, block_rng, scratch))
    write_stuck(maps, sensor, noisy, digital)
    return Frame(noisy, digital, labels, expected, sensor, plan, maps, error)


def black_level_error(sensor: SensorParams, rng) -> np.ndarray | None:
    """The frame's black-level error (3,) in DN (:func:`camsim.sensor.stages.draw_black_level_error_dn`), drawn on the
    frame's own stream (:func:`camsim.core.seeding.frame_effect_generator` of its seed ``rng``: its other draws stay
    as they were; a fresh stream where ``rng`` is None); None where ``black_level_error_dn`` is 0."""
    if not sensor.black_level_error_dn > 0:
        return None
    try:
        stream = np.random.default_rng() if rng is None else frame_effect_generator(rng)
    except ValueError:
        raise CamsimError("black_level_error_dn needs the frame's seed (a seed sequence or an integer), not a "
                          "device generator") from None
    return draw_black_level_error_dn(stream, sensor.black_level_error_dn)


def write_stuck(maps: FixedPattern | None, sensor: SensorParams, noisy, digital) -> None:
    """Stuck pixels: their levels over a frame's float layer ``noisy`` (:func:`camsim.sensor.stages.stuck_float_dn`)
    and ADC output ``digital`` (None: none), in place, on their device; nothing where there are none."""
    if maps is None or maps.stuck_index is None:
        return
    set_stuck_dn(noisy, maps.stuck_index, stuck_float_dn(maps.stuck_level_dn, sensor.pedestal_dn))
    if digital is not None:
        set_stuck_dn(digital, maps.stuck_index, maps.stuck_level_dn)


def run_blocks(height: int, rows: int, rng, workers: int | None, make_scratch, draw_rows) -> None:
    """The block scheduler: rows 0 … ``height`` in blocks of ``rows``, block *b* drawn by
    ``draw_rows(r0, r1, generator_b, scratch)`` with generator *b* of ``rng``
    (:func:`camsim.core.seeding.block_generators`), on ``workers`` threads (default: every core), each thread with
    its own ``make_scratch()``. The blocks write disjoint rows, so the output does not depend on ``workers``."""
    starts = list(range(0, height, rows))
    generators = block_generators(rng, len(starts))
    per_thread = threading.local()

    def run_block(index: int) -> None:
        if getattr(per_thread, "scratch", None) is None:
            per_thread.scratch = make_scratch()
        r0 = starts[index]
        draw_rows(r0, min(height, r0 + rows), generators[index], per_thread.scratch)

    workers = default_workers() if workers is None else max(1, int(workers))
    if workers == 1 or len(starts) == 1:
        for index in range(len(starts)):
            run_block(index)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(run_block, range(len(starts))))
