"""Fixed-pattern noise maps (DSNU and PRNU) and the heavy-tailed read-noise law, beyond the paper.

The maps belong to the sensor, not the frame: they are drawn from ``sensor_seed`` alone, so that frames of the
same sensor share them while their temporal noise changes (as in ISETCam and the ELD low-light noise model).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import special

from camsim.sensor import SensorParams

_MAP_KEY = 0x46504E  # "FPN": the maps' spawn key, apart from every frame's


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
    offset_ss, gain_ss = np.random.SeedSequence(sensor_seed, spawn_key=(_MAP_KEY,)).spawn(2)
    offset = np.random.Generator(np.random.PCG64(offset_ss)).standard_normal((3, *shape), dtype=np.float32)
    gain = np.random.Generator(np.random.PCG64(gain_ss)).standard_normal((3, *shape), dtype=np.float32)
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


def tukey_lambda_variance(lam: float) -> float:
    """Variance of the standard Tukey lambda law, x = (u^λ − (1 − u)^λ) / λ (λ = 0: the logistic law)."""
    if abs(lam) < 1e-9:
        return np.pi**2 / 3
    return 2 / lam**2 * (1 / (1 + 2 * lam) - special.gamma(lam + 1) ** 2 / special.gamma(2 * lam + 2))


def tukey_lambda(rng: np.random.Generator, out: np.ndarray, lam: float, std: float) -> np.ndarray:
    """Fill ``out`` with Tukey lambda draws of shape ``lam``, scaled to standard deviation ``std``.

    Inverse-CDF sampling on float64 uniforms in (0, 1); heavier tails than the Gaussian for λ < 0.14.
    """
    u = rng.random(out.shape)
    u[u == 0] = np.finfo(float).tiny
    x = np.log(u / (1 - u)) if abs(lam) < 1e-9 else (u**lam - (1 - u) ** lam) / lam
    out[...] = x * (std / np.sqrt(tukey_lambda_variance(lam)))
    return out
