"""``camsim calibrate``: the round trip (a camsim sensor rendered into DNG darks and flats, calibrated back), each
estimator against an independent closed form or synthetic numbers of known law, and the refusals of bad input.

The round trip's design (:data:`SIZE`, :data:`DARKS`, :data:`LEVELS`) and its margins: per plane N = 256 × 512 =
131 072 pixels, n = 16 darks, 5 flat levels from 4 % to 60 % of the ADC's range. Standard errors at the worst
corner of the parameter ranges (K 0.5–4 DN/e⁻, read σ 1.5–6 DN, λ −0.15…0.15, row σ 0.2–1 DN, DSNU ≤ 4 DN):

* K: each level's variance to √(2/N) = 0.39 %; the weighted fit over 5 levels and 4 planes, ≈ 0.15 % (tolerance
  2 % = 13 SE);
* read σ: √(2/(N (n − 1)))/2 = 0.05 % per plane (3 % = 60 SE);
* row σ: σ_row² from (n − 1) H = 7680 row means of variance σ_row² + σ²/W ≤ 0.04 + 36/1024 DN²: SE(σ_row) ≤ 1.5 %
  at σ_row = 0.2 DN, σ = 6 DN (10 % = 6.5 SE);
* λ: the matched PPCC over 2.1 M samples per plane, ≈ 0.004 per plane, 0.002 for the planes' mean (0.03 = 7 SE);
* black level: √(DSNU²/N + σ_row²/(n H)) ≤ √(16/131072 + 1/4096) = 0.019 DN per plane (0.1 DN = 5 SE).

The test also checks that ``calibration.json``'s own standard errors give each tolerance at least 4 of them.
"""

import json
import tomllib

import numpy as np
import pytest
from scipy import optimize, special, stats

from camsim.calibration import dark, flats, ptc, tukey
from camsim.calibration.estimate import Estimate
from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.io.dng import write_dng, write_dng_cfa
from camsim.light.spectra import WavelengthGrid
from camsim.render.pipeline import LitScene, make_frame
from camsim.sensor.kernels import tukey_lambda, tukey_lambda_variance
from camsim.sensor.params import SensorParams
from camsim.sensor.presets import sensor_preset
from tests.support.hostile_files import HUGE_SIZES, no_hang, not_regular, one_error_line, with_tiff_size

#: Round trip: frame height and width (pixels), dark frames, flat levels (fractions of the ADC's range above the
#: pedestal; two frames each).
SIZE = (512, 1024)
DARKS = 16
LEVELS = (0.04, 0.12, 0.25, 0.4, 0.6)
#: The white light's electrons in R, G, B relative to the level (a camera's unequal channel gains).
TINT = np.array([0.8, 1.0, 0.9])
GRID = WavelengthGrid(500.0, 600.0, 50.0)  # three bins; with an identity Qe each bin feeds one channel


def drawn_sensor(seed: int) -> SensorParams:
    """A 14-bit RGGB sensor with a 512 DN pedestal, parameters drawn from ``seed`` within plausible ranges."""
    rng = np.random.default_rng(seed)
    k = rng.uniform(0.5, 4.0)
    read_dn, lam, row_dn = rng.uniform(1.5, 6.0), rng.uniform(-0.15, 0.15), rng.uniform(0.2, 1.0)
    dsnu_dn, prnu = rng.uniform(0.5, 4.0), rng.uniform(0.3, 1.5)
    return SensorParams(cfa="RGGB", bits=14, conversion_gain_v_per_e=1e-4, analog_gain_dn_per_v=k / 1e-4,
                        dark_current=False, full_well_e=1.5 * 16383 / k, read_noise_e=read_dn / k,
                        read_noise_model="tukey-lambda", tukey_lambda=lam, row_noise_e=row_dn / k,
                        dsnu_e=dsnu_dn / k, prnu_percent=prnu, pedestal_dn=512, sensor_seed=seed)


