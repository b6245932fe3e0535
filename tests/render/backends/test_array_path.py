"""The array path (camsim.render.backends.array_path) against the exact law, on every namespace it runs on.

Each test runs with numpy as the namespace (always: the GPU's code, run on the CPU in CI) and with CuPy on an
NVIDIA GPU (skipped cleanly where CuPy or a GPU is missing). The samplers are checked against the exact laws —
Poisson's pmf, the digital number's pmf (camsim.sensor.dn_law.dn_pmf), scipy's Tukey λ — by χ² or KS tests and by their
moments; the frames against the CPU's block renderer in distribution; and the same seed on the same device
gives the same bits.
"""

import numpy as np
import pytest
from scipy import stats

from camsim.core.errors import CamsimError
from camsim.core.xp import to_host
from camsim.render.backends import device_generator
from camsim.render.backends.array_path import render_frame_xp
from camsim.render.frame import clean_dn
from camsim.sensor.dn_law import dn_pmf
from camsim.sensor.expected import expected_signal
from camsim.sensor.kernels import poisson, tukey_lambda_variance
from camsim.sensor.params import PRESETS, SensorParams
from tests.support.helpers import chi2_p_counts, cupy_or_skip, patch_pixels, small_scene

TABLE1 = PRESETS["paper-table1"]
#: χ² and KS tests must not reject at this level (many tests run: a false alarm stays rare).
P_MIN = 1e-4


@pytest.fixture(params=["numpy", "cuda"], scope="module")
def xp(request):
    """numpy, or CuPy where it sees a GPU (else the test is skipped)."""
    return np if request.param == "numpy" else cupy_or_skip()


def chi2_p(values, first: int, pmf: np.ndarray) -> float:
    """p of Pearson's χ² test of integer ``values`` against P(first + j) = pmf[j], the bins pooled until each expects
    at least 5 (:func:`tests.support.helpers.chi2_p_counts`)."""
    values = np.asarray(values).ravel().astype(np.int64)
    n = values.size
    inside = (values >= first) & (values < first + pmf.size)
    assert np.all(inside), f"values outside the law's window: {np.unique(values[~inside])[:10]}"
    return chi2_p_counts(np.bincount(values - first, minlength=pmf.size).astype(float), pmf * n)


def poisson_pmf_window(lam: float):
    lo, hi = max(0, int(lam - 13 * np.sqrt(lam) - 20)), int(lam + 13 * np.sqrt(lam) + 20)
    k = np.arange(lo, hi + 1)
    return lo, stats.poisson.pmf(k, lam)


@pytest.mark.parametrize("lam", [0.5, 3.0, 30.0, 500.0, 3000.0, 10000.0])
def test_poisson_draws_follow_the_exact_pmf(xp, lam):
    """The stage's Poisson sampler (camsim.sensor.kernels.poisson, the device's generator) against Poisson's pmf: χ²,
    the mean and the variance (the issue's check, which torch.poisson fails on CUDA at λ = 3000)."""
    n = 400_000
    draws = to_host(poisson(device_generator(xp, 11), xp.full(n, lam)))
    first, pmf = poisson_pmf_window(lam)
    assert chi2_p(draws, first, pmf) > P_MIN
    z_mean = (draws.mean() - lam) / np.sqrt(lam / n)
    z_var = (draws.var(ddof=1) - lam) / np.sqrt((lam + 2 * lam * lam) / n)  # Var s² = (μ₄ − σ⁴)/n, μ₄ = λ + 3λ²
    assert abs(z_mean) < 5 and abs(z_var) < 5, (z_mean, z_var)


def _uniform_expected(sensor, means_e):
    """An ExpectedSignal of one spectrum whose three channels collect ``means_e`` signal electrons."""
    qe = np.asarray(means_e, dtype=float).reshape(3, 1)
    return expected_signal(np.array([[1.0]]), qe, sensor, 1.0, "pixel")


