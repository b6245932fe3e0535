"""Counts that numpy cannot draw, and dark current that fills the well.

* The saturation cap (:func:`camsim.sensor.stages.cap_mean_e`): its bound, and the law of the clipped value against the
  exact clipped Poisson law, computed independently with scipy.
* Every method and both statistics at astronomically bright light: rendered (saturated, finite, clean layer at the
  full well) where the full well is on, refused with the reason where it is off or where float64 overflows — before
  any file is written.
* Dark current alone filling the well (or the ADC): one warning line, and a DNG whose BlackLevel stays below its
  WhiteLevel, read back with rawpy.
"""

import copy
import dataclasses
import json

import numpy as np
import pytest
from scipy import special, stats

from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.render.pipeline import check_frames, frame_warnings, light_scene, make_frame
from camsim.sensor.camera import load_camera
from camsim.sensor.params import PRESETS, SensorParams
from camsim.sensor.stages import SATURATION_CAP_TAIL, cap_mean_e, collect_charge_e, saturating_mean_e
from tests.support.helpers import small_scene
from tests.support.theory import mean_dn_tail_sum

TABLE1 = SensorParams()
SMALL = ["--illuminant", "D65", "--size", "64x48", "-q"]
LOG_EPS = np.log(SATURATION_CAP_TAIL)


@pytest.fixture(scope="module")
def lit():
    scene = small_scene(width=64, height=48)
    return light_scene(scene, "D65", load_camera(scene.camera, scene.grid))


# --- the cap's law ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("level", [0.0, 0.5, 1.0, 10.0, 137.2, 9000.0, 9000.5, 1e4, 1e6, 1e12])
def test_the_cap_leaves_a_poisson_below_the_level_with_probability_below_eps(level):
    cap = saturating_mean_e(level)
    below = np.ceil(level) - 1  # a count below the level is at most this
    assert below < 0 or stats.poisson.logcdf(below, cap) < LOG_EPS
    # and the cap is not wasteful: a mean a little lower already allows more (the bound is within ~2 σ of tight)
    if level >= 100:
        assert stats.poisson.logcdf(below, cap - 2.5 * np.sqrt(cap)) > LOG_EPS


@pytest.mark.parametrize("step", [1.5e-14, 1e-3, 0.5, 3.0])
def test_the_cap_of_a_scaled_poisson(step):
    """``paper`` statistics: S = s · Poisson(S̄ / s) stays below L with probability < ε at S̄ = M(L, s)."""
    level = 9000.0
    cap = saturating_mean_e(level, step)
    assert stats.poisson.logcdf(np.floor(level / step), cap / step) < LOG_EPS


def _clipped_tv(lam_a, lam_b, full_well):
    """Total variation between min(Poisson(a), FW) and min(Poisson(b), FW), summed over the values below FW.

    Both laws put the rest of their mass on FW, so TV = ½ (Σ_{j<FW} |p_j − q_j| + |Σ_{j<FW} (p_j − q_j)|): no
    1 − (tiny) that float64 would round to 1.
    """
    j = np.arange(int(np.ceil(full_well)))
    p = np.exp(stats.poisson.logpmf(j, lam_a))
    q = np.exp(stats.poisson.logpmf(j, lam_b))
    return 0.5 * (np.abs(p - q).sum() + abs((p - q).sum()))


@pytest.mark.parametrize("full_well", [9000.0, 9000.5, 120.0])
@pytest.mark.parametrize("factor", [0.9, 0.999, 1.0, 1.2, 10.0, 1e3, 1e12, 1e100, 1e300])
def test_capped_clipped_law_is_within_eps_of_the_exact_one(full_well, factor):
    cap = saturating_mean_e(full_well)
    lam = factor * cap
    drawn = cap_mean_e(lam, full_well)
    if factor <= 1:
        assert drawn is lam  # below the cap nothing changes (the same object: no draw changes)
        return
    assert drawn == cap
    tv = _clipped_tv(lam, drawn, full_well)
    assert tv <= SATURATION_CAP_TAIL
    # and the bound is a real one: the clipped law's mass below the full well is itself that small
    mass_below = np.exp(special.logsumexp(stats.poisson.logpmf(np.arange(int(np.ceil(full_well))), drawn)))
    assert tv <= mass_below * (1 + 1e-9) and mass_below <= SATURATION_CAP_TAIL


