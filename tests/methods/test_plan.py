"""Sampling methods: right moments where valid, and pinned-down behaviour where each one breaks (MODEL.md §5)."""

import numpy as np
import pytest
from scipy import stats

from camsim.methods.plan import (
    DEFAULT_TOLERANCE,
    EXACT,
    GAUSSIAN,
    SATURATED,
    TABLE,
    ks_gaussian,
    plan_methods,
    predicted_ks,
)
from camsim.sensor.expected import expected_signal
from camsim.sensor.params import PRESETS, preset
from tests.support.helpers import ROOT, WHITE, patch_pixels, render, small_scene
from tests.support.theory import assert_mean_var, digital_pmf, pmf_moments

TABLE1 = PRESETS["paper-table1"]
IDEAL = PRESETS["ideal"]


@pytest.fixture(scope="module")
def scene():
    return small_scene()


@pytest.mark.parametrize("method", ["gaussian", "auto"])
@pytest.mark.parametrize("factor", [1.0, 0.05])
def test_fast_methods_have_the_model_moments_where_valid(scene, method, factor):
    frame, radiance = render(scene, TABLE1, factor=factor, method=method, seed=5)
    k = TABLE1.dn_per_electron
    ex = frame.expected
    for index in (WHITE, 14, 23):
        noisy = patch_pixels(frame.noisy_dn, radiance.patch_rects[index])
        digital = patch_pixels(frame.digital_dn, radiance.patch_rects[index])
        for c in range(3):
            lam = ex.signal_e[index, c] + ex.dark_e[c]
            assert frame.plan.kind[index, c] == GAUSSIAN  # Table I: read noise keeps every KS below 0.0065
            assert_mean_var(noisy[c], k * lam, k * k * (lam + 16.0), what=f"{method} noisy ch{c}")
            mean, var = pmf_moments(digital_pmf(lam, k, 4.0, 9000.0, 8))
            assert_mean_var(digital[c], mean, var, what=f"{method} digital ch{c}")


@pytest.mark.parametrize("lam", [0.01, 0.1, 1.0, 3.0, 10.0])
def test_gaussian_breaks_at_low_counts(lam):
    """Without read noise, N(λ, λ) against Poisson(λ): negative values, no zeros, no skew — as predicted."""
    expected = expected_signal(np.array([[1.0]]), np.array([[lam], [lam], [lam]]), IDEAL, 1.0, "pixel")
    labels = np.zeros((300, 400), np.uint8)
    from camsim.render.frame import render_frame

    gauss = render_frame(labels, expected, IDEAL, method="gaussian", rng=1).noisy_dn[0].ravel().astype(float)
    exact = render_frame(labels, expected, IDEAL, method="poisson", rng=1).noisy_dn[0].ravel().astype(float)
    n = gauss.size
    p_neg = stats.norm.cdf(-np.sqrt(lam))  # P(N(λ, λ) < 0)
    assert abs(np.mean(gauss < 0) - p_neg) < 5 * np.sqrt(p_neg * (1 - p_neg) / n) + 1e-9
    assert np.all(exact >= 0)
    p0 = np.exp(-lam)
    assert np.mean(gauss == 0) == 0.0 and abs(np.mean(exact == 0) - p0) < 5 * np.sqrt(p0 * (1 - p0) / n)
    skew_se = np.sqrt(6 / n)
    assert abs(stats.skew(gauss)) < 5 * skew_se
    assert abs(stats.skew(exact) - 1 / np.sqrt(lam)) < 5 * skew_se * max(1.0, 1 / lam)
    # both keep the mean and the variance
    for x in (gauss, exact):
        assert_mean_var(x, lam, lam, kurtosis_excess=1 / lam, what=f"λ={lam}")
    # and auto never takes the Gaussian there
    plan = plan_methods(expected, IDEAL, "pixel", "auto")
    assert np.all(np.isin(plan.kind, (EXACT, TABLE))) and plan.predicted_ks[0, 0] > DEFAULT_TOLERANCE  # exact kinds


