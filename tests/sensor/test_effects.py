"""Issue 28's sensor effects — temperature, hot/dead/stuck pixels, the black-level error, dark shading and column
FPN — each checked against a closed form written here (EMVA 1288's doubling law, binomial counts, the exponential
law of the hot pixels' dark current, χ² on the black-level error's variance), through every renderer that takes it:
the block renderer (three-chip and Bayer, every method), the raw renderer and the array path on numpy.
"""

import json
import math

import numpy as np
import pytest
from scipy import stats

from camsim.core.errors import CamsimError
from camsim.render.backends.array_path import render_frame_xp
from camsim.render.frame import render_frame
from camsim.render.raw_frame import render_raw_frame
from camsim.sensor.expected import expected_signal
from camsim.sensor.fixed_pattern import fixed_pattern
from camsim.sensor.params import HOT_PIXEL_BASE_E_PER_S, SensorParams

#: Gain 1 DN/e⁻, 16 bits, no full well: charges read in DN directly.
UNIT = dict(conversion_gain_v_per_e=1.0, analog_gain_dn_per_v=1.0, bits=16, saturation=False)
#: The three ways a frame of a scene is drawn on the CPU (spectral: one mean per spectrum, no dead pixels).
METHODS = ("poisson", "gaussian", "spectral")


def expected_for(sensor, signal_e=0.0):
    """The ExpectedSignal of one spectrum giving ``signal_e`` mean electrons in every channel (0: a dark frame)."""
    radiance = np.full((1, 4), signal_e / 4 / sensor.exposure_s)
    return expected_signal(radiance, np.ones((3, 4)), sensor, 1.0, "pixel")


def draw(sensor, shape=(64, 64), seed=1, method="poisson", signal_e=0.0, renderer="block"):
    """(noisy (planes, H, W), digital or None, clean (3, H, W) or (H, W), maps, drawn black-level error) of a frame
    by ``renderer``: ``block`` (render_frame), ``array`` (render_frame_xp on numpy) or ``raw`` (render_raw_frame of a
    flat source of ``signal_e`` electrons, fraction 1)."""
    labels = np.zeros(shape, dtype=np.uint8)
    rng = np.random.SeedSequence(seed)
    if renderer == "raw":
        raw = render_raw_frame(np.full(shape, signal_e, dtype=np.float32), sensor, 1.0, rng=rng, workers=1)
        return raw.noisy_dn, raw.digital_dn, raw.clean_dn, raw.maps, raw.black_level_error_dn
    expected = expected_for(sensor, signal_e)
    if renderer == "array":
        device = render_frame_xp(np, labels, expected, sensor, rng=rng)
        frame = device.to_frame(labels, expected, sensor)
    else:
        frame = render_frame(labels, expected, sensor, rng=rng, method=method, workers=1)
    return frame.noisy_dn, frame.digital_dn, frame.clean_dn(), frame.maps, frame.black_level_error_dn


# ---- temperature ------------------------------------------------------------------------------------------------

def test_dark_current_doubles_per_doubling_temperature():
    rates, t, td, tref = np.array([40.0, 60.0, 80.0]), 2.0, 6.0, 25.0
    base = SensorParams(**UNIT, dark_current_e_per_s=tuple(rates), exposure_s=t, read_noise_e=2.0,
                        quantisation=False, dark_current_doubling_c=td, dark_current_reference_c=tref)
    for temperature in (tref, tref + 9.0, tref - 6.0):
        sensor = SensorParams(**{**UNIT, **{k: getattr(base, k) for k in ("dark_current_e_per_s", "exposure_s",
                              "read_noise_e", "quantisation", "dark_current_doubling_c",
                              "dark_current_reference_c")}}, temperature_c=temperature)
        noisy = draw(sensor, shape=(128, 128))[0]
        truth = rates * t * 2.0 ** ((temperature - tref) / td)  # EMVA 1288's law: D_ref · 2^(ΔT/T_d) · t
        n = noisy[0].size
        for c in range(3):
            se = math.sqrt((truth[c] + 2.0**2) / n)  # Poisson dark charge + read noise, over n pixels
            assert abs(noisy[c].mean() - truth[c]) < 4 * se, (temperature, c)
    assert np.allclose(SensorParams(temperature_c=31.0).dark_current_effective_e_per_s,
                       2 * np.array(SensorParams().dark_current_e_per_s))