def shoot(sensor: SensorParams, folder, seed: int, shape=SIZE, darks=DARKS, levels=LEVELS):
    """Render the darks and the flat pairs of ``sensor`` with camsim (``make_frame`` on a uniform field) and write
    them as DNGs (CFA, or 3-sample LinearRaw for a three-chip sensor). Returns (dark paths, flat paths)."""
    labels = np.zeros(shape, np.uint8)
    seeds = iter(np.random.SeedSequence(seed).spawn(darks + 2 * len(levels)))

    def frame_file(name, electrons):
        lit = LitScene(labels, np.array([electrons], float), np.eye(3), GRID)
        dn = make_frame(lit, sensor, 1.0, rng=next(seeds), workers=1).digital_dn
        path = folder / name
        tags = dict(black_level_dn=sensor.black_level_tag_dn, unique_camera_model="camsim calibrate test",
                    color_matrix1=np.eye(3), as_shot_neutral=[1, 1, 1])
        if sensor.cfa:
            write_dng_cfa(path, dn[0], pattern=sensor.cfa, white_level=sensor.max_dn, **tags)
        else:
            write_dng(path, dn, white_level=sensor.max_dn, **tags)
        return str(path)

    dark_files = [frame_file(f"dark_{i:02d}.dng", [0.0, 0.0, 0.0]) for i in range(darks)]
    span_e = (sensor.max_dn - sensor.pedestal_dn) / sensor.dn_per_electron
    flat_files = [frame_file(f"flat_{j}_{i}.dng", f * span_e * TINT) for j, f in enumerate(levels) for i in range(2)]
    return dark_files, flat_files


def _ok(capsys, argv):
    code = main(argv)
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return captured


