"""How each spectrum and channel of a frame is drawn: the plans of ``poisson``, ``gaussian`` and ``auto``.

``gaussian`` replaces the collected charge and the read noise of a pixel by one normal draw with the same mean
and variance: value = k · (λ + √(Var(S + D) + σ_read²) · z). It is fast (one float32 normal per pixel and
channel, no Poisson draw at all) and wrong at low counts: negative values, no skew, the wrong probability of
zero. Where saturation can act, it draws S + D as a normal, clips it at the full well, then adds read noise.

``auto`` decides before drawing anything, from the expected counts: for each distinct spectrum and channel it
takes the Gaussian path when the Kolmogorov–Smirnov distance between the exact law of the pixel value before
quantisation and its moment-matched normal is at most the tolerance (default :data:`DEFAULT_TOLERANCE`), and
saturation cannot act; else an exact path. A spectrum far above the full well is exact either way (its value is
the full well plus read noise).

* ``pixel`` statistics: the exact law is Poisson(S̄ + D̄) plus Gaussian read noise σ; its KS distance to the
  normal is computed numerically (:func:`ks_gaussian`), once per σ on a grid of means, and the decision uses its
  envelope max over λ' ≥ λ, so that no mean between grid points is judged better than it is. The exact path is
  the ``poisson`` draw.
* ``paper`` statistics: the exact law is Eq. 4's S = Σᵢ wᵢ Nᵢ, Nᵢ ~ Poisson(μᵢ) (μᵢ = F g(λᵢ), wᵢ = T Qe(λᵢ)),
  plus D ~ Poisson(D̄) and the read noise. At low F (μᵢ of order one: F ≲ 1e-15 for 100 cd/m²) S is a sum of
  a few weighted counts, far from normal, and also far from ``poisson``'s stand-in s · Poisson(S̄/s). Its KS
  distance to the normal is bounded, not computed (:func:`paper_ks_bounds`: Berry–Esseen for the compound
  Poisson S, plus the exact KS of the dark and read part). Where the Gaussian is refused, ``auto`` draws the
  stand-in where its own KS distance to Eq. 4 is bounded within the tolerance, and Eq. 4 itself (per-bin
  counts, shared by the channels, :data:`BINS`) where it is not. So under both statistics every spectrum and
  channel of an ``auto`` frame is within the tolerance of the exact law, in KS distance of one pixel value.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
from scipy import special, stats

from camsim.light.rates import FactoredSpectra
from camsim.methods.tolerance import DEFAULT_TOLERANCE
from camsim.sensor.expected import ExpectedSignal
from camsim.sensor.fixed_pattern import dark_gain_at, map_file_extreme
from camsim.sensor.params import SensorParams

#: Saturation cannot act on a spectrum whose mean is this many standard deviations below the full well.
SATURATION_MARGIN_SIGMA = 6.0

EXACT, GAUSSIAN, GAUSSIAN_CLIPPED, SATURATED, BINS, TABLE = 0, 1, 2, 3, 4, 5
#: The sidecar's names of the kinds: ``poisson`` is the exact draw (under ``paper`` statistics the scaled-Poisson
#: stand-in), ``spectral`` Eq. 4's per-bin draw (``auto`` under ``paper`` statistics only).
KIND_NAMES = {EXACT: "poisson", GAUSSIAN: "gaussian", GAUSSIAN_CLIPPED: "gaussian-clipped", SATURATED: "saturated",
              BINS: "spectral", TABLE: "table"}
_LAMBDA_GRID = np.geomspace(1e-3, 1e6, 181)
#: Below this read noise (e⁻) :func:`ks_gaussian` takes the bare lattice's KS distance (an upper bound).
SIGMA_LATTICE = 0.05
#: Berry–Esseen's constant for sums of i.i.d. terms (Shevtsova 2011: C < 0.4748). A compound Poisson S is the sum
#: of n i.i.d. compound Poissons of rate Λ/n for every n; as n → ∞ their Lyapunov ratio tends to
#: E|J|³ / (E J² )^{3/2} / √Λ (J a jump), so sup |F_S − Φ| ≤ C Σ μᵢ wᵢ³ / (Σ μᵢ wᵢ²)^{3/2}.
BERRY_ESSEEN_C = 0.4748
KS_MARGIN = 1.01
#: Above this mean the KS distance is taken from its asymptotic form instead of summing the Poisson law.
EXACT_KS_MAX_LAMBDA = 1e3


def ks_gaussian(lam_poisson: float, sigma_gauss: float) -> float:
    """KS distance between Poisson(λ) + N(0, σ²) and N(λ, λ + σ²).

    Computed on the lattice (σ below :data:`SIGMA_LATTICE`: the bare lattice's distance, an upper bound, as adding
    N(0, σ²) to both laws cannot raise it) or on a grid of x with a bound on what the grid can miss between its
    points; above a mean of :data:`EXACT_KS_MAX_LAMBDA`, from the asymptotic form. Never below the true distance
    but for the asymptotic form's approximation.

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
    # a lattice law against a continuous one: the supremum is reached just below or at the integers
    cdf = np.cumsum(pmf) + stats.poisson.cdf(n[0] - 1, lam)
    gauss = special.ndtr((n - lam) / np.sqrt(lam))
    bare = float(max(np.max(np.abs(cdf - gauss)), np.max(np.abs(cdf - pmf - gauss))))
    if sigma < SIGMA_LATTICE:
        return bare
    # on a grid of x (spacing ≤ σ/4 where that takes at most 4001 points); between its points |F − Φ| can exceed
    # its sampled maximum by at most |g''| h² / 8 (h the spacing), where g'' = F'' − Φ'' is bounded by
    # max pₙ (2 φ(1) + 2 σ φ(0)) / σ² + φ(1) / sd²
    points = int(min(4001, max(801, np.ceil(64 * sd / sigma) + 1)))
    x = lam + sd * np.linspace(-8, 8, points)
    chunk = max(1, 2**21 // n.size)  # at most 2M values of Φ at once
    sampled = max(np.max(np.abs(pmf @ special.ndtr((part[None, :] - n[:, None]) / sigma)
                                - special.ndtr((part - lam) / sd)))
                  for part in (x[i : i + chunk] for i in range(0, x.size, chunk)))
    phi0, phi1 = stats.norm.pdf(0), stats.norm.pdf(1)
    curvature = pmf.max() * (2 * phi1 + 2 * sigma * phi0) / sigma**2 + phi1 / sd**2
    return float(min(bare, sampled + curvature * (x[1] - x[0]) ** 2 / 8))


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


def ks_normals(var_a, var_b):
    """KS distance between N(0, var_a) and N(0, var_b) (arrays broadcast): Φ(t / r) − Φ(t) at the t where the two
    densities cross, t² = −ln(r²) r² / (1 − r²), r the ratio of the smaller standard deviation to the larger."""
    lo, hi = np.minimum(var_a, var_b), np.maximum(var_a, var_b)
    with np.errstate(divide="ignore", invalid="ignore"):
        r2 = np.where(hi > 0, lo / hi, 1.0)
        t = np.sqrt(np.where((r2 > 0) & (r2 < 1), -np.log(r2) * r2 / (1 - r2), 0.0))
        value = special.ndtr(t / np.sqrt(r2)) - special.ndtr(t)
    return np.where(r2 >= 1, 0.0, np.where(r2 <= 0, 0.5, value))


@lru_cache(maxsize=4096)
def _ks_at(lam: float, sigma: float) -> float:
    return ks_gaussian(lam, sigma)


def _sigma_below(sigma):
    """σ rounded down to a 2 % grid (0 below :data:`SIGMA_LATTICE`): the KS distance falls as σ grows, so the
    distance at the rounded σ bounds the one at σ, and few distinct values need computing."""
    sigma = np.asarray(sigma, dtype=np.float64)
    with np.errstate(divide="ignore"):
        grid = 10 ** (np.floor(np.log10(np.maximum(sigma, SIGMA_LATTICE)) * 100) / 100)
    return np.where(sigma < SIGMA_LATTICE, 0.0, np.minimum(grid, sigma))


def paper_ks_bounds(expected: ExpectedSignal, read_noise_e: float, gaussian_read: bool = True):
    """Upper bounds on KS distances to the law of a pixel value under ``paper`` statistics, shape (K, 3) each.

    The exact law is V = S + D + R: Eq. 4's S = Σᵢ wᵢ Nᵢ, Nᵢ ~ Poisson(μᵢ), μᵢ = F g(λᵢ) (``photon_rate``),
    wᵢ = T Qe(λᵢ); D ~ Poisson(D̄); R the read noise (σ = ``read_noise_e``). Bounds of the KS distance
    sup |F_V − F| (before saturation and quantisation, which are monotone maps and cannot raise it) between it and

    * the moment-matched normal N(S̄ + D̄, Var S + D̄ + σ²) (the ``gaussian`` path): the least of
      (A) B(S) + KS(Poisson(D̄) + N(0, Var S + σ²), its normal) — S replaced by the normal of its moments, which
      moves the law by at most B(S), Berry–Esseen's bound for the compound Poisson S
      (:data:`BERRY_ESSEEN_C` · Σ μ w³ / (Σ μ w²)^{3/2}); and, with Gaussian read noise,
      (B) φ(0) sd(S) / σ + KS(Poisson(D̄) + N(0, σ²), its normal) + KS(N(0, D̄ + σ²), N(0, D̄ + σ² + Var S)) —
      S as a perturbation of a law whose density is at most φ(0) / σ;
    * ``poisson``'s stand-in, S' = s · Poisson(S̄ / s), s = Var S / S̄ (the same mean and variance): the least of
      (I) KS(S', normal) + B(S); (II) with Gaussian read noise, 2 φ(0) sd(S) / σ; (III) with D̄ > 0,
      max pₖ(D̄) · min(1, (I)) + min(1, S̄) — both S ≥ 0 exceed 1 e⁻ with probability ≤ S̄ (Markov), so only the
      one count of D just below x sees the difference (S̄ in e⁻).

    Parameters
    ----------
    expected : ExpectedSignal
        A frame's expected signal under ``paper`` statistics with photon noise on.
    read_noise_e : float
        σ, 0 without read noise. Unit: e⁻.
    gaussian_read : bool
        Whether the read noise is Gaussian (routes B and II need its density).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        The bounds for the Gaussian and for the stand-in, each at most 1.
    """
    qe, rate = expected.qe, expected.photon_rate  # (K, N) rows, or factored (an image's colours, a cube's pixels)
    signal, var, dark = expected.signal_e, expected.signal_var_e2, np.asarray(expected.dark_e, dtype=np.float64)
    # B(S) = C Σ μ w³ / (Σ μ w²)^{3/2} is free of the scale of w and falls as 1/√(scale of μ): both normalised, μ
    # by each row's peak (dense rows) or by one bound on every value (factored rows: both sums are linear in μ, so
    # they need no K × N array), so that no sum of a huge μ overflows; the ratio is taken in logarithms
    w = qe / np.where(qe.max(axis=1, keepdims=True) > 0, qe.max(axis=1, keepdims=True), 1.0)
    if isinstance(rate, FactoredSpectra):  # one bound for every row (a cube's stored values taken as ≤ 1)
        coefficients = rate.coefficients
        largest = float(np.max(np.abs(coefficients), initial=0.0)) if isinstance(coefficients, np.ndarray) else 1.0
        peak = largest * float(np.max(np.abs(rate.basis), initial=0.0)) * rate.basis.shape[0] or 1.0
        mu = rate.scaled(1.0 / peak)
    else:
        rate = np.asarray(rate, dtype=np.float64)
        peak = rate.max(axis=1, keepdims=True)
        mu = rate / np.where(peak > 0, peak, 1.0)
    m2, m3 = mu @ (w * w).T, mu @ (w**3).T
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        ratio = np.exp(np.log(m3) - 1.5 * np.log(m2) - 0.5 * np.log(np.where(peak > 0, peak, 1.0)))
        berry_esseen = np.where(m2 > 0, np.minimum(1.0, BERRY_ESSEEN_C * ratio), 0.0)
        counts = np.where(var > 0, signal / (var / signal), 0.0)  # S̄ / s, the stand-in's Poisson mean
    sd_signal = np.sqrt(var)
    sigma_a = _sigma_below(np.sqrt(read_noise_e**2 + var))
    dark_part = np.empty(var.shape)
    for c in range(3):  # σ is on a 2 % grid: one KS per distinct σ, not per spectrum
        sigmas, where = np.unique(sigma_a[:, c], return_inverse=True)
        dark_part[:, c] = np.array([_ks_at(float(dark[c]), float(s)) for s in sigmas])[where.ravel()]
    gaussian = berry_esseen + dark_part
    stand_in = predicted_ks(counts, 0.0) + berry_esseen
    phi0 = stats.norm.pdf(0)
    if gaussian_read and read_noise_e > 0:
        base = dark + read_noise_e**2
        route_b = (phi0 * sd_signal / read_noise_e + np.array([_ks_at(float(d), float(read_noise_e)) for d in dark])
                   + ks_normals(base, base + var))
        gaussian = np.minimum(gaussian, route_b)
        route_ii = 2 * phi0 * sd_signal / read_noise_e
    else:
        route_ii = np.inf
    mode = np.where(dark > 0, stats.poisson.pmf(np.floor(dark), dark), np.inf)
    route_iii = np.where(dark > 0, mode * np.minimum(1.0, stand_in) + np.minimum(1.0, signal), np.inf)
    stand_in = np.minimum(np.minimum(stand_in, route_ii), route_iii)
    return np.minimum(gaussian, 1.0), np.minimum(stand_in, 1.0)


@dataclass(frozen=True)
class DrawPlan:
    """How each spectrum (row) and channel (column) is drawn, shape (K, 3) each.

    Attributes
    ----------
    kind : numpy.ndarray of int8
        :data:`EXACT`, :data:`GAUSSIAN`, :data:`GAUSSIAN_CLIPPED`, :data:`SATURATED` or :data:`BINS`.
    predicted_ks : numpy.ndarray
        KS distance the Gaussian has for that spectrum and channel, chosen or not, to the exact law of a pixel
        value before quantisation (0 where it is exact: a saturated spectrum). Computed under ``pixel``
        statistics (:func:`predicted_ks`), an upper bound under ``paper`` statistics (:func:`paper_ks_bounds`);
        0 for the ``poisson`` method, which does not compute it.
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

    @cached_property
    def kinds_by_channel(self) -> tuple:
        """The distinct kinds of each channel, three int8 arrays: computed once per frame, not per block (a cube or
        an image has one spectrum per colour, up to one per pixel)."""
        return tuple(np.flatnonzero(np.bincount(self.kind[:, c], minlength=TABLE + 1)).astype(np.int8)
                     for c in range(3))

    @cached_property
    def clip_by_channel(self) -> np.ndarray:
        """Whether any spectrum needs the full-well clip, per channel, shape (3,) bool."""
        if self.needs_clip is None:
            return np.ones(3, dtype=bool)
        return np.any(self.needs_clip, axis=0)

    @cached_property
    def bins_spectra(self) -> np.ndarray | None:
        """Spectra drawn by :data:`BINS` in some channel, shape (K,) bool; None where there are none."""
        spectra = np.any(self.kind == BINS, axis=1)
        return spectra if spectra.any() else None


def plan_methods(expected: ExpectedSignal, sensor: SensorParams, statistics: str, method: str,
                 tolerance: float = DEFAULT_TOLERANCE) -> DrawPlan:
    """Decide per spectrum and channel (``method`` is ``poisson``, ``table``, ``gaussian`` or ``auto``).

    ``table`` and ``auto`` draw an exact spectrum and channel by :data:`TABLE` (its charge law as an alias table,
    :mod:`camsim.methods.table`) where the law fits one and no fixed-pattern map gives pixels laws of their own
    (else :data:`EXACT`, numpy's Poisson sampler): the same law, at about a fifth of the cost.
    """
    read = sensor.read_noise_e if sensor.read_noise else 0.0
    lam = expected.signal_e + expected.dark_e
    var_charge = expected.total_var_e2
    needs_clip = _needs_clip(expected, sensor, lam, var_charge)
    if method in ("poisson", "table"):  # every spectrum exact: nothing to judge (an image's K may be ~1e6 colours)
        kind = np.zeros(lam.shape, dtype=np.int8)
        if method == "table":
            kind = _tables_where_they_fit(kind, expected, sensor, statistics)
        return DrawPlan(kind, np.zeros(lam.shape), None, needs_clip)
    paper = statistics == "paper" and sensor.photon_noise
    spread = SATURATION_MARGIN_SIGMA * np.sqrt(var_charge)
    # fixed-pattern maps move a pixel's mean: widen the margins by 6 σ of each map
    spread = spread + 6 * (sensor.prnu_percent / 100 * expected.signal_e + sensor.dsnu_e)
    cold = 0.0  # how far below D̄ the coldest pixel's dark mean lies (the dark-current map)
    if sensor.dsnu_dark_current_percent > 0:
        # the log-normal dark map, within 6 σ of its normal: a hot pixel's dark mean and variance grow by
        # D̄ (d₆ − 1) (more than a cold one's fall); a cold one's Poisson mean, D̄ d₋₆, is where the KS is judged
        hot = expected.dark_e * (dark_gain_at(sensor, 6.0) - 1)
        spread = spread + hot + SATURATION_MARGIN_SIGMA * (np.sqrt(var_charge + hot) - np.sqrt(var_charge))
        cold = expected.dark_e * (1 - dark_gain_at(sensor, -6.0))
    hot, offsets = effect_margins_e(expected, sensor)
    if sensor.hot_pixels or sensor.dark_offsets:  # issue 28's maps: their largest shifts of a pixel's mean
        spread = spread + offsets + hot + SATURATION_MARGIN_SIGMA * (np.sqrt(var_charge + hot) - np.sqrt(var_charge))
    if sensor.saturation:
        below = lam + spread <= sensor.full_well_e
        # a dead pixel collects nothing: no spectrum is drawn as saturated wholesale when there are dead pixels
        above = (lam - spread >= sensor.full_well_e) & (not sensor.dead_pixel_fraction > 0)
    else:
        below, above = np.ones(lam.shape, bool), np.zeros(lam.shape, bool)
    ks = np.zeros(lam.shape)
    stand_in = np.zeros(lam.shape)  # KS distance of the exact path to the exact law: 0 but for paper's stand-in
    if method != "poisson" and paper:  # judged at the coldest pixel of a dark-current DSNU map, as below
        judged = expected if np.all(cold == 0) else dataclasses.replace(expected, dark_e=expected.dark_e - cold)
        ks, stand_in = paper_ks_bounds(judged, read, sensor.gaussian_read_noise)
    elif method != "poisson":  # the Poisson part: S + D (pixel statistics) or D alone (no photon noise)
        lam_poisson = (lam if sensor.photon_noise else np.broadcast_to(expected.dark_e, lam.shape)) - cold
        ks[~above] = predicted_ks(lam_poisson[~above], read)  # saturated spectra are exact either way: KS 0
    if method == "gaussian":
        kind, tolerance = np.where(above, SATURATED, np.where(below, GAUSSIAN, GAUSSIAN_CLIPPED)), None
    else:  # a non-Gaussian read noise: the Gaussian replacement's KS is not tabulated, so never taken
        ok = below & (ks <= tolerance) & (sensor.gaussian_read_noise or read == 0)
        exact = np.where(stand_in <= tolerance, EXACT, BINS)  # paper: Eq. 4 itself where the stand-in may be off
        kind = np.where(above, SATURATED, np.where(ok, GAUSSIAN, exact))
    kind = _tables_where_they_fit(kind.astype(np.int8), expected, sensor, statistics)
    return DrawPlan(kind, np.where(above, 0.0, ks), tolerance, needs_clip)


def _tables_where_they_fit(kind, expected: ExpectedSignal, sensor: SensorParams, statistics: str) -> np.ndarray:
    """``kind`` with :data:`EXACT` replaced by :data:`TABLE` where the charge law fits a table and the frame has no
    fixed-pattern map (:func:`camsim.methods.table.table_eligible`)."""
    from camsim.methods.table import charge_tables_fit, table_eligible

    if not table_eligible(sensor, statistics):
        return kind
    return np.where((kind == EXACT) & charge_tables_fit(expected, sensor), TABLE, kind).astype(np.int8)


def _needs_clip(expected: ExpectedSignal, sensor: SensorParams, lam, var_charge) -> np.ndarray:
    """(K, 3) bool: whether the full well can be reached by a pixel of the spectrum, in the channel.

    P(X ≥ mean + 10 σ + 10) < 1e-22 for these Poisson-like totals: below that, clipping cannot act (fixed-pattern
    maps move the mean by up to 10 σ of each map).
    """
    if not sensor.saturation:
        return np.zeros(lam.shape, dtype=bool)
    fpn = 10 * (sensor.prnu_percent / 100 * expected.signal_e + sensor.dsnu_e)
    if sensor.dsnu_dark_current_percent > 0:  # the dark map's hot pixels, within 10 σ of its normal
        hot = expected.dark_e * (dark_gain_at(sensor, 10.0) - 1)
        fpn = fpn + hot + 10 * (np.sqrt(var_charge + hot) - np.sqrt(var_charge))
    if sensor.hot_pixels or sensor.dark_offsets:
        hot, offsets = effect_margins_e(expected, sensor)
        fpn = fpn + offsets + hot + 10 * (np.sqrt(var_charge + hot) - np.sqrt(var_charge))
    return lam + 10 * np.sqrt(var_charge) + 10 + fpn >= sensor.full_well_e


#: A hot pixel's extra dark current is below this many times its mean but with probability e⁻⁵⁰ = 2e-22
#: (exponential law).
HOT_MARGIN_MEANS = 50.0
#: The dark shading's and column FPN's largest offsets are taken as this many times their RMS or σ (the shading is a
#: normalised sum of three unit-RMS parts, each within a few times its RMS).
OFFSET_MARGIN = 10.0


def effect_margins_e(expected: ExpectedSignal, sensor: SensorParams):
    """The largest extra mean charge of a hot pixel, per channel (3,) (0 where the channel has no dark charge: the
    dark factor then does nothing), and the largest |offset| of the dark shading and column FPN, for the plan's
    margins (issue 28). A map file counts with its largest value. Unit: e⁻."""
    rate = 0.0
    if sensor.hot_pixel_fraction > 0:
        rate += HOT_MARGIN_MEANS * sensor.hot_pixel_dark_e_per_s
    if sensor.hot_pixel_map is not None:
        rate += map_file_extreme(sensor.hot_pixel_map, "hot_pixel_map")
    hot = np.where(expected.dark_e > 0, rate * sensor.temperature_factor * sensor.exposure_s, 0.0)
    offsets = OFFSET_MARGIN * (sensor.dark_shading_e + sensor.column_fpn_e)
    if sensor.dark_shading_map is not None:
        offsets += map_file_extreme(sensor.dark_shading_map, "dark_shading_map")
    return hot, offsets