def test_temperature_scales_the_dark_current_dsnu_and_the_hot_pixels_alike():
    cold = SensorParams(**UNIT, dsnu_dark_current_percent=20.0, hot_pixel_fraction=0.01, temperature_c=25.0)
    warm = SensorParams(**UNIT, dsnu_dark_current_percent=20.0, hot_pixel_fraction=0.01, temperature_c=37.0)
    a, b = draw(cold, seed=3)[2], draw(warm, seed=3)[2]  # the clean layers: k · D̄ · d per pixel
    assert np.allclose(b, 4 * a, rtol=1e-5)


# ---- hot, dead and stuck pixels ---------------------------------------------------------------------------------

@pytest.mark.parametrize("cfa", [None, "RGGB"])
def test_defect_counts_are_binomial_and_the_maps_belong_to_the_sensor(cfa):
    shape, f = (200, 200), dict(hot_pixel_fraction=0.004, dead_pixel_fraction=0.002, stuck_pixel_fraction=0.003)
    sensor = SensorParams(cfa=cfa, sensor_seed=11, **f)
    maps = fixed_pattern(sensor, shape)
    n = shape[0] * shape[1] * (3 if cfa is None else 1)  # a three-chip sensor: each chip's pixels
    for name in ("hot", "dead", "stuck"):
        low, high = stats.binom.interval(0.9999, n, f[f"{name}_pixel_fraction"])
        assert low <= maps.defect_counts[name] <= high, name
    # the same pixels and levels in every frame and run of the sensor; other pixels with another sensor_seed
    a = draw(sensor, shape, seed=1, signal_e=500.0)
    b = draw(sensor, shape, seed=2, signal_e=500.0)
    index, levels = maps.stuck_index, maps.stuck_level_dn
    for frame in (a, b):
        assert np.array_equal(frame[1].reshape(-1)[index], levels)
    assert not np.array_equal(a[1], b[1])
    other = fixed_pattern(SensorParams(cfa=cfa, sensor_seed=12, **f), shape)
    assert not np.array_equal(other.stuck_index, index)
    assert not np.array_equal(other.dark_gain, maps.dark_gain)


def test_stuck_levels_are_uniform_over_the_adc_range():
    sensor = SensorParams(bits=10, stuck_pixel_fraction=0.05, sensor_seed=2)
    levels = fixed_pattern(sensor, (200, 200)).stuck_level_dn
    assert np.all(levels == np.round(levels)) and levels.min() >= 0 and levels.max() <= 1023
    assert stats.kstest((levels + 0.5) / 1024, "uniform").pvalue > 1e-3  # discrete uniform on 0 … 1023


def test_hot_pixels_dark_current_is_exponential_with_the_stated_mean():
    rates, scale = (50.0, 50.0, 50.0), 800.0
    sensor = SensorParams(**UNIT, dark_current_e_per_s=rates, hot_pixel_fraction=0.02, hot_pixel_dark_e_per_s=scale,
                          sensor_seed=4)
    maps = fixed_pattern(sensor, (256, 256))
    extra = (maps.dark_gain.astype(np.float64) - 1) * rates[0]  # e⁻/s above the ordinary rate, the three chips
    hot = extra[extra > 1e-3]
    assert hot.size == maps.defect_counts["hot"]
    assert stats.kstest(hot, "expon", args=(0, scale)).pvalue > 1e-3
    # and the frames show it: the mean of dark frames at the hot pixels is (σ²_dark + h) T
    t = 0.5
    frames = [draw(SensorParams(**{**UNIT, "dark_current_e_per_s": rates, "hot_pixel_fraction": 0.02,
                                   "hot_pixel_dark_e_per_s": scale, "sensor_seed": 4, "exposure_s": t,
                                   "read_noise": False, "quantisation": False}),
                   shape=(256, 256), seed=s)[0] for s in range(8)]
    mean = np.mean(frames, axis=0)
    where = extra > 1e-3
    truth = (rates[0] + extra[where]) * t
    z = (mean[where] - truth) / np.sqrt(truth / len(frames))
    assert abs(z.mean()) < 4 / math.sqrt(z.size) and 0.8 < z.std() < 1.2


@pytest.mark.parametrize("renderer,cfa,method", [("block", None, "poisson"), ("block", "RGGB", "poisson"),
                                                 ("block", None, "gaussian"), ("block", "GRBG", "gaussian"),
                                                 ("array", None, "poisson"), ("array", "RGGB", "poisson"),
                                                 ("raw", "RGGB", "poisson")])
