"""The photon laws of raw sources (camsim.sensor.raw_laws) and their renderer (camsim.render.raw_frame), against the
exact laws computed here with scipy.stats: a site's DN is k · (min(X, FW) + R), then the ADC
clip(floor(· + ½) + P), with X ~ Poisson(f s + D̄_c) (``add``) or Binomial(round(s), f) + Poisson(D̄_c) (``thin``).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from camsim.core.errors import CamsimError
from camsim.render.raw_frame import render_raw_frame
from camsim.sensor.cfa import cfa_sites
from camsim.sensor.params import SensorParams
from camsim.sensor.raw_laws import PHOTON_LAWS, add_photons_e, check_thin_exposure, thin_photons_e

#: The target sensor of the moment tests: 14 bits, a pedestal, k = 1.7 DN/e⁻ (not an integer: the ADC's rounding
#: shows), read noise 2.5 e⁻, dark current per channel (D̄ = 1.95, 2.3, 2.18 e⁻ at T = 0.01 s).
SENSOR = SensorParams(cfa="GRBG", bits=14, pedestal_dn=512, analog_gain_dn_per_v=8500.0, conversion_gain_v_per_e=0.0002,
                      read_noise_e=2.5, full_well_e=20000.0, exposure_s=0.01,
                      dark_current_e_per_s=(195.0, 230.0, 218.0))

#: The source's electrons at the four sites of the 2 × 2 cell (row by row): the ratio-1 frame holds them whole.
CELL_E = np.array([[6000.4, 3000.0], [1499.6, 5999.0]])


def _charge_pmf(law: str, source_e: float, fraction: float, dark_e: float):
    """(values, pmf) of the charge X of one site, exactly: Poisson(f max(s, 0) + D̄) or
    Binomial(round(max(s, 0)), f) ⊛ Poisson(D̄)."""
    if law == "add":
        lam = fraction * max(source_e, 0.0) + dark_e
        x = np.arange(0, int(lam + 15 * np.sqrt(lam) + 30))
        return x, stats.poisson.pmf(x, lam)
    n = int(np.rint(max(source_e, 0.0)))
    x = np.arange(0, n + 1)
    binom = stats.binom.pmf(x, n, fraction)
    d = np.arange(0, int(dark_e + 15 * np.sqrt(dark_e) + 30))
    total = np.convolve(binom, stats.poisson.pmf(d, dark_e))
    return np.arange(total.size), total


def _dn_moments(values, pmf, sensor: SensorParams):
    """Mean, variance and 4th central moment of the digital DN and the mean and variance of the DN before the ADC,
    from the charge's pmf: DN before = k (min(X, FW) + R), R ~ N(0, σ²); the ADC clip(floor(· + ½) + P, 0, max)."""
    k, sigma, P = sensor.dn_per_electron, sensor.read_noise_e, sensor.pedestal_dn
    keep = pmf > 1e-16
    y = k * np.minimum(values[keep], sensor.full_well_e)
    w = pmf[keep] / pmf[keep].sum()
    noisy_mean = float(w @ y)
    noisy_var = float(w @ (y - noisy_mean) ** 2) + (k * sigma) ** 2
    j = np.arange(int(y.min() - 12 * k * sigma) - 2, int(y.max() + 12 * k * sigma) + 3)
    cdf_hi = stats.norm.cdf((j[None, :] + 0.5 - y[:, None]) / (k * sigma))
    cdf_lo = stats.norm.cdf((j[None, :] - 0.5 - y[:, None]) / (k * sigma))
    p_dn = w @ (cdf_hi - cdf_lo)  # P(floor(y + kR + ½) = j)
    dn = np.clip(j + P, 0, sensor.max_dn).astype(float)
    mean = float(p_dn @ dn)
    var = float(p_dn @ (dn - mean) ** 2)
    m4 = float(p_dn @ (dn - mean) ** 4)
    return mean, var, m4, noisy_mean, noisy_var


def _assert_moments(sample: np.ndarray, mean: float, var: float, m4: float, what: str):
    """Sample mean and variance within 5 standard errors of the exact ones (the variance's:
    √((μ4 − σ⁴ (n−3)/(n−1)) / n))."""
    n = sample.size
    x = sample.astype(np.float64)
    m, v = x.mean(), x.var(ddof=1)
    se_mean = np.sqrt(var / n)
    se_var = np.sqrt((m4 - var**2 * (n - 3) / (n - 1)) / n)
    assert abs(m - mean) < 5 * se_mean, f"{what}: mean {m:.5f} vs exact {mean:.5f} (se {se_mean:.2g})"
    assert abs(v - var) < 5 * se_var, f"{what}: variance {v:.5f} vs exact {var:.5f} (se {se_var:.2g})"


