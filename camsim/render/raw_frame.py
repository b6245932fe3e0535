"""The per-pixel renderer of raw sources: a real camera's raw electrons made into a target sensor's frame.

The source gives each CFA site its electrons s (:mod:`camsim.sensor.raw_laws`); a photon law draws the target's
charge from f · s (f = F · T / T_src), and every later stage is the target sensor's, by the stage functions of
:mod:`camsim.sensor.stages` in the order :func:`camsim.render.frame.render_frame` runs them: the charge (with the
dark current, PRNU and the dark-current DSNU), the offset DSNU, the full well, the read noise (its model and Tukey
λ), the gain, the row noise, the black-level error and the ADC with its pedestal, then the stuck pixels' levels
(issue 28's dark shading, column FPN, hot and dead pixels are in the maps). The block scheduler is render_frame's
(:func:`camsim.render.frame.run_blocks`): row blocks (:func:`camsim.render.frame.block_rows`), block *b* drawing from
child *b* of the frame's seed, on a pool of threads, so a seed gives the same bits whatever the number of workers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.xp import namespace_of
from camsim.render.frame import Frame, black_level_error, block_rows, run_blocks, write_stuck
from camsim.sensor.cfa import CFA_PATTERNS, cfa_sites
from camsim.sensor.expected import clean_charge_e, poisson_tail_reach
from camsim.sensor.fixed_pattern import FixedPattern, fixed_pattern
from camsim.sensor.params import SensorParams
from camsim.sensor.raw_laws import (
    PHOTON_LAWS,
    add_photons_e,
    check_thin_fraction,
    keep_probability,
    source_count_e,
    thin_photons_e,
)
from camsim.sensor.stages import (
    add_black_level_error_dn,
    add_offset_e,
    add_read_noise_e,
    add_row_noise,
    dn_dtype,
    draw_read_noise_e,
    electrons_to_dn,
    quantise_dn,
    saturate_e,
    saturation_level_e,
    set_stuck_dn,
    stuck_float_dn,
)


@dataclass(frozen=True)
class RawDraw:
    """One frame drawn from a raw source.

    Attributes
    ----------
    noisy_dn : numpy.ndarray, shape (1, H, W), float32
        k · (f_sat(charge + o) + read noise) + row noise: the DN before quantisation (as
        :attr:`camsim.render.frame.Frame.noisy_dn` of a CFA frame). Unit: DN.
    digital_dn : numpy.ndarray or None, shape (1, H, W), uint8 (nb ≤ 8) or uint16
        The quantised DN, with the pedestal; None when quantisation is off. Unit: DN.
    clean_dn : numpy.ndarray or None, shape (H, W), float32
        The law's expected DN before quantisation at each site, k · E[min(charge + o, full well)] (the fixed-pattern
        maps' shifts included, as :func:`camsim.render.frame.clean_dn`; a stuck pixel's level; not the black-level
        error): see :func:`render_raw_frame` for where it is exact; None where not asked for
        (:func:`render_expectation_frame`'s ``clean``). Unit: DN.
    maps : FixedPattern or None
        The target sensor's DSNU (offset, dark-current) and PRNU maps, shape (3, H, W) each (a site uses its
        channel's plane), or None when all are off.
    """

    noisy_dn: np.ndarray
    digital_dn: np.ndarray | None
    clean_dn: np.ndarray | None
    maps: FixedPattern | None
    black_level_error_dn: np.ndarray | None = None  # the frame's drawn black-level error (3,), DN, if on


@dataclass(frozen=True)
class _RawJob:
    """What every block of a raw frame needs (read-only but the outputs)."""

    source: np.ndarray  # (planes, H, W) float32, e⁻: one plane (a CFA mosaic) or three (a three-chip sensor's)
    sensor: SensorParams
    fraction: float
    law: str
    maps: FixedPattern | None
    dark_cell: np.ndarray  # (2, 2) float64: D̄ of each site of the CFA cell, e⁻
    noisy: np.ndarray  # (1, H, W) float32 output
    digital: np.ndarray | None  # (1, H, W) output
    clean: np.ndarray | None  # (planes, H, W) float32 output, or None: not computed
    black_level_error_dn: np.ndarray | None = None  # (3,) DN: added before the ADC


class _Scratch:
    """A thread's reusable buffers, (rows, W) each (Box–Muller's ``work``: half of that)."""

    def __init__(self, rows: int, width: int):
        self.rows, self.width = rows, width
        self.mean = np.empty((rows, width), dtype=np.float64)
        self.noise = np.empty((rows, width), dtype=np.float32)
        self.work = np.empty(rows * width // 2 + 1, dtype=np.float32)
        self.dark = None  # (rows, W) float64 tiling of the dark cell, made on first use
        self.maps = {}  # name -> (rows, W) float32 buffer of a mosaicked map

    def map_rows(self, name: str, planes: np.ndarray, cfa: str | None, r0: int, r1: int,
                 channel: int = 0) -> np.ndarray:
        """Rows r0:r1 of a (3, H, W) map mosaicked by the CFA: each site takes its channel's plane (no CFA: the
        plane ``channel``'s rows, a view)."""
        if cfa is None:
            return planes[channel, r0:r1]
        buffer = self.maps.get(name)
        if buffer is None:
            buffer = self.maps[name] = np.empty((self.rows, self.width), dtype=np.float32)
        out = buffer[: r1 - r0]
        for dy, dx, c in cfa_sites(cfa):
            out[dy::2, dx::2] = planes[c, r0 + dy : r1 : 2, dx::2]
        return out