@pytest.mark.slow
@pytest.mark.parametrize("seed", [11, 12, 13])
def test_round_trip_recovers_the_rendered_sensor(tmp_path, capsys, seed):
    sensor = drawn_sensor(seed)
    darks, flat_files = shoot(sensor, tmp_path, seed)
    shuffled = [flat_files[i] for i in np.random.default_rng(seed).permutation(len(flat_files))]  # paired by level
    out = tmp_path / "out"
    # --no-maps: the preset renders the DSNU as a drawn pattern (so at any size: the chart below is 64 × 48)
    _ok(capsys, ["calibrate", "--dark", *darks, "--flat", *shuffled, "--out", str(out), "--iso", "3200", "-q",
                 "--no-maps"])
    preset = tomllib.loads((out / "preset.toml").read_text(encoding="utf-8"))
    record = json.loads((out / "calibration.json").read_text(encoding="utf-8"))
    iso = preset["iso"][0]
    k = sensor.dn_per_electron
    # none of issue 28's effects is on: no map named, the figures' intervals hold 0, and few pixels pass the hot
    # threshold (a Gaussian's 5 σ tail is 2.9e-7 of 524 288 pixels; a mean of 16 Tukey-λ draws with λ < 0 has
    # heavier tails: 3, 4 and 0 at seeds 11, 12, 13; bound 2e-5 of the pixels, 1/50 of a 1e-3 hot fraction)
    assert not {"dark_shading_map", "hot_pixel_map"} & set(iso)
    assert iso["column_fpn_e"] == 0 and iso["black_level_error_dn"] == 0
    assert record["dark_effects"]["hot_pixels"]["count"] <= 2e-5 * SIZE[0] * SIZE[1]
    assert np.load(out / "dark_shading.npy").shape == SIZE
    assert not (out / "hot_pixels.npy").exists()  # these DNGs say no exposure: no map in e⁻/s
    assert any("do not say their exposure" in w for w in record["warnings"])
    truth = {"k_dn_per_e": (k, 0.02, "k_dn_per_e"),
             "gaussian_sigma_dn": (sensor.read_noise_e * k, 0.03, "read_noise_dn"),
             "row_sigma_dn": (sensor.row_noise_e * k, 0.10, "row_noise_dn")}
    for key, (true, tolerance, json_key) in truth.items():
        assert iso[key] == pytest.approx(true, rel=tolerance), key
        assert tolerance * true >= 4 * record[json_key]["standard_error"], f"{key}: too little margin"
    assert iso["tukey_lambda"] == pytest.approx(sensor.tukey_lambda, abs=0.03)
    assert 0.03 >= 4 * record["tukey_lambda"]["standard_error"]
    for name, plane in record["planes"].items():
        true_black = sensor.black_level_dn["RGB".index(plane["colour"])]
        assert plane["black_level_dn"]["value"] == pytest.approx(true_black, abs=0.1), name
        assert 0.1 >= 4 * plane["black_level_dn"]["standard_error"], name
    # beyond the required: DSNU and PRNU (the maps drawn differ from their σ by ~0.2 %), the preset's header
    assert iso["dsnu_dn"] == pytest.approx(sensor.dsnu_e * k, rel=0.05)
    assert iso["prnu_percent"] == pytest.approx(sensor.prnu_percent, rel=0.05)
    assert iso["iso"] == 3200
    assert preset["preset"] == {
        "name": "camsim calibrate test", "source": preset["preset"]["source"], "bits": 14, "pedestal_dn": 512,
        "cfa": "RGGB", "read_noise_model": preset["preset"]["read_noise_model"]}
    assert preset["preset"]["source"].startswith(f"camsim calibrate: {DARKS} dark frames, 5 flat pairs")
    gaussian = abs(iso["tukey_lambda"] - tukey.GAUSSIAN_LAMBDA) <= 0.02
    assert preset["preset"]["read_noise_model"] == ("gaussian" if gaussian else "tukey-lambda")
    assert iso["tukey_scale_dn"] * np.sqrt(tukey_lambda_variance(iso["tukey_lambda"])) == pytest.approx(
        iso["gaussian_sigma_dn"], rel=0.01)
    for name in ("report.md", "ptc.png", "probability_plot.png", "row_spectrum.png"):
        assert (out / name).stat().st_size > 0
    assert not list(out.glob(".*partial"))
    # the preset file is camsim's own: the recovered sensor, in electrons, and a render with --preset PATH.toml
    recovered = sensor_preset(str(out / "preset.toml"), 3200, read_noise_model="gaussian")
    assert recovered.dn_per_electron == pytest.approx(k, rel=0.02)
    assert recovered.read_noise_e == pytest.approx(sensor.read_noise_e, rel=0.03)
    assert recovered.row_noise_e == pytest.approx(sensor.row_noise_e, rel=0.10)
    assert (recovered.bits, recovered.pedestal_dn, recovered.cfa) == (14, 512, "RGGB")
    frames = tmp_path / "frames"
    _ok(capsys, ["render", "macbeth_26", "--preset", str(out / "preset.toml"), "--iso", "3200", "--illuminant",
                 "D65", "--intensity", "0.1", "--size", "64x48", "--out", str(frames), "-q"])
    assert json.loads((frames / "macbeth_26_D65_F0.1.json").read_text())["iso"] == 3200


@pytest.mark.slow
def test_a_three_chip_linear_raw_file_gives_three_planes_and_no_cfa(tmp_path, capsys):
    sensor = SensorParams(bits=12, conversion_gain_v_per_e=1e-4, analog_gain_dn_per_v=1e4, dark_current=False,
                          read_noise_e=2.5, full_well_e=8000.0, row_noise_e=0.5, pedestal_dn=64)
    darks, flat_files = shoot(sensor, tmp_path, 3, shape=(128, 192), darks=4, levels=(0.05, 0.2, 0.5))
    out = tmp_path / "out"
    captured = _ok(capsys, ["calibrate", "--dark", *darks, "--flat", *flat_files, "--out", str(out)])
    assert "calibrated camsim calibrate test at ISO 100" in captured.out
    assert "only 3 flat levels" in captured.err  # a warning, not an error
    preset = tomllib.loads((out / "preset.toml").read_text(encoding="utf-8"))
    assert "cfa" not in preset["preset"] and preset["preset"]["bits"] == 12 and preset["preset"]["pedestal_dn"] == 64
    assert preset["preset"]["read_noise_model"] == "gaussian"
    assert preset["iso"][0]["k_dn_per_e"] == pytest.approx(1.0, rel=0.03)
    assert preset["iso"][0]["gaussian_sigma_dn"] == pytest.approx(2.5, rel=0.03)
    record = json.loads((out / "calibration.json").read_text(encoding="utf-8"))
    assert list(record["planes"]) == ["R", "G", "B"]


