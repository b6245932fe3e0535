"""``auto`` under ``paper`` statistics: its KS bounds cover Eq. 4's law, its frames meet the tolerance down to
F = 1e-18, and which methods keep Eq. 4's correlation between the channels (MODEL.md §4–5)."""

import numpy as np
import pytest
from scipy import special, stats

from camsim.methods import DEFAULT_TOLERANCE
from camsim.methods.plan import BINS, GAUSSIAN, ks_gaussian, ks_normals, paper_ks_bounds, plan_methods
from camsim.render.frame import render_frame
from camsim.render.pipeline import light_scene
from camsim.sensor.camera import load_camera
from camsim.sensor.params import PRESETS
from tests.support.helpers import WHITE, patch_pixels, small_scene
from tests.support.theory import compound_poisson_cdf_bounds, ks_to_normal_bounds

IDEAL = PRESETS["ideal"]
BLACK, RED, GREEN, BLUE = 23, 14, 13, 12  # ColorChecker order: black 2 (1.5 D), red, green, blue


@pytest.fixture(scope="module")
def lit():
    scene = small_scene(width=360, height=240)
    return light_scene(scene, "D65", load_camera(scene.camera, scene.grid))


def eq4_bounds(mu, w):
    """Lattice bounds on the CDF of Σ wᵢ Poisson(μᵢ) (tests.support.theory), on a lattice fine against its spread."""
    lam = mu.sum()
    if lam < 30:  # the whole support from 0: a step of 1/2000 of the largest weight
        return compound_poisson_cdf_bounds(mu, w, w.max() / 2000)
    # ±14 σ in L steps: the roundings move S by at most (photons) · step ≈ 28 Λ σ / L, 1.2 % of σ
    sd = np.sqrt(mu @ (w * w))
    size = 2 ** int(np.clip(np.ceil(np.log2(28 * lam / 0.012)), 16, 20))
    return compound_poisson_cdf_bounds(mu, w, 28 * sd / size, centre_sds=14)


@pytest.mark.parametrize("factor", [1e-18, 1e-17, pytest.param(1e-16, marks=pytest.mark.slow),
                                    pytest.param(1e-15, marks=pytest.mark.slow)])
def test_paper_ks_bounds_cover_the_exact_law_of_eq4(lit, factor):
    """The Gaussian's and the stand-in's KS bounds are never below their KS distance to Eq. 4's law, which is
    computed independently: the law of Σ wᵢ Poisson(μᵢ) between two lattice roundings, by FFT."""
    ex = lit.expected(IDEAL, factor, "paper")
    gaussian, stand_in = paper_ks_bounds(ex, 0.0)
    w_all = IDEAL.exposure_s * ex.qe
    far = checked = 0
    for k in (WHITE, BLACK, RED, GREEN, BLUE):
        mu = ex.photon_rate[k]
        if mu.sum() > 400:
            continue  # (the white at F = 1e-15, 1200 photons: its lattice would be long; it is 120 at 1e-16)
        checked += 1
        for c in range(3):
            w = w_all[c]
            keep = (mu > 0) & (w > 0)
            mean, var = ex.signal_e[k, c], ex.signal_var_e2[k, c]
            bounds = eq4_bounds(mu[keep], w[keep])
            lower, upper = ks_to_normal_bounds(bounds, mean, np.sqrt(var))
            assert upper - lower < 0.02  # the oracle pins the exact distance down
            assert gaussian[k, c] >= lower, (k, c, gaussian[k, c], lower)
            # the stand-in s · Poisson(S̄ / s): its CDF against the lattice bounds, at their values
            step = var / mean
            (x_lo, f_lo), (x_hi, f_hi) = bounds
            standin_lo = special.pdtr(np.floor(x_lo / step + 1e-9), mean / step)
            standin_hi = special.pdtr(np.floor(x_hi / step + 1e-9), mean / step)
            lower_st = max(np.max(standin_lo - f_lo), np.max(f_hi - standin_hi))
            assert stand_in[k, c] >= lower_st, (k, c, stand_in[k, c], lower_st)
            far += lower_st > 0.1
    assert checked >= 3
    if factor <= 1e-17:  # poisson's stand-in is far from Eq. 4 there: auto must not take it
        assert far >= 3


def test_normals_ks_matches_a_dense_search():
    x = np.linspace(-40, 40, 400001)
    for a, b in ((1.0, 1.5), (4.0, 4.001), (0.3, 30.0)):
        dense = np.max(np.abs(stats.norm.cdf(x / a) - stats.norm.cdf(x / b)))
        assert abs(float(ks_normals(a * a, b * b)) - dense) < 1e-6
    assert float(ks_normals(2.0, 2.0)) == 0.0 and float(ks_normals(0.0, 1.0)) == 0.5


def test_ks_gaussian_with_little_read_noise_is_not_underestimated():
    """A grid of x misses the steps of a lattice smoothed by a small σ: the bound must not. Dense reference:
    F(x) = Σ pₙ Φ((x − n) / σ) near each integer (where the steps are) and the lattice's own values for σ → 0."""
    for lam, sigma in ((218.0, 1e-5), (218.0, 0.05), (30.0, 0.1), (600.0, 0.3)):
        sd = np.sqrt(lam + sigma**2)
        n = np.arange(0, int(lam + 15 * np.sqrt(lam)) + 20)
        p = stats.poisson.pmf(n, lam)
        near = n[np.abs(n - lam) < 6 * sd]
        if sigma > 1e-3:
            x = (near[:, None] + np.linspace(-4 * sigma, 4 * sigma, 81)[None, :]).ravel()
            exact = np.concatenate([p @ special.ndtr((part[None, :] - n[:, None]) / sigma)
                                    for part in np.array_split(x, 20)])
        else:  # the lattice CDF at the integers and its left limits just below them
            x = np.concatenate([near, near - 1e-9])
            exact = np.concatenate([special.pdtr(near, lam), special.pdtr(near - 1, lam)])
        dense = np.max(np.abs(exact - special.ndtr((x - lam) / sd)))
        assert ks_gaussian(lam, sigma) >= dense - 1e-9, (lam, sigma)


