"""The true black level (camsim.sensor.black_level): the exact mean digital number of an unlit pixel, against closed
forms computed here by other routes (tail sums, the Owen-free integral over the DSNU, scipy's Tukey CDF), Monte Carlo
where no closed form exists, rendered dark frames, and what the DNG and the sidecar say."""

import dataclasses
import json

import numpy as np
import pytest
from scipy import integrate, special, stats

from camsim.sensor.black_level import unlit_mean_dn
from camsim.sensor.kernels import tukey_lambda_variance
from camsim.sensor.params import PRESETS, SensorParams
from tests.support.helpers import libraw_black_levels, render, small_scene
from tests.support.theory import digital_pmf, mean_dn_tail_sum, pmf_moments

TABLE1 = PRESETS["paper-table1"]
K1 = TABLE1.dn_per_electron
#: A Bayer 12-bit sensor with DSNU, row noise and Tukey read noise (k = 0.4 DN/e⁻).
BAYER = SensorParams(cfa="RGGB", bits=12, conversion_gain_v_per_e=4e-5, analog_gain_dn_per_v=1e4,
                     dark_current_e_per_s=(25.0, 30.0, 20.0), read_noise_e=3.0, full_well_e=10000.0, dsnu_e=2.0,
                     row_noise_e=0.5, read_noise_model="tukey-lambda")
#: A sensor whose dark current varies from pixel to pixel (a log-normal map of 60 % spatial σ) at a gain of 0.5
#: DN/e⁻ and a dark mean of 3–4 e⁻: the floor and the zero clip make the black level depend on the map.
DARK_MAP = SensorParams(conversion_gain_v_per_e=5e-3, analog_gain_dn_per_v=100.0, exposure_s=0.015,
                        read_noise_e=1.0, dsnu_dark_current_percent=60.0)
#: A 14-bit Bayer raw with a 512 DN pedestal, as Sony's (k = 0.8 DN/e⁻, Tukey read noise, row noise).
PEDESTAL = SensorParams(cfa="RGGB", bits=14, conversion_gain_v_per_e=8e-5, analog_gain_dn_per_v=1e4,
                        dark_current_e_per_s=(2.0, 3.0, 2.5), read_noise_e=2.5, full_well_e=20000.0, row_noise_e=0.4,
                        read_noise_model="tukey-lambda", tukey_lambda=-0.05, pedestal_dn=512)


def _floor_law_mean(mu, k, sigma, pedestal, top, full_well=None):
    """E[clip(round(k X) + P, 0, top)] (halves up: the ADC's offset P + ½ before its floor), X = min(D, FW) +
    N(0, σ²), D ~ Poisson(μ): the law of round(k X) summed code by code over a wide window (differences of normal
    CDFs between the half-integers), then shifted and clipped — no tail sums."""
    d = np.arange(0, int(mu + 20 * np.sqrt(mu) + 30))
    p = stats.poisson.pmf(d, mu)
    if full_well is not None:
        d = np.minimum(d, full_well)
    codes = np.arange(-2000, top + 2001)
    cdf = stats.norm.cdf(((codes[None, :] - 0.5) / k - d[:, None]) / sigma)  # P(round(k X) < code)
    return float(p @ (np.diff(cdf, axis=1) @ np.clip(codes[:-1] + pedestal, 0, top)))


@pytest.mark.parametrize("mu, k, sigma, pedestal, bits, full_well", [
    (10.0, 0.5, 3.0, 512, 14, None),     # Sony's 14-bit pedestal: nothing clips at 0
    (0.0, 0.5, 3.0, 512, 14, None),      # no dark current: P exactly (the published black level)
    (5.0, 2.0, 1.5, 3, 10, None),        # a pedestal of a few DN: the zero clip still acts
    (1000.0, 1.0, 2.0, 64, 10, 990.0),   # the full well below the top code, with a pedestal
    (0.0, 1.3, 0.7, 1, 8, None),
])
def test_the_pedestal_against_the_floors_law(mu, k, sigma, pedestal, bits, full_well):
    got = unlit_mean_dn([mu], dn_per_electron=k, bits=bits, read_noise_e=sigma, pedestal_dn=pedestal,
                        full_well_e=full_well)[0]
    assert got == pytest.approx(_floor_law_mean(mu, k, sigma, pedestal, 2**bits - 1, full_well), abs=1e-8)
    # the EXR's level (before the ADC) has no pedestal: k E[min(D, FW)]
    d = np.arange(0, 3000)
    charge = stats.poisson.pmf(d, mu) @ (d if full_well is None else np.minimum(d, full_well))
    assert unlit_mean_dn([mu], dn_per_electron=k, bits=bits, read_noise_e=sigma, pedestal_dn=pedestal,
                         full_well_e=full_well, quantisation=False)[0] == pytest.approx(k * charge, rel=1e-9)


