"""The true black level: the exact expected digital number of an unlit pixel (Eqs. 6–11).

An unlit pixel of channel κ reads

    I = clip(floor(k · (min(D + o, FW) + R + W)), 0, 2^nb − 1),

with k = G · G_Ve⁻, D ~ Poisson(D̄ · L) its dark charge (D̄ = σ²_dark,κ · T; L a per-pixel dark-current
factor, log-normal of mean 1, or 1), o its DSNU offset (N(0, σ_o²), fixed per pixel), FW the full well (if
saturation is on), R the read noise (N(0, σ_read²), or Tukey λ scaled to σ_read) and W the row noise, N(0, σ_row²).
"An unlit pixel" means its law averaged over the fixed-pattern maps' population law (o, L): the mean over a dark
frame's pixels, which is what a raw reader subtracts as the black level.

:func:`unlit_mean_dn` computes E[I] = Σ_{j=1}^{2^nb−1} P(k X ≥ j), X = min(D + o, FW) + R + W: the atoms of D's
probability function, each against the noise's survival function, with closed forms (normal CDFs, Owen's T for
the DSNU at the full well) or quadratures (Tukey λ, the log-normal factor, DSNU at the full well with Tukey noise)
where none exists. :mod:`tests.sensor.test_black_level` checks it against separate closed forms to 1e-8 DN (1e-7 against
a quadrature for the log-normal factor) and against Monte Carlo; halving the quadrature steps moves the Tukey
cases by < 2e-12 DN. Cost per channel, cached: under 2 ms with Gaussian read noise, 10–300 ms with Tukey noise,
about 10 s in the rarest case (a dark charge at the full well with DSNU and Tukey noise).

Without quantisation the value is k · E[min(D + o, FW)] exactly (read and row noise have mean 0), which is k · D̄
unless the full well clips the dark charge. The value is that of exact arithmetic: without read and row noise (a
pure lattice k · d) the renderer's float32 floor can differ where k · d lies within a float32 ulp of an integer.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import special, stats

from camsim.sensor.kernels import tukey_lambda_variance
from camsim.sensor.stages import adc_offset_dn

#: Half-width of the Gaussian windows, in standard deviations: Φ(−9.5) = 1e-21.
_GAUSS_HALF = 9.5
#: Tail probability outside the window of a Tukey λ read noise (its quantiles at ε and 1 − ε).
_TUKEY_TAIL = 1e-12
#: The trapezoid rule over the Tukey law in s = logit(u): range ±_TUKEY_S (tails of e⁻³⁰ = 1e-13) and step.
_TUKEY_S, _TUKEY_STEP = 30.0, 0.2
#: Gauss–Hermite nodes over a Gaussian noise narrower than half the Tukey read noise.
_HERMITE_NODES = 24
#: Standard deviations of o, or of the log of L, beyond which their laws are cut (tail below 1e-30).
_FIXED_HALF = 12.0
#: Gauss–Hermite nodes over log L (the dark-current factor).
_LOG_NORMAL_NODES = 64
#: Atoms of smaller probability are dropped (at most 1e-22 × 2^16 × their number of DN in all).
_NEGLIGIBLE = 1e-22
#: Pairs (atom, code) evaluated at once.
_CHUNK = 1 << 20


def unlit_mean_dn(dark_mean_e, *, dn_per_electron: float, bits: int, quantisation: bool = True,
                  full_well_e: float | None = None, dsnu_e: float = 0.0, dark_rate_rel_sigma: float = 0.0,
                  read_noise_e: float = 0.0, read_noise_model: str = "gaussian", tukey_lambda: float = -0.1,
                  row_noise_e: float = 0.0, pedestal_dn: int = 0) -> np.ndarray:
    """The exact expected digital number of an unlit pixel, per channel (the true black level).

    Parameters
    ----------
    dark_mean_e : float or array_like
        D̄ = σ²_dark · T per channel (0 without dark current). Unit: e⁻.
    dn_per_electron : float
        k = G · G_Ve⁻. Unit: DN / e⁻.
    bits : int
        nb: the ADC clips to [0, 2^nb − 1].
    quantisation : bool
        Off: the mean of k · (min(D + o, FW) + R + W), the values before the ADC.
    full_well_e : float or None
        FW, where saturation is on; None: no clip. Unit: e⁻.
    dsnu_e : float
        σ_o of the per-pixel dark offset, added before saturation. Unit: e⁻.
    dark_rate_rel_sigma : float
        Relative σ of the per-pixel dark-current factor L (log-normal, mean 1); 0: none. Unitless.
    read_noise_e : float
        σ_read (0 when the read noise is off). Unit: e⁻.
    read_noise_model : {'gaussian', 'tukey-lambda'}
    tukey_lambda : float
        Shape of the Tukey λ read noise.
    row_noise_e : float
        σ_row. Unit: e⁻.
    pedestal_dn : int
        The ADC's black-level pedestal P: with P > 0 the ADC adds an offset O = P + ½ before its floor
        (:func:`camsim.sensor.stages.adc_offset_dn`), I = clip(floor(k X + O), 0, 2^nb − 1), whose mean is
        Σ_{j=1}^{2^nb−1} P(k X + O ≥ j) — the sum without a pedestal, with X moved up by O / k electrons after the
        full well (computed so; the noiseless lattice is floor(k X + ½) + P). With no dark charge and symmetric
        noise that nothing clips, the mean is P exactly. Quantised values only. Unit: DN.

    Returns
    -------
    numpy.ndarray
        E[I] per channel, shaped like ``dark_mean_e``. Unit: DN.
    """
    tukey = read_noise_model == "tukey-lambda" and read_noise_e > 0
    common = (float(dn_per_electron), int(bits), bool(quantisation),
              None if full_well_e is None else float(full_well_e), float(dsnu_e), float(dark_rate_rel_sigma),
              float(read_noise_e), float(tukey_lambda) if tukey else None, float(row_noise_e),
              int(pedestal_dn) if quantisation else 0)
    means = np.asarray(dark_mean_e, dtype=np.float64)
    return np.array([_channel_mean_dn(float(mu), *common) for mu in means.ravel()]).reshape(means.shape)


@lru_cache(maxsize=256)
def _channel_mean_dn(mu, k, bits, quantised, full_well, sigma_o, rel, sigma_read, lam, sigma_row, pedestal) -> float:
    """:func:`unlit_mean_dn` of one channel; ``lam`` None: Gaussian read noise."""
    top = 2**bits - 1
    offset = adc_offset_dn(pedestal)
    lift = offset / k  # the ADC's offset in electrons: X + O / k is read by the ADC without an offset
    lo, hi = _dark_support(mu, rel)
    sat = full_well is not None and hi + _FIXED_HALF * sigma_o >= full_well  # the full well can act
    if sat and lo - _FIXED_HALF * sigma_o >= full_well:  # it always acts: every pixel holds the full well
        mu, lo, hi, sigma_o, sat, rel = 0.0, 0, 0, 0.0, False, 0.0
        shift = full_well
    else:
        shift = 0.0
    if not quantised:
        if not sat:
            return k * (mu + shift)
        d, p = _dark_pmf(mu, rel)
        if sigma_o == 0:
            return k * float(p @ np.minimum(d, full_well))
        a = (full_well - d) / sigma_o  # E[min(o, s a)] = s (a Φ(−a) − φ(a))
        return k * float(p @ (d + sigma_o * (a * special.ndtr(-a) - _phi(a))))
    gauss_var = sigma_row**2 + (sigma_read**2 if lam is None else 0.0)
    tukey = None if lam is None else (lam, sigma_read / np.sqrt(tukey_lambda_variance(lam)))
    if not sat or sigma_o == 0:
        if not sat:
            gauss_var += sigma_o**2
        if k * (lo + shift - _noise_half(gauss_var, tukey)) + offset >= top:  # every code is the top one
            return float(top)
        d, p = _dark_pmf(mu, rel)
        atoms = d + shift
        if sat:  # the dark charges at or above the full well: one atom there
            below = d < full_well
            atoms, p = np.append(d[below], full_well), np.append(p[below], p[~below].sum())
        return _atoms_mean(atoms, p, k, top, gauss_var, tukey, pedestal)
    d, p = _dark_pmf(mu, rel)
    if gauss_var == 0 and tukey is None:  # min(d + o, FW) ≥ x ⇔ d + o ≥ x and x ≤ FW
        # X + O/k = min(d + o + O/k, FW + O/k): the top code floor(k FW + O)
        return _atoms_mean(d + lift, p, k, min(top, int(np.floor(k * full_well + offset - pedestal)) + pedestal),
                           sigma_o**2, None)
    if tukey is None:
        return _saturated_gaussian_mean(d + lift, p, k, top, full_well + lift, sigma_o, np.sqrt(gauss_var))
    return _saturated_panels_mean(d, p, k, top, full_well, sigma_o, gauss_var, tukey, pedestal)


def _phi(x):
    return np.exp(-0.5 * x * x) / np.sqrt(2 * np.pi)


def _log_normal_nodes(rel):
    """Gauss–Hermite nodes L and weights of the log-normal factor of mean 1 and relative σ ``rel``."""
    s = np.sqrt(np.log1p(rel * rel))
    z, w = np.polynomial.hermite_e.hermegauss(_LOG_NORMAL_NODES)
    w = w / w.sum()
    keep = w > 1e-20
    return np.exp(-0.5 * s * s + s * z[keep]), w[keep]


def _poisson_range(mu):
    half = 13.0 * np.sqrt(mu) + 20.0
    return max(0, int(np.floor(mu - half))), int(np.ceil(mu + half))


def _dark_support(mu, rel):
    """The integers [lo, hi] outside which D's probability is below 1e-30 (about)."""
    if mu == 0:
        return 0, 0
    if rel == 0:
        return _poisson_range(mu)
    factors, _ = _log_normal_nodes(rel)
    return _poisson_range(mu * factors.min())[0], _poisson_range(mu * factors.max())[1]


