"""Virtual cameras (camsim.sensor.presets.virtual) and camera presets in dataset specs: K log-uniform over the
camera's range, each noise scale on its fit with the fit's residual scatter (tested by Kolmogorov–Smirnov against
the laws the draws should follow), the conversion to the model's units, and the spec's ``[virtual_camera]`` table
and ``iso`` parameter."""

import math

import numpy as np
import pytest
from scipy import stats

from camsim.core.errors import CamsimError
from camsim.dataset.spec import load_spec
from camsim.sensor.presets import CAMERA_PRESETS, sensor_preset
from camsim.sensor.presets.virtual import draw_virtual_cameras

N = 4000
QUANTITIES = ("tukey_scale_dn", "gaussian_sigma_dn", "row_sigma_dn")


def _streams(seed):
    names = ("camera", "k", "shape", *QUANTITIES)
    return {name: np.random.default_rng([seed, i]) for i, name in enumerate(names)}


def _k(draw):
    return draw["analog_gain_dn_per_v"] * CAMERA_PRESETS[draw["preset"]].conversion_gain_v_per_e


@pytest.mark.parametrize("name", ["nikon-d850", "sony-a7m4"])
def test_k_is_log_uniform_and_the_scales_scatter_about_their_fits(name):
    camera = CAMERA_PRESETS[name]
    draws = draw_virtual_cameras([camera], N, _streams(1), read_noise_model="gaussian")
    k = np.array([_k(d) for d in draws])
    lo, hi = camera.k_range_dn_per_e
    assert stats.kstest((np.log(k) - math.log(lo)) / math.log(hi / lo), "uniform").pvalue > 1e-3
    # the Gaussian σ in DN, read back from the model's electrons: ln σ − fit ~ N(0, residual²)
    fit = camera.fits["gaussian_sigma_dn"]
    sigma_dn = np.array([d["read_noise_e"] for d in draws]) * k
    z = (np.log(sigma_dn) - (fit.slope * np.log(k) + fit.bias)) / fit.residual_sigma
    assert stats.kstest(z, "norm").pvalue > 1e-3
    row = camera.fits["row_sigma_dn"]
    z_row = (np.log(np.array([d["row_noise_e"] for d in draws]) * k) - (row.slope * np.log(k) + row.bias)) \
        / row.residual_sigma
    assert stats.kstest(z_row, "norm").pvalue > 1e-3
    assert abs(np.corrcoef(z, z_row)[0, 1]) < 4 / math.sqrt(N)  # independent scatters


@pytest.mark.slow
def test_tukey_draws_convert_to_the_laws_standard_deviation():
    camera = CAMERA_PRESETS["canon-eos-70d"]
    draws = draw_virtual_cameras([camera], N, _streams(2))
    shapes = np.array([d["tukey_lambda"] for d in draws])
    assert set(shapes) <= set(camera.tukey_shapes)
    # each published shape step equally likely (the list has repeats: count by step)
    counts = np.bincount([int(u * 16) for u in _streams(2)["shape"].random(N)], minlength=16)
    assert stats.chisquare(counts).pvalue > 1e-3
    fit = camera.fits["tukey_scale_dn"]
    z = []
    for d in draws:
        k = _k(d)
        scale_dn = d["read_noise_e"] * k / math.sqrt(stats.tukeylambda(d["tukey_lambda"]).var())
        z.append((math.log(scale_dn) - (fit.slope * math.log(k) + fit.bias)) / fit.residual_sigma)
    assert stats.kstest(z, "norm").pvalue > 1e-3
    # the overrides on top of the preset give the drawn camera
    sensor = sensor_preset(draws[0]["preset"], **{k: v for k, v in draws[0].items() if k != "preset"})
    assert sensor.dn_per_electron == pytest.approx(_k(draws[0]), rel=1e-12)
    assert (sensor.bits, sensor.pedestal_dn) == (14, 2048)


def test_the_union_of_ranges_and_a_uniform_choice_of_camera():
    cameras = [CAMERA_PRESETS[n] for n in ("sony-a7s2-eld", "canon-eos-700d")]
    draws = draw_virtual_cameras(cameras, N, _streams(3), k_range="union")
    k = np.array([_k(d) for d in draws])
    lo, hi = 0.09391607086816033, 28.648249130566832
    assert stats.kstest((np.log(k) - math.log(lo)) / math.log(hi / lo), "uniform").pvalue > 1e-3
    picked = np.array([d["preset"] == "canon-eos-700d" for d in draws])
    assert abs(picked.mean() - 0.5) < 4 * 0.5 / math.sqrt(N)


def _spec(tmp_path, body):
    from camsim.scene.builtin_scenes import resolve_scene_file

    path = tmp_path / "spec.toml"
    path.write_text(f'name = "v"\nscene = "{resolve_scene_file("macbeth_26")}"\nseed = 4\n[frame]\nwidth = 64\n'
                    'height = 48\n[fixed]\nilluminant = "D65"\nintensity_factor = 0.1\n' + body)
    return path


def test_a_spec_draws_virtual_cameras_reproducibly(tmp_path):
    path = _spec(tmp_path, '[random]\ncount = 40\n[virtual_camera]\ncameras = ["nikon-d850", "canon-eos-5d4"]\n')
    first, again = load_spec(path), load_spec(path)
    assert [f.id for f in first.frames] == [f.id for f in again.frames]
    records = [f.record for f in first.frames]
    assert {r["preset"] for r in records} == {"nikon-d850", "canon-eos-5d4"}
    for r in records:
        camera = CAMERA_PRESETS[r["preset"]]
        lo, hi = camera.k_range_dn_per_e
        assert lo <= r["dn_per_electron"] <= hi
        assert r["pedestal_dn"] == camera.pedestal_dn
    assert len({r["dn_per_electron"] for r in records}) == len(records)


@pytest.mark.parametrize("body, message", [
    ('[fixed2]\n', "unknown"),
    ('[virtual_camera]\ncameras = ["sony-imx174"]\n', "no noise fits"),
    ('[virtual_camera]\ncameras = ["nope"]\n', "cannot be drawn from"),
    ('[virtual_camera]\nk_range = "all"\n', "k_range must be one of"),
    ('[virtual_camera]\ncolour = 1\n', "unknown key"),
])
def test_bad_virtual_camera_tables(tmp_path, body, message):
    with pytest.raises(CamsimError, match=message):
        load_spec(_spec(tmp_path, body))


def test_a_virtual_camera_cannot_be_set_twice(tmp_path):
    path = _spec(tmp_path, '[virtual_camera]\ncameras = "all"\n')
    path.write_text(path.read_text().replace("[fixed]\n", "[fixed]\nread_noise_e = 2.0\n"))
    with pytest.raises(CamsimError, match="read_noise_e, which \\[fixed\\] sets too"):
        load_spec(path)


def test_a_spec_varies_the_iso_of_a_camera_preset(tmp_path):
    path = _spec(tmp_path, '[grid]\niso = [800, 3200]\n')
    path.write_text(path.read_text().replace("[fixed]\n", '[fixed]\npreset = "sony-a7s2"\n'))
    records = [f.record for f in load_spec(path).frames]
    assert [r["iso"] for r in records] == [800.0, 3200.0]
    assert [r["dn_per_electron"] for r in records] == pytest.approx([0.765, 3.06], rel=1e-12)
