"""Per-stage and whole-chain statistics of rendered frames against the model's closed forms (MODEL.md §3–4).

Each flat patch of n pixels is n independent trials; sample means and variances must lie within 5 standard
errors of the model's values.
"""

import numpy as np
import pytest
from scipy import stats

from camsim.sensor.params import PRESETS, preset
from tests.support.helpers import WHITE, patch_pixels, render, small_scene
from tests.support.theory import anchored_signal_e, assert_mean_var, digital_pmf, pmf_moments

TABLE1 = PRESETS["paper-table1"]
IDEAL = PRESETS["ideal"]
PATCHES = {"white": WHITE, "black": 23, "red": 14, "blue": 12}


@pytest.fixture(scope="module")
def scene():
    return small_scene()


@pytest.mark.parametrize("factor", [1.0, 0.01])
def test_whole_chain_pixel_statistics_matches_exact_digital_distribution(scene, factor):
    frame, radiance = render(scene, TABLE1, factor=factor, seed=11)
    k = TABLE1.dn_per_electron
    ex = frame.expected
    for name, index in PATCHES.items():
        rect = radiance.patch_rects[index]
        digital = patch_pixels(frame.digital_dn, rect)
        noisy = patch_pixels(frame.noisy_dn, rect)
        for c in range(3):
            lam = ex.signal_e[index, c] + ex.dark_e[c]
            pmf = digital_pmf(lam, k, TABLE1.read_noise_e, TABLE1.full_well_e, TABLE1.bits)
            mean, var = pmf_moments(pmf)
            assert_mean_var(digital[c], mean, var, what=f"F={factor} {name} ch{c} digital")
            # before quantisation: k (S + D) and k² (S + D + σ_read²), far below the full well
            assert lam < TABLE1.full_well_e - 10 * np.sqrt(lam)
            assert_mean_var(noisy[c], k * lam, k * k * (lam + TABLE1.read_noise_e**2),
                            kurtosis_excess=1 / lam, what=f"F={factor} {name} ch{c} noisy")


def test_noisy_minus_clean_is_zero_mean_including_saturation(scene):
    for factor in (1.0, 1.25):  # at 1.25 the white patch's G mean (≈ 9100 e⁻) sits at the full well
        frame, radiance = render(scene, TABLE1, factor=factor, seed=5)
        residual = frame.noisy_dn - frame.clean_dn()
        for index in (WHITE, 19, 14):
            r = patch_pixels(residual, radiance.patch_rects[index])
            for c in range(3):
                se = r[c].std() / np.sqrt(r[c].size)
                assert abs(r[c].mean()) < 5 * se + 1e-6, (factor, index, c)


@pytest.mark.parametrize("method", ["poisson", "spectral"])
@pytest.mark.parametrize("factor", [1e-3, 1e-4])
def test_pixel_statistics_are_poisson_at_low_light(scene, method, factor):
    """Ideal sensor: the output is electrons, Poisson(S); the spectral method agrees (thinning)."""
    sc = scene.replace(width=360, height=240) if method == "spectral" else scene
    frame, radiance = render(sc, IDEAL, factor=factor, method=method, seed=3)
    for index in (WHITE, 14):
        x = patch_pixels(frame.noisy_dn, radiance.patch_rects[index])
        for c in range(3):
            s = frame.expected.signal_e[index, c]
            assert np.all(x[c] == np.round(x[c]))  # whole electrons
            assert_mean_var(x[c], s, s, kurtosis_excess=1 / s, what=f"{method} F={factor} ch{c}")
            zeros = np.mean(x[c] == 0)
            p0 = np.exp(-s)
            assert abs(zeros - p0) <= 5 * np.sqrt(p0 * (1 - p0) / x[c].size) + 1e-9


@pytest.mark.parametrize("method", ["poisson", "spectral"])
def test_paper_statistics_variance_is_sum_g_qe_squared(scene, method):
    """``paper`` statistics: Var S = T² F Σ g Qe², visible only at F ~ 1e-13 (Eq. 4 per m²·sr)."""
    sc = scene.replace(width=360, height=240)
    frame, radiance = render(sc, IDEAL, factor=1e-13, statistics="paper", method=method, seed=4)
    ex = frame.expected
    for index in (WHITE, 14):
        x = patch_pixels(frame.noisy_dn, radiance.patch_rects[index]).astype(np.float64)
        for c in range(3):
            s, v = ex.signal_e[index, c], ex.signal_var_e2[index, c]
            assert v < 0.1 * s * 1e-6  # far below Poisson(S): the paper's shot noise is tiny
            assert_mean_var(x[c], s, v, k=5.5, what=f"paper {method} ch{c}")
        if method == "spectral":
            # the three channels integrate the same per-bin photon draws: Cov(S_R, S_G) = T² F Σ g Qe_R Qe_G
            cov_model = ex.photon_rate[index] @ (ex.qe[0] * ex.qe[1])
            cov = np.cov(x[0], x[1])[0, 1]
            se = np.sqrt((ex.signal_var_e2[index, 0] * ex.signal_var_e2[index, 1] + cov_model**2) / x.shape[1])
            assert abs(cov - cov_model) < 5 * se