@pytest.mark.parametrize("sensor, means", [
    (TABLE1, (0.0, 20.0, 300.0)),                       # the dark level, low light, mid-grey (8 bits, k = 0.0283)
    (TABLE1, (8600.0, 8900.0, 9500.0)),                 # at the full well: the clip's mass and the ADC's top
    (SensorParams(bits=12, conversion_gain_v_per_e=4e-5, analog_gain_dn_per_v=1e4, read_noise_e=3.0,
                  full_well_e=10000.0, dark_current_e_per_s=(25.0, 25.0, 25.0)), (2.0, 150.0, 9990.0)),
    (SensorParams(bits=14, conversion_gain_v_per_e=1e-4, analog_gain_dn_per_v=2e4, read_noise_e=0.0,
                  full_well_e=5000.0, dark_current=False), (0.7, 40.0, 4990.0)),  # no read noise: the lattice
])
def test_digital_numbers_follow_the_exact_law(xp, sensor, means):
    """A uniform frame's digital numbers per channel against camsim.sensor.dn_law.dn_pmf (Poisson charge with the dark
    current, full well, read noise, gain, floor, ADC clip): χ² and the mean."""
    expected = _uniform_expected(sensor, means)
    labels = np.zeros((300, 400), np.uint8)
    frame = render_frame_xp(xp, labels, expected, sensor, rng=3)
    digital = to_host(frame.digital_dn)
    read = sensor.read_noise_e if sensor.read_noise else 0.0
    for c in range(3):
        lam = float(expected.signal_e[0, c] + expected.dark_e[c])
        law = dn_pmf(lam, sensor.dn_per_electron, read, sensor.full_well_e, sensor.bits, sensor.pedestal_dn)
        values = digital[c].ravel()
        assert chi2_p(values, law.first, law.pmf) > P_MIN, f"channel {c}, λ = {lam}"
        sd = np.sqrt(max(law.pmf @ (law.levels - law.mean) ** 2, 1e-12) / values.size)
        assert abs(values.mean() - law.mean) < 5 * sd + 1e-12, (c, values.mean(), law.mean)


def test_tukey_read_noise_follows_its_law(xp):
    """Read noise alone (no charge, no ADC, k = 1): Tukey λ of σ = read_noise_e, KS against scipy's law."""
    lam, sigma = -0.1, 3.0
    sensor = SensorParams(read_noise_model="tukey-lambda", tukey_lambda=lam, read_noise_e=sigma,
                          conversion_gain_v_per_e=1.0, analog_gain_dn_per_v=1.0, photon_noise=False,
                          dark_current=False, saturation=False, quantisation=False)
    frame = render_frame_xp(xp, np.zeros((400, 500), np.uint8), _uniform_expected(sensor, (0.0, 0.0, 0.0)),
                            sensor, rng=4)
    values = to_host(frame.noisy_dn).ravel().astype(np.float64)
    scale = sigma / np.sqrt(tukey_lambda_variance(lam))
    assert stats.kstest(values, stats.tukeylambda(lam, scale=scale).cdf).pvalue > P_MIN
    assert abs(values.std() / sigma - 1) < 0.01
    assert frame.digital_dn is None


def test_row_noise_is_one_offset_per_row_and_plane(xp):
    """Row noise σ_row shared by a row's pixels: the variance of the row means is σ_row² + σ_read² / W."""
    sensor = SensorParams(row_noise_e=2.0, read_noise_e=1.0, conversion_gain_v_per_e=1.0, analog_gain_dn_per_v=1.0,
                          photon_noise=False, dark_current=False, saturation=False, quantisation=False)
    frame = render_frame_xp(xp, np.zeros((2000, 200), np.uint8), _uniform_expected(sensor, (0.0, 0.0, 0.0)),
                            sensor, rng=8)
    rows = to_host(frame.noisy_dn).mean(axis=2)  # (3, 2000)
    target = 4.0 + 1.0 / 200
    for c in range(3):
        assert abs(rows[c].var(ddof=1) / target - 1) < 5 * np.sqrt(2 / 1999)
    assert abs(np.corrcoef(rows[0], rows[1])[0, 1]) < 0.12  # each plane its own offsets


SCENE = small_scene(width=240, height=160)


@pytest.fixture(scope="module")
def lit():
    from camsim.render.pipeline import light_scene

    return light_scene(SCENE, "D65")


