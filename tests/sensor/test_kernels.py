"""The random-draw building blocks: Box–Muller normals and Poisson draws beyond numpy's range."""

import numpy as np
import pytest
from scipy import stats

from camsim.sensor.kernels import POISSON_LAM_MAX, poisson, standard_normal_f32


@pytest.mark.parametrize("size", [2_000_000, 1_000_001])
def test_box_muller_normals_are_standard_normal(size):
    rng = np.random.default_rng(123)
    z = standard_normal_f32(rng, np.empty(size, np.float32), np.empty(size // 2 + 1, np.float32))
    assert z.dtype == np.float32 and np.all(np.isfinite(z))
    n = z.size
    x = z.astype(np.float64)
    assert abs(x.mean()) < 5 / np.sqrt(n)
    assert abs(x.var() - 1) < 5 * np.sqrt(2 / n)
    assert abs(stats.skew(x)) < 5 * np.sqrt(6 / n)
    assert abs(stats.kurtosis(x)) < 5 * np.sqrt(24 / n)
    assert stats.kstest(x, "norm").pvalue > 1e-3
    assert np.abs(x).max() <= np.sqrt(48 * np.log(2)) + 1e-5
    half = n // 2  # the two normals of a Box–Muller pair are independent (no linear or variance coupling)
    assert abs(np.corrcoef(x[:half], x[half : 2 * half])[0, 1]) < 5 / np.sqrt(half)
    assert abs(np.corrcoef(x[:half] ** 2, x[half : 2 * half] ** 2)[0, 1]) < 5 / np.sqrt(half)


def test_box_muller_is_reproducible_and_needs_contiguous_output():
    a = standard_normal_f32(np.random.default_rng(5), np.empty((7, 9), np.float32), np.empty(40, np.float32))
    b = standard_normal_f32(np.random.default_rng(5), np.empty((7, 9), np.float32), np.empty(40, np.float32))
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError):
        standard_normal_f32(np.random.default_rng(5), np.empty((8, 8), np.float32)[:, ::2], np.empty(40, np.float32))


def test_poisson_beyond_numpy_limit():
    rng = np.random.default_rng(0)
    lam = np.array([5.0, 3 * POISSON_LAM_MAX])
    draws = np.array([poisson(rng, lam) for _ in range(4000)])
    assert np.all(draws == np.round(draws))
    assert abs(draws[:, 0].mean() - 5) < 5 * np.sqrt(5 / 4000)
    big = draws[:, 1]
    assert abs(big.mean() - lam[1]) < 5 * np.sqrt(lam[1] / 4000)
    assert abs(big.var() / lam[1] - 1) < 5 * np.sqrt(2 / 4000)


@pytest.mark.parametrize("lam", [0.5, 3.0, 30.0, 230.0, 7000.0, 4e5])
def test_histogram_poisson_sampler_is_poisson(lam):
    """Multinomial histogram + random order: the law, the moments and independence of iid Poisson draws."""
    from camsim.sensor.kernels import HISTOGRAM_MIN_PIXELS_PER_VALUE, poisson_run

    shape = (400, 1000)
    assert shape[0] * shape[1] >= HISTOGRAM_MIN_PIXELS_PER_VALUE * (26 * np.sqrt(lam) + 41)
    x = poisson_run(np.random.default_rng(int(lam * 10)), lam, shape)
    assert x.dtype == np.float32 and x.shape == shape  # the histogram path, not numpy's sampler
    v = x.astype(np.float64).ravel()
    assert np.all(v == np.round(v)) and v.min() >= 0
    n = v.size
    assert abs(v.mean() - lam) < 5 * np.sqrt(lam / n)
    assert abs(v.var() - lam) < 5 * lam * np.sqrt(2 / n + 1 / (lam * n))
    # goodness of fit: bins of the support with an expected count of at least 20
    values, counts = np.unique(v, return_counts=True)
    lo, hi = int(max(0, lam - 6 * np.sqrt(lam) - 5)), int(lam + 6 * np.sqrt(lam) + 5)
    edges = np.unique(np.concatenate([[-0.5], np.arange(lo, hi + 1) + 0.5, [np.inf]]))
    observed = np.histogram(v, bins=edges)[0]
    expected = n * np.diff(stats.poisson.cdf(np.floor(edges), lam))
    merged_o, merged_e, acc_o, acc_e = [], [], 0, 0.0
    for o, e in zip(observed, expected):
        acc_o, acc_e = acc_o + o, acc_e + e
        if acc_e >= 20:
            merged_o.append(acc_o), merged_e.append(acc_e)
            acc_o, acc_e = 0, 0.0
    merged_o[-1] += acc_o
    merged_e[-1] += acc_e
    chi2 = np.sum((np.array(merged_o) - merged_e) ** 2 / np.array(merged_e))
    assert stats.chi2.sf(chi2, len(merged_o) - 1) > 1e-4
    # independence: neighbouring pixels (along rows and down columns) are uncorrelated
    for a, b in ((x[:, :-1], x[:, 1:]), (x[:-1, :], x[1:, :])):
        r = np.corrcoef(a.ravel().astype(float), b.ravel().astype(float))[0, 1]
        assert abs(r) < 5 / np.sqrt(a.size)


def test_histogram_sampler_falls_back_for_short_runs_and_huge_means():
    from camsim.sensor.kernels import poisson_run

    rng = np.random.default_rng(0)
    assert poisson_run(rng, 7000.0, (3, 4)).dtype == np.int64  # 12 pixels: numpy's sampler
    assert poisson_run(rng, 1e9, (400, 1000)).dtype == np.int64  # support too wide
    assert not poisson_run(rng, 0.0, (400, 1000)).any()