def _dark_pmf(mu, rel):
    """D's values and probabilities: Poisson(D̄), or its mixture over the log-normal factor."""
    lo, hi = _dark_support(mu, rel)
    d = np.arange(lo, hi + 1, dtype=np.float64)
    if mu == 0:
        return d, np.ones(1)
    if rel == 0:
        p = stats.poisson.pmf(d, mu)
    else:
        factors, weights = _log_normal_nodes(rel)
        p = sum(w * stats.poisson.pmf(d, mu * f) for f, w in zip(factors, weights))
    return d, p / p.sum()


def _tukey_quantile(u, v, lam):
    """Standard Tukey λ quantile at u (v = 1 − u, given separately for accuracy in the upper tail)."""
    return np.log(u / v) if abs(lam) < 1e-9 else (u**lam - v**lam) / lam


@lru_cache(maxsize=16)
def _tukey_table(lam, scale):
    s_grid = np.linspace(-45.0, 45.0, 90001)
    return s_grid, scale * _tukey_quantile(special.expit(s_grid), special.expit(-s_grid), lam)


def _tukey_survival(x, lam, scale):
    """P(R ≥ x) for R = scale · Tukey λ: the quantile map inverted (interpolation, then Newton in logit space)."""
    s_grid, r_grid = _tukey_table(lam, scale)
    s = np.interp(x, r_grid, s_grid)
    for _ in range(2):
        u, v = special.expit(s), special.expit(-s)
        slope = scale * (u**lam * v + v**lam * u)  # d r / d s
        s = np.clip(s - (scale * _tukey_quantile(u, v, lam) - x) / slope, -45.0, 45.0)
    out = special.expit(-s)
    out[x < r_grid[0]], out[x > r_grid[-1]] = 1.0, 0.0
    return out