@pytest.mark.parametrize("law", PHOTON_LAWS)
@pytest.mark.parametrize("ratio", [1, 10, 300])
def test_site_moments_match_the_exact_law(law, ratio):
    """Each site's digital DN and DN before the ADC have the mean and variance of the exact law, at ratios 1, 10,
    300 (f = 1, 0.1, 1/300), with read noise, dark current per channel, gain, 14-bit ADC and pedestal."""
    fraction = 1.0 / ratio
    source = np.tile(CELL_E, (160, 128)).astype(np.float32)  # 320 × 256: 20 480 pixels a site
    draw = render_raw_frame(source, SENSOR, fraction, law=law, rng=12345 + ratio, workers=2)
    for dy, dx, c in cfa_sites(SENSOR.cfa):
        s = float(np.float32(CELL_E[dy, dx]))
        values, pmf = _charge_pmf(law, s, fraction, float(SENSOR.dark_mean_e[c]))
        mean, var, m4, noisy_mean, noisy_var = _dn_moments(values, pmf, SENSOR)
        digital = draw.digital_dn[0, dy::2, dx::2]
        _assert_moments(digital, mean, var, m4, f"{law} 1:{ratio} site {dy}{dx} digital")
        noisy = draw.noisy_dn[0, dy::2, dx::2].astype(np.float64)
        n = noisy.size
        assert abs(noisy.mean() - noisy_mean) < 5 * np.sqrt(noisy_var / n)
        assert abs(noisy.var(ddof=1) - noisy_var) < 5 * noisy_var * np.sqrt(2.0 / n) * 1.2  # near-normal μ4
        # the clean layer is the law's mean before quantisation
        np.testing.assert_allclose(draw.clean_dn[dy::2, dx::2], noisy_mean, rtol=2e-6)


def test_thin_is_the_poisson_law_of_the_darker_exposure():
    """A source drawn as a Poisson count N ~ Poisson(50), thinned by f = 0.1: the frame's charge follows Poisson(5)
    by χ²; ``add`` on the same source does not (it keeps the source's noise: variance 5 + 0.01 · 50)."""
    rng = np.random.default_rng(7)
    source = rng.poisson(50.0, size=(512, 512)).astype(np.float32)
    sensor = SensorParams(cfa="RGGB", analog_gain_dn_per_v=5000.0, conversion_gain_v_per_e=0.0002).with_stages(
        read_noise=False, dark_current=False, quantisation=False, saturation=False)
    k = sensor.dn_per_electron

    def chi2_p(law):
        draw = render_raw_frame(source, sensor, 0.1, law=law, rng=99, workers=2)
        counts = np.rint(draw.noisy_dn[0] / k).astype(np.int64).ravel()
        top = 16  # bins 0..15 and ≥ 16, each expecting ≥ 400 pixels
        observed = np.bincount(np.minimum(counts, top), minlength=top + 1)
        pmf = stats.poisson.pmf(np.arange(top), 5.0)
        expected = counts.size * np.append(pmf, stats.poisson.sf(top - 1, 5.0))
        return stats.chisquare(observed, expected).pvalue

    assert chi2_p("thin") > 1e-3
    assert chi2_p("add") < 1e-6


def test_thin_keeps_the_source_read_noise_scaled_by_p_squared():
    """A source N + σ_r Z (N ~ Poisson(50), σ_r = 3 e⁻, continuous): thin's charge has mean p λ T_src and variance
    p λ T_src + p² (σ_r² + 1/12) (the module's derivation; rounding adds 1/12), here at p = 0.5."""
    rng = np.random.default_rng(11)
    shape = (512, 512)
    source = (rng.poisson(50.0, size=shape) + 3.0 * rng.standard_normal(shape)).astype(np.float32)
    sensor = SensorParams(cfa="BGGR", analog_gain_dn_per_v=5000.0, conversion_gain_v_per_e=0.0002).with_stages(
        read_noise=False, dark_current=False, quantisation=False, saturation=False)
    draw = render_raw_frame(source, sensor, 0.5, law="thin", rng=5, workers=2)
    charge = draw.noisy_dn[0].astype(np.float64) / sensor.dn_per_electron
    p, lam, n = 0.5, 50.0, charge.size
    var = p * lam + p * p * (9.0 + 1 / 12)
    assert abs(charge.mean() - p * lam) < 5 * np.sqrt(var / n)
    assert abs(charge.var(ddof=1) - var) < 5 * var * np.sqrt(2.0 / n) * 1.1
    assert abs(charge.var(ddof=1) - p * lam) > 10 * var * np.sqrt(2.0 / n)  # the source's residual shows