def test_dead_pixels_read_black_and_stuck_pixels_their_level_in_every_renderer(renderer, cfa, method):
    sensor = SensorParams(cfa=cfa, bits=12, read_noise_e=3.0, pedestal_dn=64, dead_pixel_fraction=0.01,
                          stuck_pixel_fraction=0.01, sensor_seed=7)
    noisy, digital, clean, maps, _ = draw(sensor, (64, 64), method=method, signal_e=5000.0, renderer=renderer)
    planes = noisy.shape[0]
    dead = np.broadcast_to(maps.gain == 0, (3, 64, 64))[:planes]  # a Bayer frame's plane: every channel's mask
    stuck = np.zeros(noisy.size, bool)
    stuck[maps.stuck_index] = True
    dead = dead & ~stuck.reshape(noisy.shape)
    assert dead.any()
    k = sensor.dn_per_electron
    # dead: the pedestal plus read noise only (5000 e⁻ of light are 141 DN above it at k = 0.0283 DN/e⁻)
    assert np.all(np.abs(digital[dead].astype(float) - 64) < 6 * 3.0 * k + 1)
    lit = ~dead & ~stuck.reshape(noisy.shape)
    assert np.all(digital[lit] > 64 + 100)
    assert np.array_equal(digital.reshape(-1)[maps.stuck_index], maps.stuck_level_dn)
    assert np.array_equal(noisy.reshape(-1)[maps.stuck_index], maps.stuck_level_dn - np.float32(64.5))
    # the clean layer: a dead pixel's expectation is black (0 DN before the ADC), a stuck one's its level
    clean_planes = clean[None] if clean.ndim == 2 else clean
    if planes == 1 and clean_planes.shape[0] == 3:  # a Bayer frame's clean planes: each pixel's own channel
        assert np.all(np.abs(clean_planes[:, dead[0]]) < 1e-3)
    else:
        assert np.all(np.abs(clean_planes[dead]) < 1e-3)


def test_spectral_refuses_dead_pixels_in_one_line():
    with pytest.raises(CamsimError, match="dead pixels") as info:
        draw(SensorParams(dead_pixel_fraction=0.01), method="spectral")
    assert "\n" not in str(info.value)


def test_hot_pixels_on_a_sensor_without_dark_current_and_fractions_at_most_one():
    # a camera preset that publishes no dark current: the hot pixels still collect h T, the others ~nothing
    t = 2.0
    sensor = SensorParams(**UNIT, dark_current_e_per_s=(0.0, 0.0, 0.0), exposure_s=t, read_noise=False,
                          quantisation=False, hot_pixel_fraction=0.02, hot_pixel_dark_e_per_s=500.0, sensor_seed=8)
    maps = fixed_pattern(sensor, (128, 128))
    h = (maps.dark_gain.astype(np.float64) - 1) * HOT_PIXEL_BASE_E_PER_S  # the extra rate over the floor
    where = h > 1e-6
    mean = np.mean([draw(sensor, (128, 128), seed=s)[0] for s in range(8)], axis=0)
    z = (mean[where] - h[where] * t) / np.sqrt(h[where] * t / 8)
    assert abs(z.mean()) < 4 / math.sqrt(z.size) and 0.8 < z.std() < 1.2
    assert np.all(mean[~where] == 0)  # 10⁻¹² e⁻/s · 2 s: no electron
    with pytest.raises(CamsimError, match="at most 1"):
        SensorParams(hot_pixel_fraction=0.5, dead_pixel_fraction=0.4, stuck_pixel_fraction=0.2)


# ---- black-level error ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("renderer,cfa,method", [("block", None, "poisson"), ("block", "RGGB", "gaussian"),
                                                 ("block", None, "spectral"), ("array", "RGGB", "poisson"),
                                                 ("raw", "RGGB", "poisson")])
def test_black_level_error_is_one_offset_per_frame_and_channel_on_a_stream_of_its_own(renderer, cfa, method):
    on = SensorParams(cfa=cfa, quantisation=False, black_level_error_dn=3.0)
    off = SensorParams(cfa=cfa, quantisation=False)
    a = draw(on, (32, 32), seed=5, method=method, renderer=renderer)
    b = draw(off, (32, 32), seed=5, method=method, renderer=renderer)
    error = a[4]
    assert error is not None and error.shape == (3,) and b[4] is None
    # the frame's other draws are the same: the difference is the offset of each pixel's channel, exactly
    expect = np.empty(a[0].shape)
    if cfa is None:
        expect[:] = error.reshape(3, 1, 1)
    else:
        from camsim.sensor.cfa import cfa_sites

        for dy, dx, c in cfa_sites(cfa):
            expect[0, dy::2, dx::2] = error[c]
    assert np.allclose(a[0] - b[0], expect, atol=1e-4)
    assert np.array_equal(a[2], b[2])  # the clean layer leaves it out


