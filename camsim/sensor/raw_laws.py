"""The photon laws of a raw source made dark: the charge of a target exposure drawn from a real camera's raw file.

A raw source gives, at each CFA site, its electrons s = (DN − black) / K_src (K_src the source camera's DN per
electron at its ISO): an estimate of the photons it converted in its exposure T_src. A target frame at intensity F
and exposure T then expects the fraction f = F · T / T_src of them, and every later stage is the target sensor's
(:mod:`camsim.sensor.stages`). Two laws turn s into the target's charge (per pixel; g the target's PRNU gain,
D̄ its mean dark charge σ²_dark · T, d its dark-current DSNU factor):

``add`` (the ELD / PMN convention): the source is taken as noise-free, its value as the expected signal,

    charge ~ Poisson(f · max(s, 0) · g + D̄ · d),

one Poisson draw (:func:`camsim.sensor.stages.collect_charge_e` under ``pixel`` statistics). The source's own
photon and read noise stay in its value and the target's Poisson noise is added on top: the frame's variance is
f g E[s] + D̄ d (the target's) plus f² g² Var s (the source's, scaled). For a source limited by its photon noise
(Var s ≈ E s) the second is f times the first's photon part: negligible only for f ≪ 1 (1 % at f = 1/100; at
f = 1 the variance doubles).

``thin``: the source is taken as a photon count n = round(max(s, 0)), and each of its electrons is kept with
probability p = f · g,

    charge ~ Binomial(n, f · g) + Poisson(D̄ · d).

Thinning. If the source count is N ~ Poisson(λ T_src) (λ the pixel's photo-electron rate), then
Binomial(N, p) ~ Poisson(λ T_src p) *exactly*: its generating function is
E[(1 − p + p z)^N] = exp(λ T_src (1 − p + p z − 1)) = exp(λ T_src p (z − 1)), that of Poisson(λ T_src p). With
p = F · T / T_src (no PRNU) that is Poisson(F λ T), the photon count of the darker exposure itself, not the
source's noise plus the target's. ``thin`` therefore needs p ≤ 1: it cannot brighten (f > 1 is refused, and with
PRNU so is f · g > 1 at any pixel).

What the source's readout leaves behind. A real source value is not N but s = N + e, e = r + q / K_src: its read
noise r (σ_r, e⁻, plus the Poisson noise of any dark charge its black level does not remove) and its ADC's
rounding q (DN): where the read noise spreads a value over several DN (K_src σ_r ≳ 1), q adds K_src⁻²/12 e⁻² to the
variance (Sheppard's correction). The law rounds again, n = round(max(N + e, 0)), which adds 1/12 e⁻² on the same
terms (σ ≳ 1 e⁻; the error is of order exp(−2π²σ²), σ² = σ_r² + K_src⁻²/12). Where the clip does not act, and
given n (Binomial(n, p): mean n p, variance n p (1 − p)),

    E[charge] = p (λ T_src + E e) + D̄ d,
    Var[charge] = E[n] p (1 − p) + p² Var n + D̄ d = p λ T_src + p² (σ_r² + K_src⁻²/12 + 1/12) + D̄ d

(E e = 0 for a black level that is the dark mean): the darker exposure's own Poisson variance p λ T_src plus
p² (σ_r² + K_src⁻²/12 + 1/12), the source's readout scaled by p², which fades as the square of the ratio (at
f = 1/100 and σ_r = 3 e⁻, about 9e-4 e⁻², against the target's own read noise). The clip at 0 adds a bias: with
x⁻ = max(−x, 0), E[max(N + e, 0)] = λ T_src + E e + E[(N + e)⁻], and for Gaussian e of σ (σ² = σ_r² +
K_src⁻²/12), E[(m + e)⁻] = σ φ(m / σ) − m Φ(−m / σ), so the mean charge is higher by
p Σ_m P(N = m) (σ φ(m/σ) − m Φ(−m/σ)): p σ / √(2π) ≈ 0.4 p σ for a black source pixel (λ T_src = 0), 0.048 p σ at
λ T_src = 5 and σ = 3 e⁻, 1e-8 p σ at 30 e⁻ and 3e-32 p σ at 100 e⁻; the variance above likewise holds where the
clip does not act (near black it is lower). ``add`` has the same source terms with p² replaced by f² g² and no
1/12 (it does not round), on top of the source's photon variance f² g² λ T_src.
"""

