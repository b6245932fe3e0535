"""Fixed-pattern and structured noise beyond the paper: DSNU, PRNU, row noise, Tukey-lambda read noise."""

import numpy as np
import pytest
from scipy import stats

from camsim.sensor.params import preset
from tests.support.helpers import WHITE, patch_pixels, render, small_scene
from tests.support.theory import assert_mean_var

OFF = dict(photon_noise=False, dark_current=False, saturation=False, read_noise=False, quantisation=False)


@pytest.fixture(scope="module")
def scene():
    return small_scene()


def test_dsnu_map_is_fixed_per_sensor_and_has_its_spread(scene):
    sensor = preset("paper-table1", dsnu_e=3.0, sensor_seed=7, **OFF)
    a, radiance = render(scene, sensor, factor=0.5, seed=1)
    b, _ = render(scene, sensor, factor=0.5, seed=2)  # another frame of the same sensor
    np.testing.assert_array_equal(a.noisy_dn, b.noisy_dn)  # no temporal noise: only the fixed pattern
    c, _ = render(scene, preset("paper-table1", dsnu_e=3.0, sensor_seed=8, **OFF), factor=0.5, seed=1)
    assert np.mean(a.noisy_dn != c.noisy_dn) > 0.99  # another sensor, another pattern
    k = sensor.dn_per_electron
    for index in (WHITE, 14):
        x = patch_pixels(a.noisy_dn, radiance.patch_rects[index]).astype(float) / k
        for ch in range(3):
            assert_mean_var(x[ch], a.expected.signal_e[index, ch], 9.0, what=f"DSNU ch{ch}")
    np.testing.assert_allclose(a.clean_dn(), a.noisy_dn, rtol=1e-6, atol=1e-4)  # the map is in the expectation


def test_prnu_scales_the_signal_per_pixel(scene):
    sensor = preset("paper-table1", prnu_percent=2.0, **OFF)
    frame, radiance = render(scene, sensor, factor=1.0, seed=1)
    x = patch_pixels(frame.noisy_dn, radiance.patch_rects[WHITE]).astype(float)
    for ch in range(3):
        mean = sensor.dn_per_electron * frame.expected.signal_e[WHITE, ch]
        assert_mean_var(x[ch], mean, (0.02 * mean) ** 2, what=f"PRNU ch{ch}")


def test_prnu_with_shot_noise_is_poisson_around_each_pixels_mean(scene):
    """Temporal noise stays Poisson(g S̄) per pixel: the difference of two frames has variance 2 g S̄."""
    sensor = preset("paper-table1", prnu_percent=5.0, **(OFF | {"photon_noise": True}))
    a, radiance = render(scene, sensor, factor=0.2, seed=1)
    b, _ = render(scene, sensor, factor=0.2, seed=2)
    k = sensor.dn_per_electron
    diff = patch_pixels(a.noisy_dn - b.noisy_dn, radiance.patch_rects[WHITE]).astype(float) / k
    total = patch_pixels(a.noisy_dn, radiance.patch_rects[WHITE]).astype(float) / k
    for ch in range(3):
        s = a.expected.signal_e[WHITE, ch]
        assert_mean_var(diff[ch], 0.0, 2 * s, what=f"temporal ch{ch}")
        assert_mean_var(total[ch], s, s + (0.05 * s) ** 2, kurtosis_excess=0.5, what=f"spatial+temporal ch{ch}")
    residual = patch_pixels(a.noisy_dn - a.clean_dn(), radiance.patch_rects[WHITE])
    assert abs(residual.mean()) < 5 * residual.std() / np.sqrt(residual.size)


@pytest.mark.parametrize("method", ["poisson", "auto", "gaussian"])
def test_row_noise_is_shared_along_each_row(scene, method):
    sensor = preset("paper-table1", row_noise_e=6.0, **(OFF | {"read_noise": True}))
    frame, radiance = render(scene, sensor, factor=0.5, method=method, seed=4)
    x, y, w, h = radiance.patch_rects[WHITE]
    block = frame.noisy_dn[:, y + 2 : y + h - 2, x + 2 : x + w - 2].astype(float) / sensor.dn_per_electron
    for ch in range(3):
        rows = block[ch].mean(axis=1)
        n_cols = block.shape[2]
        expected_var = 36.0 + 16.0 / n_cols  # row offset plus the read noise averaged over a row
        assert_mean_var(rows, frame.expected.signal_e[WHITE, ch], expected_var, what=f"row means ch{ch}")
        # pixel variance: row offsets plus read noise (the row part is known from only ~100 rows)
        n_rows = block.shape[1]
        tolerance = 5 * (36.0 * np.sqrt(2 / n_rows) + 16.0 * np.sqrt(2 / block[ch].size))
        assert abs(block[ch].var() - 52.0) < tolerance


