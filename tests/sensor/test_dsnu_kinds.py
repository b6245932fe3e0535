"""The two kinds of dark-signal non-uniformity: a fixed offset (``dsnu_e``, the same at every exposure time) and a
non-uniform dark-current rate (``dsnu_dark_current_percent``, a log-normal factor d on σ²_dark, so that the spatial
σ of the mean dark charge grows ∝ T). Each property is checked against a closed form written here."""

import json
import math

import numpy as np
import pytest
from scipy import stats

from camsim.core.errors import CamsimError
from camsim.sensor.fixed_pattern import fixed_pattern
from camsim.sensor.params import SENSOR_PARAMS, preset
from tests.support.helpers import ROOT, render, small_scene
from tests.support.theory import assert_mean_var

#: Dark frames: no light, no read noise, no quantisation, no full well: the charge in e⁻ (k = 1 DN/e⁻).
DARK = dict(read_noise=False, quantisation=False, saturation=False, conversion_gain_v_per_e=1.0,
            analog_gain_dn_per_v=1.0)
SHAPE = (160, 240)


@pytest.fixture(scope="module")
def scene():
    return small_scene(width=SHAPE[1], height=SHAPE[0])


def lognormal_moments(p):
    """Mean, σ, skewness and excess kurtosis of d = exp(s z − s²/2), s² = ln(1 + (p/100)²) (closed forms)."""
    w = 1 + (p / 100) ** 2  # e^{s²}
    return 1.0, p / 100, (w + 2) * math.sqrt(w - 1), w**4 + 2 * w**3 + 3 * w**2 - 6


def test_dark_map_is_lognormal_with_mean_one_and_the_configured_spread():
    p = 30.0
    sensor = preset("paper-table1", dsnu_dark_current_percent=p, sensor_seed=5)
    d = fixed_pattern(sensor, (400, 400)).dark_gain.astype(np.float64).ravel()
    n = d.size
    mean, sigma, skew, kurt = lognormal_moments(p)
    assert_mean_var(d, mean, sigma**2, kurtosis_excess=kurt, what="dark map")
    # the sample skewness against (e^{s²} + 2) √(e^{s²} − 1), within 5 standard errors: the standard error of the
    # third standardised moment is √Var((d − 1)³) / (σ³ √n), from the log-normal's raw moments E d^k = e^{k(k−1)s²/2}
    s2 = math.log1p((p / 100) ** 2)
    raw = [math.exp(k * (k - 1) * s2 / 2) for k in range(7)]
    central = [sum(math.comb(k, j) * raw[j] * (-1) ** (k - j) for j in range(k + 1)) for k in range(7)]
    se_skew = math.sqrt(central[6] - central[3] ** 2) / (sigma**3 * math.sqrt(n))
    assert abs(stats.skew(d) - skew) < 5 * se_skew, (stats.skew(d), skew, se_skew)
    assert skew > 0.9 and d.min() > 0  # positive and skewed to the hot side
    # ln d is exactly normal, N(−s²/2, s²)
    assert stats.kstest(np.log(d[:20000]), "norm", args=(-s2 / 2, math.sqrt(s2))).pvalue > 1e-3


def test_same_sensor_seed_same_map_and_other_maps_unchanged():
    base = preset("paper-table1", dsnu_e=2.0, prnu_percent=1.0, sensor_seed=11)
    with_dark = preset("paper-table1", dsnu_e=2.0, prnu_percent=1.0, dsnu_dark_current_percent=10.0, sensor_seed=11)
    a, b = fixed_pattern(base, (48, 64)), fixed_pattern(with_dark, (48, 64))
    assert a.dark_gain is None and b.dark_gain is not None
    np.testing.assert_array_equal(a.offset_e, b.offset_e)  # the new stream leaves the others' bits alone
    np.testing.assert_array_equal(a.gain, b.gain)
    # the streams as documented in camsim.core.seeding: children 0, 1 and 2 of SeedSequence(sensor_seed, (0x46504E,))
    children = [np.random.Generator(np.random.PCG64(np.random.SeedSequence(11, spawn_key=(0x46504E, i))))
                for i in range(3)]
    np.testing.assert_array_equal(a.offset_e, 2.0 * children[0].standard_normal((3, 48, 64), dtype=np.float32))
    z = children[2].standard_normal((3, 48, 64), dtype=np.float32).astype(np.float64)
    s = math.sqrt(math.log1p(0.1**2))
    np.testing.assert_allclose(b.dark_gain, np.exp(s * z - s * s / 2), rtol=1e-6)
    again = fixed_pattern(preset("paper-table1", dsnu_dark_current_percent=10.0, sensor_seed=11), (48, 64))
    np.testing.assert_array_equal(again.dark_gain, b.dark_gain)  # same seed, same map (without the other maps)
    other = fixed_pattern(preset("paper-table1", dsnu_dark_current_percent=10.0, sensor_seed=12), (48, 64))
    assert np.mean(other.dark_gain != b.dark_gain) > 0.99