@pytest.mark.parametrize("overrides, factor", [
    ({}, 0.3),
    ({"dsnu_e": 3.0, "prnu_percent": 2.0, "dsnu_dark_current_percent": 30.0, "row_noise_e": 1.5,
      "read_noise_model": "tukey-lambda"}, 0.2),
    ({"cfa": "GRBG", "bits": 12, "pedestal_dn": 5, "dsnu_e": 1.0, "prnu_percent": 1.0}, 0.5),
    ({"photon_noise": False, "dsnu_dark_current_percent": 10.0}, 0.1),
    ({"dsnu_e": 2.0, "prnu_percent": 1.0}, 1.3),          # saturating patches
])
def test_array_path_agrees_with_the_cpu_in_distribution(xp, lit, overrides, factor):
    """Per patch and plane, the array path's values before quantisation against the CPU block renderer's (the same
    sensor, maps and F; independent noise): two-sample KS, and the means within their standard errors."""
    from camsim.render.pipeline import make_frame

    sensor = SCENE.sensor.__class__(**{**TABLE1.__dict__, **overrides})
    expected = lit.expected(sensor, factor, "pixel")
    device = to_host(render_frame_xp(xp, lit.labels, expected, sensor, rng=21).noisy_dn)
    cpu = make_frame(lit, sensor, factor, rng=22, workers=1).noisy_dn
    worst = 1.0
    for rect in lit.radiance.patch_rects:
        a, b = patch_pixels(device, rect), patch_pixels(cpu, rect)
        for p in range(a.shape[0]):
            if np.all(a[p] == a[p][0]) and np.all(b[p] == a[p][0]):  # a saturated patch without read noise
                continue
            worst = min(worst, stats.ks_2samp(a[p], b[p]).pvalue)
            se = np.sqrt((a[p].var() + b[p].var()) / a.shape[1]) + 1e-9
            assert abs(a[p].mean() - b[p].mean()) < 5 * se
    assert worst > P_MIN / 10  # ~30 patch-planes per case


def test_same_seed_same_frame_other_seed_other_frame(xp, lit):
    sensor = SensorParams(dsnu_e=1.0, row_noise_e=0.5)
    expected = lit.expected(sensor, 0.5, "pixel")
    one = render_frame_xp(xp, lit.labels, expected, sensor, rng=np.random.SeedSequence(5))
    two = render_frame_xp(xp, lit.labels, expected, sensor, rng=5)
    other = render_frame_xp(xp, lit.labels, expected, sensor, rng=6)
    assert np.array_equal(to_host(one.noisy_dn), to_host(two.noisy_dn))
    assert np.array_equal(to_host(one.digital_dn), to_host(two.digital_dn))
    assert not np.array_equal(to_host(one.digital_dn), to_host(other.digital_dn))


def test_clean_layer_on_the_device_is_the_cpu_one(xp, lit):
    """camsim.render.frame.clean_dn with the labels and maps on the device gives the host's clean layer."""
    from camsim.render.backends.array_path import device_maps
    from camsim.sensor.fixed_pattern import fixed_pattern

    sensor = SensorParams(dsnu_e=3.0, prnu_percent=2.0, dsnu_dark_current_percent=20.0)
    expected = lit.expected(sensor, 1.2, "pixel")
    host = clean_dn(lit.labels, expected, sensor, fixed_pattern(sensor, lit.labels.shape))
    device = clean_dn(xp.asarray(lit.labels), expected, sensor, device_maps(xp, sensor, lit.labels.shape))
    np.testing.assert_allclose(to_host(device), host, rtol=1e-6, atol=1e-6)


def test_device_refuses_what_it_does_not_draw(lit):
    expected = lit.expected(TABLE1, 0.5, "paper")
    with pytest.raises(CamsimError, match="paper statistics render on the CPU only"):
        render_frame_xp(np, lit.labels, expected, TABLE1, rng=1, statistics="paper")
    with pytest.raises(CamsimError, match="spectral .* renders on the CPU only"):
        render_frame_xp(np, lit.labels, lit.expected(TABLE1, 0.5, "pixel"), TABLE1, rng=1, method="spectral")
    with pytest.raises(CamsimError, match="even frame size"):
        render_frame_xp(np, np.zeros((5, 8), np.uint8), lit.expected(TABLE1, 0.5, "pixel"),
                        SensorParams(cfa="RGGB"), rng=1)


def test_make_frame_on_a_device_returns_a_host_frame(lit):
    """make_frame(device="numpy") runs the device code and hands back a host Frame the writers take, the same for
    the same seed; gaussian and auto are drawn exactly there."""
    from camsim.render.pipeline import make_frame

    a = make_frame(lit, TABLE1, 0.4, rng=9, device="numpy", method="auto")
    b = make_frame(lit, TABLE1, 0.4, rng=9, device="numpy")
    assert isinstance(a.noisy_dn, np.ndarray) and a.digital_dn.dtype == np.uint8 and a.plan is None
    assert np.array_equal(a.digital_dn, b.digital_dn)
    assert a.clean_dn().shape == (3,) + lit.labels.shape