@pytest.mark.slow
def test_auto_never_picks_the_gaussian_outside_its_valid_range():
    rng = np.random.default_rng(0)
    for _ in range(40):
        read = float(rng.choice([0.0, 0.5, 2.0, 4.0]))
        sensor = preset("paper-table1", read_noise_e=read, full_well_e=float(rng.uniform(500, 20000)),
                        dark_current=bool(rng.integers(2)))
        signal = 10 ** rng.uniform(-2, 4.5, size=(8, 3))
        expected = expected_signal(signal, np.eye(3), sensor, 1.0, "pixel")  # g = S per "bin", Qe = identity
        tolerance = float(rng.choice([0.002, 0.005, 0.01, 0.03]))
        plan = plan_methods(expected, sensor, "pixel", "auto", tolerance)
        lam = expected.signal_e + expected.dark_e
        sd = np.sqrt(expected.total_var_e2)
        for (i, c), kind in np.ndenumerate(plan.kind):
            if kind == GAUSSIAN:
                assert ks_gaussian(lam[i, c], read) <= tolerance + 1e-12
                assert lam[i, c] + 6 * sd[i, c] <= sensor.full_well_e
            elif kind == SATURATED:
                assert lam[i, c] - 6 * sd[i, c] >= sensor.full_well_e


def test_predicted_ks_is_conservative_between_grid_points():
    for sigma in (0.0, 4.0):
        lam = np.geomspace(0.02, 5e4, 300)
        exact = np.array([ks_gaussian(v, sigma) for v in lam])
        assert np.all(predicted_ks(lam, sigma) >= exact - 1e-9)


def test_auto_samples_match_the_exact_law_within_tolerance(scene):
    """Empirical two-sample KS between auto and poisson frames, on the values before quantisation."""
    sensor = TABLE1.with_stages(quantisation=False)
    auto, radiance = render(scene, sensor, factor=0.01, method="auto", seed=1)
    exact, _ = render(scene, sensor, factor=0.01, method="poisson", seed=2)
    for index in (WHITE, 14, 23):
        for c in range(3):
            a = patch_pixels(auto.noisy_dn, radiance.patch_rects[index])[c]
            b = patch_pixels(exact.noisy_dn, radiance.patch_rects[index])[c]
            d = stats.ks_2samp(a, b).statistic
            noise = 1.63 * np.sqrt(2 / a.size)  # the 1 % critical value of the two-sample test
            assert d <= auto.plan.predicted_ks[index, c] + noise


def test_everything_saturates(scene):
    frame, radiance = render(scene, TABLE1, factor=1000.0, method="auto", seed=3)
    assert np.all(frame.plan.kind[:24] == SATURATED)
    white = patch_pixels(frame.digital_dn, radiance.patch_rects[WHITE])
    assert set(np.unique(white)) <= {254, 255}
    noisy = patch_pixels(frame.noisy_dn, radiance.patch_rects[WHITE])
    k = TABLE1.dn_per_electron
    assert_mean_var(noisy[1], k * 9000.0, k * k * 16.0, what="saturated")


def test_paper_statistics_beyond_numpys_poisson_range(scene):
    """F = 1e4 puts ~1e20 photons per m²·sr in a bin: the per-bin draws fall back to a rounded normal."""
    sc = scene.replace(width=120, height=80)
    frame, radiance = render(sc, IDEAL, factor=1e4, statistics="paper", method="spectral", seed=1)
    assert np.all(np.isfinite(frame.noisy_dn))
    x = patch_pixels(frame.noisy_dn, radiance.patch_rects[WHITE], border=1)
    np.testing.assert_allclose(x.mean(axis=1), frame.expected.signal_e[WHITE], rtol=1e-5)