def _tukey_half(tukey):
    lam, scale = tukey
    eps = _TUKEY_TAIL
    return scale * float(_tukey_quantile(1 - eps, eps, lam))


def _noise_half(gauss_var, tukey):
    """Half-width of the window outside which the noise's survival function is 0 or 1 (to < 1e-15). Unit: e⁻."""
    return _GAUSS_HALF * np.sqrt(gauss_var) + (0.0 if tukey is None else _tukey_half(tukey))


def _noise_survival(x, gauss_var, tukey):
    """P(Z ≥ x) for the continuous noise Z: N(0, gauss_var), or Tukey λ (``tukey`` = (λ, scale)), not both."""
    if tukey is None:
        return special.ndtr(-x / np.sqrt(gauss_var))
    return _tukey_survival(x, *tukey)


def _windows(atoms, k, top, below_e, above_e):
    """Per atom c, the codes j in [1, top] with j / k − c in (−below_e, above_e]: first code and count."""
    first = np.clip(np.floor(k * (atoms - below_e)) + 1, 1, top + 1)
    last = np.clip(np.ceil(k * (atoms + above_e)), 0, top)
    return first.astype(np.int64), np.maximum(last - first + 1, 0).astype(np.int64)


def _pair_sum(atoms, weights, first, count, k, term):
    """Σ_i weights_i Σ_{j = first_i}^{first_i + count_i − 1} term(j / k − atoms_i, i), in chunks of pairs."""
    total, i0 = 0.0, 0
    cum = np.cumsum(count)
    while i0 < atoms.size:
        i1 = int(np.searchsorted(cum, (cum[i0 - 1] if i0 else 0) + _CHUNK, side="right"))
        i1 = max(i1, i0 + 1)
        n = count[i0:i1]
        idx = np.repeat(np.arange(i0, i1), n)
        offset = np.arange(idx.size) - np.repeat(np.cumsum(n) - n, n)
        x = (first[idx] + offset) / k - atoms[idx]
        total += float(np.bincount(idx - i0, weights=term(x, idx), minlength=i1 - i0) @ weights[i0:i1])
        i0 = i1
    return total