# --- the estimators against closed forms and synthetic numbers of known law ---------------------------------------


def test_plain_ppcc_is_scipys_ppcc_max():
    """Without thinning, the fit maximises the same correlation as ``scipy.stats.ppcc_max`` (Filliben's positions
    and the Tukey-λ ppf): the two agree to the optimisers' tolerance."""
    x = stats.tukeylambda.rvs(-0.1, size=4000, random_state=np.random.default_rng(1))
    ours = tukey.fit_tukey(x, keep=x.size).lam
    theirs = stats.ppcc_max(x, brack=(-0.3, 0.3), dist="tukeylambda")
    assert ours == pytest.approx(theirs, abs=2e-4)
    r = tukey.ppcc(x, [ours], keep=x.size)[0]
    (osm, osr), (slope, intercept, r_scipy) = stats.probplot(x, sparams=(ours,), dist="tukeylambda")
    assert r == pytest.approx(r_scipy, abs=1e-12)


@pytest.mark.parametrize("lam", [-0.2, 0.0, 0.14, 0.3])
def test_plain_ppcc_recovers_lambda_and_scale_of_tukey_samples(lam):
    rng = np.random.default_rng(7)
    x = 2.5 * stats.tukeylambda.rvs(lam, size=400_000, random_state=rng)
    fit = tukey.fit_tukey(x)
    assert fit.lam == pytest.approx(lam, abs=0.015)
    assert fit.scale_dn == pytest.approx(2.5, rel=0.02)
    assert fit.std_dn == pytest.approx(np.std(x), rel=0.02)


def test_the_blurred_quantiles_of_a_uniform_are_the_closed_forms():
    """λ = 1 is the uniform law on (−1, 1): plus a box of width w its law is a trapezoid, plus a Gaussian its CDF is
    ½ s (ψ((x + 1)/s) − ψ((x − 1)/s)), ψ(z) = z Φ(z) + φ(z). Their quantiles by root finding. (The uniform's edges
    are kinks of F_T, which the quadrature over the blur resolves to ~1e-3, and a box alone, with no Gaussian, is
    summed on nodes, so its bounded support's last 1e-6 is not resolved; the Tukey laws of λ ≤ ½ are smooth, and
    there halving the steps moves the quantiles by < 1e-5 relative.)"""
    p = np.array([1e-6, 1e-3, 0.02, 0.2, 0.5, 0.7, 0.99])

    def psi(z):
        return z * special.ndtr(z) + np.exp(-z * z / 2) / np.sqrt(2 * np.pi)

    s = 0.3
    gauss_cdf = lambda x: 0.5 * s * (psi((x + 1) / s) - psi((x - 1) / s))  # noqa: E731
    w = 0.6
    trapezoid_cdf = lambda x: np.clip(  # noqa: E731
        (psi_box(x + 1, w) - psi_box(x - 1, w)) / 2, 0, 1)
    for cdf, args, probabilities in ((gauss_cdf, (0.0, s), p), (trapezoid_cdf, (w, 0.0), p[1:])):
        expected = [optimize.brentq(lambda x: cdf(x) - q, -3, 3, xtol=1e-13) for q in probabilities]
        got = tukey.blurred_tukey_quantiles(1.0, probabilities, *args)
        np.testing.assert_allclose(got, expected, atol=2e-3)


def psi_box(x, w):
    """∫ of the CDF of the box of width w: the ramp's integral, for the trapezoid (box ∗ uniform) CDF."""
    h = w / 2
    return np.where(x <= -h, 0.0, np.where(x >= h, x, (x + h) ** 2 / (2 * w)))