def test_collect_charge_draws_at_the_cap_and_saturates():
    rng = np.random.default_rng(0)
    fw = 9000.0
    for statistics, var in (("pixel", None), ("paper", 1e180)):
        charge = collect_charge_e(rng, 1e200, 230.0, var, statistics=statistics, size=(48, 64), saturation_e=fw)
        assert np.all(np.isfinite(charge)) and charge.min() >= fw and charge.max() < 2 * fw
    gain = 1 + 0.02 * np.random.default_rng(1).standard_normal((48, 64))
    charge = collect_charge_e(rng, 1e200, 230.0, size=(48, 64), gain=gain, saturation_e=fw)
    assert charge.min() >= fw and charge.max() < 2 * fw
    # dark current far beyond numpy's Poisson range (1e20 s of it), photon noise on or off
    for statistics, photon_noise in (("paper", True), ("pixel", False)):
        charge = collect_charge_e(rng, 10.0, 2.3e22, 1e-12, statistics=statistics, photon_noise=photon_noise,
                                  size=(48, 64), saturation_e=fw)
        assert np.all(np.isfinite(charge)) and charge.min() >= fw


@pytest.mark.parametrize("statistics", ["pixel", "paper"])
def test_below_the_cap_the_draws_are_unchanged(statistics):
    args = (5000.0, 230.0, 1e-10 if statistics == "paper" else None)
    plain = collect_charge_e(np.random.default_rng(3), *args, statistics=statistics, size=(48, 64))
    capped = collect_charge_e(np.random.default_rng(3), *args, statistics=statistics, size=(48, 64),
                              saturation_e=9000.0)
    assert np.array_equal(plain, capped)


# --- every method at astronomically bright light -----------------------------------------------------------

FIXED = [{}, {"dsnu_e": 5.0}, {"prnu_percent": 2.0}, {"cfa": "RGGB"}]


@pytest.mark.parametrize("factor", [1e20, 1e291])
@pytest.mark.parametrize("statistics", ["pixel", "paper"])
@pytest.mark.parametrize("method", ["poisson", "gaussian", "auto", "spectral"])
def test_every_method_saturates_at_huge_light(lit, factor, statistics, method):
    k = TABLE1.dn_per_electron
    for extra in FIXED:
        if method == "spectral" and "prnu_percent" in extra:
            continue
        sensor = SensorParams(**extra)
        with np.errstate(over="raise", invalid="raise"):  # nothing overflows, nothing is NaN
            frame = make_frame(lit, sensor, factor, statistics=statistics, method=method, rng=1, workers=1)
            clean = frame.clean_dn()
        what = f"{method} {statistics} F={factor:g} {extra}"
        assert np.all(np.isfinite(frame.noisy_dn)), what
        # the full well plus read noise (k · 9000 = 255.006 DN; 4 e⁻ of read noise: 0.11 DN, cut at 5.8 σ)
        assert np.all(np.abs(frame.noisy_dn - k * 9000) < 6 * 4 * k), what
        assert set(np.unique(frame.digital_dn)) <= {254, 255}, what
        assert np.array_equal(clean, np.full_like(clean, np.float32(k * 9000))), what
        assert np.allclose(frame.expected.clean_e, 9000.0), what


@pytest.mark.parametrize("method", ["poisson", "gaussian", "auto", "spectral"])
def test_every_pixel_reads_the_white_level_when_the_well_maps_above_it(lit, method):
    sensor = dataclasses.replace(TABLE1, analog_gain_dn_per_v=200.0)  # full well = 360 DN > 255
    frame = make_frame(lit, sensor, 1e100, method=method, rng=2, workers=1)
    assert np.all(frame.digital_dn == 255)


def test_paper_clean_value_far_above_the_full_well(lit):
    """E[min(S + D, FW)] under the Gaussian approximation: 1e23 − (1e23 − 9000) was 0 in float64."""
    expected = lit.expected(TABLE1, 1e20, "paper")
    assert np.allclose(expected.clean_e, 9000.0)
    ordinary = lit.expected(TABLE1, 1.0, "paper")
    assert np.all(ordinary.clean_e < 9000.0) and np.all(ordinary.clean_e > 0)


