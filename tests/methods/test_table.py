"""The ``table`` method: the alias construction against the law it must hold (mass reconstructed column by
column), the alias draws and whole rendered frames against the exact pmf (χ² per patch and channel, with
camsim.sensor.dn_law's independent computation of the digital number's law), the EXR's noisy layer's moments, where it
falls back to ``poisson``'s draws, and reproducibility."""

import dataclasses

import numpy as np
import pytest
from scipy import special, stats

from camsim.methods.table import charge_table
from camsim.sensor.dn_law import charge_pmf, dn_pmf
from camsim.sensor.kernels import alias_columns, alias_draw, alias_table
from camsim.sensor.params import PRESETS, SensorParams
from tests.support.helpers import render, small_scene

TABLE1 = PRESETS["paper-table1"]


def _mass(own, alias, n):
    """Each item's probability implied by an alias table: its own column's part plus the parts aliased to it."""
    mass = own.copy()
    np.add.at(mass, alias, 1.0 - own)
    return mass[:n] / own.size


@pytest.mark.parametrize("kind", ["uniform-random", "poisson", "spiky", "flat", "one", "power-of-two"])
def test_alias_columns_hold_the_law(kind):
    rng = np.random.default_rng(hash(kind) % 2**32)
    for _ in range(200):
        n = int(rng.integers(1, 5000))
        if kind == "uniform-random":
            p = rng.random(n)
        elif kind == "poisson":
            p = stats.poisson.pmf(np.arange(n), rng.uniform(0, 1.2 * n))
        elif kind == "spiky":
            p = rng.random(n) ** 40
        elif kind == "flat":
            p = np.ones(n)
        elif kind == "one":
            p = np.zeros(n)
            p[rng.integers(n)] = 1.0
        else:
            n = 2 ** int(rng.integers(1, 12))
            p = np.ones(n)
        if not p.sum() > 0:
            continue
        p = p / p.sum()
        own, alias = alias_columns(p)
        assert own.size >= n and own.size & (own.size - 1) == 0
        assert np.all((own >= 0) & (own <= 1))
        np.testing.assert_allclose(_mass(own, alias, n), p, rtol=0, atol=1e-12)


@pytest.mark.parametrize("mean, well", [(0.3, None), (50.0, None), (5000.0, None), (8990.0, 9000.0), (2e4, 9000.0)])
def test_alias_draws_follow_the_charge_law(mean, well):
    charges, p = charge_pmf(mean, well)
    table = charge_table(mean, well)
    n = 400_000
    draws = alias_draw(np.random.default_rng(7), table, np.empty(n, dtype=np.float32))
    index = np.searchsorted(charges, draws)
    assert np.all(charges[index] == draws)  # only the law's values
    counts = np.bincount(index, minlength=charges.size)
    expected = p / p.sum() * n
    keep = expected > 5
    if keep.sum() < 2:  # one value (a saturated pixel): every draw is it
        assert counts[keep].sum() == n
        return
    observed = np.append(counts[keep], counts[~keep].sum())
    want = np.append(expected[keep], expected[~keep].sum())
    want *= observed.sum() / want.sum()
    assert stats.chisquare(observed[want > 0], want[want > 0]).pvalue > 1e-4


def test_a_table_of_few_values_uses_the_coin_to_its_resolution():
    # a Bernoulli(1e-6) law: the coin must resolve it (63 − 1 bits): 1e-6 · n draws of the rare value
    table = alias_table(np.array([0.0, 1.0]), np.array([1 - 1e-6, 1e-6]))
    draws = alias_draw(np.random.default_rng(1), table, np.empty(4_000_000, dtype=np.float32))
    assert stats.binomtest(int(draws.sum()), draws.size, 1e-6).pvalue > 1e-3


def _chi2_per_patch(frame, sensor, pixels_per_patch_min=2000):
    pvalues = []
    for i in range(24):
        mask = frame.labels == i
        for c in range(3):
            lam = frame.expected.signal_e[i, c] + frame.expected.dark_e[c]
            law = dn_pmf(lam, sensor.dn_per_electron, sensor.read_noise_e, sensor.full_well_e, sensor.bits)
            values = frame.digital_dn[c][mask].astype(np.int64)
            assert values.size >= pixels_per_patch_min
            counts = np.bincount(values - law.first, minlength=law.pmf.size)
            assert counts.size == law.pmf.size  # nothing outside the law's window
            expected = law.pmf * values.size
            keep = expected > 5
            if keep.sum() < 2:
                assert counts[keep].sum() >= values.size - 10
                continue
            observed = np.append(counts[keep], counts[~keep].sum())
            want = np.append(expected[keep], expected[~keep].sum())
            want *= observed.sum() / want.sum()
            pvalues.append(stats.chisquare(observed[want > 0], want[want > 0]).pvalue)
    return np.array(pvalues)