@pytest.mark.parametrize("lam, dsnu, full_well", [(-0.1, 0.0, None), (0.1, 2.0, 1010.0)])
def test_the_pedestal_with_tukey_noise_and_dsnu_at_the_well_against_monte_carlo(lam, dsnu, full_well):
    from camsim.sensor.kernels import tukey_lambda

    rng, n, mu, k, sigma, pedestal = np.random.default_rng(5), 2_000_000, 1000.0, 1.0, 2.0, 64
    charge = rng.poisson(mu, n) + (rng.normal(0, dsnu, n) if dsnu else 0.0)
    read = tukey_lambda(rng, np.empty(n), lam, sigma)
    values = np.clip(np.round(k * ((np.minimum(charge, full_well) if full_well else charge) + read)) + pedestal,
                     0, 1023)  # round half to even: the ties have probability 0
    got = unlit_mean_dn([mu], dn_per_electron=k, bits=10, read_noise_e=sigma, pedestal_dn=pedestal,
                        full_well_e=full_well, dsnu_e=dsnu, read_noise_model="tukey-lambda", tukey_lambda=lam)[0]
    assert abs(got - values.mean()) < 5 * values.std() / np.sqrt(n)


def test_table1_is_the_tail_sum_of_poisson_and_normal():
    expected = [pmf_moments(digital_pmf(lam, K1, 4.0, 9000.0, 8))[0] for lam in (195.0, 230.0, 218.0)]
    np.testing.assert_allclose(TABLE1.black_level_dn, expected, atol=1e-9)
    # about ½ DN below k · σ²_dark · T, which the sidecar keeps as dark_level_dn
    np.testing.assert_allclose(TABLE1.dark_level_dn, np.array([195.0, 230.0, 218.0]) * K1, rtol=1e-12)
    assert np.all(np.abs(TABLE1.black_level_dn - (TABLE1.dark_level_dn - 0.5)) < 0.03)


@pytest.mark.parametrize("lam, k, sigma, bits", [
    (0.0, 1.0, 2.0, 16),        # no dark current: half the read noise is clipped at 0
    (3.3, 0.5, 0.0, 16),        # no read noise: a pure lattice
    (1000.0, 1.0, 2.0, 16),     # 16 bits
    (1e5, 1e-3, 5.0, 16),       # a tiny gain
    (50.0, 1e-4, 4.0, 16),      # a tiny gain: everything in code 0
    (30.0, 3.0, 0.7, 8),        # a high gain
])
def test_extremes_against_the_tail_sum(lam, k, sigma, bits):
    got = unlit_mean_dn([lam], dn_per_electron=k, bits=bits, read_noise_e=sigma)[0]
    assert got == pytest.approx(mean_dn_tail_sum(lam, k, sigma, bits), abs=1e-9)


def test_gaussian_dsnu_and_row_noise_add_to_the_read_noise():
    # below the full well, the DSNU offset, the read and the row noise are one Gaussian: √(2² + 3² + 1.5²) e⁻
    got = unlit_mean_dn(25.0, dn_per_electron=0.4, bits=12, full_well_e=10000.0, dsnu_e=2.0, read_noise_e=3.0,
                        row_noise_e=1.5)
    assert got == pytest.approx(mean_dn_tail_sum(25.0, 0.4, np.sqrt(4 + 9 + 2.25), 12), abs=1e-9)


def test_dark_that_fills_the_well():
    # every pixel holds the full well: I = floor(k (9000 + z)), k · 9000 = 255.006, so I ≥ 254 and I = 255 when
    # z ≥ 255 / k − 9000
    expected = 254 + stats.norm.sf((255 / K1 - 9000) / 4.0)
    long = dataclasses.replace(TABLE1, exposure_s=50.0)
    np.testing.assert_allclose(long.black_level_dn, expected, atol=1e-9)
    np.testing.assert_allclose(long.dark_level_dn, K1 * 9000, rtol=1e-12)  # before the ADC: k · FW
    assert unlit_mean_dn(1e12, dn_per_electron=K1, bits=8, full_well_e=9000.0, read_noise_e=4.0) == \
        pytest.approx(expected, abs=1e-9)
    # without a well, a huge dark level reads the top code
    assert unlit_mean_dn(1e12, dn_per_electron=K1, bits=8, read_noise_e=4.0) == 255.0


