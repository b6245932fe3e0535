"""Signal-to-noise ratio: the model (the paper's Eqs. 13–14), empirical, and ΔSNR (Eq. 17).

SNR is a power ratio, signal² / variance, in DN; ``snr_db = 10 log10(snr)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

QUANTISATION_VARIANCE_DN2 = 1.0 / 12.0
"""Variance of the uniform rounding error of an ideal quantiser with 1 DN steps. Unit: DN²."""
QUANTISATION_MEAN_SQUARE_DN2 = 1.0 / 3.0
"""Mean square of the paper's quantisation error σ_ADC = I − G·Ṽ (Eq. 12) when I is the integer part: the error is
uniform on (−1, 0], so E[σ_ADC²] = 1/4 + 1/12. Eq. 13 adds this, bias included. Unit: DN²."""
QUANTISATION_TERMS = {"variance": QUANTISATION_VARIANCE_DN2, "mean-square": QUANTISATION_MEAN_SQUARE_DN2}


@dataclass(frozen=True)
class SNRModel:
    """Model SNR terms, arrays broadcast from the inputs of :func:`snr_model`.

    Attributes
    ----------
    signal_dn : numpy.ndarray
        The numerator's signal: k S, or Eq. 14's quantised [k S]_nb. Unit: DN.
    variance_dn2 : numpy.ndarray
        k² (Var S + D + σ_read²) (+ 1/12 with quantisation). Unit: DN².
    snr : numpy.ndarray
        signal_dn² / variance_dn2 (power ratio, Eq. 14); 0 where the signal is 0 (also when the variance is 0
        too), ``inf`` where the signal is positive and the variance exactly 0 (a noiseless model).
    snr_db : numpy.ndarray
        10 log10(snr); ``-inf`` where snr is 0, ``inf`` where snr is ``inf``. Never NaN.
    """

    signal_dn: np.ndarray
    variance_dn2: np.ndarray
    snr: np.ndarray
    snr_db: np.ndarray


def _non_negative(value, name):
    value = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(value)) or np.any(value < 0):
        raise ValueError(f"{name} must be finite and non-negative")
    return value


def _to_db(snr: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return 10.0 * np.log10(snr)  # log10(0) = -inf, log10(inf) = inf


def quantised_signal_dn(signal_dn, bits: int) -> np.ndarray:
    """Eq. 14's numerator [k S]_nb: the integer part of the noise-free signal, clipped to [0, 2^nb − 1].

    Parameters
    ----------
    signal_dn : array_like
        The noise-free signal k S. Unit: DN.
    bits : int
        ADC resolution nb.

    Returns
    -------
    numpy.ndarray
        Unit: DN. 0 wherever k S < 1 DN.
    """
    return np.clip(np.floor(np.asarray(signal_dn, dtype=np.float64)), 0, 2**int(bits) - 1)


def snr_model(signal_e, dark_e, signal_var_e2, read_noise_e, dn_per_electron, quantisation: bool,
              quantisation_term: str = "variance", numerator_bits: int | None = None) -> SNRModel:
    """Model SNR of a pixel (Eqs. 13–14), vectorised over broadcastable arrays.

    Parameters
    ----------
    signal_e : array_like
        Mean photo-electrons S. Unit: e⁻.
    dark_e : array_like
        Mean dark electrons D; Poisson, so also their variance. 0 if dark current is off. Unit: e⁻.
    signal_var_e2 : array_like
        Variance of the photo-electrons, Var S (= S for Poisson photon noise). Unit: e⁻².
    read_noise_e : array_like
        Read-noise standard deviation σ_read; 0 if off. Unit: e⁻ (rms).
    dn_per_electron : array_like
        Overall gain k. Unit: DN/e⁻. Positive.
    quantisation : bool
        Add a quantisation term.
    quantisation_term : {'variance', 'mean-square'}
        ``variance``: 1/12 DN², the variance the quantiser adds to the pixel values (what an empirical SNR from
        pixel samples sees); ``mean-square``: 1/3 DN², Eq. 13 literally, the mean square of Eq. 12's error
        including its −½ DN bias.
    numerator_bits : int, optional
        nb: the numerator is Eq. 14's quantised noise-free signal [k S]_nb (:func:`quantised_signal_dn`), so the
        SNR is 0 wherever k S < 1 DN. None (default): the numerator is k S.

    Returns
    -------
    SNRModel
    """
    s = _non_negative(signal_e, "signal_e")
    d = _non_negative(dark_e, "dark_e")
    var_s = _non_negative(signal_var_e2, "signal_var_e2")
    sigma = _non_negative(read_noise_e, "read_noise_e")
    k = _non_negative(dn_per_electron, "dn_per_electron")
    if np.any(k == 0):
        raise ValueError("dn_per_electron must be positive")
    signal_dn = k * s if numerator_bits is None else quantised_signal_dn(k * s, numerator_bits)
    if quantisation_term not in QUANTISATION_TERMS:
        raise ValueError(f"quantisation_term must be one of {tuple(QUANTISATION_TERMS)}, got {quantisation_term!r}")
    variance = k**2 * (var_s + d + sigma**2) + (QUANTISATION_TERMS[quantisation_term] if quantisation else 0.0)
    signal_dn, variance = np.broadcast_arrays(signal_dn, variance)
    snr = np.zeros(signal_dn.shape)
    positive = signal_dn > 0
    noiseless = positive & (variance == 0)
    noisy = positive & (variance > 0)
    snr[noisy] = signal_dn[noisy] ** 2 / variance[noisy]
    snr[noiseless] = np.inf
    return SNRModel(signal_dn.copy(), variance.copy(), snr, _to_db(snr))


def snr_empirical(samples_dn, black_dn):
    """SNR of pixel samples: (mean − black)² / sample variance (ddof = 1).

    Parameters
    ----------
    samples_dn : array_like
        Pixel values of one channel of a flat patch, any shape (flattened). Unit: DN. Must be finite.
    black_dn : float
        Black level subtracted from the mean. Unit: DN.

    Returns
    -------
    snr : float or None
        Power ratio; None unless status is "ok". 0 when the mean equals the black level.
    snr_db : float or None
        10 log10(snr); None when snr is 0 (mean exactly at the black level) or status is not "ok".
    status : str
        ``"ok"``, ``"too-few-samples"`` (fewer than 2) or ``"constant"`` (all samples equal: variance 0, SNR
        undefined).
    """
    x = np.asarray(samples_dn, dtype=np.float64).reshape(-1)
    if not np.all(np.isfinite(x)) or not np.isfinite(black_dn):
        raise ValueError("samples_dn and black_dn must be finite")
    if x.size < 2:
        return None, None, "too-few-samples"
    return snr_from_moments(float(x.mean()), float(np.var(x, ddof=1)), x.size, black_dn)


def snr_from_moments(mean_dn, var_dn2, n, black_dn):
    """:func:`snr_empirical` from a sample's mean, variance (ddof = 1) and size; same returns."""
    if n < 2:
        return None, None, "too-few-samples"
    if var_dn2 <= 0:
        return None, None, "constant"
    snr = float((mean_dn - black_dn) ** 2 / var_dn2)
    return snr, (10.0 * float(np.log10(snr)) if snr > 0 else None), "ok"


def delta_snr_percent(snr_1, snr_2):
    """ΔSNR(%) = 100 (SNR₁ − SNR₂) / SNR₁ (Eq. 17), for scalars.

    Parameters
    ----------
    snr_1 : float or None
        Baseline SNR (power ratio).
    snr_2 : float or None
        SNR with the changed parameter.

    Returns
    -------
    float or None
        None where SNR₁ is None, 0 or not finite, or SNR₂ is None or not finite.
    """
    if snr_1 is None or snr_2 is None:
        return None
    snr_1, snr_2 = float(snr_1), float(snr_2)
    if snr_1 == 0 or not (np.isfinite(snr_1) and np.isfinite(snr_2)):
        return None
    return 100.0 * (snr_1 - snr_2) / snr_1