def test_black_level_error_has_the_stated_sigma_chi_square():
    sigma, frames = 2.0, 300
    sensor = SensorParams(**UNIT, quantisation=False, read_noise_e=1.0, dark_current_e_per_s=(5.0, 5.0, 5.0),
                          black_level_error_dn=sigma)
    n = 16 * 16
    means = np.array([draw(sensor, (16, 16), seed=s)[0].reshape(3, -1).mean(axis=1) for s in range(frames)])
    # per-frame channel means about the dark level: σ² of the error plus the temporal noise of a mean of n pixels
    variance = sigma**2 + (5.0 + 1.0) / n
    for c in range(3):
        statistic = (frames - 1) * means[:, c].var(ddof=1) / variance
        assert stats.chi2.ppf(1e-4, frames - 1) < statistic < stats.chi2.ppf(1 - 1e-4, frames - 1), c
        assert abs(means[:, c].mean() - 5.0) < 4 * math.sqrt(variance / frames)


# ---- dark shading and column FPN --------------------------------------------------------------------------------

@pytest.mark.parametrize("renderer,cfa", [("block", None), ("block", "RGGB"), ("array", "RGGB"), ("raw", "RGGB")])
def test_the_mean_of_dark_frames_reproduces_the_dark_shading(renderer, cfa):
    rms, m, shape = 4.0, 16, (64, 96)
    sensor = SensorParams(**UNIT, cfa=cfa, quantisation=False, read_noise_e=3.0, dark_current_e_per_s=(2.0,) * 3,
                          dark_shading_e=rms, sensor_seed=9)
    mean = np.mean([draw(sensor, shape, seed=s, renderer=renderer)[0] for s in range(m)], axis=0)[0]
    estimate = mean - mean.mean()
    truth = fixed_pattern(sensor, shape).offset_e[0]  # a Bayer sensor's planes hold one pattern
    assert abs(math.sqrt(np.mean(truth**2)) - rms) < 1e-3 * rms  # the pattern's RMS is dark_shading_e
    assert np.corrcoef(estimate.ravel(), truth.ravel())[0, 1] > 0.95
    noise_var = (2.0 + 9.0) / m  # the temporal noise left in the mean of m frames
    assert abs(math.sqrt(max(np.mean(estimate**2) - noise_var, 0)) - rms) < 0.1 * rms
    # its structure: rows, columns and a smooth part each carry some of it
    assert np.std(truth.mean(axis=1)) > 0.1 * rms and np.std(truth.mean(axis=0)) > 0.1 * rms


def test_column_fpn_has_the_stated_column_sigma():
    sigma, m, shape = 3.0, 4, (200, 400)
    sensor = SensorParams(**UNIT, quantisation=False, read_noise_e=2.0, dark_current_e_per_s=(1.0,) * 3,
                          column_fpn_e=sigma, sensor_seed=13)
    mean = np.mean([draw(sensor, shape, seed=s)[0] for s in range(m)], axis=0)
    columns = mean.mean(axis=1)  # (3, W): the column offsets plus the noise of a mean of H · m values
    noise_var = (1.0 + 4.0) / (shape[0] * m)
    n = columns.size
    statistic = (n - 1) * (columns.var(axis=1, ddof=1).mean() * 3 - 0) / 3 / (sigma**2 + noise_var)
    # the columns of the three chips pooled: (n − 3) s² / σ² ~ χ²(n − 3)
    pooled = sum(((columns[c] - columns[c].mean()) ** 2).sum() for c in range(3)) / (sigma**2 + noise_var)
    assert stats.chi2.ppf(1e-4, n - 3) < pooled < stats.chi2.ppf(1 - 1e-4, n - 3), statistic
    # the rows carry none of it
    assert np.std(mean.mean(axis=2)) < 0.3 * sigma