def test_dark_at_the_full_well_with_dsnu_against_an_integral_over_the_offset():
    # E[I] = ∫ φ(o) Σ_n P(N = n) E[I | min(n + o, FW)] do, by adaptive quadrature with the kinks as break points
    lam, k, fw, s_o, s_n, bits = 48.0, 0.5, 50.0, 3.0, 1.5, 8
    n = np.arange(0, 121)
    p_n = stats.poisson.pmf(n, lam)
    j = np.arange(1, 2**bits)

    def given_offset(o):
        charge = np.minimum(n + o, fw)
        return p_n @ stats.norm.sf((j[None, :] / k - charge[:, None]) / s_n).sum(axis=1)

    kinks = sorted({fw - m for m in range(0, 100) if abs(fw - m) < 12 * s_o})
    expected, _ = integrate.quad(lambda o: given_offset(o) * stats.norm.pdf(o, scale=s_o), -12 * s_o, 12 * s_o,
                                 points=kinks, limit=500, epsabs=1e-12, epsrel=1e-12)
    got = unlit_mean_dn(lam, dn_per_electron=k, bits=bits, full_well_e=fw, dsnu_e=s_o, read_noise_e=s_n)
    assert got == pytest.approx(expected, abs=1e-8)
    # and without the read noise: min(n + o, FW) ≥ x ⇔ n + o ≥ x and x ≤ FW
    top = int(np.floor(k * fw))
    lattice = p_n @ stats.norm.sf((j[None, :top] / k - n[:, None]) / s_o).sum(axis=1)
    assert unlit_mean_dn(lam, dn_per_electron=k, bits=bits, full_well_e=fw, dsnu_e=s_o) == \
        pytest.approx(lattice, abs=1e-9)


def test_without_quantisation_it_is_the_mean_charge():
    # k · E[min(N + o, FW)], with E[min(o, a)] = a Φ(−a/σ) − σ φ(a/σ) for o ~ N(0, σ²)
    lam, k, fw, s_o = 48.0, 0.5, 50.0, 3.0
    n = np.arange(0, 121)
    a = fw - n
    expected = k * stats.poisson.pmf(n, lam) @ (n + a * stats.norm.sf(a / s_o) - s_o * stats.norm.pdf(a / s_o))
    got = unlit_mean_dn(lam, dn_per_electron=k, bits=8, quantisation=False, full_well_e=fw, dsnu_e=s_o,
                        read_noise_e=2.0, row_noise_e=1.0)
    assert got == pytest.approx(expected, rel=1e-12)
    assert unlit_mean_dn(195.0, dn_per_electron=K1, bits=8, quantisation=False, read_noise_e=4.0) == 195.0 * K1


def test_tukey_read_noise_against_scipys_tukey_cdf():
    # a lattice of dark charges plus Tukey λ read noise: Σ_n P(N = n) Σ_j P(R ≥ j / k − n), P(R ≥ x) from
    # scipy.special.tklmbda (its own inversion of the quantile function)
    lam, k, sigma, shape = 25.0, 0.4, 3.0, -0.1
    scale = sigma / np.sqrt(tukey_lambda_variance(shape))
    n = np.arange(0, 101)
    j = np.arange(1, 4096)
    tail = 1 - special.tklmbda((j[None, :] / k - n[:, None]) / scale, shape)
    expected = stats.poisson.pmf(n, lam) @ tail.sum(axis=1)
    got = unlit_mean_dn(lam, dn_per_electron=k, bits=12, read_noise_e=sigma, read_noise_model="tukey-lambda",
                        tukey_lambda=shape)
    assert got == pytest.approx(expected, abs=1e-8)


@pytest.mark.parametrize("dsnu, row, rel, full_well", [
    (2.0, 1.5, 0.0, None),    # the Gaussian part wider than half the Tukey noise
    (0.5, 0.0, 0.3, None),    # narrower, and a log-normal dark-current factor
    (3.0, 0.0, 0.0, 30.0),    # the dark charge at the full well, with DSNU
])
def test_tukey_with_gaussian_parts_against_monte_carlo(dsnu, row, rel, full_well):
    rng = np.random.default_rng(7)
    n, lam, k, sigma, shape = 2_000_000, 25.0, 0.4, 3.0, -0.1
    s_log = np.sqrt(np.log1p(rel**2))
    rate = lam * np.exp(rng.normal(-s_log**2 / 2, s_log, n)) if rel else lam
    charge = rng.poisson(rate, n) + dsnu * rng.standard_normal(n)
    if full_well is not None:
        charge = np.minimum(charge, full_well)
    u = rng.random(n)
    read = (u**shape - (1 - u) ** shape) / shape * sigma / np.sqrt(tukey_lambda_variance(shape))
    dn = np.clip(np.floor(k * (charge + read + row * rng.standard_normal(n))), 0, 4095)
    got = unlit_mean_dn(lam, dn_per_electron=k, bits=12, full_well_e=full_well, dsnu_e=dsnu,
                        dark_rate_rel_sigma=rel, read_noise_e=sigma, read_noise_model="tukey-lambda",
                        tukey_lambda=shape, row_noise_e=row)
    se = dn.std() / np.sqrt(n)
    assert abs(dn.mean() - got) < 4 * se, (dn.mean(), got, se)