def test_the_blurred_quantiles_against_monte_carlo():
    rng = np.random.default_rng(3)
    lam, w, s, n = -0.2, 0.5, 0.4, 2_000_000
    x = tukey_lambda(rng, np.empty(n), lam, np.sqrt(tukey_lambda_variance(lam))) + rng.uniform(-w / 2, w / 2, n) \
        + rng.normal(0, s, n)
    p = np.array([1e-3, 0.01, 0.1, 0.3, 0.6, 0.95])
    got = tukey.blurred_tukey_quantiles(lam, p, w, s)
    density = stats.gaussian_kde(x[:20000])(np.quantile(x, p))
    se = np.sqrt(p * (1 - p) / n) / density  # the sample quantile's standard error
    assert np.all(np.abs(got - np.quantile(x, p)) < 5 * se + 1e-3)


def test_the_matched_ppcc_removes_the_bias_of_mean_subtraction_and_quantisation():
    """Quantised dark frames (σ = 1.5 DN, each pixel its own level), residuals about each pixel's mean over n = 8
    frames less their row means: the plain PPCC is pulled towards 0.14 by ~0.035, the matched one is not."""
    rng = np.random.default_rng(4)
    lam, sigma, n, h, w = -0.15, 1.5, 8, 256, 512
    levels = rng.uniform(0, 1, (1, h, w)) + rng.normal(0, 3, (1, h, w))
    x = np.floor(tukey_lambda(rng, np.empty((n, h, w)), lam, sigma) + levels)
    r = x - x.mean(axis=0)
    r -= r.mean(axis=2, keepdims=True)
    var_y = float(np.mean(np.var(x, axis=0, ddof=1)))
    plain = tukey.fit_tukey(r)
    matched = tukey.fit_tukey(r, variance_dn2=var_y, frames=n, row_pixels=w)
    assert plain.lam - lam > 0.02
    assert matched.lam == pytest.approx(lam, abs=0.015)
    assert matched.std_dn == pytest.approx(sigma, rel=0.01)


def _integer_law_variance(sigma, level, lam=None):
    """Var(floor(X + level)) exactly, from the integer law's probabilities: differences of the normal CDF (λ None)
    or of the Tukey-λ CDF, X of standard deviation σ."""
    codes = np.arange(-600, 601)
    if lam is None:
        cdf = special.ndtr((codes - level) / sigma)
    else:
        cdf = stats.tukeylambda.cdf((codes - level) / (sigma / np.sqrt(tukey_lambda_variance(lam))), lam)
    pmf = np.diff(cdf)
    k = codes[:-1]
    mean = pmf @ k
    return pmf @ (k - mean) ** 2


@pytest.mark.parametrize("lam, sigma, worst, average", [
    (None, 0.5, (1e-3, 0.1), 2e-5),    # Gaussian at ½ DN: only the average over levels holds
    (None, 0.8, (0.0, 2e-5), 1e-10),
    (None, 1.0, (0.0, 1e-7), 1e-12),
    (-0.15, 1.0, (1e-3, 1e-2), 1e-5),  # heavy tails, narrow core: at 1 DN one level is off by up to 0.4 %
    (-0.15, 1.5, (0.0, 2e-4), 1e-6),
    (-0.15, 3.0, (0.0, 1e-5), 1e-5),
])
def test_sheppard_against_the_exact_variance_of_the_integer_law(lam, sigma, worst, average):
    """(Var(floor(X + m)) − 1/12) / σ² − 1 over 32 levels m: its largest value (one pixel level) and its mean (the
    pixels of a sensor, spread over the lattice by their DSNU and black levels)."""
    errors = np.array([dark.sheppard_read_variance_dn2(_integer_law_variance(sigma, m, lam)) / sigma**2 - 1
                       for m in np.linspace(0, 1, 32, endpoint=False)])
    assert worst[0] <= np.max(np.abs(errors)) < worst[1]
    assert abs(np.mean(errors)) < average


def _dark_stack(rng, n, h, w, sigma, row_sigma, dsnu=2.0):
    """Quantised dark frames: a black level, a fixed pattern, Gaussian pixel noise and row noise."""
    fixed = 100.0 + rng.normal(0, dsnu, (h, w))
    frames = fixed + rng.normal(0, sigma, (n, h, w)) + rng.normal(0, row_sigma, (n, h, 1)) if row_sigma else \
        fixed + rng.normal(0, sigma, (n, h, w))
    return np.floor(frames).astype(np.int64)


