"""The closed-form moments the exposure/ISO search scores settings with (no rendering in the search).

A patch's channel at exposure T and ISO collects S = r · F · T signal electrons (r its rate at F = 1, e⁻/s) and
D = d · T dark electrons (d the dark current at the sensor's ``temperature_c``, D_ref · 2^((T − T_ref)/T_d):
``--sensor temperature_c=40`` moves it); its black-subtracted value, in electrons, has mean S and variance

    S (shot) + D (dark shot) + σ_read² + σ_row² + 1 / (12 k²) (the quantiser, Sheppard: its steps are 1 / k e⁻),

with k, σ_read, σ_row (and the well, the ADC's range and the pedestal) the camera preset's at that ISO
(:func:`camsim.sensor.presets.sensor_preset`, dual conversion gain included). These are Eqs. 13–14 of the paper
(SNR = (k S)² / k² · variance, a power ratio) with the quantiser's variance 1/12 DN²; they are exact for the pixel
values while nothing clips, which :func:`saturation_free` makes a constraint: a setting is allowed only where every
patch and channel stays :data:`CLIP_SIGMAS` standard deviations below the well and below the top of the ADC.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camsim.sensor.stages import adc_offset_dn

#: A setting may not bring any patch within this many standard deviations of the well or the ADC's top.
CLIP_SIGMAS = 4.0
#: Gauss–Hermite nodes per axis of the ΔE expectation (a 2-D rule on (a*, b*): 24² points per patch).
DELTA_E_NODES = 24


@dataclass(frozen=True)
class SensorAtIso:
    """The figures of one ISO setting the moments need (from a :class:`camsim.sensor.params.SensorParams`)."""

    iso: float | None
    dn_per_electron: float
    read_noise_e: float
    row_noise_e: float
    dark_current_e_per_s: np.ndarray  # (3,) at the sensor's temperature_c (SensorParams.dark_current_effective_e_per_s)
    full_well_e: float | None
    adc_range_e: float  # (white − P − ½) / k (P > 0; white / k without a pedestal): the charge at the ADC's top
    quantisation: bool

    @classmethod
    def of(cls, sensor, iso) -> "SensorAtIso":
        k = sensor.dn_per_electron
        return cls(iso=iso, dn_per_electron=k, read_noise_e=sensor.read_noise_e if sensor.read_noise else 0.0,
                   row_noise_e=sensor.row_noise_e,
                   dark_current_e_per_s=np.asarray(sensor.dark_current_effective_e_per_s) if sensor.dark_current
                   else np.zeros(3),
                   full_well_e=sensor.full_well_e if sensor.saturation else None,
                   adc_range_e=(sensor.max_dn - adc_offset_dn(sensor.pedestal_dn)) / k if sensor.quantisation
                   else np.inf,
                   quantisation=sensor.quantisation)

    @property
    def quantisation_var_e2(self) -> float:
        """The quantiser's variance referred to the charge, 1 / (12 k²). Unit: e⁻²."""
        return 1.0 / (12.0 * self.dn_per_electron**2) if self.quantisation else 0.0


def noise_terms_e2(signal_e, dark_e, sensor: SensorAtIso) -> dict:
    """The variance terms of a pixel's value, referred to the charge, broadcast over ``signal_e`` and ``dark_e``:
    ``shot``, ``dark``, ``read``, ``row``, ``quantisation``. Unit: e⁻²."""
    shape = np.broadcast_shapes(np.shape(signal_e), np.shape(dark_e))
    return {"shot": np.broadcast_to(signal_e, shape), "dark": np.broadcast_to(dark_e, shape),
            "read": np.full(shape, sensor.read_noise_e**2), "row": np.full(shape, sensor.row_noise_e**2),
            "quantisation": np.full(shape, sensor.quantisation_var_e2)}


def snr_db(signal_e, dark_e, sensor: SensorAtIso) -> np.ndarray:
    """Eq. 14's SNR in dB, 10 log10(S² / variance), broadcast (variance by :func:`noise_terms_e2`)."""
    variance = sum(noise_terms_e2(signal_e, dark_e, sensor).values())
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(np.asarray(signal_e, dtype=np.float64) ** 2 / variance)


