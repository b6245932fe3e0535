"""Fixed-pattern noise maps (the two kinds of DSNU, and PRNU), beyond the paper.

The maps belong to the sensor, not the frame: they are drawn from ``sensor_seed`` alone, so that frames of the
same sensor share them while their temporal noise changes (as in ISETCam and the ELD low-light noise model).

Two kinds of dark-signal non-uniformity:

* the offset DSNU (``dsnu_e``): a fixed charge o(x) added to each pixel, Gaussian, the same whatever the
  exposure time T;
* the dark-current DSNU (``dsnu_dark_current_percent`` = p): each pixel's dark-current rate is σ²_dark · d(x), so
  it collects Poisson(σ²_dark · T · d(x)) dark electrons; the spatial σ of its mean dark charge, p/100 · σ²_dark · T,
  grows ∝ T. d is log-normal with mean 1 and σ = p/100: d = exp(s z − s²/2), z standard normal, s² = ln(1 + (p/100)²).
  Log-normal because a dark-current rate is positive and its spread skewed to the high side: real sensors show a
  tail of hot pixels far above the median rate, never a negative one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from camsim.core.seeding import fixed_pattern_generators
from camsim.sensor.params import SensorParams


@dataclass(frozen=True)
class FixedPattern:
    """Per-pixel maps of a sensor, shape (3, H, W) float32 each, or None where off.

    Attributes
    ----------
    offset_e : numpy.ndarray or None
        Offset DSNU: dark offset added to the charge. Unit: e⁻.
    gain : numpy.ndarray or None
        PRNU: factor on the mean signal, around 1. Unitless.
    dark_gain : numpy.ndarray or None
        Dark-current DSNU: factor d on the mean dark charge σ²_dark · T, log-normal of mean 1. Unitless.
    gain_excess : numpy.ndarray or None
        ``gain - 1`` (float32, the same values), kept with the maps so that each frame's clean layer does not
        compute it again; None where ``gain`` is None or it was not kept. Unitless.
    """

    offset_e: np.ndarray | None
    gain: np.ndarray | None
    dark_gain: np.ndarray | None = None
    gain_excess: np.ndarray | None = None


def lognormal_log_sigma(relative_sigma: float) -> float:
    """s, the σ of ln d for a log-normal d of mean 1 and standard deviation ``relative_sigma``: s² = ln(1 + σ²)."""
    return math.sqrt(math.log1p(relative_sigma**2))


def dark_gain_at(sensor: SensorParams, z: float) -> float:
    """The dark-current DSNU factor d = exp(s z − s²/2) of a pixel whose normal deviate is ``z`` (1 when off).

    The map's margins: its d lies within [``dark_gain_at(sensor, −m)``, ``dark_gain_at(sensor, m)``] wherever its
    normal is within m σ, as the offset and gain maps' margins of m σ assume. Unitless.
    """
    s = lognormal_log_sigma(sensor.dsnu_dark_current_percent / 100)
    return math.exp(s * z - s * s / 2)


@lru_cache(maxsize=2)
def _unit_maps(sensor_seed: int, shape: tuple) -> tuple:
    offset_rng, gain_rng, _ = fixed_pattern_generators(sensor_seed)
    offset = offset_rng.standard_normal((3, *shape), dtype=np.float32)
    gain = gain_rng.standard_normal((3, *shape), dtype=np.float32)
    return offset, gain


def prnu_gain(xp, unit_gain, prnu_percent: float):
    """The PRNU gain map g = max(1 + z σ, 0) of unit normals ``z`` (σ = ``prnu_percent`` / 100), float32 on ``xp``'s
    device: a pixel collects no negative charge, so the normal's far tail below 0 (z < −100 / ``prnu_percent``: at a
    PRNU of 20 % and more) is a pixel that collects nothing. Unitless."""
    return xp.maximum(1 + unit_gain * np.float32(prnu_percent / 100), np.float32(0))


@lru_cache(maxsize=1)
def _scaled_maps(sensor_seed: int, shape: tuple, dsnu_e: float, prnu_percent: float) -> tuple:
    """The offset DSNU map o (e⁻), the PRNU gain map g and g − 1 (unitless), float32, read-only (None where
    off): the unit maps scaled, once per sensor and frame size: consecutive frames of a dataset share them (one
    entry: a spec whose frames draw their own DSNU or PRNU scales them per frame, as before)."""
    unit_offset, unit_gain = _unit_maps(sensor_seed, shape)
    offset = unit_offset * np.float32(dsnu_e) if dsnu_e > 0 else None
    gain = prnu_gain(np, unit_gain, prnu_percent) if prnu_percent > 0 else None
    excess = None if gain is None else gain - 1
    for array in (offset, gain, excess):
        if array is not None:
            array.setflags(write=False)  # cached: shared by every frame of the sensor
    return offset, gain, excess


@lru_cache(maxsize=2)
def _dark_gain_map(sensor_seed: int, shape: tuple, relative_sigma: float) -> np.ndarray:
    """d = exp(s z − s²/2) on the third fixed-pattern stream's standard normals z, float32, read-only."""
    _, _, dark_rng = fixed_pattern_generators(sensor_seed)
    z = dark_rng.standard_normal((3, *shape), dtype=np.float32)
    s = lognormal_log_sigma(relative_sigma)
    z *= np.float32(s)
    z -= np.float32(s * s / 2)
    d = np.exp(z, out=z)
    d.setflags(write=False)  # cached: shared by every frame of the sensor
    return d


def fixed_pattern(sensor: SensorParams, shape) -> FixedPattern | None:
    """The sensor's DSNU (offset and dark-current) and PRNU maps for a frame of ``shape`` (H, W); None when all are
    off.

    The unit maps depend on ``sensor_seed`` and the shape only; their magnitudes scale them, so a sensor with more
    offset DSNU has the same pattern, stronger (the dark-current map's hot pixels are the same pixels at any p > 0).
    The dark-current map is kept whether or not the dark-current stage is on: it scales σ²_dark · T, which is then 0.
    """
    if not sensor.fixed_pattern:
        return None
    offset = gain = excess = None
    if sensor.dsnu_e > 0 or sensor.prnu_percent > 0:
        offset, gain, excess = _scaled_maps(sensor.sensor_seed, tuple(shape), sensor.dsnu_e, sensor.prnu_percent)
    p = sensor.dsnu_dark_current_percent
    dark_gain = _dark_gain_map(sensor.sensor_seed, tuple(shape), p / 100) if p > 0 else None
    return FixedPattern(offset, gain, dark_gain, excess)
