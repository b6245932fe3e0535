"""Layer 4, the sensor: its parameters and presets, the physical stages, their exact laws and expected values, the
colour filter array, the camera's quantum efficiency and real cameras' presets; imports only :mod:`camsim.core`,
:mod:`camsim.light` and :mod:`camsim.colour`.

:mod:`camsim.sensor.params` (:class:`SensorParams`, the presets of the paper's Table I), :mod:`camsim.sensor.stages`
(Eqs. 4–12, one pure array function each), :mod:`camsim.sensor.kernels` (fast exact samplers),
:mod:`camsim.sensor.dn_law` (the exact law of a pixel's digital number), :mod:`camsim.sensor.black_level`,
:mod:`camsim.sensor.fixed_pattern` (DSNU and PRNU maps), :mod:`camsim.sensor.expected` (expected values and
variances), :mod:`camsim.sensor.noise_profile` (the DNG NoiseProfile), :mod:`camsim.sensor.cfa` (Bayer patterns),
:mod:`camsim.sensor.camera` (the camera's Qe) and :mod:`camsim.sensor.presets` (real cameras at an ISO).
``tests/test_layers.py`` checks the layers.

The names of :mod:`camsim.sensor.params` that programs import are also here, so that
``from camsim.sensor import SensorParams`` keeps working; camsim's own modules import them from
:mod:`camsim.sensor.params`.
"""

from camsim.sensor.params import (
    EXPOSURE_KEYS,
    PRESETS,
    READ_NOISE_MODELS,
    SENSOR_PARAMS,
    STAGES,
    SensorBatch,
    SensorParams,
    preset,
    with_checked_values,
    with_overrides,
)

__all__ = ["EXPOSURE_KEYS", "PRESETS", "READ_NOISE_MODELS", "SENSOR_PARAMS", "STAGES", "SensorBatch", "SensorParams",
           "preset", "with_checked_values", "with_overrides"]