@pytest.mark.parametrize("factor", [1e-15, 1e-16, 1e-17, 1e-18])
def test_auto_under_paper_statistics_meets_its_tolerance(lit, factor):
    """auto against spectral (Eq. 4 literally), ideal sensor: two-sample KS within the tolerance plus the
    critical value at 1e-3 over all 288 comparisons (conservative for discrete laws), and negative values no more
    often than the tolerance allows (the exact law has none: P(V < 0) ≤ KS distance)."""
    ex = lit.expected(IDEAL, factor, "paper")
    labels = lit.labels
    auto = render_frame(labels, ex, IDEAL, statistics="paper", method="auto", rng=1)
    exact = render_frame(labels, ex, IDEAL, statistics="paper", method="spectral", rng=2)
    assert np.all(auto.plan.predicted_ks[:24] > 0)  # a bound, not the 0.0 of a Gaussian-only estimate
    crit = np.sqrt(-np.log(1e-3 / (2 * 288)) / 2)
    tol = DEFAULT_TOLERANCE
    for index, rect in enumerate(lit.radiance.patch_rects):
        a, b = patch_pixels(auto.noisy_dn, rect), patch_pixels(exact.noisy_dn, rect)
        n = a.shape[1]
        for c in range(3):
            d = stats.ks_2samp(a[c], b[c]).statistic
            assert d <= tol + crit * np.sqrt(2 / n), (factor, index, c, d, auto.plan.names(index))
            negative = np.mean(a[c] < 0)
            assert negative <= tol + 5 * np.sqrt(tol / n), (factor, index, c, negative)


def test_auto_refuses_the_gaussian_where_its_bound_exceeds_the_tolerance(lit):
    ex = lit.expected(IDEAL, 1e-14, "paper")
    for tolerance in (0.002, 0.01, 0.05):
        plan = plan_methods(ex, IDEAL, "paper", "auto", tolerance)
        gaussian, stand_in = paper_ks_bounds(ex, 0.0)
        np.testing.assert_array_equal(plan.predicted_ks, gaussian)
        assert np.all((plan.kind == GAUSSIAN) == (gaussian <= tolerance))
        assert np.all((plan.kind == BINS) == ((gaussian > tolerance) & (stand_in > tolerance)))


def eq4_correlations(mu, w, dark):
    """corr(S_a + D_a, S_b + D_b) of Eq. 4's shared counts: Σ μ w_a w_b / √((Σ μ w_a² + D̄_a)(Σ μ w_b² + D̄_b))."""
    cov = (w * mu) @ w.T
    sd = np.sqrt(np.diag(cov) + dark)
    return {(a, b): cov[a, b] / (sd[a] * sd[b]) for a, b in ((0, 1), (0, 2), (1, 2))}


def test_channel_correlation_under_paper_statistics(lit):
    """Eq. 4's per-bin counts are shared by R, G and B: spectral keeps the correlation, and auto where it draws a
    spectrum's three channels by bins (low F); poisson, gaussian and auto's Gaussian draw the channels apart.
    (The ideal sensor: with dark current the signal's variance, ~1e-26 e⁻² at F = 1e-16, leaves none.)"""
    sensor = IDEAL
    labels = np.full((300, 400), WHITE, dtype=np.uint8)
    n = labels.size
    for factor, keeps in ((1e-16, {"spectral": True, "auto": True, "poisson": False, "gaussian": False}),
                          (1e-11, {"spectral": True, "auto": False, "poisson": False, "gaussian": False})):
        ex = lit.expected(sensor, factor, "paper")
        theory = eq4_correlations(ex.photon_rate[WHITE], sensor.exposure_s * ex.qe, ex.dark_e)
        for method, keep in keeps.items():
            frame = render_frame(labels, ex, sensor, statistics="paper", method=method, rng=4)
            x = frame.noisy_dn.reshape(3, -1).astype(np.float64)
            for (a, b), rho in theory.items():
                r = np.corrcoef(x[a], x[b])[0, 1]
                expected = rho if keep else 0.0
                assert abs(r - expected) < 5 * (1 - expected**2) / np.sqrt(n), (factor, method, a, b, r, rho)
            if method == "auto" and keep:
                assert np.all(frame.plan.kind[WHITE] == BINS)
        assert min(theory.values()) > 0.1  # the correlation is there, whatever F: only the methods lose it


def test_auto_bins_draws_do_not_depend_on_the_thread_count(lit, monkeypatch):
    import camsim.render.frame as render_module

    monkeypatch.setattr(render_module, "BLOCK_PIXELS", 4096)
    ex = lit.expected(PRESETS["paper-table1"].with_stages(read_noise=False), 1e-16, "paper")
    sensor = PRESETS["paper-table1"].with_stages(read_noise=False)
    first = render_frame(lit.labels, ex, sensor, statistics="paper", method="auto", rng=5, workers=1)
    assert np.any(first.plan.kind == BINS)
    again = render_frame(lit.labels, ex, sensor, statistics="paper", method="auto", rng=5, workers=3)
    np.testing.assert_array_equal(again.noisy_dn, first.noisy_dn)
    np.testing.assert_array_equal(again.digital_dn, first.digital_dn)