def _check(source_e, sensor: SensorParams, fraction: float, law: str) -> np.ndarray:
    """The source as a 2-D float32 array, or a CamsimError with the reason."""
    if law not in PHOTON_LAWS:
        raise CamsimError(f"unknown photon law {law!r}; photon laws: {', '.join(PHOTON_LAWS)}")
    if sensor.cfa not in CFA_PATTERNS:
        raise CamsimError("a raw source needs a sensor with a Bayer colour filter array (sensor.cfa), got none")
    try:
        value = float(fraction)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and value >= 0):
        raise CamsimError(f"the fraction F·T/T_source must be a finite number ≥ 0, got {fraction!r}")
    source = np.asarray(source_e)
    if source.ndim != 2 or source.size == 0:
        raise CamsimError(f"a raw source is one (H, W) plane of electrons, got an array of shape {source.shape}")
    if not np.issubdtype(source.dtype, np.floating) and not np.issubdtype(source.dtype, np.integer):
        raise CamsimError(f"a raw source holds numbers, got dtype {source.dtype}")
    source = source.astype(np.float32, copy=False)
    if not np.isfinite(source).all():
        raise CamsimError("the raw source has non-finite electron values (NaN or infinite)")
    if law == "thin":
        check_thin_fraction(float(fraction))
    return source