def test_spectral_method_with_bins_of_zero_radiance(scene):
    """A reflectance that is zero below 500 nm and a black patch: zero-mean bins draw zeros, no NaN."""
    grid = scene.grid
    cube = np.zeros((40, 60, grid.size))
    cube[:, :30, grid.wavelengths_nm >= 500] = 0.5  # left half: half-grey above 500 nm only; right: black
    from camsim.light.photons import photon_radiance, scale_to_luminance
    from camsim.light.spectra import cmfs_on_grid, illuminant_spd
    from camsim.render.pipeline import lit_scene, make_frame
    from camsim.scene.radiance import SceneRadiance
    from camsim.sensor.camera import load_camera

    white = scale_to_luminance(illuminant_spd("D65", grid), cmfs_on_grid(grid)[1], grid.step_nm, 100.0)
    labels = np.zeros((40, 60), np.uint8)
    labels[:, 30:] = 1
    spectra = np.stack([cube[0, 0], cube[0, -1]]) * white
    radiance = SceneRadiance(labels, spectra, white, [], [], "test")
    camera = load_camera("Nikon 5100 (NPL)", grid)
    sensor = IDEAL
    for statistics in ("pixel", "paper"):
        factor = 0.01 if statistics == "pixel" else 1e-12
        frame = make_frame(lit_scene(radiance, camera, scene.scale, grid), sensor, factor, statistics=statistics,
                           method="spectral", rng=3)
        expected = frame.expected
        assert np.all(np.isfinite(frame.noisy_dn))
        assert np.all(frame.noisy_dn[:, :, 30:] == 0)  # black: exactly no electron
        left = frame.noisy_dn[:, :, :30].reshape(3, -1).astype(float)
        for c in range(3):
            s, v = expected.signal_e[0, c], expected.signal_var_e2[0, c]
            assert_mean_var(left[c], s, v, k=5.5, what=f"{statistics} ch{c}")
    assert photon_radiance(spectra, grid.wavelengths_nm, grid.step_nm)[0, 0] == 0.0


def test_quantisation_that_collapses_a_patch(scene, tmp_path):
    """A gain of 6e-4 DN/e⁻ (1 DN ≈ 1700 e⁻, noise ≤ 0.05 DN) maps most patches to one number, named as such."""
    from camsim.analysis.analyze import analyse_paths
    from camsim.analysis.patches import AnalysisSettings
    from camsim.render.run import render_scene

    sc = scene.replace(intensity_factors=(1.0,), width=240, height=160).with_sensor(analog_gain_dn_per_v=3.0)
    render_scene(sc, tmp_path, progress=False)
    result = analyse_paths([tmp_path], AnalysisSettings(), progress=False)[0]
    sensor = sc.sensor
    k = sensor.dn_per_electron
    checked = {"constant": 0, "all-zero": 0}
    for patch, measured in zip(json_patches(tmp_path), result["patches"]):
        lam = np.add(patch["signal_e"], patch["dark_e"])
        mean, sd = k * lam, k * np.sqrt(lam + 16.0)
        margin = np.minimum(mean - np.floor(mean), np.ceil(mean) - mean)
        if np.any(margin < 6 * sd):
            continue  # too close to a step: both numbers can occur
        if np.all(np.floor(mean) == 0):  # every channel reads 0: X + Y + Z = 0, no chromaticity at all
            assert measured["ellipse_status"] == "too-few-samples" and measured["n_xy_valid"] == 0
            assert measured["n_xy_undefined"] == measured["channels"][0]["n_pixels"]
            checked["all-zero"] += 1
        else:
            assert measured["ellipse_status"] == "constant" and measured["n_distinct_values"] == 1
            checked["constant"] += 1
        assert all(ch["constant"] and ch["snr_status"] == "constant" for ch in measured["channels"])
    assert checked["constant"] >= 5 and checked["all-zero"] >= 1


def json_patches(folder):
    """The patches of the one frame's sidecar in ``folder``."""
    import json

    sidecar = next(p for p in folder.glob("*.json") if p.name != "manifest.json")
    return json.loads(sidecar.read_text())["patches"]