def _reduce(x):
    """The two passes of :func:`camsim.calibration.measure.calibrate` on one plane."""
    n, h, w = x.shape
    mean, var = dark.pixel_moments(x.sum(axis=0), (x * x).sum(axis=0), n)
    r = x - mean
    rows = r.mean(axis=2)
    s = r - rows[..., None]
    return mean, var, rows, float(np.sum(s * s)), s.size


@pytest.mark.parametrize("row_sigma", [0.0, 0.3, 1.0])
def test_read_row_and_dsnu_estimators_on_synthetic_darks(row_sigma):
    rng = np.random.default_rng(5)
    n, h, w, sigma, dsnu = 8, 512, 256, 2.0, 2.0
    x = _dark_stack(rng, n, h, w, sigma, row_sigma, dsnu)
    mean, var, rows, sq, count = _reduce(x)
    read, var_y = dark.read_noise(sq, count, n, w)
    assert abs(read.value - sigma) < 4 * read.standard_error
    row = dark.row_noise(rows, var_y, w)
    if row_sigma:
        assert abs(row.value - row_sigma) < 4 * row.standard_error
    else:
        assert row.value < 4 * row.standard_error
    temporal = dark.temporal_variance(var, n)
    assert abs(temporal.value - (sigma**2 + 1 / 12 + row_sigma**2)) < 4 * temporal.standard_error
    fixed = dark.dsnu(mean, temporal, n, row.value**2)
    assert fixed.value == pytest.approx(dsnu, rel=0.02)  # the drawn map's σ is within 0.3 % of 2
    black = dark.black_level(mean, var, n, row.value**2)
    assert abs(black.value - 99.5) < 5 * black.standard_error + 0.002  # E floor(X) = level − ½


def test_photon_transfer_on_synthetic_poisson_gaussian_pairs():
    """Pairs of K·Poisson(μ/K) + read noise, quantised, with a fixed pattern: the fit recovers K within its
    interval, with R² ≈ 1 and an intercept ≈ 0; the variance peak marks saturation."""
    rng = np.random.default_rng(6)
    k, sigma, n_pix = 1.7, 3.0, 40_000
    gain = 1 + rng.normal(0, 0.01, n_pix)  # PRNU: cancels in A − B
    dark_frames = np.floor(20 + rng.normal(0, sigma, (4, n_pix)))
    dark_var = float(np.mean(np.var(dark_frames, axis=0, ddof=1)))
    black = float(dark_frames.mean())
    means, variances = [], []
    for mu in (200.0, 800.0, 2000.0, 4000.0, 6000.0):
        pair = [np.floor(20 + k * rng.poisson(gain * mu / k) + rng.normal(0, sigma, n_pix)) for _ in range(2)]
        m, v = ptc.pair_statistics(*pair, black)
        means.append(m)
        variances.append(v)
    used = ptc.fit_range(means, variances, 10_000.0)
    assert used.all()
    fit = ptc.fit_photon_transfer(means, variances, dark_var, n_pix, used)
    low, high = fit.k_dn_per_e.ci95
    assert low < k < high and fit.k_dn_per_e.standard_error < 0.01 * k
    assert fit.r_squared > 0.999
    assert abs(fit.intercept_dn2.value) < 4 * fit.intercept_dn2.standard_error
    # a variance that falls at the top (a full well): only the levels up to 70 % of the peak's are fitted
    assert list(ptc.fit_range([100, 1000, 3000, 5000, 6000], [90, 900, 2700, 4500, 200], 10_000.0)) == \
        [True, True, True, False, False]


