"""The DNG NoiseProfile of a frame: its temporal noise variance against the normalised raw value, from the model.

The DNG specification (1.3 and later, tag 51041) describes a raw file's noise by one pair (S, O) per colour plane
(in CFAPlaneColor order: R, G, B; for a three-sample LinearRaw file one pair per sample): a pixel of normalised
value

    x = (DN − BlackLevel) / (WhiteLevel − BlackLevel) ∈ [0, 1]

has the noise variance S · x + O. The noise meant is the random, temporal noise of one frame — photon (shot) and
read noise; fixed-pattern effects are left out (the specification's model, and what a raw developer's denoiser uses
the profile for: a fixed pattern is not removed by averaging over frames or over neighbours).

camsim's ADC gives DN = clip(floor(k · (min(S + D + o, FW) + R + W) + h) + P, 0, 2^nb − 1) (:mod:`camsim.sensor.stages`;
h = ½ with a pedestal, 0 without), with
k = G · G_Ve⁻ the gain in DN / e⁻, S the signal charge, D ~ Poisson(D̄ · d) the dark charge, o the DSNU offset, R
the read noise (σ_read), W the row noise (σ_row) and P the pedestal. Below saturation and above the ADC's zero, a
pixel's temporal variance in DN² is

    Var DN = k² · s · S̄ + k² · (D̄ + σ_read² + σ_row²) + 1/12,

s = Var S / S̄ (1 e⁻ under ``pixel`` statistics: Poisson photo-electrons; see :func:`shot_step_e` for ``paper``
statistics) and 1/12 DN² the quantiser's (Sheppard's correction: exact to 4e-5 DN² where the noise before the ADC
has σ ≥ ¾ DN, to 8e-3 DN² at ½ DN). The BlackLevel B is the exact mean of an unlit pixel, so the mean of
DN − B is k · S̄ and k · S̄ = x · (W − B). Hence, per channel,

    S = k · s / (W − B),    O = (k² · (D̄ + σ_read² + σ_row²) + 1/12) / (W − B)².

What is in and what is not:

* shot noise of the signal and of the dark current, read noise (Gaussian or Tukey λ: σ_read either way), row noise
  and the quantiser are temporal: in. The row noise is shared by a row's pixels, which the DNG model (white noise)
  cannot say: O holds its per-pixel variance.
* DSNU (offset and dark-current) and PRNU are fixed patterns: out. Per pixel the relation still holds under
  ``pixel`` statistics: a PRNU gain g makes the variance k² g S̄ and the pixel's own x = k g S̄ / (W − B), so S · x
  is its shot variance; likewise a dark-current factor d. An offset o shifts x by k o / (W − B) and not the
  variance; over a patch (o of mean 0) the profile holds on average.
* saturation (the full well, the ADC's top code) and the ADC's clip at 0 (a black level within a few σ of 0, i.e.
  no pedestal and little dark current) make the variance smaller than the profile says: the model is linear only
  between them.
"""

from __future__ import annotations

import numpy as np

from camsim.sensor.params import SensorParams

#: The quantiser's variance for a noise wider than about ¾ DN (Sheppard's correction). Unit: DN².
QUANTISER_VAR_DN2 = 1.0 / 12.0


def shot_step_e(statistics: str, signal_e=None, signal_var_e2=None, labels=None) -> np.ndarray:
    """s = Var S / S̄ per channel R, G, B: the shot variance per mean signal electron, of a frame. Unit: e⁻.

    ``pixel`` statistics: 1 (Poisson photo-electrons). ``paper`` statistics (Eq. 4, Var S = T² F Σ g Qe²): s
    differs between spectra (it is a Qe-weighted mean of T · Qe(λ)), and the profile has one value per channel: the
    pixel-weighted ratio Σ Var S / Σ S̄ over the frame's pixels, i.e. the s that makes S · x give the frame's total
    shot variance. A channel without signal (Σ S̄ = 0) gets 1.

    Parameters
    ----------
    statistics : {'pixel', 'paper'}
    signal_e, signal_var_e2 : numpy.ndarray, shape (K, 3), optional
        Per spectrum S̄ and Var S (:class:`camsim.sensor.expected.ExpectedSignal`); needed for ``paper`` statistics.
        Unit: e⁻ and e⁻².
    labels : numpy.ndarray of int, shape (H, W), optional
        Spectrum index of each pixel (the weights); None: the spectra weigh alike.

    Returns
    -------
    numpy.ndarray, shape (3,)
        Unit: e⁻.
    """
    if statistics == "pixel":
        return np.ones(3)
    signal = np.asarray(signal_e, dtype=np.float64)
    var = np.asarray(signal_var_e2, dtype=np.float64)
    weights = (np.ones(signal.shape[0]) if labels is None
               else np.bincount(np.ravel(labels), minlength=signal.shape[0]).astype(np.float64))
    total, total_var = weights @ signal, weights @ var
    return np.divide(total_var, total, out=np.ones(3), where=total > 0)


def dng_noise_profile(sensor: SensorParams, shot_step: float | np.ndarray = 1.0) -> np.ndarray | None:
    """The DNG NoiseProfile pairs (S, O) of a sensor's quantised frames, per channel R, G, B (module docstring).

    Parameters
    ----------
    sensor : SensorParams
    shot_step : float or array_like, shape (3,)
        s = Var S / S̄ per channel (:func:`shot_step_e`): 1 under ``pixel`` statistics. Unit: e⁻.

    Returns
    -------
    numpy.ndarray, shape (3, 2), or None
        Row c: (S_c, O_c), unitless (variances of the normalised value x). None where no profile applies: without
        quantisation (no DNG is written) or without photon noise (S = 0, which the DNG SDK rejects: a profile
        needs S > 0).
    """
    if not sensor.quantisation or not sensor.photon_noise:
        return None
    step = np.broadcast_to(np.asarray(shot_step, dtype=np.float64), (3,))
    if not np.all(step > 0):
        return None
    k = sensor.dn_per_electron
    span = sensor.max_dn - sensor.black_level_tag_dn  # W − B per channel, ≥ 1
    read = sensor.read_noise_e if sensor.read_noise else 0.0
    floor_e2 = sensor.dark_mean_e + read**2 + sensor.row_noise_e**2  # D̄ + σ_read² + σ_row² per channel
    scale = k * step / span
    offset = (k * k * floor_e2 + QUANTISER_VAR_DN2) / span**2
    return np.stack([scale, offset], axis=1)


def frame_noise_profile(frame, statistics: str) -> np.ndarray | None:
    """:func:`dng_noise_profile` of a rendered :class:`camsim.render.frame.Frame` under its photon ``statistics``."""
    ex = frame.expected
    step = shot_step_e(statistics, ex.signal_e, ex.signal_var_e2, frame.labels if statistics != "pixel" else None)
    return dng_noise_profile(frame.sensor, step)