def test_tukey_lambda_read_noise_has_the_right_spread_and_tails(scene):
    lam = -0.15
    sensor = preset("paper-table1", read_noise_model="tukey-lambda", tukey_lambda=lam, read_noise_e=4.0,
                    **(OFF | {"read_noise": True}))
    frame, radiance = render(scene, sensor, factor=0.5, seed=6)
    x = (patch_pixels(frame.noisy_dn, radiance.patch_rects[WHITE]).astype(float) / sensor.dn_per_electron)
    noise = (x - frame.expected.signal_e[WHITE][:, None]).ravel()
    kurt = float(stats.tukeylambda.stats(lam, moments="k"))
    n = noise.size
    assert abs(noise.mean()) < 5 * 4 / np.sqrt(n)
    assert abs(noise.var() / 16 - 1) < 5 * np.sqrt((2 + kurt) / n)
    assert kurt > 1 and stats.kurtosis(noise) > 1  # heavy tails (the sample kurtosis itself converges too slowly)
    assert stats.kstest(noise / (4 / np.sqrt(float(stats.tukeylambda.var(lam)))), "tukeylambda",
                        args=(lam,)).pvalue > 1e-3
    gauss = preset("paper-table1", read_noise_e=4.0, **(OFF | {"read_noise": True}))
    frame_g, _ = render(scene, gauss, factor=0.5, seed=6)
    xg = patch_pixels(frame_g.noisy_dn, radiance.patch_rects[WHITE]).astype(float) / gauss.dn_per_electron
    assert abs(stats.kurtosis((xg - frame_g.expected.signal_e[WHITE][:, None]).ravel())) < 0.1


def test_auto_takes_no_gaussian_under_tukey_read_noise(scene):
    sensor = preset("paper-table1", read_noise_model="tukey-lambda")
    frame, _ = render(scene, sensor, factor=0.5, method="auto", seed=1)
    assert not np.any(frame.plan.kind == 1)


def test_prnu_with_the_spectral_method_is_a_clear_error(scene):
    from camsim.core.errors import CamsimError

    with pytest.raises(CamsimError, match="PRNU"):
        render(scene.replace(width=60, height=40), preset("paper-table1", prnu_percent=1.0), method="spectral")


def test_paper_preset_has_no_fixed_pattern():
    sensor = preset("paper-table1")
    assert sensor.dsnu_e == sensor.prnu_percent == sensor.row_noise_e == 0
    assert sensor.read_noise_model == "gaussian" and not sensor.fixed_pattern


def test_a_prnu_beyond_20_percent_clips_its_gains_at_zero_and_renders(scene):
    """At a PRNU of 29 % the Gaussian map's tail below −1/0.29 σ would be a negative gain (a failed Poisson draw
    before): those pixels have gain 0 and collect nothing; every other gain is 1 + 0.29 z."""
    from camsim.sensor.fixed_pattern import fixed_pattern

    sensor = preset("paper-table1", prnu_percent=29.0, **(OFF | {"photon_noise": True}))
    frame, _ = render(scene, sensor, factor=1.0, seed=1)  # raised numpy's "lam < 0" before
    gain = fixed_pattern(sensor, frame.labels.shape).gain
    assert gain.min() == 0 and np.count_nonzero(gain == 0) > 0
    zero = gain[0] == 0
    assert np.all(frame.noisy_dn[0][zero] == 0) and np.all(frame.clean_dn()[0][zero] == 0)
    # the clipped share is the normal's tail below −1/0.29 (3.45 σ: 2.8e-4), within 5 binomial σ
    share, n = np.mean(gain == 0), gain.size
    tail = stats.norm.cdf(-1 / 0.29)
    assert abs(share - tail) < 5 * np.sqrt(tail * (1 - tail) / n) + 1 / n


@pytest.mark.parametrize("name, value, message", [
    ("dark_shading_map", 1e300, "holds a value of magnitude 1e+300 e⁻, beyond the 1e+08 e⁻ its parameter allows"),
    ("dark_shading_map", -1e300, "holds a value of magnitude 1e+300 e⁻, beyond the 1e+08 e⁻"),
    ("hot_pixel_map", 1e300, "holds a value of magnitude 1e+300 e⁻/s, beyond the 1e+10 e⁻/s"),
    ("hot_pixel_map", 1e10, "gives a dark charge of 1e+16 e⁻ in the 1e+06 s exposure, over 9.01e+15 e⁻"),
])
def test_a_maps_values_have_their_parameters_bounds(tmp_path, capsys, name, value, message):
    """A map file adds to its parameter (dark_shading_e's pattern, hot pixels' dark current): its values are bounded
    as the parameter is, on one line through the command line, instead of overflowing the float32 maps."""
    from camsim.cli import main

    np.save(tmp_path / "map.npy", np.full((40, 60), value))
    out = tmp_path / "out"
    rc = main(["render", "macbeth_26", "--size", "60x40", "-F", "1", "--illuminant", "D65", "-q", "--out", str(out),
               "--sensor", f'{name}="{tmp_path / "map.npy"}"', "--sensor", "exposure_s=1e6"])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and message in err, err
    assert not list(out.glob("*.json")) if out.exists() else True


def test_a_map_at_its_bounds_renders_finite_values(tmp_path):
    from camsim.cli import main
    from camsim.io.exr import read_exr

    np.save(tmp_path / "shade.npy", np.full((40, 60), -1e8))
    np.save(tmp_path / "hot.npy", np.full((40, 60), 1e9))
    out = tmp_path / "out"
    assert main(["render", "macbeth_26", "--size", "60x40", "-F", "1", "--illuminant", "D65", "-q", "--out", str(out),
                 "--sensor", f'dark_shading_map="{tmp_path / "shade.npy"}"',
                 "--sensor", f'hot_pixel_map="{tmp_path / "hot.npy"}"']) == 0
    noisy, clean, _ = read_exr(out / "macbeth_26_D65_F1.exr")
    assert np.all(np.isfinite(noisy)) and np.all(np.isfinite(clean))
