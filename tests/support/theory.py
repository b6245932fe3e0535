"""Closed-form model distributions for the tests, written independently of the renderer.

``digital_pmf`` is the exact distribution of one pixel's digital number I = clip(floor(k (min(N, FW) + r)))
with N ~ Poisson(λ) and r ~ N(0, σ_read²) (MODEL.md §3, ``pixel`` statistics), by summing over N.
"""

import numpy as np
from scipy import special, stats


def digital_pmf(lam, dn_per_e, read_noise_e, full_well_e, bits, saturation=True, pedestal_dn=0):
    """P(I = j) for j = 0 … 2^bits − 1, shape (2^bits,), I = clip(round(k (min(N, c) + R)) + P, 0, 2^bits − 1) with
    a pedestal P > 0 (the ADC's offset P + ½ before its floor: rounding to the nearest level, halves up), and
    I = clip(floor(k (min(N, c) + R)), 0, 2^bits − 1) without one (the paper's Eq. 11)."""
    n_max = int(lam + 12 * np.sqrt(lam) + 20)
    n_min = max(0, int(lam - 12 * np.sqrt(lam) - 20))
    n = np.arange(n_min, n_max + 1)
    p_n = stats.poisson.pmf(n, lam)
    charge = np.minimum(n, full_well_e) if saturation else n.astype(float)
    top = 2**bits - 1
    # I ≥ j  ⇔  k e ≥ j − P − ½ (with a pedestal; j without), for j = 1 … top
    edges = (np.arange(1, top + 1) - (pedestal_dn + 0.5 if pedestal_dn else 0.0)) / dn_per_e
    if read_noise_e > 0:
        cdf = stats.norm.cdf((edges[None, :] - charge[:, None]) / read_noise_e)
    else:
        cdf = (charge[:, None] < edges[None, :]).astype(float)
    cdf_total = p_n @ cdf  # P(e < j / k), j = 1 … top
    cdf_total = np.concatenate([cdf_total, [1.0]])
    return np.diff(np.concatenate([[0.0], cdf_total]))


def pmf_moments(pmf):
    j = np.arange(pmf.size)
    mean = float(pmf @ j)
    var = float(pmf @ (j - mean) ** 2)
    return mean, var


def assert_mean_var(samples, mean, var, k=5.0, kurtosis_excess=0.0, what=""):
    """Sample mean and variance within k standard errors of the model's.

    Standard errors: √(var / n) for the mean, var · √(2 / (n − 1) + κ / n) for the variance (κ: excess kurtosis).
    """
    samples = np.asarray(samples, dtype=np.float64).ravel()
    n = samples.size
    m, v = samples.mean(), samples.var(ddof=1)
    se_mean = np.sqrt(var / n) if var > 0 else 1e-12
    se_var = var * np.sqrt(2.0 / (n - 1) + kurtosis_excess / n) if var > 0 else 1e-12
    assert abs(m - mean) <= k * se_mean + 1e-9 * abs(mean), f"{what}: mean {m} vs model {mean} (± {se_mean:.3g})"
    assert abs(v - var) <= k * se_var + 1e-12, f"{what}: variance {v} vs model {var} (± {se_var:.3g})"


def _colour_data(illuminant, camera):
    """colour-science's camera curves, the illuminant and ȳ on the camera's native sampling (5 nm)."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import colour

        sens = colour.MSDS_CAMERA_SENSITIVITIES[camera]
        light = colour.SDS_ILLUMINANTS[illuminant].copy().align(sens.shape).values
        ybar = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(sens.shape).values[:, 1]
    return colour, sens, light, ybar


def white_response(illuminant, camera="Nikon 5100 (NPL)"):
    """The camera's response to the perfect white under ``illuminant`` at a fixed luminance, [R, G, B]:
    Σ s_c E / Σ ȳ E with energy-basis curves s_c, on colour-science's own 5 nm data."""
    _, sens, light, ybar = _colour_data(illuminant, camera)
    return sens.values.T @ light / (ybar @ light)


def anchored_signal_e(patch, illuminant, factor=1.0, exposure_s=1.0, reference_e=8000.0,
                      camera="Nikon 5100 (NPL)", chart="ColorChecker N Ohta", reference_illuminant="D65"):
    """Expected signal electrons [R, G, B] of ColorChecker patch ``patch`` (index) under the anchor scale.

    The anchor puts the perfect white under ``reference_illuminant`` at ``reference_e`` electrons in its strongest
    channel at F = 1 and T = 1 s, once for the camera (MODEL.md §3); with every light scaled to the same luminance
    and curves s_c that are responses per unit radiant power ('energy' basis), the patch then collects
    S_c = reference_e · F · T · (Σ ρ E s_c / Σ ȳ E) / max_c' white_response(reference)_c'. Integrated with
    colour-science's own data on the camera's native wavelength sampling (5 nm), independently of camsim's grid
    and resampling.
    """
    colour, sens, light, ybar = _colour_data(illuminant, camera)
    rho = list(colour.SDS_COLOURCHECKERS[chart].values())[patch].copy().align(sens.shape).values
    response = ((rho * light) @ sens.values) / (ybar @ light)
    return reference_e * factor * exposure_s * response / white_response(reference_illuminant, camera).max()


