"""What the EMVA 1288 measurement should find: the configured camera's values and camsim's exact model terms."""

from __future__ import annotations

import math

import numpy as np

from camsim.core.errors import CamsimError
from camsim.sensor.fixed_pattern import lognormal_log_sigma
from camsim.sensor.params import PRESETS, SensorParams
from camsim.sensor.stages import adc_offset_dn

#: The preset ``camsim emva`` measures by default: 12 bits, so that quantisation does not dominate the dark noise.
DEFAULT_PRESET = "emva-12bit"
#: The analysed channel (G).
CHANNEL = 1

def sensor_for(preset_name: str | None = None, sensor: SensorParams | None = None) -> tuple[SensorParams, str]:
    """The sensor to measure: ``sensor`` if given, else the preset (default :data:`DEFAULT_PRESET`)."""
    if sensor is not None:
        return sensor, preset_name or "custom"
    name = preset_name or DEFAULT_PRESET
    if name not in PRESETS:
        raise CamsimError(f"unknown sensor preset {name!r}; presets: {', '.join(PRESETS)}")
    return PRESETS[name], name


def configured_values(sensor: SensorParams, eta: float) -> dict:
    """What the configuration says each EMVA quantity is (None where the stage is off).

    * K: G · G_Ve⁻ (DN/e⁻).
    * dark noise: the temporal dark noise EMVA's σ_d measures at this exposure, √(σ²_read + μ_dark + σ²_row) in
      e⁻: read noise, the shot noise of the dark electrons and the row noise (0 in the presets). μ_dark is
      ``SensorParams.dark_mean_e``: the dark current at the sensor's ``temperature_c`` times the exposure.
    * QE: η of the analysed channel at the test wavelength (e⁻ per photon; EMVA reports it in %).
    * saturation: the full well (e⁻). EMVA's μ_e,sat is the photo-electrons at the step where the temporal
      variance peaks, a little below it: see :func:`predicted_saturation_e` and the report.
    * DSNU (e⁻) and PRNU (%): the configured standard deviations of the fixed-pattern maps; the DSNU at this
      exposure has both kinds, √(dsnu_e² + (p/100 · μ_dark)²), the offset and the dark-current one (independent
      maps: their variances add).
    """
    c = CHANNEL
    read = sensor.read_noise_e if sensor.read_noise else 0.0
    dark = sensor.dark_mean_e[c]
    return {
        "K_dn_per_e": sensor.dn_per_electron,
        "dark_noise_e": math.sqrt(read**2 + dark + sensor.row_noise_e**2),
        "qe": float(eta),
        "saturation_e": float(sensor.full_well_e),
        "dsnu_e": math.hypot(sensor.dsnu_e, sensor.dsnu_dark_current_percent / 100 * dark),
        "prnu_percent": float(sensor.prnu_percent),
    }


def configured_split(sensor: SensorParams) -> dict:
    """The two kinds of DSNU as configured, for the split of the DSNU measured at two exposure times.

    * ``dsnu_offset_e``: the offset DSNU, ``dsnu_e`` (e⁻, the same at every T);
    * ``dsnu_dark_current_e_per_s``: the spatial σ of the analysed channel's dark-current rate, p/100 · σ²_dark
      (e⁻/s; 0 with the dark-current stage off), so that its DSNU at T is that times T. σ²_dark is the rate at
      the sensor's temperature (``SensorParams.dark_current_effective_e_per_s``: D_ref · 2^((T − T_ref)/T_d)).
    """
    rate = sensor.dark_current_effective_e_per_s[CHANNEL] if sensor.dark_current else 0.0
    return {"dsnu_offset_e": float(sensor.dsnu_e),
            "dsnu_dark_current_e_per_s": sensor.dsnu_dark_current_percent / 100 * rate}