def test_clean_layer_at_the_full_well():
    """Near the full well the clean layer is k E[min(X, FW)], computed here by summing the pmf: exact for ``add``
    (X Poisson) and for ``thin`` at f = 1 (X = n + Poisson(D̄)); the frame's mean agrees with it."""
    sensor = SensorParams(cfa="RGGB", full_well_e=1000.0, read_noise_e=2.0, exposure_s=0.01,
                          dark_current_e_per_s=(195.0, 230.0, 218.0)).with_stages(quantisation=False)
    cell = np.array([[990.0, 1010.0], [1000.0, 960.0]])
    source = np.tile(cell, (128, 128)).astype(np.float32)
    k = sensor.dn_per_electron
    for law in PHOTON_LAWS:
        draw = render_raw_frame(source, sensor, 1.0, law=law, rng=3, workers=2)
        for dy, dx, c in cfa_sites(sensor.cfa):
            values, pmf = _charge_pmf(law, cell[dy, dx], 1.0, float(sensor.dark_mean_e[c]))
            clipped = np.minimum(values, sensor.full_well_e)
            exact = k * float(pmf @ clipped)
            np.testing.assert_allclose(draw.clean_dn[dy::2, dx::2], exact, rtol=1e-5)
            sd = k * np.sqrt(float(pmf @ (clipped - pmf @ clipped) ** 2) + 4.0)
            site = draw.noisy_dn[0, dy::2, dx::2].astype(np.float64)
            assert abs(site.mean() - exact) < 5 * sd / np.sqrt(site.size)
            if law == "add" or cell[dy, dx] >= sensor.full_well_e:
                assert exact < k * (cell[dy, dx] + sensor.dark_mean_e[c]) * (1 - 1e-4)  # the clip shows


@pytest.mark.parametrize("fraction", [0.1, 0.5, 0.9, 0.99])
def test_thin_clean_layer_near_the_full_well_is_close(fraction):
    """``thin`` at p < 1 near the full well: the clean layer's shifted Poisson (same mean and variance) is within
    1e-4 of k E[min(Binomial(n, p) + Poisson(D̄), FW)] summed here exactly, n around FW / p."""
    sensor = SensorParams(cfa="RGGB", full_well_e=1000.0, read_noise_e=2.0, exposure_s=0.01).with_stages(
        quantisation=False)
    n0 = int(1000 / fraction)
    cell = np.array([[n0 - 40, n0], [n0 + 40, n0 - 10]], dtype=float)
    draw = render_raw_frame(np.tile(cell, (4, 4)).astype(np.float32), sensor, fraction, law="thin", rng=1)
    k = sensor.dn_per_electron
    for dy, dx, c in cfa_sites(sensor.cfa):
        values, pmf = _charge_pmf("thin", cell[dy, dx], fraction, float(sensor.dark_mean_e[c]))
        exact = k * float(pmf @ np.minimum(values, sensor.full_well_e))
        np.testing.assert_allclose(draw.clean_dn[dy::2, dx::2], exact, rtol=1e-4)


def test_thin_refuses_to_brighten():
    source = np.full((4, 4), 100.0, dtype=np.float32)
    with pytest.raises(CamsimError, match="thin cannot brighten"):
        render_raw_frame(source, SENSOR, 1.5, law="thin", rng=0)
    prnu = SensorParams(cfa="RGGB", prnu_percent=1.0)
    with pytest.raises(CamsimError, match="PRNU gain"):
        render_raw_frame(source, prnu, 1.0, law="thin", rng=0)
    render_raw_frame(source, SENSOR, 1.0, law="thin", rng=0)  # f = 1 without PRNU: allowed
    render_raw_frame(source, SENSOR, 1.5, law="add", rng=0)  # add may brighten
    with pytest.raises(CamsimError, match="thin cannot brighten"):
        thin_photons_e(np.random.default_rng(0), np.full(3, 10), 0.5, gain=np.array([1.0, 2.5, 1.0]))
    with pytest.raises(CamsimError, match=r"F·T = 0.2 s > the source's exposure 0.1 s; use photon_law = 'add'"):
        check_thin_exposure(2.0, 0.1, 0.1)
    check_thin_exposure(1.0, 0.1, 0.1)


