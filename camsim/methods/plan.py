"""How each spectrum and channel of a frame is drawn: the plans of ``poisson``, ``gaussian`` and ``auto`` (MODEL.md §5).

``gaussian`` replaces the collected charge and the read noise of a pixel by one normal draw with the same mean
and variance: value = k · (λ + √(Var(S + D) + σ_read²) · z). It is fast (one float32 normal per pixel and
channel, no Poisson draw at all) and wrong at low counts: negative values, no skew, the wrong probability of
zero. Where saturation can act, it draws S + D as a normal, clips it at the full well, then adds read noise.

``auto`` decides before drawing anything, from the expected counts: for each distinct spectrum and channel it
takes the Gaussian path when the Kolmogorov–Smirnov distance between the exact law of the pixel value before
quantisation (Poisson(λ_p) plus Gaussian noise σ_g) and its moment-matched normal is at most the tolerance
(default :data:`DEFAULT_TOLERANCE`), and saturation cannot act; else the exact ``poisson`` path. A spectrum far
above the full well is exact either way (its value is the full well plus read noise). The KS distance is
computed numerically, once per σ_g, on a grid of λ_p, and the decision uses its envelope max over λ' ≥ λ_p, so
that no λ_p between grid points is judged better than it is.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import stats

from camsim.expected import ExpectedSignal
from camsim.fixed_pattern import dark_gain_at
from camsim.methods import DEFAULT_TOLERANCE
from camsim.sensor import SensorParams

#: Saturation cannot act on a spectrum whose mean is this many standard deviations below the full well.
SATURATION_MARGIN_SIGMA = 6.0

EXACT, GAUSSIAN, GAUSSIAN_CLIPPED, SATURATED = 0, 1, 2, 3
KIND_NAMES = {EXACT: "poisson", GAUSSIAN: "gaussian", GAUSSIAN_CLIPPED: "gaussian-clipped", SATURATED: "saturated"}
_LAMBDA_GRID = np.geomspace(1e-3, 1e6, 181)
KS_MARGIN = 1.01
#: Above this mean the KS distance is taken from its asymptotic form instead of summing the Poisson law.
EXACT_KS_MAX_LAMBDA = 1e3


def ks_gaussian(lam_poisson: float, sigma_gauss: float) -> float:
    """KS distance between Poisson(λ) + N(0, σ²) and N(λ, λ + σ²).

    Parameters
    ----------
    lam_poisson : float
        Mean of the Poisson part. Unit: e⁻.
    sigma_gauss : float
        Standard deviation of the independent Gaussian part (read noise). Unit: e⁻.
    """
    lam, sigma = float(lam_poisson), float(sigma_gauss)
    if lam <= 0:
        return 0.0
    sd = np.sqrt(lam + sigma**2)
    if lam > EXACT_KS_MAX_LAMBDA:
        # Edgeworth: F ≈ Φ(z) − γ/6 (z² − 1) φ(z), γ = λ / sd³, so KS ≈ γ φ(0) / 6; plus, without enough Gaussian
        # smoothing, the lattice's half step, φ(0) / (2 sd). Both bounds are conservative at these counts.
        lattice = stats.norm.pdf(0) / (2 * sd) if sigma < 1 else 0.0
        return float(lam / sd**3 * stats.norm.pdf(0) / 6 + lattice)
    n = np.arange(max(0, int(lam - 12 * np.sqrt(lam) - 12)), int(lam + 12 * np.sqrt(lam) + 13))
    pmf = stats.poisson.pmf(n, lam)
    if sigma > 0:
        x = lam + sd * np.linspace(-8, 8, 801)
        exact = pmf @ stats.norm.cdf((x[None, :] - n[:, None]) / sigma)
        gauss = stats.norm.cdf((x - lam) / sd)
        return float(np.max(np.abs(exact - gauss)))
    # a lattice law against a continuous one: the supremum is reached just below or at the integers
    cdf = np.cumsum(pmf) + stats.poisson.cdf(n[0] - 1, lam)
    below = cdf - pmf
    gauss = stats.norm.cdf((n - lam) / sd)
    return float(max(np.max(np.abs(cdf - gauss)), np.max(np.abs(below - gauss))))


@lru_cache(maxsize=64)
def _ks_envelope(sigma_gauss: float) -> np.ndarray:
    ks = np.array([ks_gaussian(lam, sigma_gauss) for lam in _LAMBDA_GRID])
    return np.maximum.accumulate(ks[::-1])[::-1]  # max over λ' ≥ λ


def predicted_ks(lam_poisson, sigma_gauss: float) -> np.ndarray:
    """Conservative KS distance of the Gaussian method for Poisson means ``lam_poisson`` (array), read noise σ."""
    envelope = _ks_envelope(round(float(sigma_gauss), 6))
    lam = np.asarray(lam_poisson, dtype=np.float64)
    index = np.searchsorted(_LAMBDA_GRID, lam, side="right") - 1  # the grid point at or below λ: conservative
    # 1 % margin: without read noise the lattice law's KS has cusps between grid points (measured: ≤ 0.3 % above)
    return np.where(lam <= 0, 0.0, KS_MARGIN * envelope[np.clip(index, 0, _LAMBDA_GRID.size - 1)])


@dataclass(frozen=True)
class DrawPlan:
    """How each spectrum (row) and channel (column) is drawn, shape (K, 3) each.

    Attributes
    ----------
    kind : numpy.ndarray of int8
        :data:`EXACT`, :data:`GAUSSIAN`, :data:`GAUSSIAN_CLIPPED` or :data:`SATURATED`.
    predicted_ks : numpy.ndarray
        KS distance the Gaussian has for that spectrum and channel, chosen or not (0 where it is exact: a
        saturated spectrum).
    tolerance : float or None
        ``auto``'s tolerance; None for the ``gaussian`` and ``poisson`` methods.
    needs_clip : numpy.ndarray of bool
        Whether the full well can be reached (mean + 10 σ + 10 e⁻); where not, the exact path skips the clip.
    """

    kind: np.ndarray
    predicted_ks: np.ndarray
    tolerance: float | None
    needs_clip: np.ndarray | None = None

    def names(self, index: int) -> list:
        return [KIND_NAMES[int(k)] for k in self.kind[index]]


def plan_methods(expected: ExpectedSignal, sensor: SensorParams, statistics: str, method: str,
                 tolerance: float = DEFAULT_TOLERANCE) -> DrawPlan:
    """Decide per spectrum and channel (``method`` is ``poisson``, ``gaussian`` or ``auto``)."""
    read = sensor.read_noise_e if sensor.read_noise else 0.0
    lam = expected.signal_e + expected.dark_e
    var_charge = expected.total_var_e2
    if statistics == "pixel" and sensor.photon_noise:
        lam_poisson, extra_var = lam, 0.0
    else:  # paper: the signal's scaled-Poisson counts are ~1e16: Gaussian already; only D is Poisson
        lam_poisson, extra_var = np.broadcast_to(expected.dark_e, lam.shape), expected.signal_var_e2
    spread = SATURATION_MARGIN_SIGMA * np.sqrt(var_charge)
    # fixed-pattern maps move a pixel's mean: widen the margins by 6 σ of each map
    spread = spread + 6 * (sensor.prnu_percent / 100 * expected.signal_e + sensor.dsnu_e)
    if sensor.dsnu_dark_current_percent > 0:
        # the log-normal dark map, within 6 σ of its normal: a hot pixel's dark mean and variance grow by
        # D̄ (d₆ − 1) (more than a cold one's fall); a cold one's Poisson mean, D̄ d₋₆, is where the KS is judged
        hot = expected.dark_e * (dark_gain_at(sensor, 6.0) - 1)
        spread = spread + hot + SATURATION_MARGIN_SIGMA * (np.sqrt(var_charge + hot) - np.sqrt(var_charge))
        lam_poisson = lam_poisson - expected.dark_e * (1 - dark_gain_at(sensor, -6.0))
    if sensor.saturation:
        below = lam + spread <= sensor.full_well_e
        above = lam - spread >= sensor.full_well_e
    else:
        below, above = np.ones(lam.shape, bool), np.zeros(lam.shape, bool)
    ks = np.zeros(lam.shape)
    sigma_g = np.broadcast_to(np.round(np.sqrt(read**2 + extra_var), 6), lam.shape)
    # one KS curve per distinct Gaussian part; none for saturated spectra (exact either way, their KS is 0): under
    # ``paper`` statistics a bright frame has a distinct Gaussian part per spectrum, each curve costs a second
    for value in np.unique(sigma_g[~above]) if method != "poisson" else ():
        where = (sigma_g == value) & ~above
        ks[where] = predicted_ks(lam_poisson[where], value)
    # P(X ≥ mean + 10 σ + 10) < 1e-22 for these Poisson-like totals: below that, clipping cannot act
    fpn = 10 * (sensor.prnu_percent / 100 * expected.signal_e + sensor.dsnu_e)
    if sensor.dsnu_dark_current_percent > 0:  # the dark map's hot pixels, within 10 σ of its normal
        hot = expected.dark_e * (dark_gain_at(sensor, 10.0) - 1)
        fpn = fpn + hot + 10 * (np.sqrt(var_charge + hot) - np.sqrt(var_charge))
    needs_clip = sensor.saturation & (lam + 10 * np.sqrt(var_charge) + 10 + fpn >= sensor.full_well_e)
    if method == "poisson":
        kind, tolerance = np.full(lam.shape, EXACT), None
    elif method == "gaussian":
        kind, tolerance = np.where(above, SATURATED, np.where(below, GAUSSIAN, GAUSSIAN_CLIPPED)), None
    else:  # a non-Gaussian read noise: the Gaussian replacement's KS is not tabulated, so never taken
        ok = below & (ks <= tolerance) & (sensor.gaussian_read_noise or read == 0)
        kind = np.where(above, SATURATED, np.where(ok, GAUSSIAN, EXACT))
    return DrawPlan(kind.astype(np.int8), np.where(above, 0.0, ks), tolerance, needs_clip)