def test_prnu_of_a_known_gain_map_and_a_shaded_light():
    rng = np.random.default_rng(8)
    h, w, mu = 300, 400, 5000.0
    gain = 1 + rng.normal(0, 0.01, (h, w))
    yy, xx = np.mgrid[0:h, 0:w]
    shading = 1 - 0.2 * (((xx - w / 2) / w) ** 2 + ((yy - h / 2) / h) ** 2)  # vignetting: not the sensor's
    dark_mean = 100 + rng.normal(0, 2, (h, w))
    a, b = (dark_mean + rng.poisson(gain * shading * mu) for _ in range(2))
    _, pair_var = ptc.pair_statistics(a, b, 100.0)
    got = ptc.prnu(0.5 * (a + b), dark_mean, pair_var, 0.0, 1_000_000)
    true = 100 * np.std(gain * shading) / np.mean(gain * shading)  # what it would be without the detrending
    assert got.value == pytest.approx(100 * np.std(gain), rel=0.03)
    assert true > 2 * got.value


def test_flats_pair_by_level_in_any_order():
    signal = [410.0, 100.0, 1200.0, 101.5, 405.0, 1190.0]
    names = [f"f{i}" for i in range(6)]
    assert flats.group_levels(signal, names) == [[(1, 3)], [(0, 4)], [(2, 5)]]
    assert flats.group_levels(signal + [99.0, 100.5], names + ["g", "h"])[0] == [(1, 3), (6, 7)]
    with pytest.raises(CamsimError, match=r"level of about 100.*has 3 files.*pairs"):
        flats.group_levels(signal + [99.0], names + ["g"])
    with pytest.raises(CamsimError, match="2 levels; .* at least 3"):
        flats.group_levels(signal[:2] + [101.0, 410.0], names[:4])


def test_the_estimate_record_and_the_preset_numbers():
    from camsim.calibration.outputs import _number

    assert Estimate(2.0, 0.5).ci95 == pytest.approx((2 - 0.98, 2 + 0.98), abs=1e-3)
    assert Estimate(1.0).record() == {"value": 1.0, "standard_error": None, "ci95": None}
    for value in (0.0, 3.0, 1e-7, 123456789.0, -0.035):
        text = _number(value)
        assert isinstance(tomllib.loads(f"x = {text}")["x"], float) and float(text) == pytest.approx(value, rel=1e-5)


# --- bad input: one line, exit 2, nothing written -----------------------------------------------------------------


@pytest.fixture(scope="module")
def small_set(tmp_path_factory):
    """A small valid set: 3 darks and flats at 3 levels (64 × 64 RGGB, 12-bit, synthetic numbers), plus a
    saturated flat, a dark of another size, a flat without a partner and a file that is no raw."""
    folder = tmp_path_factory.mktemp("small")
    rng = np.random.default_rng(9)
    tags = dict(pattern="RGGB", black_level_dn=64, white_level=4095, unique_camera_model="t",
                color_matrix1=np.eye(3), as_shot_neutral=[1, 1, 1])

    def write(name, level, shape=(64, 64)):
        values = np.clip(np.floor(64 + rng.poisson(level, shape) + rng.normal(0, 2, shape)), 0, 4095)
        write_dng_cfa(folder / name, values.astype(np.uint16), **tags)
        return str(folder / name)

    files = {"dark": [write(f"d{i}.dng", 0.0) for i in range(3)],
             "flat": [write(f"f{j}{i}.dng", level) for j, level in enumerate((200, 800, 2000)) for i in range(2)],
             "saturated": write("sat.dng", 5000), "small": write("small.dng", 0.0, (48, 64)),
             "extra": write("extra.dng", 3000)}
    files["copy"] = str(folder / "copy.dng")
    (folder / "copy.dng").write_bytes((folder / "d0.dng").read_bytes())
    (folder / "garbage.dng").write_bytes(b"not a raw file at all" * 10)
    files["garbage"] = str(folder / "garbage.dng")
    return files


@pytest.mark.slow
def test_the_small_set_calibrates(small_set, tmp_path, capsys):
    _ok(capsys, ["calibrate", "--dark", *small_set["dark"], "--flat", *small_set["flat"], "--out",
                 str(tmp_path / "o"), "-q"])
    assert (tmp_path / "o" / "preset.toml").exists()