def test_bad_inputs_are_refused():
    source = np.full((4, 4), 100.0, dtype=np.float32)
    with pytest.raises(CamsimError, match="photon law"):
        render_raw_frame(source, SENSOR, 0.5, law="scale")
    with pytest.raises(CamsimError, match="colour filter array"):
        render_raw_frame(source, SensorParams(), 0.5)
    with pytest.raises(CamsimError, match="even"):
        render_raw_frame(np.ones((5, 4), np.float32), SENSOR, 0.5)
    with pytest.raises(CamsimError, match="non-finite"):
        render_raw_frame(np.where(np.eye(4) > 0, np.nan, 1.0).astype(np.float32), SENSOR, 0.5)
    with pytest.raises(CamsimError, match="fraction"):
        render_raw_frame(source, SENSOR, -0.5)


def _busy_sensor(**overrides) -> SensorParams:
    """Every stage on: DSNU (both kinds), PRNU, row noise, Tukey λ read noise, a pedestal."""
    values = dict(cfa="GBRG", bits=12, pedestal_dn=64, dsnu_e=2.0, prnu_percent=1.0, dsnu_dark_current_percent=20.0,
                  row_noise_e=1.0, read_noise_model="tukey-lambda", full_well_e=6000.0, exposure_s=0.05,
                  sensor_seed=7)
    values.update(overrides)
    return SensorParams(**values)


@pytest.mark.parametrize("law", PHOTON_LAWS)
def test_same_seed_same_bits_whatever_the_workers(law):
    source = np.random.default_rng(1).uniform(-3.0, 9000.0, size=(2048, 256)).astype(np.float32)  # 2 row blocks
    sensor = _busy_sensor()
    one = render_raw_frame(source, sensor, 0.5, law=law, rng=2024, workers=1)
    two = render_raw_frame(source, sensor, 0.5, law=law, rng=2024, workers=2)
    other = render_raw_frame(source, sensor, 0.5, law=law, rng=2025, workers=2)
    assert np.array_equal(one.noisy_dn, two.noisy_dn) and np.array_equal(one.digital_dn, two.digital_dn)
    assert np.array_equal(one.clean_dn, two.clean_dn)
    assert not np.array_equal(one.noisy_dn, other.noisy_dn)


def test_fixed_pattern_maps_belong_to_the_sensor():
    """The maps are the same for every frame seed of a sensor_seed and differ for another; each site takes its
    channel's plane: with photon, dark and read noise off, a pixel is k (f s g_c + o_c) exactly (g_c, o_c its site's
    channel's PRNU gain and DSNU offset)."""
    source = np.random.default_rng(3).uniform(0.0, 4000.0, size=(64, 96)).astype(np.float32)
    sensor = _busy_sensor(dsnu_dark_current_percent=0.0)
    a = render_raw_frame(source, sensor, 0.25, rng=1)
    b = render_raw_frame(source, _busy_sensor(dsnu_dark_current_percent=0.0, sensor_seed=8), 0.25, rng=1)
    c = render_raw_frame(source, sensor, 0.25, rng=2)
    for name in ("offset_e", "gain"):
        assert np.array_equal(getattr(a.maps, name), getattr(c.maps, name))
        assert not np.array_equal(getattr(a.maps, name), getattr(b.maps, name))
    assert np.array_equal(a.clean_dn, c.clean_dn) and not np.array_equal(a.noisy_dn, c.noisy_dn)
    quiet = sensor.with_stages(photon_noise=False, dark_current=False, read_noise=False, quantisation=False)
    quiet = SensorParams(**{**quiet.__dict__, "row_noise_e": 0.0})
    k = quiet.dn_per_electron
    for law in PHOTON_LAWS:
        draw = render_raw_frame(source, quiet, 0.25, law=law, rng=5)
        for dy, dx, ch in cfa_sites(quiet.cfa):
            s = source[dy::2, dx::2].astype(np.float64)
            s = s if law == "add" else np.rint(s)  # thin keeps a count
            g = a.maps.gain[ch, dy::2, dx::2].astype(np.float64)
            o = a.maps.offset_e[ch, dy::2, dx::2].astype(np.float64)
            expected = k * np.minimum(0.25 * s * g + o, quiet.full_well_e)
            np.testing.assert_allclose(draw.noisy_dn[0, dy::2, dx::2], expected, rtol=2e-6, atol=1e-5)
            np.testing.assert_allclose(draw.clean_dn[dy::2, dx::2], expected, rtol=2e-6, atol=1e-5)