def test_paper_and_pixel_statistics_share_the_mean(scene):
    k = TABLE1.dn_per_electron
    for factor in (1.0, 0.05):
        pixel, radiance = render(scene, TABLE1, factor=factor, statistics="pixel", seed=2)
        paper, _ = render(scene, TABLE1, factor=factor, statistics="paper", seed=2)
        # both statistics' mean signal against an independent integration of the anchored white patch
        truth = anchored_signal_e(WHITE, "D65", factor, TABLE1.exposure_s)
        for frame in (pixel, paper):
            np.testing.assert_allclose(frame.expected.signal_e[WHITE], truth, rtol=1e-3)
        x = patch_pixels(paper.noisy_dn, radiance.patch_rects[WHITE])
        y = patch_pixels(pixel.noisy_dn, radiance.patch_rects[WHITE])
        for c in range(3):
            lam = paper.expected.signal_e[WHITE, c] + paper.expected.dark_e[c]
            var = paper.expected.signal_var_e2[WHITE, c] + paper.expected.dark_e[c] + TABLE1.read_noise_e**2
            assert_mean_var(x[c], k * lam, k * k * var, what=f"paper F={factor} ch{c}")
            # the pixel frame: Poisson(S + D) plus read noise around the same mean
            assert_mean_var(y[c], k * lam, k * k * (lam + TABLE1.read_noise_e**2), kurtosis_excess=1 / lam,
                            what=f"pixel F={factor} ch{c}")
            # and the two frames' measured means agree (two-sample, 5 standard errors)
            se = np.sqrt(x[c].var(ddof=1) / x[c].size + y[c].var(ddof=1) / y[c].size)
            assert abs(float(x[c].mean(dtype=np.float64)) - float(y[c].mean(dtype=np.float64))) < 5 * se


# --- each switch removes its stage ---------------------------------------------------------------------------


def _stage_moments(scene, sensor, factor=0.5, seed=7):
    frame, radiance = render(scene, sensor, factor=factor, seed=seed)
    return frame, patch_pixels(frame.noisy_dn, radiance.patch_rects[WHITE]).astype(np.float64)


def test_photon_noise_switch(scene):
    only_signal = IDEAL.with_stages(photon_noise=False)
    frame, x = _stage_moments(scene, only_signal)
    s = frame.expected.signal_e[WHITE]
    for c in range(3):
        assert np.all(x[c] == np.float32(s[c]))  # exactly the mean: no noise at all


@pytest.mark.parametrize(
    "stage, variance_e2",
    [
        ("dark_current", lambda s, d, r: d),
        ("read_noise", lambda s, d, r: r * r),
        ("photon_noise", lambda s, d, r: s),
    ],
)
def test_each_noise_stage_alone_adds_its_variance(scene, stage, variance_e2):
    off = dict(photon_noise=False, dark_current=False, saturation=False, read_noise=False, quantisation=False)
    off[stage] = True
    sensor = TABLE1.with_stages(**off)
    frame, x = _stage_moments(scene, sensor)
    k = sensor.dn_per_electron
    s = frame.expected.signal_e[WHITE]
    d = TABLE1.dark_mean_e
    for c in range(3):
        mean = k * (s[c] + (d[c] if stage == "dark_current" else 0.0))
        var = k * k * variance_e2(s[c], d[c], TABLE1.read_noise_e)
        assert_mean_var(x[c], mean, var, kurtosis_excess=0.01, what=f"{stage} ch{c}")
    assert frame.digital_dn is None  # quantisation off: no digital numbers


def test_dark_switch_removes_mean_and_black_level(scene):
    sensor = TABLE1.with_stages(dark_current=False)
    assert np.all(sensor.dark_level_dn == 0) and np.all(TABLE1.black_level_dn > 5)
    # an unlit pixel reads 1 only where its read noise reaches 1 / k = 35.3 e⁻ (8.8 σ)
    from scipy import stats

    np.testing.assert_allclose(sensor.black_level_dn, stats.norm.sf(1 / (sensor.dn_per_electron * 4.0)), rtol=1e-9)
    frame, x = _stage_moments(scene, sensor)
    k = sensor.dn_per_electron
    for c in range(3):
        s = frame.expected.signal_e[WHITE, c]
        assert_mean_var(x[c], k * s, k * k * (s + sensor.read_noise_e**2), what=f"no dark ch{c}")


def test_saturation_switch(scene):
    factor = 3.0  # the white patch collects ~21 000 e⁻ in G, far above the 9000 e⁻ full well
    on, x_on = _stage_moments(scene, TABLE1.with_stages(quantisation=False), factor=factor)
    off, x_off = _stage_moments(scene, TABLE1.with_stages(quantisation=False, saturation=False), factor=factor)
    k = TABLE1.dn_per_electron
    g_total = on.expected.signal_e[WHITE, 1] + on.expected.dark_e[1]
    assert g_total > TABLE1.full_well_e + 50 * np.sqrt(g_total)
    assert_mean_var(x_on[1], k * TABLE1.full_well_e, k * k * TABLE1.read_noise_e**2, what="saturated")
    assert_mean_var(x_off[1], k * g_total, k * k * (g_total + 16), what="unsaturated")