def render_raw_frame(source_e, sensor: SensorParams, fraction: float, *, law: str = "add",
                     rng: np.random.Generator | np.random.SeedSequence | int | None = None,
                     workers: int | None = None) -> RawDraw:
    """Draw one frame of the target ``sensor`` from a raw source's electrons, by a photon law.

    Per pixel (site of channel c; g, d, o the PRNU gain, dark-current factor and DSNU offset of the sensor's maps,
    D̄_c = σ²_dark,c · T), the charge X is ``add``'s Poisson(f · max(s, 0) · g + D̄_c d) or ``thin``'s
    Binomial(round(max(s, 0)), f · g) + Poisson(D̄_c d) (:mod:`camsim.sensor.raw_laws`), and the frame's value is
    k · (min(X + o, full well) + read noise) + row noise, then the ADC: the stages of :mod:`camsim.sensor.stages`,
    each on or off as ``sensor`` says (photon noise off: the signal's mean exactly, the dark charge still drawn). The
    PRNU gains are ≥ 0 (:func:`camsim.sensor.fixed_pattern.prnu_gain`).

    Parameters
    ----------
    source_e : numpy.ndarray, shape (H, W)
        The source's electrons s = (DN − black) / K_src at each site (may be negative: read noise; the laws clip
        at 0). H and W even. Unit: e⁻.
    sensor : SensorParams
        The target sensor, ``cfa`` set to the source's pattern (of the top-left cell).
    fraction : float
        f = F · T / T_src: the frame expects f · max(s, 0) signal electrons. ``thin`` needs f ≤ 1 (and f · g ≤ 1).
    law : {'add', 'thin'}
    rng : numpy.random.Generator, numpy.random.SeedSequence or int, optional
        Seed of the frame; row block *b* draws from its child *b*.
    workers : int, optional
        Threads (default: the machine's cores). The output does not depend on it.

    Returns
    -------
    RawDraw
        ``clean_dn`` is k · E[min(X + o, full well)]: exact for ``add`` (X Poisson; photon noise off: the signal
        plus a Poisson dark charge) by :func:`camsim.sensor.expected.clean_charge_e` wherever a pixel can reach the
        full well and k · (E X + o) elsewhere; exact for ``thin`` away from the full well, and at it when f · g = 1
        or photon noise is off (X is then a constant plus a Poisson dark charge). ``thin`` near the full well
        with p = f · g < 1 is approximated there: its X = Binomial(n, p) + Poisson(D̄ d) by the shifted Poisson
        n p² + Poisson(n p (1 − p) + D̄ d) of the same mean and variance, in the same closed form (within 5e-5 of
        the exact value, summed over the binomial, for a full well of 1000 e⁻ and p from 0.1 to 0.99:
        ``tests/sensor/test_raw_laws.py``).

    Raises
    ------
    CamsimError
        An unknown law, a sensor without a CFA, an odd frame size, a source that is not a finite (H, W) plane, a
        negative or non-finite fraction; ``thin`` with f > 1 or f · g > 1.
    """
    source = _check(source_e, sensor, fraction, law)
    fraction = float(fraction)
    height, width = source.shape
    rows = block_rows(source.shape, sensor.cfa)  # refuses an odd size
    maps = fixed_pattern(sensor, source.shape)
    if law == "thin" and maps is not None and maps.gain is not None:  # the largest gain of a site's own channel
        sites = cfa_sites(sensor.cfa)
        check_thin_fraction(fraction, max(float(maps.gain[c, dy::2, dx::2].max()) for dy, dx, c in sites))
    dark_cell = np.empty((2, 2))
    for dy, dx, c in cfa_sites(sensor.cfa):
        dark_cell[dy, dx] = sensor.dark_mean_e[c]
    noisy = np.empty((1, height, width), dtype=np.float32)
    digital = np.empty((1, height, width), dtype=dn_dtype(sensor.bits)) if sensor.quantisation else None
    clean = np.empty((height, width), dtype=np.float32)
    error = black_level_error(sensor, rng)
    job = _RawJob(source[None], sensor, fraction, law, maps, dark_cell, noisy, digital, clean[None], error)
    run_blocks(height, rows, rng, workers, lambda: _Scratch(rows, width),
               lambda r0, r1, block_rng, scratch: _draw_block(job, r0, r1, block_rng, scratch))
    write_stuck(maps, sensor, noisy, digital)
    if maps is not None and maps.stuck_index is not None:
        set_stuck_dn(clean[None], maps.stuck_index, stuck_float_dn(maps.stuck_level_dn, sensor.pedestal_dn))
    return RawDraw(noisy, digital, clean, maps, error)


def _can_saturate(poisson_mean_e: np.ndarray, base_e, full_well_e: float) -> bool:
    """Whether some pixel, base + Poisson(mean), may reach the full well with a probability that shows in a float64
    mean: :func:`camsim.sensor.expected.poisson_min_e`'s test (⌊c − base⌋ − 1 ≤
    :func:`camsim.sensor.expected.poisson_tail_reach` (λ)), on the rows' largest mean and base (so never false where
    a pixel's own test is true)."""
    top = max(float(poisson_mean_e.max()), 0.0)
    top_base = 0.0 if base_e is None else float(np.max(base_e))
    return math.floor(full_well_e - top_base) - 1 <= poisson_tail_reach(top, math)


def _draw_block(job: _RawJob, r0: int, r1: int, rng: np.random.Generator, scratch: _Scratch) -> None:
    """Rows ``r0:r1`` (r0 even) of a raw frame: the charge by the law, then the target's stages, and the clean
    layer; plane after plane from the block's one generator (a CFA mosaic is one plane)."""
    for plane in range(job.source.shape[0]):
        _draw_plane(job, plane, r0, r1, rng, scratch)


