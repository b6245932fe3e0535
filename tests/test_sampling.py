"""The random-draw building blocks: Box–Muller normals and Poisson draws beyond numpy's range."""

import numpy as np
import pytest
from scipy import stats

from camsim.sampling import POISSON_LAM_MAX, poisson, standard_normal_f32


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
