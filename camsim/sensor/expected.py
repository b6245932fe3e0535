"""Expected values and variances per distinct spectrum (K of them), known before anything is drawn.

These are the model's closed forms (the docs' model page) used both by the renderer (what to draw) and by the tests
and sidecars (what the frame should show):

* signal electrons S = T · F · Σ g(λi) Qe_κ(λi);
* Var S = S under ``pixel`` statistics (Poisson thinning), T² · F · Σ g Qe² under ``paper`` statistics (Eq. 4);
* dark electrons D ~ Poisson(σ²_dark · T);
* the clean value E[f_sat(S + D)], exact for Poisson totals, Gaussian-approximated for ``paper`` statistics.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy import stats

from camsim.core.errors import CamsimError
from camsim.core.xp import namespace_of, on_device, special_namespace
from camsim.light.rates import FactoredSpectra, all_finite
from camsim.sensor.params import SensorParams


@dataclass(frozen=True)
class ExpectedSignal:
    """Per-spectrum moments of the collected charge, for one frame.

    Attributes
    ----------
    photon_rate : numpy.ndarray or camsim.light.rates.FactoredSpectra, shape (K, N)
        F · g(λi), photons / (s m² sr) per bin at the frame's intensity factor (factored for an image scene's
        colours: rows are dense only when indexed).
    qe : numpy.ndarray, shape (3, N)
        Qe_κ(λi). Unit: e⁻ · m² · sr / photon.
    signal_e : numpy.ndarray, shape (K, 3)
        Mean signal electrons S. Unit: e⁻.
    signal_var_e2 : numpy.ndarray, shape (K, 3)
        Variance of S under the frame's photon statistics (0 if photon noise is off). Unit: e⁻².
    dark_e : numpy.ndarray, shape (3,)
        Mean dark electrons σ²_dark · T (0 if the stage is off). Unit: e⁻.
    clean_e : numpy.ndarray, shape (K, 3)
        E[f_sat(S + D)], the expected charge after saturation. Unit: e⁻.
    """

    photon_rate: np.ndarray
    qe: np.ndarray
    signal_e: np.ndarray
    signal_var_e2: np.ndarray
    dark_e: np.ndarray
    clean_e: np.ndarray

    @cached_property
    def charge_mean_e(self) -> np.ndarray:
        """S̄ + D̄ per channel, shape (3, K), each row contiguous: the Poisson means of ``pixel`` statistics, gathered
        per pixel (an image's colours) without a 2-D gather. Unit: e⁻."""
        return np.ascontiguousarray((self.signal_e + self.dark_e).T)

    @property
    def total_var_e2(self) -> np.ndarray:
        """Variance of S + D before saturation, shape (K, 3). Unit: e⁻²."""
        return self.signal_var_e2 + self.dark_e


def expected_signal(photon_radiance, qe, sensor: SensorParams, intensity_factor: float, statistics: str):
    """Compute :class:`ExpectedSignal` for K spectra.

    Parameters
    ----------
    photon_radiance : numpy.ndarray or camsim.light.rates.FactoredSpectra, shape (K, N)
        g(λi) at F = 1. Unit: photons / (s m² sr). Factored spectra give S = T F c (B Qeᵀ): one J × 3 matrix.
    qe : numpy.ndarray, shape (3, N)
        Unit: e⁻ · m² · sr / photon.
    sensor : SensorParams
    intensity_factor : float
        F.
    statistics : {'pixel', 'paper'}

    Raises
    ------
    CamsimError
        Where a mean overflows float64 (F · g, S, Var S or σ²_dark · T infinite): the reason, and the largest F
        the scene, camera and exposure allow.
    """
    T = sensor.exposure_s
    with np.errstate(over="ignore", invalid="ignore"):  # an overflow is refused below, with its reason
        if isinstance(photon_radiance, FactoredSpectra):  # an image's colours: J basis spectra, never K × N
            rate = photon_radiance.scaled(intensity_factor)
        else:
            rate = intensity_factor * np.asarray(photon_radiance, dtype=np.float64)
        signal = T * (rate @ qe.T)
        if not sensor.photon_noise:
            var = np.zeros_like(signal)
        elif statistics == "pixel":
            var = signal.copy()
        else:
            var = T * T * (rate @ (qe * qe).T)
        dark = sensor.dark_mean_e
    if not (all_finite(rate) and np.all(np.isfinite(signal)) and np.all(np.isfinite(var))
            and np.all(np.isfinite(dark))):
        raise CamsimError(_overflow_reason(photon_radiance, qe, sensor, intensity_factor, statistics))
    exact_poisson = statistics == "pixel" or not sensor.photon_noise
    clean = expected_saturated(signal, var, dark, sensor, exact_poisson)
    return ExpectedSignal(rate, qe, signal, var, dark, clean)


def expected_saturated(signal, var, dark, sensor: SensorParams, exact_poisson: bool) -> np.ndarray:
    """E[min(S + D, full well)] (or E[S + D] when saturation is off), shape (K, 3). Unit: e⁻.

    Exact when the total is Poisson (``pixel`` statistics, or photon noise off so that S is a constant and D
    Poisson); a Gaussian approximation of S + D otherwise (``paper`` statistics, whose per-bin counts are huge).
    """
    mean = signal + dark
    if not sensor.saturation:
        return mean
    c = sensor.full_well_e
    dark_b = np.broadcast_to(dark, signal.shape)
    if exact_poisson:
        if sensor.photon_noise:
            # S + D ~ Poisson(λ): E[min(X, c)] = λ P(X ≤ m − 1) + c P(X > m), m = floor(c).
            return poisson_min_e(mean, c)
        # S constant, D ~ Poisson: E[min(S + D, c)] = S + E[min(D, c − S)].
        room = c - signal
        return np.where(room <= 0, c, signal + poisson_min_e(dark_b, np.maximum(room, 0)))
    sd = np.sqrt(var + dark_b)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        z = (mean - c) / sd
        excess = (mean - c) * stats.norm.cdf(z) + sd * stats.norm.pdf(z)
    excess = np.where(sd > 0, excess, np.maximum(mean - c, 0))
    # beyond z = 38 the normal tails underflow and E[min] is c; mean − excess would cancel catastrophically there
    # (at mean 1e23 e⁻, 1e23 − (1e23 − 9000) is 0 in float64)
    return np.where(z > SATURATED_Z, c, mean - excess)


#: Above this z = (mean − full well) / sd the Gaussian expectation E[min(X, c)] is c to within sd · 1e-314.
SATURATED_Z = 38.0

#: The largest float64. Unit: any.
_FLOAT64_MAX = np.finfo(np.float64).max


def _sci(log10_value: float) -> str:
    """A positive number given by its base-10 logarithm, as ``1.4e+316`` (beyond float64's range too)."""
    if -300 < log10_value < 300:
        return f"{10 ** log10_value:.2g}"
    exponent = int(np.floor(log10_value))
    mantissa = 10 ** (log10_value - exponent)
    if mantissa >= 9.95:
        mantissa, exponent = 1.0, exponent + 1
    return f"{mantissa:.2g}e{exponent:+d}"


def _overflow_reason(photon_radiance, qe, sensor: SensorParams, intensity_factor: float, statistics: str) -> str:
    """Why a frame's expected signal is not finite: which quantity overflows float64, and the largest F allowed."""
    T, F = sensor.exposure_s, intensity_factor
    g = np.asarray(photon_radiance, dtype=np.float64)
    with np.errstate(over="ignore"):
        dark = sensor.dark_mean_e
    if not np.all(np.isfinite(g)) or not np.all(np.isfinite(qe)):
        return "the scene's photon rates or the camera's Qe are not finite"
    if not np.all(np.isfinite(dark)):
        return (f"the exposure T = {T:g} s overflows the mean dark charge σ²_dark·T (float64 ends at "
                f"{_FLOAT64_MAX:.2g} e⁻)")
    # (what, unit, log10 of its value at F = 1): each grows as F
    with np.errstate(divide="ignore", over="ignore"):  # an overflow here is the reason being found: log10(inf)
        terms = [("the photon rate F·g(λ)", "photons / (s m² sr) per bin", np.log10(g.max(initial=0.0))),
                 ("the mean signal T·F·Σ g Qe", "e⁻", np.log10(np.max(g @ qe.T, initial=0.0)) + np.log10(T))]
        if sensor.photon_noise and statistics == "paper":
            terms.append(("the variance T²·F·Σ g Qe² of the paper's photon statistics", "e⁻²",
                          np.log10(np.max(g @ (qe * qe).T, initial=0.0)) + 2 * np.log10(T)))
    log_f, log_max = np.log10(F), np.log10(_FLOAT64_MAX)
    worst = max(terms, key=lambda term: term[2])
    if not np.isfinite(worst[2]):  # a product overflows already at F = 1 (the camera's Qe is vast)
        return (f"{worst[0]} overflows float64 at any F: the camera's Qe times the scene's photon rates is beyond "
                f"{_FLOAT64_MAX:.2g} (a reference charge, exposure or pixel size far beyond any camera's)")
    allowed = log_max - worst[2]
    return (f"intensity factor F = {F:g} at exposure T = {T:g} s overflows float64: {worst[0]} would reach "
            f"{_sci(log_f + worst[2])} {worst[1]}, beyond {_FLOAT64_MAX:.2g}; this scene and camera allow F up to "
            f"about {_sci(allowed - 0.01)} at this exposure")


def clean_charge_e(poisson_mean_e, sensor: SensorParams, base_e=0.0):
    """A pixel's expected charge after saturation, E[min(base + X, c)], X ~ Poisson(λ) (c the full well; without
    saturation base + λ), elementwise on numpy or CuPy arrays: the clean value of a pixel with a mean of its own.
    Unit: e⁻.

    Parameters
    ----------
    poisson_mean_e : array
        λ, the mean of the pixel's Poisson charge: g S̄ + d D̄ under ``pixel`` statistics (PRNU gain g, dark-current
        factor d), d D̄ alone without photon noise. Unit: e⁻.
    sensor : SensorParams or SensorBatch
        Its ``saturation`` and ``full_well_e`` (a :class:`~camsim.sensor.params.SensorBatch`'s, one per frame,
        broadcasting against ``poisson_mean_e``).
    base_e : float or array
        What the pixel holds besides the Poisson count: its DSNU offset o, plus S̄ without photon noise. Unit: e⁻.

    Notes
    -----
    Exact: min(base + X, c) = base + min(X, c − base) where c ≥ base, else c (X ≥ 0), so the value is
    base + :func:`poisson_min_e` (λ, c − base) or c; the saturation cap of the draws changes it by at most
    :data:`camsim.sensor.stages.SATURATION_CAP_TAIL`.
    """
    xp = namespace_of(poisson_mean_e, base_e)
    if not sensor.saturation:
        return poisson_mean_e + base_e
    well = sensor.full_well_e  # a number, or a batch's host array, one per frame (camsim.sensor.params.SensorBatch)
    c = float(well) if np.ndim(well) == 0 else on_device(xp, well, xp.float64)
    room = c - xp.asarray(base_e, dtype=xp.float64)
    lam = xp.asarray(poisson_mean_e, dtype=xp.float64)
    room = xp.broadcast_to(room, lam.shape)
    return xp.where(room <= 0, c, (c - room) + poisson_min_e(lam, xp.maximum(room, 0.0)))


#: :func:`poisson_tail_reach`'s λ + z √λ + a: beyond it P(X ≥ m) < 1e-23 for every λ from 1e-12 to 1e15 (scipy's log
#: survival function on 20 000 means; 1e-23.1 at the worst), so λ − E[min(X, c)] = λ P(X ≥ m) − c P(X > m) is below
#: λ · 1e-23, far under half a float64 ulp of λ: E[min(X, c)] rounds to λ itself.
TAIL_REACH_SIGMAS, TAIL_REACH_OFFSET = 10.0, 20.0


def poisson_tail_reach(lam, xp=np):
    """λ + 10 √λ + 20 (:data:`TAIL_REACH_SIGMAS`, :data:`TAIL_REACH_OFFSET`): a Poisson(λ) count reaches m with
    m − 1 beyond it with a probability below 1e-23, so a full well c with ⌊c⌋ − 1 beyond it leaves E[min(X, c)] = λ
    to the last bit of a float64 (:func:`poisson_min_e`). ``lam`` a float or an array of ``xp``. Unit: e⁻."""
    return lam + TAIL_REACH_SIGMAS * xp.sqrt(lam) + TAIL_REACH_OFFSET


def poisson_min_e(lam, c):
    """E[min(X, c)] for X ~ Poisson(lam), elementwise; ``c`` ≥ 0 may be fractional. Unit: e⁻.

    λ P(X ≤ m − 1) + c P(X > m), m = ⌊c⌋, with the Poisson CDF and survival function as regularised incomplete
    gamma functions (``pdtr``, ``pdtrc``: scipy's, or CuPy's for arrays on a GPU, :mod:`camsim.core.xp`). The clean
    value of a pixel of mean λ under a full well c: per spectrum here, per pixel on the device
    (:mod:`camsim.pairs`).
    """
    xp = namespace_of(lam, c)
    special = special_namespace(xp)
    lam = xp.asarray(lam, dtype=xp.float64)
    c = xp.broadcast_to(xp.asarray(c, dtype=xp.float64), lam.shape)
    m = xp.floor(c)
    # the tail is summed only where it can show in a float64 (an image has a mean per colour, ~1e6 of them; a frame
    # through optics one per pixel)
    near = m - 1 <= poisson_tail_reach(lam, xp)
    out = lam.copy()
    if not bool(near.any()):
        return out
    lam_n, c_n, m_n = lam[near], c[near], m[near]
    cdf = xp.where(m_n >= 1, special.pdtr(xp.maximum(m_n - 1, 0.0), lam_n), 0.0)  # P(X ≤ m − 1); 0 for m = 0
    below = xp.where(lam_n > 0, lam_n * cdf, 0.0)
    out[near] = below + c_n * special.pdtrc(m_n, lam_n)
    return out