def test_a_dark_shading_map_file_is_added_and_a_wrong_shape_refused(tmp_path):
    pattern = np.linspace(-5, 5, 32 * 48).reshape(32, 48)
    path = tmp_path / "dark_shading.npy"
    np.save(path, pattern)
    sensor = SensorParams(cfa="RGGB", dark_shading_map=str(path))
    assert np.allclose(fixed_pattern(sensor, (32, 48)).offset_e[1], pattern, atol=1e-5)
    with pytest.raises(CamsimError, match=r"shape \(32, 48\).*\(64, 48\)"):
        fixed_pattern(sensor, (64, 48))
    hot = np.zeros((32, 48))
    hot[3, 5] = 1000.0
    np.save(tmp_path / "hot.npy", hot)
    maps = fixed_pattern(SensorParams(cfa="RGGB", hot_pixel_map=str(tmp_path / "hot.npy")), (32, 48))
    assert maps.defect_counts == {"hot": 1, "dead": 0, "stuck": 0}
    rates = np.array(SensorParams().dark_current_e_per_s)
    assert np.allclose(maps.dark_gain[:, 3, 5], 1 + 1000.0 / rates)


# ---- records and defaults ---------------------------------------------------------------------------------------

def test_the_sidecar_records_the_frame_effects(tmp_path):
    from camsim.cli import main
    from camsim.render.frame_files import load_frame
    from tests.support.helpers import ROOT

    out = tmp_path / "out"
    assert main(["render", str(ROOT / "scenes" / "macbeth_26.toml"), "--illuminant", "D65", "--intensity", "1",
                 "--size", "48x32", "-q", "--out", str(out), "--sensor", "black_level_error_dn=2",
                 "--sensor", "temperature_c=31", "--sensor", "stuck_pixel_fraction=0.01",
                 "--sensor", "dark_shading_e=2"]) == 0
    exr = next(out.rglob("*.exr"))
    meta = json.loads(exr.with_suffix(".json").read_text())
    assert len(meta["black_level_error_drawn_dn"]) == 3
    assert meta["dark_current_effective_e_per_s"] == pytest.approx(
        [2 * v for v in SensorParams().dark_current_e_per_s])
    assert set(meta["defect_counts"]) == {"hot", "dead", "stuck"} and meta["defect_counts"]["stuck"] > 0
    assert load_frame(exr).meta["black_level_error_drawn_dn"] == meta["black_level_error_drawn_dn"]


def test_the_effects_off_change_nothing():
    sensor = SensorParams(cfa="RGGB", dsnu_e=2.0, prnu_percent=1.0)
    same = SensorParams(cfa="RGGB", dsnu_e=2.0, prnu_percent=1.0, temperature_c=None, hot_pixel_fraction=0.0,
                        black_level_error_dn=0.0, dark_shading_e=0.0, column_fpn_e=0.0)
    a, b = draw(sensor, seed=3), draw(same, seed=3)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert sensor.sidecar_record() == SensorParams(cfa="RGGB", dsnu_e=2.0, prnu_percent=1.0).sidecar_record()
    assert not {"temperature_c", "hot_pixel_fraction", "black_level_error_dn"} & set(sensor.sidecar_record())


def test_a_scene_files_map_paths_are_relative_to_it(tmp_path):
    from camsim.scene.scene_file import load_scene

    (tmp_path / "maps").mkdir()
    np.save(tmp_path / "maps" / "shading.npy", np.zeros((32, 48)))
    scene = tmp_path / "s.toml"
    scene.write_text('name = "mine"\n[chart]\n[sensor]\ndark_shading_map = "maps/shading.npy"\n')
    loaded = load_scene(scene)
    assert loaded.sensor.dark_shading_map == str(tmp_path / "maps" / "shading.npy")
    assert loaded.name == "mine"


@pytest.mark.parametrize("method", ["poisson", "gaussian", "auto", "table"])
def test_hot_pixels_clip_at_the_full_well_and_dead_pixels_stay_black_in_bright_light(method):
    k = SensorParams().dn_per_electron
    hot = SensorParams(read_noise=False, quantisation=False, hot_pixel_fraction=0.01, hot_pixel_dark_e_per_s=1e5,
                       dark_shading_e=50.0, sensor_seed=3)
    noisy = draw(hot, (64, 64), method=method, signal_e=100.0)[0]
    assert noisy.max() <= np.float32(k * 9000.0) and np.sum(noisy >= np.float32(k * 9000.0)) > 0.5 * 0.01 * noisy.size
    dead = SensorParams(read_noise=False, quantisation=False, dead_pixel_fraction=0.01, sensor_seed=3)
    noisy, _, clean, maps, _ = draw(dead, (64, 64), method=method, signal_e=1e6)
    is_dead = maps.gain == 0
    assert np.all(noisy[is_dead] == 0) and np.all(clean[is_dead] == 0)
    assert np.all(noisy[~is_dead] == np.float32(k * 9000.0))