def beyond_the_schema(sensor, **values):
    """``sensor`` with fields set past the schema's ranges (which refuse them on construction): for the guards
    of the stages below the schema, which hold for whatever reaches them."""
    sensor = copy.copy(sensor)
    for name, value in values.items():
        object.__setattr__(sensor, name, value)
    return sensor


def test_overflowing_light_is_refused_with_the_largest_usable_f(lit):
    with pytest.raises(CamsimError, match=r"F = 1e\+300 .*overflows float64.*photon rate.*allow F up to about"):
        lit.expected(TABLE1, 1e300, "pixel")
    with pytest.raises(CamsimError, match=r"variance.*paper"):
        lit.expected(beyond_the_schema(TABLE1, exposure_s=1e160), 1e100, "paper")
    with pytest.raises(CamsimError, match=r"exposure T = 1e\+306 s overflows the mean dark charge"):
        lit.expected(beyond_the_schema(TABLE1, exposure_s=1e306), 1.0, "pixel")
    # the largest F it names is usable
    largest = np.finfo(np.float64).max / lit.photon_rate.max()
    assert np.all(np.isfinite(lit.expected(TABLE1, 0.9 * largest, "pixel").clean_e))


def test_without_a_full_well_huge_light_is_refused(lit):
    for stages in ({"saturation": False}, {"saturation": False, "quantisation": False}):
        sensor = TABLE1.with_stages(**stages)
        for method in ("poisson", "spectral"):
            with pytest.raises(CamsimError, match=r"mean charge 7.\d+e\+103 e⁻ per pixel .* with saturation off"):
                make_frame(lit, sensor, 1e100, method=method, rng=1)
    # up to the float32 range it is drawn (numpy's sampler, a rounded normal past 1e18) and stays finite
    frame = make_frame(lit, TABLE1.with_stages(saturation=False), 1e25, rng=1, workers=1)
    assert np.all(np.isfinite(frame.noisy_dn)) and np.all(frame.digital_dn == 255)


def test_huge_dark_current_is_drawn_at_the_cap(lit):
    # the schema's largest dark charge: 2⁵³ e⁻ (more is refused, below)
    sensor = dataclasses.replace(TABLE1, dark_current_e_per_s=1e10, exposure_s=2.0**53 / 1e10)
    with pytest.raises(CamsimError, match=r"dark charge of 9\.02e\+15 e⁻ in an exposure, over 9\.01e\+15 e⁻"):
        dataclasses.replace(sensor, exposure_s=sensor.exposure_s * 1.001)
    assert frame_warnings(sensor) and "every pixel saturates" in frame_warnings(sensor)[0]
    for statistics, method in (("paper", "poisson"), ("pixel", "spectral"), ("paper", "spectral")):
        frame = make_frame(lit, sensor, 1e-30, statistics=statistics, method=method, rng=1, workers=1)
        assert set(np.unique(frame.digital_dn)) <= {254, 255}


# --- the command line: refused before anything is written, or written right -----------------------------------


@pytest.mark.parametrize("method", ["poisson", "auto", "gaussian", "spectral"])
@pytest.mark.parametrize("statistics", ["pixel", "paper"])
def test_cli_refuses_overflowing_light_before_writing(tmp_path, capsys, method, statistics):
    out = tmp_path / "o"
    code = main(["render", "macbeth_26", "--intensity", "1", "1e300", "--method", method, "--statistics",
                 statistics, "--out", str(out), *SMALL])
    assert code == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error: frame under D65 at F = 1e+300: intensity factor F = 1e+300")
    assert "overflows float64" in err and "Traceback" not in err and err.count("\n") == 1
    assert not out.exists()  # not even the F = 1 frame


def test_cli_refuses_unbounded_charge_before_writing(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["render", "macbeth_26", "--intensity", "1e100", "--disable", "saturation", "--out", str(out),
                 *SMALL]) == 2
    err = capsys.readouterr().err
    assert "mean charge" in err and "float32" in err and "with saturation off nothing bounds the charge" in err
    assert not out.exists()