def test_log_normal_dark_rate_against_its_mixture():
    # E over the factor L of the Poisson(λ L) tail sum, by quadrature over log L (scipy.integrate.quad)
    lam, k, sigma, rel = 40.0, 0.3, 1.5, 0.5
    s_log = np.sqrt(np.log1p(rel**2))

    def integrand(z):
        return mean_dn_tail_sum(lam * np.exp(-s_log**2 / 2 + s_log * z), k, sigma, 12) * stats.norm.pdf(z)

    expected, _ = integrate.quad(integrand, -10, 10, epsabs=1e-10, limit=200)
    got = unlit_mean_dn(lam, dn_per_electron=k, bits=12, read_noise_e=sigma, dark_rate_rel_sigma=rel)
    assert got == pytest.approx(expected, abs=1e-7)


def _per_channel_rows(frame, sensor):
    """Per channel, the mean of each row's pixels of that channel (rows share their row noise)."""
    dn = frame.digital_dn.astype(np.float64)
    if sensor.cfa is None:
        return [dn[c].mean(axis=1) for c in range(3)]
    m = dn[0]
    return [m[0::2, 0::2].mean(axis=1), np.concatenate([m[0::2, 1::2], m[1::2, 0::2]], axis=1).mean(axis=1),
            m[1::2, 1::2].mean(axis=1)]


@pytest.mark.parametrize("sensor", [TABLE1, BAYER, DARK_MAP, PEDESTAL],
                         ids=["table1", "bayer12", "dark-current-map", "pedestal-14bit"])
def test_a_rendered_dark_frame_averages_to_the_black_level(sensor):
    frame, _ = render(small_scene(), sensor, factor=1e-30, seed=3)  # F tiny: signal ≪ 1e-20 e⁻
    for c, rows in enumerate(_per_channel_rows(frame, sensor)):
        se = rows.std(ddof=1) / np.sqrt(rows.size)  # rows are independent: their means carry the row noise
        assert abs(rows.mean() - sensor.black_level_dn[c]) < 4 * se, (c, rows.mean(), sensor.black_level_dn[c], se)
        assert abs(rows.mean() - sensor.dark_level_dn[c]) > 0.2  # the old tag, about ½ DN too high
    if sensor is DARK_MAP:  # the map's law is part of the black level: without it the mean would be off
        plain = dataclasses.replace(sensor, dsnu_dark_current_percent=0.0).black_level_dn
        assert np.all(np.abs(plain - sensor.black_level_dn) > 0.01)


@pytest.mark.parametrize("cfa", [None, "RGGB"])
def test_the_dng_and_the_sidecar_carry_the_true_black_level(tmp_path, cfa):
    import rawpy
    import tifffile

    from camsim.cli import main

    out = tmp_path / "o"
    argv = ["render", "macbeth_26", "--intensity", "1", "--out", str(out), "--illuminant", "D65", "--size", "64x48",
            "-q"]
    assert main(argv + (["--cfa", cfa] if cfa else [])) == 0
    sidecar = json.loads((out / "macbeth_26_D65_F1.json").read_text())
    expected = [pmf_moments(digital_pmf(lam, K1, 4.0, 9000.0, 8))[0] for lam in (195.0, 230.0, 218.0)]
    np.testing.assert_allclose(sidecar["black_level_dn"], expected, atol=1e-9)
    np.testing.assert_allclose(sidecar["dark_level_dn"], np.array([195.0, 230.0, 218.0]) * K1, rtol=1e-12)
    with tifffile.TiffFile(out / "macbeth_26_D65_F1.dng") as tif:
        tag = tif.pages[0].tags[50714].value
    values = np.array(tag, dtype=float).reshape(-1, 2)
    written = values[:, 0] / values[:, 1]
    per_colour = written if cfa is None else written[[0, 1, 3]]  # RGGB: R, G, (G), B
    np.testing.assert_allclose(per_colour, expected, atol=1e-6)
    with rawpy.imread(str(out / "macbeth_26_D65_F1.dng")) as raw:
        # LibRaw rounds a LinearRaw file's stored black level and truncates a CFA file's
        stored = libraw_black_levels(out / "macbeth_26_D65_F1.dng")
        rounded = stored if cfa is None else [stored[0], stored[1], stored[3]]  # RGGB: R, G, (G), B
        np.testing.assert_array_equal(raw.black_level_per_channel[:3], rounded)  # R, G, B (LibRaw's colour order)