@pytest.mark.parametrize("factor", [1.0, 0.05, 30.0])  # Table I's F = 1, low light, saturating
def test_table_frames_have_the_exact_digital_number_law(factor):
    frame, _ = render(small_scene(width=480, height=320), TABLE1, factor=factor, method="table", seed=5)
    assert set(frame.plan.names(0)) <= {"table", "saturated"}
    p = _chi2_per_patch(frame, TABLE1)
    assert p.min() > 1e-6 and stats.combine_pvalues(p).pvalue > 1e-3, (p.min(), np.sort(p)[:5])


def test_the_exr_layer_has_the_exact_moments():
    sensor = SensorParams(bits=12, conversion_gain_v_per_e=4e-5, analog_gain_dn_per_v=1e4, read_noise_e=3.0,
                          full_well_e=10000.0, dark_current_e_per_s=(25.0, 25.0, 25.0))
    frame, _ = render(small_scene(width=480, height=320), sensor, factor=0.3, method="table", seed=9)
    k = sensor.dn_per_electron
    for i in range(0, 24, 5):
        mask = frame.labels == i
        for c in range(3):
            charges, p = charge_pmf(frame.expected.signal_e[i, c] + frame.expected.dark_e[c], sensor.full_well_e)
            mean = p @ charges
            var = p @ (charges - mean) ** 2 + sensor.read_noise_e**2
            values = frame.noisy_dn[c][mask].astype(np.float64) / k
            se = np.sqrt(var / values.size)
            assert abs(values.mean() - mean) < 5 * se
            assert abs(values.var() / var - 1) < 5 * np.sqrt(2 / values.size) + 1e-3


def test_bayer_sites_are_drawn_by_tables_too():
    sensor = dataclasses.replace(TABLE1, cfa="RGGB")
    frame, _ = render(small_scene(width=480, height=320), sensor, factor=1.0, method="table", seed=2)
    mosaic = frame.digital_dn[0]
    lam = frame.expected.signal_e[0, 0] + frame.expected.dark_e[0]
    law = dn_pmf(lam, sensor.dn_per_electron, sensor.read_noise_e, sensor.full_well_e, sensor.bits)
    red = mosaic[0::2, 0::2][frame.labels[0::2, 0::2] == 0].astype(np.int64)
    counts = np.bincount(red - law.first, minlength=law.pmf.size)
    keep = law.pmf * red.size > 5
    observed = np.append(counts[keep], counts[~keep].sum())
    want = np.append(law.pmf[keep], law.pmf[~keep].sum()) * red.size
    assert stats.chisquare(observed, want * observed.sum() / want.sum()).pvalue > 1e-4


@pytest.mark.parametrize("change, statistics", [({"prnu_percent": 1.0}, "pixel"), ({"dsnu_e": 2.0}, "pixel"),
                                                ({}, "paper"), ({"photon_noise": False}, "pixel")])
def test_pixels_with_laws_of_their_own_fall_back_to_poisson(change, statistics):
    sensor = SensorParams(**change)
    frame, _ = render(small_scene(width=120, height=80), sensor, factor=1.0, method="table", statistics=statistics)
    assert set(frame.plan.names(0)) <= {"poisson", "saturated"}


def test_the_same_seed_gives_the_same_frame_whatever_the_workers():
    from camsim.render.pipeline import light_scene, make_frame
    from camsim.sensor.camera import load_camera

    scene = small_scene(width=600, height=400)
    lit = light_scene(scene, "D65", load_camera(scene.camera, scene.grid))
    one = make_frame(lit, TABLE1, 1.0, method="table", rng=4, workers=1)
    two = make_frame(lit, TABLE1, 1.0, method="table", rng=4, workers=2)
    np.testing.assert_array_equal(one.digital_dn, two.digital_dn)
    np.testing.assert_array_equal(one.noisy_dn, two.noisy_dn)
    other = make_frame(lit, TABLE1, 1.0, method="table", rng=5, workers=2)
    assert not np.array_equal(one.digital_dn, other.digital_dn)


def test_auto_draws_its_exact_spectra_by_tables():
    frame, _ = render(small_scene(width=120, height=80), SensorParams(read_noise=False), factor=0.01, method="auto")
    names = {n for i in range(24) for n in frame.plan.names(i)}
    assert "table" in names and "poisson" not in names


def test_the_poisson_law_of_the_table_is_numpys_law():
    # the charge law of a table is Poisson's: its mean and variance from the pmf equal λ (no truncation shows)
    for lam in (0.01, 3.3, 250.0, 9.8e4):
        charges, p = charge_pmf(lam)
        assert p @ charges == pytest.approx(lam, rel=1e-12, abs=1e-15)
        assert p @ (charges - lam) ** 2 == pytest.approx(lam, rel=1e-10, abs=1e-15)
        assert special.pdtrc(charges[-1], lam) < 1e-30