from __future__ import annotations

import numpy as np

from camsim.core.errors import CamsimError
from camsim.sensor.kernels import poisson
from camsim.sensor.stages import cap_mean_e, collect_charge_e

#: The photon laws: ``add`` (Poisson of the scaled source, the ELD/PMN convention) and ``thin`` (binomial thinning
#: of the source's electron count).
PHOTON_LAWS = ("add", "thin")

#: Each law's charge, as a sidecar records it (s the source's electrons, f = F·T/T_source, g the PRNU gain, D̄ the
#: mean dark charge, d its DSNU factor).
PHOTON_LAW_FORMULAS = {
    "add": "Poisson(f·max(s, 0)·g + D̄·d): the source as noise-free (ELD/PMN)",
    "thin": "Binomial(round(max(s, 0)), f·g) + Poisson(D̄·d): binomial thinning of the source's electron count",
}


def add_photons_e(rng: np.random.Generator, expected_e, dark_e=0.0, *, gain=None, dark_gain=None,
                  photon_noise: bool = True, saturation_e=None) -> np.ndarray:
    """The ``add`` law: charge ~ Poisson(expected_e · g + D̄ · d), one draw per pixel (the source as noise-free).

    :func:`camsim.sensor.stages.collect_charge_e` under ``pixel`` statistics, with its saturation cap.

    Parameters
    ----------
    rng : numpy.random.Generator
    expected_e : numpy.ndarray, shape (h, w), float64
        f · max(s, 0): the frame's expected signal at each pixel before PRNU (f = F · T / T_src, s the source's
        electrons). Unit: e⁻.
    dark_e : float or numpy.ndarray
        D̄ = σ²_dark · T: one value, or one per pixel (h, w) (a CFA's sites take their channel's). Unit: e⁻.
    gain : numpy.ndarray, optional
        PRNU gain g per pixel, shape (h, w). Unitless.
    dark_gain : numpy.ndarray, optional
        Dark-current DSNU factor d per pixel, shape (h, w). Unitless.
    photon_noise : bool
        Off: charge = expected_e · g + Poisson(D̄ · d) (the signal exactly, the dark charge still drawn).
    saturation_e : float, optional
        The level at and above which the pixel saturates (:func:`camsim.sensor.stages.saturation_level_e`): Poisson
        means far above it are capped (:func:`camsim.sensor.stages.cap_mean_e`). None: no full well.

    Returns
    -------
    numpy.ndarray, shape (h, w)
        The charge (int64 counts, or float64 without photon noise). Unit: e⁻.
    """
    return collect_charge_e(rng, expected_e, dark_e, statistics="pixel", photon_noise=photon_noise, gain=gain,
                            dark_gain=dark_gain, saturation_e=saturation_e)


def source_count_e(source_e) -> np.ndarray:
    """n = round(max(s, 0)): the source's electrons as the integer count ``thin`` thins, int64. Unit: e⁻."""
    count = np.rint(np.maximum(source_e, 0.0))
    return count.astype(np.int64)


def check_thin_fraction(fraction: float, gain_max: float = 1.0) -> None:
    """Refuse a thinning probability above 1: f · max g > 1 (f the fraction, g the PRNU gains; 1 without PRNU).

    Raises
    ------
    CamsimError
    """
    if fraction > 1:
        raise CamsimError(f"thin cannot brighten: the fraction F·T/T_source = {fraction:g} > 1; use photon_law = 'add'")
    if fraction * gain_max > 1:
        raise CamsimError(f"thin cannot brighten: the fraction F·T/T_source = {fraction:g} times the largest PRNU "
                          f"gain {gain_max:.6g} is {fraction * gain_max:.6g} > 1; lower F or T, or use "
                          f"photon_law = 'add'")