def _atoms_mean(atoms, weights, k, top, gauss_var, tukey, pedestal=0):
    """Σ_i w_i E[clip(floor(k (c_i + Z) + O), 0, top)] for atoms c_i and the continuous noise Z (none: a lattice).

    ``pedestal`` P (DN): the ADC's offset O = P + ½ for P > 0, else 0 (:func:`camsim.sensor.stages.adc_offset_dn`); the
    atoms move up by O / k (the noiseless lattice is floor(k c + ½) + P).

    Z = N(0, gauss_var) plus, if ``tukey`` = (λ, scale), a Tukey λ variable. The sum of the two is averaged over
    one of them, whichever leaves a smooth integrand: over the Tukey law (u = expit(s), trapezoid in s) when the
    Gaussian is at least half as wide, else over the Gaussian (Gauss–Hermite).
    """
    if tukey is not None and gauss_var > 0:  # one noise becomes atoms: c_i + node_n, of weight w_i · w_n
        sigma, sigma_r = np.sqrt(gauss_var), tukey[1] * np.sqrt(tukey_lambda_variance(tukey[0]))
        if sigma >= 0.5 * sigma_r:
            s = np.arange(-_TUKEY_S, _TUKEY_S + 1e-9, _TUKEY_STEP)
            u, v = special.expit(s), special.expit(-s)
            nodes, node_weights = tukey[1] * _tukey_quantile(u, v, tukey[0]), _TUKEY_STEP * u * v
            gauss_var, tukey = gauss_var, None
        else:
            z, node_weights = np.polynomial.hermite_e.hermegauss(_HERMITE_NODES)
            nodes, node_weights = sigma * z, node_weights / node_weights.sum()
            gauss_var = 0.0
        atoms = (atoms[None, :] + nodes[:, None]).ravel()
        weights = (weights[None, :] * node_weights[:, None]).ravel()
        keep = weights > _NEGLIGIBLE
        atoms, weights = atoms[keep], weights[keep]
    if gauss_var == 0 and tukey is None:
        half = adc_offset_dn(pedestal) - pedestal
        return float(weights @ np.clip(np.floor(k * atoms + half) + pedestal, 0, top))
    atoms = atoms + adc_offset_dn(pedestal) / k if pedestal else atoms
    half = _noise_half(gauss_var, tukey)
    first, count = _windows(atoms, k, top, half, half)
    sure = np.minimum(first - 1, top)  # codes below the window: P(k X ≥ j) = 1
    return float(weights @ sure) + _pair_sum(atoms, weights, first, count, k,
                                             lambda x, _: _noise_survival(x, gauss_var, tukey))


