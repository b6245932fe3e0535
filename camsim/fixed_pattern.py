"""Fixed-pattern noise maps (DSNU and PRNU), beyond the paper.

The maps belong to the sensor, not the frame: they are drawn from ``sensor_seed`` alone, so that frames of the
same sensor share them while their temporal noise changes (as in ISETCam and the ELD low-light noise model).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from camsim.seeding import fixed_pattern_generators
from camsim.sensor import SensorParams


@dataclass(frozen=True)
class FixedPattern:
    """Per-pixel maps of a sensor, shape (3, H, W) float32 each, or None where off.

    Attributes
    ----------
    offset_e : numpy.ndarray or None
        DSNU: dark offset added to the charge. Unit: e⁻.
    gain : numpy.ndarray or None
        PRNU: factor on the mean signal, around 1. Unitless.
    """

    offset_e: np.ndarray | None
    gain: np.ndarray | None


@lru_cache(maxsize=2)
def _unit_maps(sensor_seed: int, shape: tuple) -> tuple:
    offset_rng, gain_rng = fixed_pattern_generators(sensor_seed)
    offset = offset_rng.standard_normal((3, *shape), dtype=np.float32)
    gain = gain_rng.standard_normal((3, *shape), dtype=np.float32)
    return offset, gain


def fixed_pattern(sensor: SensorParams, shape) -> FixedPattern | None:
    """The sensor's DSNU and PRNU maps for a frame of ``shape`` (H, W); None when both are off.

    The unit maps depend on ``sensor_seed`` and the shape only; their magnitudes scale them, so a sensor with more
    DSNU has the same pattern, stronger.
    """
    if not sensor.fixed_pattern:
        return None
    unit_offset, unit_gain = _unit_maps(sensor.sensor_seed, tuple(shape))
    offset = unit_offset * np.float32(sensor.dsnu_e) if sensor.dsnu_e > 0 else None
    gain = 1 + unit_gain * np.float32(sensor.prnu_percent / 100) if sensor.prnu_percent > 0 else None
    return FixedPattern(offset, gain)