@pytest.mark.parametrize("case, message", [
    ("one dark", "needs at least 2 dark frames (--dark), got 1"),
    ("mixed sizes", "mixed frames: "),
    ("unreadable", "cannot read raw file "),
    ("saturated", "is saturated: "),
    ("unpaired", "has 1 file"),
    ("two levels", "needs at least 3 pairs of flat frames"),
    ("twice", "is given twice"),
    ("copies", "do not vary from one to the next"),
])
def test_bad_input_is_one_line_exit_2_and_no_files(small_set, tmp_path, capsys, case, message):
    darks, flat_files = list(small_set["dark"]), list(small_set["flat"])
    if case == "one dark":
        darks = darks[:1]
    elif case == "mixed sizes":
        darks.append(small_set["small"])
    elif case == "unreadable":
        flat_files[3] = small_set["garbage"]
    elif case == "saturated":
        flat_files.append(small_set["saturated"])
    elif case == "unpaired":
        flat_files.append(small_set["extra"])
    elif case == "two levels":
        flat_files = flat_files[:4]
    elif case == "twice":
        darks.append(darks[0])
    elif case == "copies":
        darks = [darks[0], small_set["copy"]]
    out = tmp_path / "o"
    assert main(["calibrate", "--dark", *darks, "--flat", *flat_files, "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error: ") and message in err and err.count("\n") == 1, err
    assert not out.exists()


@pytest.mark.slow
def test_a_full_disk_at_the_last_file_leaves_no_file(small_set, tmp_path, capsys, monkeypatch):
    """The preset is written last; when it cannot be, the files written before it are removed too."""
    import errno
    import os

    from camsim.io import atomic

    real = atomic.fsync_path

    def fsync(path, *, directory=False):
        if not directory and path.name.startswith(".preset.toml."):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(path, directory=directory)

    monkeypatch.setattr(atomic, "fsync_path", fsync)
    out = tmp_path / "o"
    assert main(["calibrate", "--dark", *small_set["dark"], "--flat", *small_set["flat"], "--out", str(out),
                 "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error: cannot write ") and "No space left on device" in err
    assert err.count("\n") == 1
    assert not out.exists()


@pytest.mark.parametrize("case", ["fifo", "device", *(f"{w}x{h}" for w, h in (*HUGE_SIZES, (10000, 10001))),
                                  "three-chip 30000x30000"])
def test_a_hostile_raw_is_refused_on_one_line_before_libraw_decodes(small_set, tmp_path, capfd, case):
    """A FIFO or a device among the raws is refused, not waited on; a raw whose tags declare 10⁸ to 10¹⁰ pixels
    over a 64 × 64 frame's data is refused from its tags, before LibRaw allocates (over the pixel limit) or reads
    past its strip (under it: LibRaw would print "Unexpected end of file"); one line, LibRaw silent."""
    darks = list(small_set["dark"])
    bad = tmp_path / "bad.dng"
    if case in ("fifo", "device"):
        not_regular(bad, case)
        expect = "not a regular file"
    elif case.startswith("three-chip"):
        write_dng(tmp_path / "stack.dng", np.zeros((3, 24, 24), np.uint8), black_level_dn=16, white_level=255,
                  unique_camera_model="cam", color_matrix1=np.eye(3), as_shot_neutral=[1, 1, 1])
        bad.write_bytes(with_tiff_size((tmp_path / "stack.dng").read_bytes(), 30000, 30000))
        expect = "over camsim's limit"
    else:
        width, height = map(int, case.split("x"))
        bad.write_bytes(with_tiff_size(open(darks[1], "rb").read(), width, height))
        expect = "over camsim's limit" if width * height > 200_000_000 else "uncompressed pixel data holds"
    darks[1] = str(bad)
    out = tmp_path / "o"
    capfd.readouterr()
    with no_hang(f"calibrate with a {case} raw"):
        status = main(["calibrate", "--dark", *darks, "--flat", *small_set["flat"], "--out", str(out), "-q"])
    captured = capfd.readouterr()
    assert status == 2 and captured.out == ""
    line = one_error_line(captured.err)
    assert str(bad) in line and expect in line, line
    assert not out.exists()