def mean_dn_tail_sum(lam, dn_per_e, sigma_e, bits, full_well_e=None):
    """E[I] of I = clip(floor(k (min(N, FW) + z)), 0, 2^bits − 1), N ~ Poisson(λ), z ~ N(0, σ²) (σ = 0: none),
    as the tail sum Σ_{j=1}^{top} P(I ≥ j), with P(I ≥ j) = Σ_n P(N = n) P(z ≥ j / k − min(n, FW))."""
    top = 2**bits - 1
    n = np.arange(max(0, int(lam - 15 * np.sqrt(lam) - 30)), int(lam + 15 * np.sqrt(lam) + 31))
    p_n = stats.poisson.pmf(n, lam)
    charge = n.astype(float) if full_well_e is None else np.minimum(n, full_well_e)
    j_lo = min(top + 1, max(1, int(np.floor(dn_per_e * (charge.min() - 15 * sigma_e)))))
    j_hi = min(top, int(np.ceil(dn_per_e * (charge.max() + 15 * sigma_e))) + 1)
    j = np.arange(j_lo, j_hi + 1)
    gap = j[None, :] / dn_per_e - charge[:, None]
    tail = stats.norm.sf(gap / sigma_e) if sigma_e > 0 else (dn_per_e * charge[:, None] >= j[None, :]).astype(float)
    return (j_lo - 1) + float(p_n @ tail.sum(axis=1))


def digital_pmf_without_read_noise(lam, dn_per_e, full_well_e, bits):
    """P(I = j), j = 0 … 2^bits − 1, for I = clip(floor(k min(N, c)), 0, 2^bits − 1), N ~ Poisson(λ), from the
    Poisson CDF alone: P(I ≤ j − 1) = P(min(N, c) < j / k), which is 1 if j / k > c, else P(N ≤ ⌈j / k⌉ − 1)."""
    top = 2**bits - 1
    j = np.arange(1, top + 1)
    below = np.where(j / dn_per_e > full_well_e, 1.0, stats.poisson.cdf(np.ceil(j / dn_per_e) - 1, lam))
    return np.diff(np.concatenate([[0.0], below, [1.0]]))


def compound_poisson_cdf_bounds(mu, w, step, centre_sds=None):
    """Bounds on the CDF of S = Σᵢ wᵢ Nᵢ, Nᵢ ~ Poisson(μᵢ), wᵢ ≥ 0 (Eq. 4's signal), on the lattice of ``step``.

    Rounding every weight down (up) to the lattice gives S⁻ ≤ S ≤ S⁺, so F_S⁺(x) ≤ F_S(x) ≤ F_S⁻(x) for all x.
    The laws of S± are compound Poisson on the integers; their pmfs come from the characteristic function,
    exp(Σ μᵢ (e^{−2πi f mᵢ / L} − 1)), by an inverse FFT of L points. ``centre_sds``: only the window of that many
    standard deviations either side of the mean is kept (the FFT wraps the rest onto it: keep it ≥ 12).

    Returns
    -------
    list of (values, cdf)
        For S⁻ and S⁺: the lattice values (ascending) and P(S± ≤ value).
    """
    mu, w = np.asarray(mu, float), np.asarray(w, float)
    out = []
    for rounding in (np.floor, np.ceil):
        m = rounding(w / step).astype(np.int64)
        lam = mu.sum()
        if centre_sds is None:
            n_max = lam + 12 * np.sqrt(lam) + 25
            start, size = 0, int(2 ** np.ceil(np.log2(n_max * m.max() + 2)))
        else:
            mean, sd = mu @ m, np.sqrt(mu @ (m * m.astype(float)))
            start = max(0, int(mean - centre_sds * sd))
            size = int(2 ** np.ceil(np.log2(2 * centre_sds * sd + 2)))
        jumps = np.bincount(m % size, weights=mu, minlength=size)
        phi = np.exp(np.fft.fft(jumps) - lam)
        pmf = np.real(np.fft.ifft(phi))  # pmf of S± mod L
        values = start + np.arange(size)
        pmf = np.maximum(pmf[values % size], 0.0)
        out.append((values * step, np.cumsum(pmf)))
    return out


def ks_to_normal_bounds(bounds, mean, sd):
    """(lower, upper) bounds on sup |F_S − Φ((x − mean) / sd)| from :func:`compound_poisson_cdf_bounds`.

    Lower: F_S − Φ ≥ F_S⁺ − Φ and Φ − F_S ≥ Φ − F_S⁻ (also just below each atom, with the left limits). Upper:
    |F_S − Φ| ≤ max(|F_S⁻ − Φ|, |F_S⁺ − Φ|), checked at the atoms and just below them (Φ rises in between).
    """
    (x_lo, cdf_lo), (x_hi, cdf_hi) = bounds
    g_lo, g_hi = special.ndtr((x_lo - mean) / sd), special.ndtr((x_hi - mean) / sd)
    left_lo = np.concatenate([[0.0], cdf_lo[:-1]])
    left_hi = np.concatenate([[0.0], cdf_hi[:-1]])
    lower = max(np.max(cdf_hi - g_hi), np.max(g_lo - left_lo), 0.0)
    upper = max(np.max(np.abs(cdf_lo - g_lo)), np.max(np.abs(left_lo - g_lo)),
                np.max(np.abs(cdf_hi - g_hi)), np.max(np.abs(left_hi - g_hi)))
    return float(lower), float(upper)