def predicted_saturation_e(sensor: SensorParams) -> float:
    """Signal (photo-)electrons at which the analysed channel saturates, ignoring noise. Unit: e⁻.

    The charge clips at the full well, the ADC at 2^nb − 1 DN, i.e. at (2^nb − 1) / K electrons; whichever comes
    first, minus the dark electrons already in the pixel. With a pedestal P the ADC adds P + ½ before its floor
    (:func:`camsim.sensor.stages.adc_offset_dn`), so its top code is reached at (2^nb − 1 − P − ½) / K electrons.
    """
    limits = [(sensor.max_dn - adc_offset_dn(sensor.pedestal_dn)) / sensor.dn_per_electron]
    if sensor.saturation:
        limits.append(sensor.full_well_e)
    return float(min(limits) - sensor.dark_mean_e[CHANNEL])


def model_dark_temporal_dn(sensor: SensorParams) -> tuple[float, float]:
    """The dark signal's mean and temporal variance in quantised DN, exactly from camsim's model, over pixels.

    A dark pixel reads floor(K · (D + o + r) + h) + P clipped to [0, 2^nb − 1] (P the pedestal, h = ½ with one,
    else 0: :func:`camsim.sensor.stages.adc_offset_dn`), with D ~ Poisson(μ_dark · d), o its offset
    DSNU (fixed), d its dark-current DSNU factor (fixed, log-normal of mean 1; 1 when off) and
    r ~ N(0, σ²_read + σ²_row). The variance is taken per pixel (temporal) and averaged over the offsets and the
    factors (Gauss–Hermite in their normals), which is what the pair difference of the photon transfer method
    estimates; without a pedestal the mean includes the quantiser's −½ DN. Returns (mean DN, variance DN²).
    """
    dark = float(sensor.dark_mean_e[CHANNEL])
    sigma = math.hypot(sensor.read_noise_e if sensor.read_noise else 0.0, sensor.row_noise_e)
    if sensor.dsnu_e > 0:
        nodes, weights = np.polynomial.hermite_e.hermegauss(41)
        offsets, weights = nodes * sensor.dsnu_e, weights / weights.sum()
    else:
        offsets, weights = np.zeros(1), np.ones(1)
    if sensor.dsnu_dark_current_percent > 0 and dark > 0:
        s = lognormal_log_sigma(sensor.dsnu_dark_current_percent / 100)
        nodes, factor_weights = np.polynomial.hermite_e.hermegauss(21)
        factors, factor_weights = np.exp(s * nodes - s * s / 2), factor_weights / factor_weights.sum()
    else:
        factors, factor_weights = np.ones(1), np.ones(1)
    means, variances = [], []
    for o in offsets:
        moments = [_dark_pixel_moments(sensor, dark * f, o, sigma) for f in factors]
        means.append(float(factor_weights @ [m for m, _ in moments]))
        variances.append(float(factor_weights @ [v for _, v in moments]))
    return float(weights @ means), float(weights @ variances)


def _dark_pixel_moments(sensor: SensorParams, lam: float, offset: float, sigma: float) -> tuple[float, float]:
    """Mean (DN) and temporal variance (DN²) of floor(K (D + o + r) + h) + P, clipped, D ~ Poisson(λ), r ~ N(0, σ²)."""
    from scipy import stats

    k = sensor.dn_per_electron
    d = np.arange(max(0, int(lam - 12 * math.sqrt(lam) - 12)), int(lam + 12 * math.sqrt(lam) + 13))
    pmf = stats.poisson.pmf(d, lam) if lam > 0 else (d == 0).astype(float)
    half = adc_offset_dn(sensor.pedestal_dn) - sensor.pedestal_dn
    centre = k * (d + offset) + half  # DN before the read noise, with the ADC's half step
    if sigma > 0:
        lo = int(math.floor(centre.min() - 10 * k * sigma)) - 1
        hi = int(math.ceil(centre.max() + 10 * k * sigma)) + 1
        edges = np.arange(lo, hi + 1, dtype=float)
        cdf = pmf @ stats.norm.cdf((edges[None, :] - centre[:, None]) / (k * sigma))
        values, probs = edges[:-1], np.diff(cdf)
    else:
        values, probs = np.floor(centre), pmf
    values = np.clip(values + sensor.pedestal_dn, 0, sensor.max_dn)
    mean = float(probs @ values / probs.sum())
    return mean, float(probs @ (values - mean) ** 2 / probs.sum())