def _draw_plane(job: _RawJob, plane: int, r0: int, r1: int, rng: np.random.Generator, scratch: _Scratch) -> None:
    """Rows ``r0:r1`` of plane ``plane`` (a CFA mosaic, or a three-chip sensor's channel ``plane``)."""
    sensor, cfa, h = job.sensor, job.sensor.cfa, r1 - r0
    k = sensor.dn_per_electron
    maps = job.maps
    offset = gain = dark_gain = None
    if maps is not None:
        offset = None if maps.offset_e is None else scratch.map_rows("offset", maps.offset_e, cfa, r0, r1, plane)
        gain = None if maps.gain is None else scratch.map_rows("gain", maps.gain, cfa, r0, r1, plane)
        dark_gain = None if maps.dark_gain is None else scratch.map_rows("dark_gain", maps.dark_gain, cfa, r0, r1,
                                                                         plane)
    if cfa is None:  # a three-chip sensor's channel: one mean dark charge
        has_dark = bool(job.dark_cell[plane] > 0)
        dark = 0.0 if not has_dark else float(job.dark_cell[plane]) if dark_gain is None else \
            float(job.dark_cell[plane]) * dark_gain.astype(np.float64)
    else:
        has_dark = bool(np.any(job.dark_cell > 0))
        if has_dark and scratch.dark is None:
            scratch.dark = np.tile(job.dark_cell, (scratch.rows // 2, scratch.width // 2))
        dark = 0.0 if not has_dark else scratch.dark[:h] if dark_gain is None else scratch.dark[:h] * dark_gain
    level = saturation_level_e(sensor.full_well_e, offset) if sensor.saturation else None
    source = job.source[plane, r0:r1]
    mean = scratch.mean[:h]  # float64: the Poisson means
    clean = None if job.clean is None else job.clean[plane, r0:r1]

    if job.law == "add":
        np.maximum(source, 0.0, out=mean)
        mean *= job.fraction
        if gain is not None:
            mean *= gain
        if sensor.photon_noise:  # Poisson(f max(s, 0) g + D̄ d): the mean built in place, one draw
            if has_dark:
                mean += dark
            charge = add_photons_e(rng, mean, saturation_e=level)
            poisson_mean, base = mean, offset
        else:  # the signal exactly, plus Poisson(D̄ d)
            charge = add_photons_e(rng, mean, dark, photon_noise=False, saturation_e=level)
            poisson_mean, base = dark, (mean if offset is None else mean + offset)
    else:
        count = source_count_e(source)
        charge = thin_photons_e(rng, count, job.fraction, dark, gain=gain, photon_noise=sensor.photon_noise,
                                saturation_e=level)
        p = keep_probability(job.fraction, gain)
        if sensor.photon_noise:  # X = Binomial(n, p) + Poisson(D̄ d) ≈ n p² + Poisson(n p (1 − p) + D̄ d): its mean
            # and variance, exact where p = 1 (n + Poisson(D̄ d)) and where no pixel can reach the full well
            spread = count * (p * (1.0 - p))
            poisson_mean = spread + dark if has_dark else spread
            base = count * (p * p)
            base = base if offset is None else base + offset
        else:  # the signal n p exactly, plus Poisson(D̄ d)
            signal = count * p
            poisson_mean, base = dark, (signal if offset is None else signal + offset)

    # the clean layer: k E[min(X + o, full well)], X = Poisson(poisson_mean) + (base − o)
    if clean is not None:
        _clean_rows(clean, poisson_mean, base, sensor, k)

    # the target's stages, in the order render_frame runs them (float32 in the output; float64 with offsets)
    view = job.noisy[plane, r0:r1]
    if offset is not None:
        value = add_offset_e(charge, offset)  # a new float array
    else:
        np.copyto(view, charge, casting="unsafe")  # counts: exact in float32 up to 2^24 e⁻
        value = view
    if sensor.saturation:
        saturate_e(value, sensor.full_well_e, out=value)
    if sensor.read_noise and sensor.read_noise_e > 0:
        noise = scratch.noise[:h]
        draw_read_noise_e(rng, noise, sensor.read_noise_e, sensor.read_noise_model, sensor.tukey_lambda,
                          scratch.work)
        add_read_noise_e(value, noise, out=view)
    elif value is not view:
        np.copyto(view, value, casting="unsafe")
    electrons_to_dn(view, k, out=view)
    if sensor.row_noise_e > 0:
        add_row_noise(view, sensor.row_noise_e * k, rng)
    if job.black_level_error_dn is not None:
        add_black_level_error_dn(view, job.black_level_error_dn, cfa, plane)
    if job.digital is not None:
        quantise_dn(view, sensor.bits, out=job.digital[plane, r0:r1], pedestal_dn=sensor.pedestal_dn)


def _clean_rows(clean: np.ndarray, poisson_mean, base, sensor: SensorParams, k: float) -> None:
    """Write k · E[min(base + Poisson(poisson_mean), full well)] into ``clean`` (h, W) float32 (without saturation,
    or where no pixel of the rows can reach the full well: k · (poisson_mean + base))."""
    lam = np.broadcast_to(np.asarray(poisson_mean, dtype=np.float64), clean.shape)
    if sensor.saturation and _can_saturate(lam, base, sensor.full_well_e):
        value = clean_charge_e(lam, sensor, 0.0 if base is None else np.asarray(base, dtype=np.float64))
        np.multiply(value, k, out=clean, casting="unsafe")
        return
    np.multiply(lam, k, out=clean, casting="unsafe")
    if base is not None:
        clean += np.float32(k) * np.asarray(base, dtype=np.float32)


@dataclass(frozen=True)
class ExpectationFrame(Frame):
    """A frame drawn from a per-pixel expectation (:func:`render_expectation_frame`: a moving scene's, a scene seen
    through optics), its clean layer per pixel, not one value per spectrum."""

    clean: np.ndarray | None = None  # (3, H, W) float32, DN

    def clean_dn(self) -> np.ndarray:
        return self.clean


def static_signal_e(labels, signal_e: np.ndarray):
    """S̄ per pixel and channel, (3, H, W) float32, from the per-spectrum ``signal_e`` (K, 3) through ``labels``, on
    the labels' device (numpy or CuPy: :mod:`camsim.core.xp`). Unit: e⁻."""
    xp = namespace_of(labels)
    table = xp.asarray(np.asarray(signal_e, dtype=np.float32))
    out = xp.empty((3,) + labels.shape, dtype=xp.float32)
    for c in range(3):
        out[c] = table[:, c][labels]
    return out


def render_expectation_frame(signal_e, sensor: SensorParams, *,
                             rng: np.random.Generator | np.random.SeedSequence | int | None = None,
                             workers: int | None = None, clean: bool = True) -> RawDraw:
    """Draw one frame from a per-pixel expectation of signal electrons, (planes, H, W): a moving scene's frame.

    The ``add`` law of :func:`render_raw_frame` with f = 1 on a (1, H, W) CFA mosaic (each site its channel's
    expectation) or a three-chip sensor's (3, H, W) planes: per pixel the charge is Poisson(S̄ · g + D̄ · d) and
    every later stage is the sensor's, by the same stage functions, blocks and seeds (a three-chip block draws its
    planes R, G, B one after another from the block's generator). It is how :mod:`camsim.render.sequence` draws a
    frame whose expectation is no longer one value per spectrum.

    Parameters
    ----------
    signal_e : numpy.ndarray, shape (1, H, W) (CFA) or (3, H, W) (three-chip)
        S̄: the expected signal electrons at each pixel before PRNU, ≥ 0 (the dark charge is the sensor's).
    sensor : SensorParams
    rng, workers : as :func:`render_raw_frame`.
    clean : bool
        Compute the clean layer (False: ``clean_dn`` is None, for a caller that makes its own, as a CFA sequence's
        every-channel :func:`expectation_clean_dn`; the draws are the same).

    Returns
    -------
    RawDraw
        ``noisy_dn`` and ``digital_dn`` of shape (planes, H, W); ``clean_dn`` (planes, H, W): k · E[min(X + o, full
        well)] at each pixel's own plane (exact: :func:`camsim.sensor.expected.clean_charge_e`), or None.
    """
    source = np.ascontiguousarray(signal_e, dtype=np.float32)
    planes = 1 if sensor.cfa is not None else 3
    if source.ndim != 3 or source.shape[0] != planes:
        raise CamsimError(f"an expectation frame for this sensor has shape ({planes}, H, W), got {source.shape}")
    height, width = source.shape[1:]
    rows = block_rows((height, width), sensor.cfa)
    maps = fixed_pattern(sensor, (height, width))
    if sensor.cfa is None:
        dark_cell = np.asarray(sensor.dark_mean_e, dtype=np.float64)
    else:
        dark_cell = np.empty((2, 2))
        for dy, dx, c in cfa_sites(sensor.cfa):
            dark_cell[dy, dx] = sensor.dark_mean_e[c]
    noisy = np.empty((planes, height, width), dtype=np.float32)
    digital = np.empty((planes, height, width), dtype=dn_dtype(sensor.bits)) if sensor.quantisation else None
    clean = np.empty((planes, height, width), dtype=np.float32) if clean else None
    error = black_level_error(sensor, rng)
    job = _RawJob(source, sensor, 1.0, "add", maps, dark_cell, noisy, digital, clean, error)
    run_blocks(height, rows, rng, workers, lambda: _Scratch(rows, width),
               lambda r0, r1, block_rng, scratch: _draw_block(job, r0, r1, block_rng, scratch))
    write_stuck(maps, sensor, noisy, digital)
    if clean is not None and maps is not None and maps.stuck_index is not None:
        set_stuck_dn(clean, maps.stuck_index, stuck_float_dn(maps.stuck_level_dn, sensor.pedestal_dn))
    return RawDraw(noisy, digital, clean, maps, error)


def expectation_clean_dn(signal_e, sensor: SensorParams, maps: FixedPattern | None,
                         workers: int | None = None) -> np.ndarray:
    """The clean layer (3, H, W) float32 of every channel at every pixel from a per-pixel expectation
    ``signal_e`` (3, H, W) e⁻: k · E[min(X + o, full well)], X = Poisson(S̄_c g_c + D̄_c d_c) (photon noise off: the
    signal exactly plus Poisson(D̄_c d_c)), with channel c's maps (:func:`_clean_rows`: exact); a stuck pixel's
    level on each plane. A CFA frame's EXR clean layer: its sites' own channel equals its draw's clean mosaic. In
    row blocks on ``workers`` threads (:func:`camsim.render.frame.run_blocks`; no random draws)."""
    k = sensor.dn_per_electron
    height, width = np.shape(signal_e)[1:]
    out = np.empty(np.shape(signal_e), dtype=np.float32)

    def rows(r0: int, r1: int, _rng, _scratch) -> None:
        for c in range(3):
            mean = np.maximum(np.asarray(signal_e[c, r0:r1], dtype=np.float64), 0.0)
            gain = offset = dark_gain = None
            if maps is not None:
                gain = None if maps.gain is None else maps.gain[c, r0:r1]
                offset = None if maps.offset_e is None else maps.offset_e[c, r0:r1]
                dark_gain = None if maps.dark_gain is None else maps.dark_gain[c, r0:r1]
            if gain is not None:
                mean *= gain
            dark = float(sensor.dark_mean_e[c])
            dark = dark if dark_gain is None or dark == 0 else dark * dark_gain.astype(np.float64)
            if sensor.photon_noise:
                mean += dark
                _clean_rows(out[c, r0:r1], mean, offset, sensor, k)
            else:
                _clean_rows(out[c, r0:r1], dark, mean if offset is None else mean + offset, sensor, k)

    run_blocks(height, max(1, (1 << 16) // max(width, 1)), 0, workers, lambda: None, rows)
    if maps is not None and maps.stuck_index is not None:
        level = stuck_float_dn(maps.stuck_level_dn, sensor.pedestal_dn)
        for c in range(3):
            set_stuck_dn(out[c:c + 1], maps.stuck_index, level)
    return out