def test_table1_full_well_maps_to_255(scene):
    assert np.floor(TABLE1.full_well_e * TABLE1.dn_per_electron) == 255
    assert TABLE1.full_well_e * TABLE1.dn_per_electron == pytest.approx(255.0, abs=0.01)
    no_read = TABLE1.with_stages(read_noise=False)
    frame, radiance = render(scene, no_read, factor=3.0, seed=8)
    assert np.all(patch_pixels(frame.digital_dn, radiance.patch_rects[WHITE]) == 255)
    # with read noise after saturation, floor(k (9000 + r)) is 255 when r ≥ 255/k − 9000 and 254 otherwise
    frame, radiance = render(scene, TABLE1, factor=3.0, seed=8)
    g = patch_pixels(frame.digital_dn, radiance.patch_rects[WHITE])[1]
    assert set(np.unique(g)) <= {254, 255}
    p255 = stats.norm.sf((255 / TABLE1.dn_per_electron - TABLE1.full_well_e) / TABLE1.read_noise_e)
    assert abs(np.mean(g == 255) - p255) < 5 * np.sqrt(p255 * (1 - p255) / g.size)


def test_clipping_at_zero_and_full_scale(scene):
    # no saturation stage: the ADC still clips at 2^nb − 1
    frame, radiance = render(scene, TABLE1.with_stages(saturation=False), factor=3.0, seed=9)
    assert np.all(patch_pixels(frame.digital_dn, radiance.patch_rects[WHITE]) == 255)
    assert frame.noisy_dn.max() > 400  # the float layer keeps the unclipped value
    # no dark current, almost no light: read noise makes negative DN, which clip to 0
    sensor = TABLE1.with_stages(dark_current=False)
    frame, radiance = render(scene, sensor, factor=1e-5, seed=9)
    k = sensor.dn_per_electron
    for index in (WHITE, 23):
        noisy = patch_pixels(frame.noisy_dn, radiance.patch_rects[index])
        digital = patch_pixels(frame.digital_dn, radiance.patch_rects[index])
        assert noisy.min() < 0 and digital.min() == 0
        for c in range(3):
            pmf = digital_pmf(frame.expected.signal_e[index, c], k, 4.0, 9000.0, 8)
            p0 = np.mean(digital[c] == 0)
            assert abs(p0 - pmf[0]) < 5 * np.sqrt(pmf[0] * (1 - pmf[0]) / digital[c].size) + 1e-9


def test_bits_set_the_full_scale(scene):
    sensor = preset("paper-table1", bits=10, analog_gain_dn_per_v=141.67 * 4)  # full well → 1020 DN
    frame, radiance = render(scene, sensor, factor=3.0, seed=1)
    white = patch_pixels(frame.digital_dn, radiance.patch_rects[WHITE])
    assert frame.digital_dn.dtype == np.uint16 and set(np.unique(white[1])) <= {1018, 1019, 1020, 1021, 1022}
    frame, radiance = render(scene, sensor.with_stages(saturation=False), factor=3.0, seed=1)
    assert np.all(patch_pixels(frame.digital_dn, radiance.patch_rects[WHITE]) == 1023)


def test_label_runs_tile_the_block_exactly(scene):
    from camsim.scene.radiance import scene_radiance
    from camsim.sensor.kernels import label_runs

    labels = scene_radiance(scene, "D65").labels
    for r0, r1 in ((0, 480), (100, 163), (7, 8)):
        block = labels[r0:r1]
        runs = label_runs(block)
        covered = np.full(block.shape, -1)
        for a, b, c0, c1, k in runs:
            assert np.all(covered[a:b, c0:c1] == -1)  # no overlap
            covered[a:b, c0:c1] = k
        np.testing.assert_array_equal(covered, block)
    cube_like = np.arange(64 * 64, dtype=np.uint32).reshape(64, 64)
    assert label_runs(cube_like) is None  # every pixel its own label: drawn pixel by pixel


@pytest.mark.parametrize("statistics", ["pixel", "paper"])
def test_pixel_by_pixel_path_has_the_same_statistics(scene, monkeypatch, statistics):
    """The fallback for fragmented label maps (cubes) draws per-pixel means; same model, same moments."""
    import camsim.sensor.kernels

    monkeypatch.setattr(camsim.sensor.kernels, "MIN_PIXELS_PER_RUN", 10**9)
    assert camsim.sensor.kernels.label_runs(np.zeros((4, 4), np.uint8)) is None
    frame, radiance = render(scene, TABLE1.with_stages(quantisation=False), factor=0.1, statistics=statistics,
                             seed=21)
    k = TABLE1.dn_per_electron
    ex = frame.expected
    for index in (WHITE, 14):
        x = patch_pixels(frame.noisy_dn, radiance.patch_rects[index])
        for c in range(3):
            lam = ex.signal_e[index, c] + ex.dark_e[c]
            var = ex.signal_var_e2[index, c] + ex.dark_e[c] + TABLE1.read_noise_e**2
            assert_mean_var(x[c], k * lam, k * k * var, what=f"gather {statistics} ch{c}")