def keep_probability(fraction: float, gain=None):
    """p = f · g: the probability that ``thin`` keeps one of the source's electrons (f the fraction, g the PRNU gain
    per pixel, ≥ 0: :func:`camsim.sensor.fixed_pattern.prnu_gain`, or None). Float or float64 array."""
    return fraction if gain is None else fraction * np.asarray(gain, dtype=np.float64)


def check_thin_exposure(intensity_factor: float, exposure_s: float, source_exposure_s: float) -> None:
    """Refuse ``thin`` for a frame brighter than its source: F · T > T_source (F the intensity factor, T the frame's
    exposure, T_source the source's; seconds).

    Raises
    ------
    CamsimError
    """
    if intensity_factor * exposure_s > source_exposure_s:
        raise CamsimError(f"thin cannot brighten: F·T = {intensity_factor * exposure_s:g} s > the source's exposure "
                          f"{source_exposure_s:g} s; use photon_law = 'add'")


def thin_photons_e(rng: np.random.Generator, source_count_e, fraction: float, dark_e=0.0, *, gain=None,
                   dark_gain=None, photon_noise: bool = True, saturation_e=None) -> np.ndarray:
    """The ``thin`` law: charge ~ Binomial(n, f · g) + Poisson(D̄ · d), n the source's electron count.

    Exactly Poisson(f g λ T_src) + Poisson(D̄ d) when n ~ Poisson(λ T_src) (see the module's derivation).

    Parameters
    ----------
    rng : numpy.random.Generator
    source_count_e : numpy.ndarray, shape (h, w), integer
        n = round(max(s, 0)) (:func:`source_count_e`). Unit: e⁻.
    fraction : float
        f = F · T / T_src, at most 1 (and f · max g ≤ 1 with PRNU): else a :class:`CamsimError`.
    dark_e : float or numpy.ndarray
        D̄ = σ²_dark · T: one value or one per pixel (h, w). Unit: e⁻.
    gain : numpy.ndarray, optional
        PRNU gain g per pixel, shape (h, w): the keep probability is f · g. Unitless.
    dark_gain : numpy.ndarray, optional
        Dark-current DSNU factor d per pixel, shape (h, w). Unitless.
    photon_noise : bool
        Off: the signal is its mean n · f · g exactly (no binomial draw); the dark charge is still drawn.
    saturation_e : float, optional
        The saturation level: the dark charge's Poisson means far above it are capped
        (:func:`camsim.sensor.stages.cap_mean_e`); the binomial is bounded by n and needs no cap. None: no full well.

    Returns
    -------
    numpy.ndarray, shape (h, w)
        The charge (int64 counts, or float64 without photon noise). Unit: e⁻.

    Raises
    ------
    CamsimError
        f · g > 1 somewhere.
    """
    g_max = 1.0 if gain is None else float(np.max(gain, initial=0.0))
    check_thin_fraction(fraction, g_max)
    p = keep_probability(fraction, gain)
    if photon_noise:
        charge = rng.binomial(source_count_e, p)
    else:
        charge = source_count_e * p
        if not isinstance(charge, np.ndarray) or charge.dtype != np.float64:
            charge = np.asarray(charge, dtype=np.float64)
    dark = dark_e if dark_gain is None else dark_e * dark_gain
    if np.any(np.asarray(dark) > 0):
        lam = dark if saturation_e is None else cap_mean_e(dark, saturation_e)
        shape = np.shape(source_count_e)
        draws = poisson(rng, np.broadcast_to(np.asarray(lam, dtype=np.float64), shape))
        charge = np.add(charge, draws, out=charge if charge.dtype == draws.dtype else None)
    return charge