@pytest.mark.parametrize("dsnu_e, p", [(3.0, 0.0), (0.0, 20.0), (3.0, 20.0)])
def test_spatial_variance_of_the_mean_dark_charge_against_exposure_time(scene, dsnu_e, p):
    """Averaged dark frames at T = 1 s and 4 s: the spatial variance of a pixel's average is
    dsnu_e² + (p/100 · σ²_dark · T)² + σ²_dark · T / N (the temporal Poisson variance left after N frames)."""
    frames = 12
    for exposure in (1.0, 4.0):
        sensor = preset("paper-table1", dsnu_e=dsnu_e, dsnu_dark_current_percent=p, exposure_s=exposure,
                        sensor_seed=2, **DARK)
        average = np.mean([render(scene, sensor, factor=0.0, seed=seed)[0].noisy_dn for seed in range(frames)],
                          axis=0, dtype=np.float64)
        for c in range(3):
            dark = sensor.dark_current_e_per_s[c] * exposure
            spatial = dsnu_e**2 + (p / 100 * dark) ** 2
            var = spatial + dark / frames
            kurt = (p / 100 * dark) ** 4 * lognormal_moments(p)[3] / var**2 if p else 0.0
            assert_mean_var(average[c], dark, var, kurtosis_excess=kurt, what=f"T {exposure} ch{c}")
        frame = render(scene, sensor, factor=0.0, seed=0)[0]
        maps = frame.maps
        clean = frame.clean_dn()  # the clean layer carries both maps: D̄ d + o
        for c in range(3):
            dark = sensor.dark_current_e_per_s[c] * exposure
            d = 1.0 if maps.dark_gain is None else maps.dark_gain[c].astype(np.float64)
            o = 0.0 if maps.offset_e is None else maps.offset_e[c].astype(np.float64)
            np.testing.assert_allclose(clean[c], dark * d + o, rtol=2e-6, atol=1e-3)