@pytest.mark.parametrize("method", ["poisson", "auto", "gaussian", "spectral"])
def test_cli_renders_huge_light_saturated(tmp_path, capsys, method):
    import rawpy

    from camsim.io.exr import read_exr

    out = tmp_path / "o"
    assert main(["render", "macbeth_26", "--intensity", "1e100", "--method", method, "--out", str(out),
                 *SMALL]) == 0
    assert capsys.readouterr().err == ""
    with rawpy.imread(str(out / "macbeth_26_D65_F1e+100.dng")) as raw:
        assert set(np.unique(raw.raw_image[..., :3])) <= {254, 255}
    noisy, clean, _ = read_exr(out / "macbeth_26_D65_F1e+100.exr")
    k = TABLE1.dn_per_electron
    assert np.all(np.isfinite(noisy)) and np.all(np.abs(noisy - k * 9000) < 1)
    assert np.all(clean == np.float32(k * 9000))
    sidecar = json.loads((out / "macbeth_26_D65_F1e+100.json").read_text())
    assert all(np.allclose(p["clean_dn"], k * 9000) for p in sidecar["patches"])
    assert "black_level_tag_dn" not in sidecar


# --- dark current that alone fills the well ---------------------------------------------------------------------


def test_frame_warnings_conditions():
    assert frame_warnings(TABLE1) == []
    assert frame_warnings(PRESETS["emva-12bit"]) == []
    full = frame_warnings(dataclasses.replace(TABLE1, exposure_s=50.0))
    assert len(full) == 1 and full[0].startswith(
        "dark current alone fills the well: σ²_dark·T = R 9750, G 11500, B 10900 e⁻ ≥ full well 9000 e⁻ at T = 50 s; "
        "every pixel saturates")
    assert "BlackLevel is written as 254 DN" in full[0]
    # only green and blue at 42 s (R 8190 e⁻), and only 2 σ above: "most"
    partial = frame_warnings(dataclasses.replace(TABLE1, exposure_s=42.0))[0]
    assert "G 9660, B 9156 e⁻" in partial and "most G/B pixels saturate" in partial
    # a dark-current DSNU map of 5 %: at 50 s the coldest pixels (6 σ of the map's normal, d = e^(−6s − s²/2)) hold
    # 9750 d R electrons: below the well, so only "most" pixels saturate (R 7215 e⁻ in the coldest)
    s = np.sqrt(np.log(1 + 0.05**2))
    assert 9750 * np.exp(-6 * s - s * s / 2) < 9000
    mapped = frame_warnings(dataclasses.replace(TABLE1, exposure_s=50.0, dsnu_dark_current_percent=5.0))[0]
    assert "most pixels saturate" in mapped
    # a high gain: the ADC's top before the well
    adc = frame_warnings(dataclasses.replace(TABLE1, exposure_s=20.0, analog_gain_dn_per_v=500.0))[0]
    assert adc.startswith("dark current alone reaches the top of the ADC: k·σ²_dark·T = R 390, G 460, B 436 DN ≥ "
                          "white level 255 DN") and "every pixel reads 255 DN" in adc
    assert frame_warnings(dataclasses.replace(TABLE1, exposure_s=50.0, saturation=False))[0].startswith(
        "dark current alone reaches the top of the ADC")
    # nothing clips without saturation and quantisation; with only the well, no DNG tag to mention
    assert frame_warnings(dataclasses.replace(TABLE1, exposure_s=50.0, saturation=False, quantisation=False)) == []
    assert "BlackLevel" not in frame_warnings(dataclasses.replace(TABLE1, exposure_s=50.0, quantisation=False))[0]
    # the black level within 1 DN of the white level: only the tag. k · D̄ = 254.9 DN with a noise of 0.23 DN
    # (k = 2e-4 DN/e⁻, no well): the floor and the clip at 255 make 254.33 DN of it (tests.support.theory's tail sum)
    low_gain = SensorParams(analog_gain_dn_per_v=1.0, dark_current_e_per_s=1e6, exposure_s=1.2745, saturation=False)
    np.testing.assert_allclose(low_gain.black_level_dn, mean_dn_tail_sum(1.2745e6, 2e-4, 4.0, 8), atol=1e-9)
    near = frame_warnings(low_gain)
    assert len(near) == 1 and near[0].startswith(
        "the black level (the mean digital number of an unlit pixel) = R 254.3, G 254.3, B 254.3 DN at T = 1.2745 s "
        "is within 1 DN of the white level 255 DN; the DNG's BlackLevel is written as 254 DN")
    # 12 bits: the well (4000 DN) fills below the ADC's 4095
    full_emva = dataclasses.replace(PRESETS["emva-12bit"], exposure_s=500.0)
    emva = frame_warnings(full_emva)[0]
    assert emva.startswith("dark current alone fills the well: σ²_dark·T = R 12500, G 12500, B 12500 e⁻")
    # every pixel reads floor(0.4 (10 000 + read noise)), about 3999.5 DN: a BlackLevel below the WhiteLevel
    assert "BlackLevel" not in emva
    codes = np.arange(1, 4096)
    np.testing.assert_allclose(full_emva.black_level_dn, stats.norm.sf((codes / 0.4 - 10000) / 3.0).sum(), atol=1e-9)