def test_a_prnu_gain_clipped_at_zero_collects_nothing():
    """At a PRNU of 29 % the Gaussian map's far tail is below 0, clipped to a gain of 0 (fixed_pattern.prnu_gain):
    those pixels collect no charge (add and thin), instead of a failed Poisson draw."""
    sensor = SensorParams(cfa="RGGB", prnu_percent=29.0).with_stages(dark_current=False, read_noise=False,
                                                                       quantisation=False)
    source = np.full((400, 400), 100.0, dtype=np.float32)
    for law in PHOTON_LAWS:
        draw = render_raw_frame(source, sensor, 0.3, law=law, rng=0)  # 0.3 × the largest gain, 2.3, < 1
        mosaic = np.empty(source.shape, dtype=np.float32)
        for dy, dx, c in cfa_sites(sensor.cfa):
            mosaic[dy::2, dx::2] = draw.maps.gain[c, dy::2, dx::2]
        assert mosaic.min() == 0 and np.any(mosaic == 0)
        assert np.all(draw.noisy_dn[0][mosaic == 0] == 0) and np.all(draw.clean_dn[mosaic == 0] == 0)


def test_add_law_function_is_one_poisson_draw():
    """add_photons_e: Poisson(expected · g + D̄ · d), by its mean and variance (10⁵ draws of one pixel value)."""
    rng = np.random.default_rng(0)
    n = 100_000
    expected = np.full(n, 12.0)
    gain, dark_gain = np.full(n, 1.5), np.full(n, 2.0)
    x = add_photons_e(rng, expected, 0.75, gain=gain, dark_gain=dark_gain).astype(np.float64)
    lam = 12.0 * 1.5 + 0.75 * 2.0
    assert abs(x.mean() - lam) < 5 * np.sqrt(lam / n)
    assert abs(x.var() - lam) < 5 * lam * np.sqrt(2.0 / n) * 1.05


def test_tukey_read_noise_and_row_noise_add_their_variance():
    """Tukey λ read noise (σ = 3 e⁻) and row noise (1 e⁻): a site's DN before the ADC has mean k (f s + D̄_c) and
    variance k² (f s + D̄_c + σ_read² + σ_row²) (the Tukey law scaled to σ_read); 8 bits give uint8 digital DN."""
    sensor = SensorParams(cfa="BGGR", bits=8, read_noise_model="tukey-lambda", read_noise_e=3.0, row_noise_e=1.0,
                          exposure_s=0.01, analog_gain_dn_per_v=2500.0, conversion_gain_v_per_e=0.0002)
    source = np.full((512, 512), 200.0, dtype=np.float32)
    draw = render_raw_frame(source, sensor, 0.1, rng=8, workers=2)
    assert draw.digital_dn.dtype == np.uint8
    k = sensor.dn_per_electron
    rows = source.shape[0] // 2
    for dy, dx, c in cfa_sites(sensor.cfa):
        lam = 20.0 + float(sensor.dark_mean_e[c])
        site = draw.noisy_dn[0, dy::2, dx::2].astype(np.float64)
        var = k * k * (lam + 9.0 + 1.0)
        se_mean = np.sqrt(var / site.size + (k * 1.0) ** 2 / rows)  # the row noise is shared along a row
        assert abs(site.mean() - k * lam) < 5 * se_mean
        se_var = var * np.sqrt(2.0 / site.size) * 2 + (k * 1.0) ** 2 * np.sqrt(2.0 / rows)
        assert abs(site.var(ddof=1) - var) < 5 * se_var


def test_quantisation_off_gives_no_digital_dn():
    sensor = SENSOR.with_stages(quantisation=False)
    draw = render_raw_frame(np.full((8, 8), 50.0, dtype=np.float32), sensor, 0.5, rng=1)
    assert draw.digital_dn is None and draw.noisy_dn.shape == (1, 8, 8) and draw.noisy_dn.dtype == np.float32
    assert draw.clean_dn.shape == (8, 8) and draw.clean_dn.dtype == np.float32 and draw.maps is None