def test_near_singular_camera_is_a_clear_error(tmp_path, capsys):
    from camsim.cli import main

    wl = np.arange(380, 781, 10)
    g = np.exp(-0.5 * ((wl - 540) / 40.0) ** 2)
    b = np.exp(-0.5 * ((wl - 450) / 30.0) ** 2)
    csv = tmp_path / "twin.csv"
    csv.write_text("wavelength_nm,R,G,B\n" + "\n".join(f"{w},{x:.6f},{x:.6f},{y:.6f}" for w, x, y in
                                                         zip(wl, g, b)) + "\n")
    out = tmp_path / "f"
    assert main(["render", str(ROOT / "scenes" / "macbeth_26.toml"), "--camera", str(csv), "--illuminant", "D65",
                 "--intensity", "1", "--size", "120x80", "--out", str(out), "-q"]) == 0
    assert main(["analyze", str(out), "--out", str(tmp_path / "a"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "singular" in err and "Traceback" not in err


@pytest.mark.parametrize("method", ["poisson", "spectral", "gaussian", "auto"])
def test_output_does_not_depend_on_the_thread_count(scene, method, monkeypatch):
    import camsim.render.frame as render_module

    monkeypatch.setattr(render_module, "BLOCK_PIXELS", 2048)
    from camsim.render.frame import render_frame

    first, _ = render(scene.replace(width=160, height=120), TABLE1, factor=0.1, method=method, seed=9)
    for workers in (1, 2, 3):
        again = render_frame(first.labels, first.expected, TABLE1, method=method, rng=9, workers=workers)
        np.testing.assert_array_equal(again.noisy_dn, first.noisy_dn)
        np.testing.assert_array_equal(again.digital_dn, first.digital_dn)


def test_the_tolerance_carries_to_the_digital_numbers_but_not_to_their_total_variation():
    """What auto's tolerance promises: the KS distance ε of a pixel value's law before quantisation bounds that of
    its digital number (floor and clip are monotone) — checked against closed forms: the Gaussian path's DN law
    from Φ at the level edges, the exact one from camsim.sensor.dn_law — but not the total variation of the DN pmf."""
    from camsim.sensor.dn_law import dn_pmf

    def dn_distances(lam, k, read, full_well, bits):
        exact = np.cumsum(dn_pmf(lam, k, read, full_well, bits).dense(2**bits))
        gauss = stats.norm.cdf(((np.arange(2**bits) + 1) / k - lam) / np.sqrt(lam + read**2))
        gauss[-1] = 1.0
        tv = 0.5 * np.sum(np.abs(np.diff(exact, prepend=0.0) - np.diff(gauss, prepend=0.0)))
        return np.max(np.abs(exact - gauss)), tv

    k, read = TABLE1.dn_per_electron, TABLE1.read_noise_e
    for lam in (5.0, 20.0, 32.0, 100.0, 230.0, 1000.0, 5000.0):
        ks_dn, _ = dn_distances(lam, k, read, TABLE1.full_well_e, 8)
        assert ks_dn <= ks_gaussian(lam, read) + 1e-12, lam
    # 1 DN per electron and 1 e⁻ of read noise: auto takes the Gaussian at 50 e⁻ (KS 0.0093), whose DN pmf is
    # 0.017 from the exact one in total variation; TV ≈ 1.9 KS at every mean here
    for lam in (50.0, 200.0, 1000.0):
        ks_dn, tv = dn_distances(lam, 1.0, 1.0, None, 12)
        assert ks_dn <= ks_gaussian(lam, 1.0) + 1e-12 and tv >= 1.8 * ks_dn, (lam, ks_dn, tv)
    assert predicted_ks(np.array([50.0]), 1.0)[0] <= DEFAULT_TOLERANCE < dn_distances(50.0, 1.0, 1.0, None, 12)[1]