def _bivariate_normal_cdf(h, kk, rho):
    """P(U ≤ h, V ≤ kk) for standard normals of correlation ``rho`` (Owen's T function), elementwise."""
    if abs(rho) >= 1:  # U = ±V (a DSNU that dwarfs the noise: σ_n/σ_o below 1e-8): the formula's limit, without 1/0
        if rho > 0:
            return special.ndtr(np.minimum(h, kk))
        return np.maximum(special.ndtr(h) + special.ndtr(kk) - 1.0, 0.0)
    h = np.where(h == 0, 1e-300, h)
    kk = np.where(kk == 0, 1e-300, kk)
    c = np.sqrt(1 - rho * rho)
    out = 0.5 * (special.ndtr(h) + special.ndtr(kk)) - special.owens_t(h, (kk - rho * h) / (h * c)) \
        - special.owens_t(kk, (h - rho * kk) / (kk * c))
    return out - 0.5 * (h * kk < 0)


def _saturated_gaussian_mean(d, p, k, top, full_well, sigma_o, sigma_n):
    """E[I] with saturation, DSNU σ_o and Gaussian noise σ_n: per dark charge d and code j,

    P(min(d + o, FW) + N ≥ x) = P(o < a, o + N ≥ x − d) + P(o ≥ a) P(N ≥ x − FW), a = FW − d.
    """
    sigma_z = np.hypot(sigma_o, sigma_n)
    rho = sigma_o / sigma_z
    # X lies in [min(d, FW) − 9.5 (σ_o + σ_n), min(d + 9.5 σ_o, FW) + 9.5 σ_n] but for a tail below 1e-20
    first, _ = _windows(np.minimum(d, full_well), k, top, _GAUSS_HALF * (sigma_o + sigma_n), 0.0)
    last = np.clip(np.ceil(k * (np.minimum(d + _GAUSS_HALF * sigma_o, full_well) + _GAUSS_HALF * sigma_n)), 0, top)
    count = np.maximum(last - first + 1, 0).astype(np.int64)
    alpha = (full_well - d) / sigma_o

    def term(x, i):  # x = j / k − d
        a = alpha[i]
        inside = special.ndtr(a) - _bivariate_normal_cdf(a, x / sigma_z, rho)
        return np.clip(inside, 0.0, 1.0) + special.ndtr(-a) * special.ndtr((full_well - d[i] - x) / sigma_n)

    return float(p @ np.minimum(first - 1, top)) + _pair_sum(d, p, first, count, k, term)


def _saturated_panels_mean(d, p, k, top, full_well, sigma_o, gauss_var, tukey, pedestal=0):
    """E[I] with saturation, DSNU and Tukey read noise: E over o of E[I | o], by Gauss–Legendre on unit panels.

    E[I | o] = Σ_d p_d h(min(d + o, FW)) with h smooth: its kinks lie at o ∈ FW − ℤ, the panels' edges.
    """
    nodes, gl_weights = np.polynomial.legendre.leggauss(8)
    base = full_well - np.floor(full_well)
    m0 = int(np.floor(-_FIXED_HALF * sigma_o - base))
    m1 = int(np.ceil(_FIXED_HALF * sigma_o - base))
    total = 0.0
    for m in range(m0, m1):
        o = base + m + 0.5 * (nodes + 1)
        w = 0.5 * gl_weights * stats.norm.pdf(o, scale=sigma_o)
        for oi, wi in zip(o, w):
            charge = d + oi
            below = charge < full_well
            atoms = np.append(charge[below], full_well)
            weights = np.append(p[below], p[~below].sum())
            total += wi * _atoms_mean(atoms, weights, k, top, gauss_var, tukey, pedestal)
    return total