def saturation_free(signal_e, dark_e, sensor: SensorAtIso) -> np.ndarray:
    """Whether the charge S + D stays :data:`CLIP_SIGMAS` standard deviations below the well and the ADC's top,
    reduced over the last two axes (patches, channels)."""
    charge = signal_e + dark_e
    spread = CLIP_SIGMAS * np.sqrt(sum(noise_terms_e2(signal_e, dark_e, sensor).values()))
    limit = min(sensor.full_well_e if sensor.full_well_e is not None else np.inf, sensor.adc_range_e)
    return np.all(charge + spread <= limit, axis=(-2, -1))


def lab_of(rgb_e: np.ndarray, to_xyz: np.ndarray, white_xy: np.ndarray) -> np.ndarray:
    """CIELAB of camera values scaled to Y = 100 (the paper's ΔE procedure), NaN where Y ≤ 0.

    ``rgb_e`` (..., 3) black-subtracted camera values (any common scale), ``to_xyz`` the 3 × 3 camera → XYZ matrix.
    Written out (no colour-science call per point: the search evaluates millions): L* is 100 by construction.
    """
    xyz = rgb_e @ to_xyz.T
    y = xyz[..., 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        scaled = np.where(y[..., None] > 0, xyz / y[..., None], np.nan)
    xw, yw = white_xy
    white = np.array([xw / yw, 1.0, (1.0 - xw - yw) / yw])
    t = scaled / white

    def f(v):
        return np.where(v > (6 / 29) ** 3, np.cbrt(v), v / (3 * (6 / 29) ** 2) + 4 / 29)

    fx, fy, fz = f(t[..., 0]), f(t[..., 1]), f(t[..., 2])
    return np.stack([116 * fy - 16, 500 * (fx - fy), 200 * (fy - fz)], axis=-1)


def expected_delta_e(signal_e, variance_e2, reference_lab, to_xyz, white_xy) -> np.ndarray:
    """E[ΔE_ab] of a patch's samples against ``reference_lab``, from the model's moments.

    Every sample is scaled to Y = 100 (L* = 100), so ΔE is the length of the sample's (a*, b*) less the reference's.
    Each channel's value has the model's mean ``signal_e`` and variance ``variance_e2`` (independent channels);
    (a*, b*) is taken to first order in them — a 2-D Gaussian with mean f(mean) − reference and covariance
    J Σ Jᵀ (J by central differences) — and the mean of its length by Gauss–Hermite quadrature on
    :data:`DELTA_E_NODES`² points (the length is not smooth at 0: the 2-D rule, not the 3-D one, handles it).
    Valid while Y's relative noise is small (the scaling to Y = 100 is then nearly linear); at very low light the
    rendered ΔE is smaller than this (the verification table shows where).

    ``signal_e``, ``variance_e2``: (..., P, 3); ``reference_lab``: (P, 3). Returns (..., P); NaN where Y ≤ 0.
    """
    signal = np.asarray(signal_e, dtype=np.float64)
    base = lab_of(signal, to_xyz, white_xy)[..., 1:]
    jac = np.empty(signal.shape[:-1] + (2, 3))
    for c in range(3):
        step = np.zeros(3)
        step[c] = 1.0
        h = 1e-4 * np.maximum(np.abs(signal[..., c : c + 1]), 1e-3)
        up = lab_of(signal + h * step, to_xyz, white_xy)[..., 1:]
        down = lab_of(signal - h * step, to_xyz, white_xy)[..., 1:]
        jac[..., :, c] = (up - down) / (2 * h)
    cov = np.einsum("...ic,...c,...jc->...ij", jac, np.asarray(variance_e2, dtype=np.float64), jac)
    # Cholesky of the 2 × 2 covariance, written out
    l11 = np.sqrt(np.maximum(cov[..., 0, 0], 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        l21 = np.where(l11 > 0, cov[..., 1, 0] / l11, 0.0)
    l22 = np.sqrt(np.maximum(cov[..., 1, 1] - l21**2, 0.0))
    z, w = np.polynomial.hermite_e.hermegauss(DELTA_E_NODES)
    w = w / w.sum()
    z1, z2 = (a.ravel() for a in np.meshgrid(z, z, indexing="ij"))
    weight = np.outer(w, w).ravel()
    mean = base - reference_lab[..., 1:]
    da = mean[..., 0:1] + l11[..., None] * z1
    db = mean[..., 1:2] + l21[..., None] * z1 + l22[..., None] * z2
    return np.sum(np.sqrt(da**2 + db**2) * weight, axis=-1)
