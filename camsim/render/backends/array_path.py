"""The array path: a whole frame drawn at once, by the stage functions of :mod:`camsim.sensor.stages`, on numpy or CuPy.

One implementation for both namespaces (:mod:`camsim.core.xp`): the arrays' type picks the device, and the random
generator (numpy's ``PCG64`` or CuPy's cuRAND Philox, :func:`camsim.render.backends.device_generator`) draws there. It
draws the exact law of ``pixel`` statistics per pixel and plane:

::

    charge  = Poisson(g · S̄ + d · D̄)          collect_charge_e (capped far above the full well: cap_mean_e)
            + o                                 add_offset_e      (offset DSNU)
    charge  = min(charge, full well)            saturate_e
    value   = charge + read noise               draw_read_noise_e (Gaussian or Tukey λ), add_read_noise_e
    noisy   = k · value (+ row noise)           electrons_to_dn, add_row_noise        (float32, DN)
    noisy  += black-level error (per frame)     add_black_level_error_dn
    digital = clip(⌊noisy + ½⌋ + P, 0, 2^nb − 1)    quantise_dn (⌊noisy⌋ without a pedestal)
    stuck pixels: their levels over both        set_stuck_dn

with g, d, o the sensor's fixed-pattern maps (PRNU, dark-current DSNU, offset DSNU, with issue 28's dark shading,
column FPN, hot and dead pixels folded in; drawn on the CPU from
``sensor_seed`` as for every frame, and copied to the device once). A Bayer sensor draws one plane, each site its own
channel. The law is the CPU's (:func:`camsim.render.frame.render_frame`): the two agree in distribution, not in bits
(the CPU draws in row blocks, each from its own generator, with its own fast kernels).

:func:`draw_planes` draws from per-pixel means (an image's crops, :mod:`camsim.pairs`); :func:`render_frame_xp`
gathers them from a label map and a frame's :class:`~camsim.sensor.expected.ExpectedSignal`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from camsim.core.xp import generator_namespace, namespace_of, to_host
from camsim.render.backends import device_generator, device_method
from camsim.render.frame import Frame, black_level_error, block_rows, check_frame_values, write_stuck
from camsim.sensor.cfa import cfa_sites
from camsim.sensor.expected import ExpectedSignal
from camsim.sensor.fixed_pattern import FixedPattern, _dark_gain_map, _unit_maps, fixed_pattern, prnu_gain
from camsim.sensor.params import SensorParams
from camsim.sensor.stages import (
    add_black_level_error_dn,
    add_offset_e,
    add_read_noise_e,
    add_row_noise,
    collect_charge_e,
    draw_read_noise_e,
    electrons_to_dn,
    quantise_dn,
    saturate_e,
    saturation_level_e,
)


@dataclass(frozen=True)
class DeviceFrame:
    """A frame drawn by the array path, its arrays on the device that drew it.

    Attributes
    ----------
    noisy_dn : array, shape (planes, H, W), float32
        DN before quantisation (3 planes, or 1 for a Bayer mosaic). Unit: DN.
    digital_dn : array or None, shape (planes, H, W), uint8 (nb ≤ 8) or uint16
        The quantised output; None when quantisation is off. Unit: DN.
    labels : array, shape (H, W)
        Spectrum index per pixel (on the device).
    maps : FixedPattern or None
        The sensor's fixed-pattern maps, on the device.
    """

    noisy_dn: object
    digital_dn: object
    labels: object
    maps: FixedPattern | None = None
    black_level_error_dn: np.ndarray | None = None  # the frame's drawn black-level error (3,), DN, if on

    def to_frame(self, labels: np.ndarray, expected: ExpectedSignal, sensor: SensorParams) -> Frame:
        """The host :class:`~camsim.render.frame.Frame` (its pixels copied from the device), for the usual writers."""
        return Frame(to_host(self.noisy_dn), to_host(self.digital_dn), labels, expected, sensor, None,
                     fixed_pattern(sensor, labels.shape), self.black_level_error_dn)


def draw_planes(rng, mean_e, sensor: SensorParams, *, dark_e=0.0, gain=None, dark_gain=None, offset_e=None,
                black_level_error_dn=None):
    """One frame's planes from per-pixel means, by the exact law of ``pixel`` statistics, on ``rng``'s device.

    Parameters
    ----------
    rng : numpy.random.Generator or cupy.random.Generator
    mean_e : array, shape (planes, H, W) or (B, planes, H, W), float64
        S̄ per pixel, or S̄ + D̄ where there are no dark-current DSNU factors and ``dark_e`` is 0; for B frames drawn
        together, each frame's. Unit: e⁻.
    sensor : SensorParams or SensorBatch
        One frame's sensor, or B frames' (:class:`camsim.sensor.params.SensorBatch`: its per-frame figures
        broadcast against ``mean_e``; one chain of array calls for the batch, each frame its own law).
    dark_e : float or array broadcasting to ``mean_e``
        D̄ where it is not in ``mean_e``. Unit: e⁻.
    gain, dark_gain, offset_e : array like ``mean_e``, optional
        PRNU gain on S̄, dark-current DSNU factor on D̄, offset DSNU (e⁻), per pixel.
    black_level_error_dn : sequence of 3 floats, or array (B, 3), optional
        The frame's black-level error (R, G, B), added after the gain and row noise, before the ADC (each plane its
        channel's; a Bayer mosaic, one plane, each site its channel's); B frames': each its own. Unit: DN.

    Returns
    -------
    noisy : array, float32
        DN before quantisation, shape of ``mean_e``.
    digital : array or None
        Quantised DN (uint8 or uint16), None without quantisation.
    """
    xp = generator_namespace(rng)
    level = saturation_level_e(sensor.full_well_e, offset_e) if sensor.saturation else None
    charge = collect_charge_e(rng, mean_e, dark_e, statistics="pixel", photon_noise=sensor.photon_noise,
                              gain=gain, dark_gain=dark_gain, saturation_e=level)
    charge = add_offset_e(charge, offset_e)
    if sensor.saturation:
        charge = saturate_e(charge, sensor.full_well_e)
    noisy = charge.astype(xp.float32)
    read = sensor.read_noise_e if sensor.read_noise else 0.0
    if np.any(read > 0):  # (a batch: each frame its σ, 0 adding nothing)
        noise = draw_read_noise_e(rng, xp.empty(noisy.shape, dtype=xp.float32), read, sensor.read_noise_model,
                                  sensor.tukey_lambda)
        noisy = add_read_noise_e(noisy, noise)
    electrons_to_dn(noisy, sensor.dn_per_electron, out=noisy)
    if np.any(sensor.row_noise_e > 0):  # one offset per row of each plane (a Bayer mosaic's rows, whatever colours)
        add_row_noise(noisy, sensor.row_noise_e * sensor.dn_per_electron, rng)
    if black_level_error_dn is not None:
        for p in range(noisy.shape[-3]):
            add_black_level_error_dn(noisy[..., p, :, :], black_level_error_dn, sensor.cfa, p)
    digital = quantise_dn(noisy, sensor.bits, pedestal_dn=sensor.pedestal_dn) if sensor.quantisation else None
    return noisy, digital


def mosaic(xp, cfa: str, planes) -> object:
    """The Bayer mosaic (1, H, W) of per-channel planes: each 2 × 2 site of ``cfa`` takes its channel's values.

    ``planes`` is an array (3, H, W) — or (B, 3, H, W), B frames' planes, giving their mosaics (B, 1, H, W) — or a
    function ``(channel, site) -> that site's values`` (an array of the site's shape). The frame's sizes are even
    (:func:`camsim.render.frame.block_rows` checks).
    """
    if not callable(planes):  # four copies, whatever the number of frames
        planes = xp.asarray(planes)
        out = xp.empty(planes.shape[:-3] + (1,) + planes.shape[-2:], dtype=planes.dtype)
        for dy, dx, c in cfa_sites(cfa):
            out[..., 0, dy::2, dx::2] = planes[..., c, dy::2, dx::2]
        return out
    pick = planes
    out = None
    for dy, dx, c in cfa_sites(cfa):
        site = (slice(dy, None, 2), slice(dx, None, 2))
        values = xp.asarray(pick(c, site))
        if out is None:
            out = xp.empty((1, 2 * values.shape[0], 2 * values.shape[1]), dtype=values.dtype)
        out[0][site] = values
    return out


def plane_inputs(xp, labels, expected: ExpectedSignal, sensor: SensorParams, maps: FixedPattern | None,
                 signal_e=None) -> dict:
    """The keyword arguments of :func:`draw_planes` for a label map (on ``xp``'s device) and its expected signal, or
    for per-pixel signal planes ``signal_e``.

    Without fixed-pattern maps, one gather of S̄ + D̄ per plane (:attr:`ExpectedSignal.charge_mean_e`); with them,
    S̄ per pixel, D̄ per plane (per site for a Bayer sensor) and the maps (each site's own channel). ``signal_e``
    (3, H, W) on the device, ≥ 0: S̄ at each pixel instead of the label map's (a frame through the optics,
    :mod:`camsim.render.optics`), D̄ still the expected signal's. Unit: e⁻.
    """
    dark = np.asarray(expected.dark_e, dtype=np.float64)
    offset = gain = dark_gain = None
    if maps is not None:
        offset, gain, dark_gain = maps.offset_e, maps.gain, maps.dark_gain
    per_pixel = gain is not None or dark_gain is not None
    if signal_e is None:  # pick: a site's values of channel c; whole: the three planes
        means = xp.asarray(expected.signal_e.T if per_pixel else expected.charge_mean_e, dtype=xp.float64)  # (3, K)

        def pick(c, site):
            return means[c][labels[site]]

        def whole():
            return means[:, labels]
    else:
        plus = None if per_pixel else dark  # D̄ joins S̄ in the Poisson mean where no maps scale it

        def pick(c, site):
            values = signal_e[c][site].astype(xp.float64)
            return values if plus is None else values + plus[c]

        def whole():
            values = signal_e.astype(xp.float64)
            return values if plus is None else values + xp.asarray(plus.reshape(3, 1, 1))
    if sensor.cfa is None:
        out = {"mean_e": whole(), "offset_e": offset, "gain": gain, "dark_gain": dark_gain}
        if per_pixel:
            out["dark_e"] = xp.asarray(dark.reshape(3, 1, 1))
        return out
    out = {"mean_e": mosaic(xp, sensor.cfa, pick)}
    for key, planes in (("offset_e", offset), ("gain", gain), ("dark_gain", dark_gain)):
        out[key] = None if planes is None else mosaic(xp, sensor.cfa, planes)
    if per_pixel:
        out["dark_e"] = mosaic(xp, sensor.cfa, lambda c, site: xp.full(labels[site].shape, dark[c]))
    return out


@lru_cache(maxsize=4)
def _device_unit_maps(xp, sensor_seed: int, shape: tuple) -> tuple:
    """The unit DSNU-offset and PRNU normals of a sensor on ``xp``'s device (drawn on the host, as every frame's)."""
    offset, gain = _unit_maps(sensor_seed, shape)
    return xp.asarray(offset), xp.asarray(gain)


@lru_cache(maxsize=4)
def _device_dark_gain(xp, sensor_seed: int, shape: tuple, relative_sigma: float):
    return xp.asarray(_dark_gain_map(sensor_seed, shape, relative_sigma))


def _device_effect_maps(xp, maps: FixedPattern) -> FixedPattern:
    """Issue 28's maps (:func:`camsim.sensor.fixed_pattern.fixed_pattern`, cached on the host) copied to ``xp``'s
    device, once per host maps (the last one kept)."""
    cached = _DEVICE_EFFECT.get(xp)
    if cached is not None and cached[0] is maps:
        return cached[1]
    on = {name: None if getattr(maps, name) is None else xp.asarray(getattr(maps, name))
          for name in ("offset_e", "gain", "dark_gain", "gain_excess", "stuck_index", "stuck_level_dn")}
    device = FixedPattern(**on, defect_counts=maps.defect_counts)
    _DEVICE_EFFECT[xp] = (maps, device)
    return device


#: xp -> (host maps, their device copy): issue 28's maps on each device.
_DEVICE_EFFECT: dict = {}


def device_maps(xp, sensor: SensorParams, shape) -> FixedPattern | None:
    """The sensor's fixed-pattern maps on ``xp``'s device: :func:`camsim.sensor.fixed_pattern.fixed_pattern`'s values
    (the same float32 arithmetic on the same unit maps, which are copied to the device once per sensor seed and size:
    the maps belong to the sensor, not the frame)."""
    if not sensor.fixed_pattern:
        return None
    shape = tuple(shape)
    if sensor.dark_offsets or sensor.hot_pixels or sensor.dead_pixel_fraction > 0 or sensor.stuck_pixel_fraction > 0:
        return _device_effect_maps(xp, fixed_pattern(sensor, shape))
    return _device_scaled_maps(xp, sensor.sensor_seed, shape, sensor.dsnu_e, sensor.prnu_percent,
                               sensor.dsnu_dark_current_percent)


@lru_cache(maxsize=4)
def _device_scaled_maps(xp, sensor_seed: int, shape: tuple, dsnu_e: float, prnu_percent: float,
                        dark_percent: float) -> FixedPattern:
    """The offset DSNU, PRNU and dark-current DSNU maps of :func:`device_maps`, kept for the figures they depend on
    (the same camera at another ISO or exposure: the same maps, no new arrays)."""
    offset = gain = None
    if dsnu_e > 0 or prnu_percent > 0:
        unit_offset, unit_gain = _device_unit_maps(xp, sensor_seed, shape)
        offset = unit_offset * np.float32(dsnu_e) if dsnu_e > 0 else None
        gain = prnu_gain(xp, unit_gain, prnu_percent) if prnu_percent > 0 else None
    dark_gain = _device_dark_gain(xp, sensor_seed, shape, dark_percent / 100) if dark_percent > 0 else None
    return FixedPattern(offset, gain, dark_gain)


def render_frame_xp(xp, labels, expected: ExpectedSignal, sensor: SensorParams, *, rng, statistics: str = "pixel",
                    method: str = "poisson", signal_e=None) -> DeviceFrame:
    """Render one frame with the array path on ``xp`` (numpy or CuPy): the arrays stay on the device.

    Parameters
    ----------
    xp : module
        ``numpy`` or ``cupy``.
    labels : array, shape (H, W), unsigned integer
        Spectrum index per pixel (numpy or ``xp``; copied to the device).
    expected : ExpectedSignal
    sensor : SensorParams
    rng : SeedSequence, int, numpy Generator or an ``xp`` generator
        The frame's seed (:func:`camsim.render.backends.device_generator`): the same seed, device and library version
        give the same frame.
    statistics, method : str
        ``pixel`` statistics only; every method but ``spectral`` (:func:`camsim.render.backends.device_method`).
    signal_e : array, shape (3, H, W), optional
        S̄ at each pixel on the device, ≥ 0, instead of the label map's (:func:`plane_inputs`): a frame through the
        optics (:func:`camsim.render.optics.optics_frame_xp`). Unit: e⁻.

    Raises
    ------
    CamsimError
        ``paper`` statistics, ``spectral``, a Bayer sensor with an odd frame size, values beyond float32
        (:func:`camsim.render.frame.check_frame_values`).
    """
    device_method(method, statistics)
    check_frame_values(expected, sensor)
    block_rows(labels.shape, sensor.cfa)  # a Bayer pattern needs an even size
    error = black_level_error(sensor, rng)  # on its own stream of the frame's seed, on the host
    rng = device_generator(xp, rng)
    if namespace_of(rng) is not xp:
        raise ValueError("render_frame_xp: the generator draws on another device than xp")
    labels_d = xp.asarray(labels)
    maps = device_maps(xp, sensor, labels.shape)
    noisy, digital = draw_planes(rng, sensor=sensor, black_level_error_dn=error,
                                 **plane_inputs(xp, labels_d, expected, sensor, maps, signal_e))
    write_stuck(maps, sensor, noisy, digital)
    return DeviceFrame(noisy, digital, labels_d, maps, error)


__all__ = ["DeviceFrame", "device_maps", "draw_planes", "mosaic", "plane_inputs", "render_frame_xp"]