def test_black_level_tag():
    long = dataclasses.replace(TABLE1, exposure_s=50.0)
    assert np.array_equal(long.black_level_tag_dn, [254, 254, 254])
    assert long.sidecar_record()["black_level_tag_dn"] == [254.0, 254.0, 254.0]
    assert long.sidecar_record()["black_level_dn"] == long.black_level_dn.tolist()
    assert np.array_equal(TABLE1.black_level_tag_dn, TABLE1.black_level_dn)
    assert "black_level_tag_dn" not in TABLE1.sidecar_record()


@pytest.mark.parametrize("cfa", [None, "RGGB"])
def test_cli_dark_fills_the_well_warns_once_and_writes_a_readable_dng(tmp_path, capsys, cfa):
    import rawpy

    out = tmp_path / "o"
    argv = ["render", "macbeth_26", "--exposure", "50", "--intensity", "1", "0.1", "--out", str(out), *SMALL]
    assert main(argv + (["--cfa", cfa] if cfa else [])) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("camsim: warning: dark current alone fills the well: σ²_dark·T = ")
    assert "every pixel saturates" in err[0]
    sidecar = json.loads((out / "macbeth_26_D65_F1.json").read_text())
    # every pixel holds the full well: before the ADC k · 9000 = 255.006 DN; after it 254, or 255 when the read
    # noise reaches 255 / k − 9000 e⁻
    k = TABLE1.dn_per_electron
    assert np.allclose(sidecar["dark_level_dn"], [k * 9000] * 3)
    assert np.allclose(sidecar["black_level_dn"], [254 + stats.norm.sf((255 / k - 9000) / 4.0)] * 3)
    assert sidecar["black_level_tag_dn"] == [254.0, 254.0, 254.0]
    for name in ("macbeth_26_D65_F1.dng", "macbeth_26_D65_F0.1.dng"):
        with rawpy.imread(str(out / name)) as raw:
            black = list(raw.black_level_per_channel[:3])
            assert black == [254, 254, 254] and raw.white_level == 255
            values = raw.raw_image_visible if cfa else raw.raw_image[..., :3]
            assert set(np.unique(values)) <= {254, 255}
            assert raw.postprocess().shape[:2] == (48, 64)


def test_cli_dark_reaches_the_adc_top(tmp_path, capsys):
    import rawpy

    out = tmp_path / "o"
    assert main(["render", "macbeth_26", "--exposure", "20", "--sensor", "analog_gain_dn_per_v=500",
                 "--intensity", "1", "--out", str(out), *SMALL]) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("camsim: warning: dark current alone reaches the top of the ADC")
    with rawpy.imread(str(out / "macbeth_26_D65_F1.dng")) as raw:
        assert np.all(raw.raw_image[..., :3] == 255) and raw.black_level_per_channel[:3] == [254, 254, 254]


def test_ordinary_render_has_no_warning(tmp_path, capsys):
    assert main(["render", "macbeth_26", "--intensity", "1", "--out", str(tmp_path / "o"), *SMALL]) == 0
    assert capsys.readouterr().err == ""


def test_check_frames_names_the_frame():
    scene = small_scene(width=64, height=48).replace(illuminants=("D65", "A"), intensity_factors=(1.0, 1e300))
    with pytest.raises(CamsimError, match=r"^frame under D65 at F = 1e\+300: "):
        check_frames(scene)
    assert check_frames(scene.replace(intensity_factors=(1.0, 1e100))) == []