@pytest.mark.parametrize("method, statistics, photon_noise, cfa", [
    ("poisson", "pixel", True, None),
    ("poisson", "pixel", True, "GRBG"),
    ("spectral", "pixel", True, None),
    ("auto", "pixel", True, None),
    ("poisson", "paper", True, None),
    ("poisson", "paper", False, None),
    ("spectral", "paper", False, None),
    ("gaussian", "pixel", True, None),
])
def test_one_dark_frame_is_poisson_around_each_pixels_mean(scene, method, statistics, photon_noise, cfa):
    """One frame at T = 0.05 s (D̄ ≈ 10 e⁻, d spread by 50 %): each count against Poisson(D̄ d(x)).

    Pooled over pixels, Σ (N − λ)² / λ has mean n and variance Σ (2 + 1/λ) (Poisson: μ₄ = λ + 3λ²; the moment-
    matched normal: mean n, variance 2n); the exact methods' randomised probability-integral transforms
    F(N − 1) + V f(N) are uniform, checked by a χ² over 20 bins. A uniform dark mean D̄ (no map) fails the first
    by far (Σ (N − D̄)² / D̄ ≈ n (1 + D̄ · 0.25))."""
    sensor = preset("paper-table1", dsnu_dark_current_percent=50.0, exposure_s=0.05, sensor_seed=4,
                    photon_noise=photon_noise, cfa=cfa, **DARK)
    frame = render(scene, sensor, factor=0.0, statistics=statistics, method=method, seed=9)[0]
    d = fixed_pattern(sensor, SHAPE).dark_gain.astype(np.float64)
    lam = np.asarray(sensor.dark_current_e_per_s)[:, None, None] * sensor.exposure_s * d
    counts = frame.noisy_dn.astype(np.float64)
    if cfa is not None:  # each site holds its own channel
        lam = np.choose(np.tile(np.array([[1, 0], [2, 1]]), (SHAPE[0] // 2, SHAPE[1] // 2)), lam)[None]
    lam, counts = lam.ravel(), counts.ravel()
    n = lam.size
    statistic = np.sum((counts - lam) ** 2 / lam)
    spread = math.sqrt(2 * n if method == "gaussian" else np.sum(2 + 1 / lam))
    assert abs(statistic - n) < 5 * spread, (statistic, n, spread)
    assert abs(np.sum(counts - lam)) < 5 * math.sqrt(np.sum(lam))
    if method != "gaussian":
        assert np.array_equal(counts, np.round(counts))  # counts, not a continuous approximation
        v = np.random.default_rng(0).random(n)
        pit = stats.poisson.cdf(counts - 1, lam) + v * stats.poisson.pmf(counts, lam)
        observed = np.histogram(pit, bins=20, range=(0, 1))[0]
        assert stats.chisquare(observed).pvalue > 1e-4, observed


@pytest.mark.parametrize("method", ["poisson", "gaussian", "auto", "spectral"])
@pytest.mark.parametrize("dark", [6000.0, 10500.0])
def test_the_full_well_acts_per_pixel(scene, method, dark):
    """A 9000 e⁻ full well, p = 20 %. D̄ = 6000 e⁻: without the map no pixel comes near the full well
    (D̄ + 10 √D̄ < 7000), with it the pixels with d ≳ 1.5 saturate. D̄ = 10 500 e⁻: without the map every pixel
    saturates (D̄ is beyond the saturation cap, 10 186 e⁻), with it those with d ≲ 0.85 do not. The number of
    pixels at the full well against Σₓ P(X ≥ full well) with X ~ Poisson(D̄ d(x)) (the normal N(D̄ d, D̄ d) for
    ``gaussian``), none above it, and the clean layer below it wherever D̄ d + 6 √(D̄ d) is."""
    sensor = preset("paper-table1", dsnu_dark_current_percent=20.0, dark_current_e_per_s=dark, sensor_seed=3,
                    **(DARK | {"saturation": True}))
    frame = render(scene, sensor, factor=0.0, method=method, seed=2)[0]
    full = sensor.full_well_e
    lam = dark * fixed_pattern(sensor, SHAPE).dark_gain.astype(np.float64)
    if method == "gaussian":
        p_full = stats.norm.sf(full, lam, np.sqrt(lam))
    else:
        p_full = stats.poisson.sf(full - 1, lam)
    at_full = np.sum(frame.noisy_dn == np.float32(full))
    assert frame.noisy_dn.max() == np.float32(full)
    assert abs(at_full - p_full.sum()) < 5 * math.sqrt(np.sum(p_full * (1 - p_full))) + 1, (at_full, p_full.sum())
    assert 500 < p_full.sum() < lam.size - 500
    clean = frame.clean_dn()  # every pixel's mean is at most the full well, and below it where its law is
    assert clean.max() <= np.float32(full)
    assert np.all(clean[lam + 6 * np.sqrt(lam) < full] < np.float32(full))


def test_no_dark_current_no_effect(scene):
    sensor = preset("paper-table1", dsnu_dark_current_percent=30.0, dark_current=False, sensor_seed=1, **DARK)
    frame = render(scene, sensor, factor=0.0)[0]
    assert frame.maps.dark_gain is not None and not np.any(frame.noisy_dn) and not np.any(frame.clean_dn())


def test_the_parameter_is_recorded_only_when_on(tmp_path):
    """Records (sidecar, dataset frame records) of sensors without it stay as they were: absent means 0."""
    from camsim.analysis.grouping import GROUP_KEYS
    from camsim.cli import main

    param = next(p for p in SENSOR_PARAMS if p.name == "dsnu_dark_current_percent")
    assert param.unit == "%" and param.default == 0.0
    assert "dsnu_dark_current_percent" not in preset("paper-table1").sidecar_record()
    assert "dsnu_dark_current_percent" not in preset("paper-table1").to_dict()
    assert preset("paper-table1", dsnu_dark_current_percent=7.5).to_dict()["dsnu_dark_current_percent"] == 7.5
    assert "dsnu_dark_current_percent" in GROUP_KEYS  # frames that differ in it are not one measurement
    for value, present in ((0, False), (7.5, True)):
        out = tmp_path / f"p{value}"
        assert main(["render", str(ROOT / "scenes" / "macbeth_26.toml"), "--size", "48x32", "--illuminant", "D65",
                     "--intensity", "1", "-q", "--sensor", f"dsnu_dark_current_percent={value}",
                     "--out", str(out)]) == 0
        sidecar = json.loads(next(out.rglob("*.json")).read_text())
        assert ("dsnu_dark_current_percent" in sidecar) == present
        if present:
            assert sidecar["dsnu_dark_current_percent"] == 7.5 and sidecar["dsnu_e"] == 0.0


@pytest.mark.parametrize("value", [-1.0, 100.0])
def test_out_of_range_is_refused(value):
    with pytest.raises(CamsimError, match="dsnu_dark_current_percent"):
        preset("paper-table1", dsnu_dark_current_percent=value)


def test_a_dataset_may_vary_it(tmp_path):
    """A dataset spec sets it like any sensor parameter; a frame's record (which its id hashes) names it only when
    it is on, so a frame with it off has the record, and id, of a frame of a spec that never mentions it."""
    from camsim.dataset.spec import load_spec

    (tmp_path / "scene.toml").write_text('name = "chart"\n[chart]\n[light]\nilluminants = ["D65"]\n')
    base = 'scene = "scene.toml"\nseed = 3\n[frame]\nwidth = 32\nheight = 24\n'
    (tmp_path / "plain.toml").write_text(base)
    (tmp_path / "grid.toml").write_text(base + "[grid]\ndsnu_dark_current_percent = [0.0, 5.0]\n")
    plain = load_spec(tmp_path / "plain.toml").frames
    off, on = load_spec(tmp_path / "grid.toml").frames
    assert "dsnu_dark_current_percent" not in off.record and on.record["dsnu_dark_current_percent"] == 5.0
    assert off.id == plain[0].id and on.id.split("-")[1] != off.id.split("-")[1]
    assert on.sensor_overrides["dsnu_dark_current_percent"] == 5.0
