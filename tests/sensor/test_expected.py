"""The clean value E[min(X, c)], X ~ Poisson(λ), of a pixel under a full well c (camsim.sensor.expected.poisson_min_e):
against its own sum over the pmf (scipy's, here), and the window beyond which it is λ to the last bit."""

import math

import numpy as np
import pytest
from scipy import stats

from camsim.sensor.expected import poisson_min_e, poisson_tail_reach


def exact_min_mean(lam: float, c: float) -> float:
    """E[min(X, c)] = Σ_x min(x, c) P(X = x) / Σ_x P(X = x): the pmf built outwards from the mode by its ratios
    P(x + 1) / P(x) = λ / (x + 1) (relative error ~ √n ulps, unlike exp(logpmf) at large λ), summed exactly
    (math.fsum) from 0 to where it vanishes."""
    mode = int(np.floor(lam))
    top = int(max(c, lam) + 60 * np.sqrt(lam) + 200)
    up = np.cumprod(lam / np.arange(mode + 1, top + 1, dtype=np.float64))  # P(mode + i) / P(mode), i ≥ 1
    down = np.cumprod(np.arange(mode, 0, -1, dtype=np.float64) / lam)  # P(mode − i) / P(mode), i ≥ 1
    weights = np.concatenate([down[::-1], [1.0], up])
    x = np.arange(0, top + 1, dtype=np.float64)
    return math.fsum(np.minimum(x, c) * weights) / math.fsum(weights)


@pytest.mark.parametrize("lam", [1e-6, 0.3, 2.0, 17.5, 240.0, 3.1e3, 7.09e3, 4.4e4,
                                 pytest.param(2.5e6, marks=pytest.mark.slow)])
def test_inside_the_window_the_tail_is_summed(lam):
    reach = poisson_tail_reach(lam)
    for c in (0.0, 0.5, lam / 2, lam, lam + np.sqrt(lam), lam + 3.7 * np.sqrt(lam), reach - 1.5, reach):
        assert poisson_min_e(np.array([lam]), c)[0] == pytest.approx(exact_min_mean(lam, c), rel=1e-10, abs=1e-300)


@pytest.mark.parametrize("lam", np.geomspace(1e-9, 1e9, 37).tolist())
def test_beyond_the_window_the_value_is_lambda_to_the_last_bit(lam):
    """Past λ + 10 √λ + 20 the sum is skipped: the skipped part is below half a float64 ulp of λ, so the exact value
    rounds to λ itself."""
    c = np.floor(poisson_tail_reach(lam)) + 2.0  # the first full well whose ⌊c⌋ − 1 lies beyond the reach
    assert poisson_min_e(np.array([lam]), c)[0] == lam
    skipped = lam * stats.poisson.sf(np.floor(c) - 1, lam)  # ≥ λ P(X ≥ m) − c P(X > m), the part not summed
    assert skipped < 0.5 * np.spacing(lam)
    if lam <= 1e6:  # the pmf sum of exact_min_mean is affordable (its own rounding: a few ulps)
        assert exact_min_mean(lam, c) == pytest.approx(lam, rel=1e-13, abs=1e-300)