def test_black_level_includes_the_column_fpn():
    # a dark level near the ADC's zero, where the clip makes the mean depend on the offsets' spread
    sensor = SensorParams(**{**UNIT, "saturation": False}, dark_current_e_per_s=(0.5,) * 3, read_noise_e=1.0,
                          column_fpn_e=3.0, sensor_seed=21)
    digital = draw(sensor, (64, 4096), seed=2)[1].astype(np.float64)
    column_means = digital.mean(axis=1)  # (3, W)
    se = column_means.std(axis=1, ddof=1) / math.sqrt(column_means.shape[1])
    level = sensor.black_level_dn
    assert np.all(np.abs(column_means.mean(axis=1) - level) < 5 * se)
    without = SensorParams(**{**UNIT, "saturation": False}, dark_current_e_per_s=(0.5,) * 3, read_noise_e=1.0)
    assert np.all(level - without.black_level_dn > 0.5)  # the clip at 0 lifts the mean by about E[max(o, 0)]


def test_an_absurd_temperature_is_refused_in_one_line():
    with pytest.raises(CamsimError, match="1000 doublings") as info:
        SensorParams(temperature_c=1414.0, dark_current_doubling_c=1.0)  # the hottest sensor, doubling each °C
    assert "\n" not in str(info.value)
    with pytest.raises(CamsimError, match=r"temperature_c must be ≥ -273\.15 and ≤ 1414 °C, got 1e\+300"):
        SensorParams(temperature_c=1e300)
    with pytest.raises(CamsimError, match="temperature_c"):
        SensorParams(temperature_c=-300.0)


def _header_only_npy(path, shape):
    from numpy.lib import format as npy_format

    with open(path, "wb") as file:
        npy_format.write_array_header_1_0(file, {"descr": "<f4", "fortran_order": False, "shape": shape})
        file.write(bytes(64))
    return path


@pytest.mark.parametrize("case", ["text", "huge", "short", "pickle"])
def test_hostile_map_files_are_one_line_refusals_before_their_data_is_read(tmp_path, capsys, case):
    """A map file is input: a file that is not a .npy, a header claiming 10¹⁰ values or more data than the file
    holds, an object array — each one line, exit 2, nothing written (the header is checked before any data is read)."""
    from camsim.cli import main

    path = tmp_path / "map.npy"
    if case == "text":
        path.write_text("root:x:0:0:root:/root:/bin/bash\n")
    elif case == "huge":
        _header_only_npy(path, (100_000, 100_000))
    elif case == "short":
        _header_only_npy(path, (64, 96))
    else:
        np.save(path, np.array([{"a": 1}], dtype=object), allow_pickle=True)
    out = tmp_path / "out"
    rc = main(["render", "macbeth_26", "--size", "96x64", "--illuminant", "D65", "-F", "1", "--out", str(out), "-q",
               "--sensor", f"dark_shading_map={path}"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and err[0].startswith("camsim: error: "), err
    words = {"text": "not a .npy file", "huge": "more than a frame", "short": "the file holds",
             "pickle": "must hold a real number array"}[case]
    assert words in err[0] and "pickle" not in err[0], err
    assert not out.exists() or not any(out.iterdir())


def test_a_black_level_error_beyond_a_frames_range_is_named(capsys):
    from camsim.cli import main

    rc = main(["render", "macbeth_26", "--size", "96x64", "--illuminant", "D65", "-F", "1", "-q",
               "--sensor", "black_level_error_dn=1e300", "--out", "/nonexistent-never-written"])
    err = capsys.readouterr().err
    assert rc == 2 and "black_level_error_dn must be ≥ 0 and ≤ 65535 DN, got 1e+300" in err and err.count("\n") == 1


def test_frames_drawn_one_after_another_from_one_generator_get_their_own_black_level_errors():
    """A caller that draws frames from one numpy Generator (or SeedSequence) gets a new black-level error per frame,
    as it gets new noise; a fresh seed gives the same error again."""
    from camsim.core.seeding import block_generators
    from camsim.render.frame import black_level_error

    sensor = SensorParams(black_level_error_dn=2.0)
    for make in (lambda: np.random.default_rng(5), lambda: np.random.SeedSequence(5)):
        rng = make()
        errors = []
        for _ in range(3):
            errors.append(black_level_error(sensor, rng))
            block_generators(rng, 4)  # what drawing the frame's blocks does to rng
        assert len({tuple(e) for e in errors}) == 3
        np.testing.assert_array_equal(black_level_error(sensor, make()), errors[0])
