"""``camsim calibrate`` measures the effects of issue 28: the dark-shading map, hot pixels, column FPN and the
black-level error — each estimator of :mod:`camsim.calibration.fixed_pattern` on dark frames of known law drawn
here (:func:`draw_darks`, independent of camsim's renderer), then the command's round trip.

The synthetic darks: an RGGB mosaic, DN = floor(B + s + c_j + h + b_f,colour + ρ_f,i + ε), with s a smooth shading
plus a white per-pixel DSNU, c a per-column offset, h a hot pixel's extra (on a share of the pixels), b the frame's
offset per colour (R, G, B; the two greens share it), ρ row noise and ε Gaussian pixel noise.
"""

import numpy as np
import pytest

from camsim.calibration import dark
from camsim.calibration import fixed_pattern as fp


def draw_darks(rng, *, frames=16, shape=(128, 256), black=512.0, shading=3.0, dsnu=1.5, column=0.0, hot=0.0,
               hot_dn=(40.0, 400.0), offset=0.0, row=0.0, sigma=2.0):
    """Dark frames of known law (module docstring), with their truth.

    Returns
    -------
    (numpy.ndarray, dict)
        The frames (n, H, W) int64 in DN, and the truth: ``shading`` (s, DN), ``columns`` (c, (W,)), ``hot``
        (h, (H, W), 0 where not hot), ``offsets`` (b, (n, 3)).
    """
    h, w = shape
    y, x = np.mgrid[0:h, 0:w]
    smooth = np.cos(np.pi * x / w) + 0.5 * ((y / h) - 0.5) * (x / w)  # a vignette-like shading
    s = shading * smooth / smooth.std() + rng.normal(0, dsnu, shape)
    c = rng.normal(0, column, w) if column else np.zeros(w)
    hot_map = np.zeros(shape)
    if hot:
        where = rng.random(shape) < hot
        hot_map[where] = rng.uniform(*hot_dn, np.count_nonzero(where))
    b = rng.normal(0, offset, (frames, 3)) if offset else np.zeros((frames, 3))
    colour = np.array([[0, 1], [1, 2]])[y % 2, x % 2]  # RGGB: R 0, G 1, B 2
    fixed = black + s + c[None, :] + hot_map
    out = np.empty((frames, h, w), np.int64)
    for f in range(frames):
        level = fixed + b[f][colour] + rng.normal(0, row, (h, 1)) + rng.normal(0, sigma, shape)
        out[f] = np.floor(level)
    return out, {"shading": s, "columns": c, "hot": hot_map, "offsets": b, "colour": colour}


def planes(image):
    """The four RGGB sites of a mosaic (R, Gr, Gb, B)."""
    return [image[..., dy::2, dx::2] for dy in (0, 1) for dx in (0, 1)]


def moments(x):
    n = x.shape[0]
    return dark.pixel_moments(x.sum(axis=0), (x * x).sum(axis=0), n)


def test_hot_pixels_found_with_recall_and_precision():
    """At a share of 10⁻³ and extras of 40–400 DN over a spread of √(1.5² + 2²/16) = 1.52 DN, every hot pixel is far
    above the 5 σ threshold (7.6 DN) and a normal pixel passes it with probability 3 × 10⁻⁷: recall and precision
    ≥ 0.95 (here 1), and each hot pixel's excess is its drawn extra within the mean's noise (2/√16 DN and the
    neighbourhood median's)."""
    rng = np.random.default_rng(1)
    x, truth = draw_darks(rng, shape=(256, 512), hot=1e-3)
    mean, var = moments(x)
    found = np.zeros(mean.shape, bool)
    excess = np.zeros(mean.shape)
    for (dy, dx), m, v in zip([(0, 0), (0, 1), (1, 0), (1, 1)], planes(mean), planes(var)):
        hot = fp.find_hot_pixels(m, float(np.mean(v)), x.shape[0])
        assert hot.spread_dn == pytest.approx(np.hypot(1.5, 2 / 4), rel=0.1)
        found[dy::2, dx::2] = hot.mask
        excess[dy::2, dx::2] = hot.excess_dn
    true = truth["hot"] > 0
    assert true.sum() > 80
    recall = np.count_nonzero(found & true) / np.count_nonzero(true)
    precision = np.count_nonzero(found & true) / np.count_nonzero(found)
    assert recall >= 0.95 and precision >= 0.95
    err = excess[found & true] - truth["hot"][found & true]
    assert abs(np.mean(err)) < 1.0 and np.std(err) < 2.5  # DSNU 1.5 and the local median's offset, not the extra


def test_a_normal_plane_has_few_hot_pixels():
    """Without hot pixels the 5 σ threshold (Gaussian tail 2.9 × 10⁻⁷) flags almost none of 131 072 pixels."""
    rng = np.random.default_rng(2)
    x, _ = draw_darks(rng, shape=(256, 512), dsnu=3.0)
    mean, var = moments(x)
    count = sum(fp.find_hot_pixels(m, float(np.mean(v)), x.shape[0]).count for m, v in zip(planes(mean), planes(var)))
    assert count <= 3


def test_a_one_frame_outlier_is_not_a_hot_pixel():
    """A burst of 60 DN in one frame of 16 lifts a pixel's mean by 3.75 DN, beyond the 5 σ threshold (5 × 0.51 DN
    here); the test in halves (each half's mean above half the threshold, 1.26 DN, where the half without the burst
    has noise 2/√8 = 0.71 DN) drops it but with probability P(z > 1.78) = 3.7 % (≤ 4 of 40 allowed), while every hot
    pixel of 20–60 DN stays."""
    rng = np.random.default_rng(6)
    x, truth = draw_darks(rng, frames=16, shape=(128, 256), shading=0.0, dsnu=0.0, hot=2e-3, hot_dn=(20.0, 60.0))
    burst = np.zeros((128, 256), bool)
    burst[rng.integers(0, 128, 40), rng.integers(0, 256, 40)] = True
    burst &= truth["hot"] == 0
    x[3][burst] += 60
    mean, var = moments(x)
    halves = (x[0::2].mean(axis=0), x[1::2].mean(axis=0))
    alone = np.zeros(burst.shape, bool)
    both = np.zeros(burst.shape, bool)
    for (dy, dx), m, v, a, b in zip([(0, 0), (0, 1), (1, 0), (1, 1)], planes(mean), planes(var), planes(halves[0]),
                                    planes(halves[1])):
        alone[dy::2, dx::2] = fp.find_hot_pixels(m, v, 16).mask
        both[dy::2, dx::2] = fp.find_hot_pixels(m, v, 16, (a, b)).mask
    true = truth["hot"] > 0
    assert np.array_equal(alone, true | burst) and burst.sum() > 30
    assert np.all(both[true]) and np.count_nonzero(both & burst) <= 4


def test_shading_map_and_its_standard_error():
    """The map (mean less the plane's black) correlates with the drawn shading above 0.95 at 16 darks (its noise
    σ/√n = 0.5 DN against a pattern of 3.4 DN RMS), and the RMS of map − truth is the stated standard error
    √(σ̄²/n) (σ² = 4 + 1/12 DN² with the quantiser; the map is less the black level, whose error is negligible)."""
    rng = np.random.default_rng(3)
    x, truth = draw_darks(rng, frames=16, hot=1e-3)
    mean, var = moments(x)
    full = np.zeros(mean.shape)
    for (dy, dx), m, v in zip([(0, 0), (0, 1), (1, 0), (1, 1)], planes(mean), planes(var)):
        hot = fp.find_hot_pixels(m, float(np.mean(v)), 16)
        black = float(np.mean(m[~hot.mask]))
        full[dy::2, dx::2] = fp.shading_map(m, black, hot)
    s = truth["shading"] - truth["shading"].mean()
    assert np.corrcoef(full.ravel(), s.ravel())[0, 1] > 0.95
    normal = truth["hot"] == 0
    err = (full - s)[normal]
    se = fp.map_standard_error(float(np.mean(var[normal])), 16)  # no row noise, no frame offsets here
    assert se == pytest.approx(np.sqrt((4 + 1 / 12) / 16), rel=0.03)
    assert np.sqrt(np.mean((err - err.mean()) ** 2)) == pytest.approx(se, rel=0.03)
    rms = fp.fixed_pattern_rms(full[normal], float(np.mean(var)), 16)
    assert abs(rms.value - s[normal].std()) < 4 * rms.standard_error


@pytest.mark.parametrize("column", [0.0, 0.8])
def test_column_fpn(column):
    """σ_c from the column means of the map less v_e/H: within 4 standard errors of the drawn columns' own spread,
    with a smooth shading across the columns (removed as the trend) and a DSNU of 1.5 DN whose share in a column
    mean, 1.5²/128 DN², would read as σ_c = 0.13 DN if not removed."""
    rng = np.random.default_rng(4 + int(10 * column))
    x, truth = draw_darks(rng, frames=16, shape=(128, 1024), column=column)
    mean, _ = moments(x)
    full = np.zeros(mean.shape)
    for (dy, dx), m in zip([(0, 0), (0, 1), (1, 0), (1, 1)], planes(mean)):
        full[dy::2, dx::2] = fp.shading_map(m, float(np.mean(m)))
    est = fp.column_fpn(full)
    c = truth["columns"]
    t = np.linspace(-1, 1, c.size)
    basis = np.polynomial.legendre.legvander(t, fp.COLUMN_TREND_DEGREE)
    resid = c - basis @ np.linalg.lstsq(basis, c, rcond=None)[0]
    drawn = np.sqrt(np.sum(resid**2) / (c.size - fp.COLUMN_TREND_DEGREE - 1))
    assert abs(est.value - drawn) < 4 * est.standard_error + 0.02
    naive = np.sqrt(max(np.var(full.mean(axis=0) - basis @ np.linalg.lstsq(basis, full.mean(axis=0), rcond=None)[0],
                               ddof=fp.COLUMN_TREND_DEGREE + 1), 0))
    if column == 0:
        assert est.value < 0.05 and naive > 0.1  # the correction matters


@pytest.mark.parametrize(("offset", "row"), [(0.0, 3.0), (0.7, 0.5)])
def test_black_level_error(offset, row):
    """Per-frame colour means over 300 small frames: σ_b² = s²(F) − σ_Y²/N − σ_row²/R. Without an offset but with
    row noise 3 DN, s²(F) of R (R = 16 rows of its sites) is 9/16 DN² — the estimate must remove it (within 4 SE of
    0); with σ_b = 0.7 DN it is within 4 SE of the drawn offsets' own variance."""
    rng = np.random.default_rng(5)
    frames = 300
    x, truth = draw_darks(rng, frames=frames, shape=(32, 64), offset=offset, row=row, shading=0, dsnu=0.5)
    colour = truth["colour"]
    means = np.stack([x[:, colour == c].mean(axis=1) for c in range(3)], axis=1)
    pixels = [np.count_nonzero(colour == c) for c in range(3)]
    rows = [16, 32, 16]
    var_y = [4 + 1 / 12] * 3
    est = fp.black_level_error_variance(means, var_y, pixels, row**2, rows)
    drawn = float(np.mean(np.var(truth["offsets"], axis=0, ddof=1)))
    assert abs(est.value - drawn) < 4 * est.standard_error
    if offset == 0:
        naive = float(np.mean(np.var(means, axis=0, ddof=1)))
        assert naive > 8 * est.standard_error
    sd = fp.black_level_error(means, var_y, pixels, row**2, rows)
    assert sd.value == pytest.approx(np.sqrt(max(est.value, 0)))


def test_hot_fraction_standard_error():
    est = fp.hot_fraction(100, 100_000)
    assert est.value == 1e-3 and est.standard_error == pytest.approx(np.sqrt(1e-3 * 0.999 / 1e5))


# --- the round trip: camsim's renderer with issue 28's effects on, camsim calibrate, the calibrated preset --------

import json  # noqa: E402
import tomllib  # noqa: E402

from camsim.cli import main  # noqa: E402
from camsim.io.dng import write_dng_cfa  # noqa: E402
from camsim.light.spectra import WavelengthGrid  # noqa: E402
from camsim.render.pipeline import LitScene, make_frame  # noqa: E402
from camsim.sensor.fixed_pattern import column_fpn_pattern, fixed_pattern  # noqa: E402
from camsim.sensor.params import SensorParams  # noqa: E402
from camsim.sensor.presets import sensor_preset  # noqa: E402

GRID = WavelengthGrid(500.0, 600.0, 50.0)  # three bins; with an identity Qe each feeds one channel
DARKS = 16
SITES = np.array([[0, 1], [1, 2]])  # RGGB: the channel of each site of the 2 × 2 cell


def fx_sensor(**effects) -> SensorParams:
    """A 14-bit RGGB sensor, K = 1 DN/e⁻, read noise 1.5 e⁻, row noise 0.2 e⁻, DSNU 0.5 e⁻, PRNU 0.5 %, dark
    current 0.5 e⁻/s over 2 s (hot pixels need one > 0), with ``effects`` on."""
    return SensorParams(cfa="RGGB", bits=14, conversion_gain_v_per_e=1e-4, analog_gain_dn_per_v=1e4,
                        dark_current_e_per_s=(0.5, 0.5, 0.5), exposure_s=2.0, full_well_e=20000.0, read_noise_e=1.5,
                        read_noise_model="gaussian", row_noise_e=0.2, dsnu_e=0.5, prnu_percent=0.5, pedestal_dn=512,
                        sensor_seed=7, **effects)


def render(sensor, shape, electrons, seed):
    """One frame of a uniform field of ``electrons`` (R, G, B) per pixel."""
    lit = LitScene(np.zeros(shape, np.uint8), np.array([electrons], float), np.eye(3), GRID)
    return make_frame(lit, sensor, 1.0, rng=seed, workers=1)


def shoot_fx(sensor, folder, shape, levels=(0.05, 0.15, 0.3)):
    """16 darks and a flat pair at each level (share of the range above the pedestal) as DNGs with their exposure;
    returns (dark paths, flat paths, the darks' drawn black-level errors (n, 3))."""
    seeds = iter(np.random.SeedSequence(28).spawn(DARKS + 2 * len(levels)))
    drawn = []

    def shot(name, electrons):
        frame = render(sensor, shape, electrons, next(seeds))
        if not any(electrons):
            drawn.append(frame.black_level_error_dn if frame.black_level_error_dn is not None else np.zeros(3))
        write_dng_cfa(folder / name, frame.digital_dn[0], pattern="RGGB", white_level=sensor.max_dn,
                      black_level_dn=sensor.black_level_tag_dn, unique_camera_model="camsim effects test",
                      color_matrix1=np.eye(3), as_shot_neutral=[1, 1, 1], exposure_s=sensor.exposure_s, iso=3200)
        return str(folder / name)

    darks = [shot(f"dark_{i:02d}.dng", [0.0, 0.0, 0.0]) for i in range(DARKS)]
    span = (sensor.max_dn - sensor.pedestal_dn) / sensor.dn_per_electron
    flats = [shot(f"flat_{j}_{i}.dng", [f * span] * 3) for j, f in enumerate(levels) for i in range(2)]
    return darks, flats, np.array(drawn)


def mosaic_of(maps3):
    """The (H, W) mosaic of a (3, H, W) map: each RGGB site its channel's value."""
    h, w = maps3.shape[1:]
    y, x = np.mgrid[0:h, 0:w]
    return maps3[SITES[y % 2, x % 2], y, x]


def calibrate(capsys, darks, flats, out, *extra):
    code = main(["calibrate", "--dark", *darks, "--flat", *flats, "--out", str(out), "-q", *extra])
    assert code == 0, capsys.readouterr().err
    return (tomllib.loads((out / "preset.toml").read_text(encoding="utf-8")),
            json.loads((out / "calibration.json").read_text(encoding="utf-8")))


def mean_less_black(frames):
    """The mean of dark frames (n, H, W) less each RGGB plane's mean (DN)."""
    m = np.mean(frames, axis=0, dtype=np.float64)
    for dy in (0, 1):
        for dx in (0, 1):
            m[dy::2, dx::2] -= m[dy::2, dx::2].mean()
    return m


@pytest.mark.slow
def test_round_trip_dark_shading_hot_pixels_and_black_level_error(tmp_path, capsys):
    """Darks of 256 × 512 with a dark shading of RMS 3 e⁻, hot pixels (share 10⁻³, exponential of mean 1000 e⁻/s over
    2 s) and a black-level error of σ 1 DN, calibrated and rendered again with the calibrated preset.

    Expected, K = 1 DN/e⁻: the fixed offset (shading and DSNU) σ_p = √(3² + 0.5²) = 3.04 e⁻; a pixel's temporal
    variance σ_t² = 1.5² + 0.5 · 2 + 1/12 = 3.33 e⁻², so the map of 16 darks has noise √(σ_t²/16) = 0.46 e⁻ and
    correlates with the truth as σ_p / √(σ_p² + σ_t²/16) = 0.989; the mean of 16 darks of the calibrated preset adds
    as much noise again: 0.978 (both required above 0.95). Hot pixels: the threshold (5 robust σ of the mean less its
    5 × 5 median, ~15 DN with the shading's row and column profiles) misses an exponential extra of mean 2000 e⁻ with
    probability 1 − exp(−15/2000) < 1 %; a normal pixel passes it with the Gaussian tail's 3 × 10⁻⁷: recall and
    precision ≥ 0.95 of ~131 hot pixels. The black-level error: σ_b from 16 frames × 3 colours has a standard error
    of about σ_b / √(2 · 3 · 15) = 0.11 DN (4 of them allowed), and it is the drawn offsets' own spread within 0.05 DN
    (the colour means' noise, √(σ_t²/N + σ_row²/R) ≈ 0.02 DN, is what differs)."""
    shape = (256, 512)
    truth_sensor = fx_sensor(dark_shading_e=3.0, hot_pixel_fraction=1e-3, hot_pixel_dark_e_per_s=1000.0,
                             black_level_error_dn=1.0)
    darks, flats, drawn = shoot_fx(truth_sensor, tmp_path, shape)
    out = tmp_path / "cal"
    preset, record = calibrate(capsys, darks, flats, out)
    iso = preset["iso"][0]
    assert iso["dark_shading_map"] == "dark_shading.npy" and iso["hot_pixel_map"] == "hot_pixels.npy"
    assert iso["dsnu_dn"] == 0 and iso["column_fpn_e"] == 0  # the map holds them
    fx = record["dark_effects"]

    truth = fixed_pattern(truth_sensor, shape)
    offset = mosaic_of(np.asarray(truth.offset_e, np.float64))
    offset -= offset.mean()
    rate = truth_sensor.dark_current_e_per_s[0]
    extra_e = (np.asarray(truth.dark_gain[0], np.float64) - 1) * rate * truth_sensor.exposure_s  # the hot charge
    is_hot = extra_e > 0
    # the map
    shading = np.load(out / "dark_shading.npy")
    assert shading.shape == shape and shading.dtype == np.float32
    normal = ~is_hot
    rho = np.corrcoef(shading[normal], offset[normal])[0, 1]
    sigma_t2 = 1.5**2 + 0.5 * 2 + 1 / 12
    expected = offset[normal].std() / np.sqrt(offset[normal].var() + sigma_t2 / DARKS)
    assert rho > 0.95 and rho == pytest.approx(expected, abs=0.005)
    # its stated error: the pixels' and the rows' temporal noise over 16 frames (the frames' offsets cancel)
    assert fx["dark_shading"]["per_pixel_standard_error_e"] == pytest.approx(np.sqrt((sigma_t2 + 0.2**2) / DARKS),
                                                                             rel=0.03)
    # hot pixels
    hot = np.load(out / "hot_pixels.npy")
    found = hot > 0
    recall = np.count_nonzero(found & is_hot) / np.count_nonzero(is_hot)
    precision = np.count_nonzero(found & is_hot) / np.count_nonzero(found)
    assert np.count_nonzero(is_hot) > 90 and recall >= 0.95 and precision >= 0.95
    both = found & is_hot
    rel = hot[both] * truth_sensor.exposure_s / extra_e[both] - 1
    assert abs(np.median(rel)) < 0.02  # the extra dark current (e⁻/s): the 5 × 5 median's level is the shading's
    assert fx["hot_pixels"]["fraction"]["value"] == pytest.approx(1e-3, abs=4 * fx["hot_pixels"]["fraction"][
        "standard_error"])
    # the black-level error
    b = fx["black_level_error_dn"]
    assert abs(b["value"] - 1.0) < 4 * b["standard_error"]
    assert b["value"] == pytest.approx(np.sqrt(np.mean(np.var(drawn, axis=0, ddof=1))), abs=0.05)
    assert iso["black_level_error_dn"] == pytest.approx(b["value"], rel=1e-5)

    # rendered again with the calibrated preset: its mean dark is the truth's pattern, its hot pixels those found
    again = sensor_preset(str(out / "preset.toml"), 3200)
    assert again.black_level_error_dn == pytest.approx(b["value"], rel=1e-5) and again.hot_pixel_map is not None
    seeds = np.random.SeedSequence(99).spawn(DARKS)
    frames = np.stack([render(again, shape, [0.0, 0.0, 0.0], s).digital_dn[0] for s in seeds])
    mean = mean_less_black(frames)
    rho = np.corrcoef(mean[normal], offset[normal])[0, 1]
    assert rho > 0.95 and rho == pytest.approx(offset[normal].std() / np.sqrt(offset[normal].var()
                                                                            + 2 * sigma_t2 / DARKS), abs=0.005)
    assert fixed_pattern(again, shape).defect_counts["hot"] == np.count_nonzero(found)
    assert np.corrcoef(mean[both], extra_e[both])[0, 1] > 0.999


@pytest.mark.slow
@pytest.mark.parametrize("maps", [True, False])
def test_round_trip_column_fpn(tmp_path, capsys, maps):
    """Column FPN of σ 1 e⁻ (256 columns), DSNU 0.5 e⁻: σ_c within 4 standard errors of the drawn columns' own
    detrended spread (√(2/252) ≈ 9 % of σ_c² is the estimator's, from 256 column means of noise v_e/H =
    (0.5² + 3.33/16)/128 e⁻², negligible); the preset renders it through the map (``column_fpn_e`` = 0 there), or
    with ``--no-maps`` as ``column_fpn_e`` (and the DSNU without the columns' share), which renders that σ again."""
    shape = (128, 256)
    truth_sensor = fx_sensor(column_fpn_e=1.0)
    darks, flats, _ = shoot_fx(truth_sensor, tmp_path, shape)
    out = tmp_path / "cal"
    preset, record = calibrate(capsys, darks, flats, out, *([] if maps else ["--no-maps"]))
    iso = preset["iso"][0]
    c = column_fpn_pattern(truth_sensor.sensor_seed, 1, shape[1])[0, 0]
    t = np.linspace(-1, 1, c.size)
    basis = np.polynomial.legendre.legvander(t, fp.COLUMN_TREND_DEGREE)
    resid = c - basis @ np.linalg.lstsq(basis, c, rcond=None)[0]
    drawn = np.sqrt(np.sum(resid**2) / (c.size - fp.COLUMN_TREND_DEGREE - 1))
    est = record["dark_effects"]["column_fpn_e"]
    assert abs(est["value"] - drawn) < 4 * est["standard_error"] and est["standard_error"] < 0.06
    assert record["dark_effects"]["black_level_error_dn"]["ci95"][0] == 0 and iso["black_level_error_dn"] == 0
    if maps:
        assert iso["column_fpn_e"] == 0 and iso["dark_shading_map"] == "dark_shading.npy"
        return
    assert "dark_shading_map" not in iso and "hot_pixel_map" not in iso
    assert iso["column_fpn_e"] == pytest.approx(est["value"], rel=1e-5)
    assert iso["dsnu_dn"] == pytest.approx(0.5, rel=0.1)
    again = sensor_preset(str(out / "preset.toml"), 3200)
    assert again.column_fpn_e == pytest.approx(est["value"], rel=1e-5)


# --- preset files that name the effects -----------------------------------------------------------------------------

from camsim.core.errors import CamsimError  # noqa: E402
from camsim.sensor.presets import read_preset_file  # noqa: E402

HEAD = '[preset]\nname = "fx"\nsource = "test"\nbits = 12\npedestal_dn = 64\ncfa = "RGGB"\n'
POINT = "[[iso]]\niso = {iso}\nk_dn_per_e = 2.0\ntukey_lambda = 0.14\ntukey_scale_dn = 1.0\ngaussian_sigma_dn = 2.0\n"


def _preset(folder, *points, dark_current=True):
    head = HEAD + ("dark_current_e_per_s = 0.001\n" if dark_current else "")
    (folder / "p.toml").write_text(head + "\n".join(points), encoding="utf-8")
    return folder / "p.toml"


def test_a_preset_file_renders_its_maps(tmp_path):
    """The map paths are relative to the preset file, made absolute; the effects hold at their ISO; a render with the
    preset adds the map's pattern (its mean dark is the map × K + the pedestal, to the frames' noise)."""
    (tmp_path / "maps").mkdir()
    shading = np.random.default_rng(1).normal(0, 5, (32, 48)).astype(np.float32)
    hot = np.zeros((32, 48), np.float32)
    hot[3, 5] = 1000.0
    np.save(tmp_path / "maps" / "s.npy", shading)
    np.save(tmp_path / "maps" / "h.npy", hot)
    path = _preset(tmp_path, POINT.format(iso=100) + 'dark_shading_map = "maps/s.npy"\nhot_pixel_map = "maps/h.npy"\n'
                   "column_fpn_e = 0.25\nblack_level_error_dn = 0.5\n", POINT.format(iso=400))
    camera = read_preset_file(path)
    sensor = camera.sensor(100)
    assert sensor.dark_shading_map == str((tmp_path / "maps" / "s.npy").resolve())
    assert sensor.hot_pixel_map == str((tmp_path / "maps" / "h.npy").resolve())
    assert (sensor.column_fpn_e, sensor.black_level_error_dn) == (0.25, 0.5)
    plain = camera.sensor(400)  # the other point states none
    assert (plain.dark_shading_map, plain.hot_pixel_map, plain.column_fpn_e, plain.black_level_error_dn) == (
        None, None, 0.0, 0.0)
    with pytest.raises(CamsimError, match="hold at ISO 100 only"):
        camera.sensor(200)
    sensor = sensor_preset(str(path), 100, column_fpn_e=0.0, black_level_error_dn=0.0)
    frames = np.stack([render(sensor, (32, 48), [0.0, 0.0, 0.0], s).digital_dn[0] for s in range(16)])
    mean = frames.mean(axis=0) - 64
    # K = 2: the map is 10 DN RMS; the frames' noise (2 DN) / 4 and the ADC's ½-offset stay
    assert np.corrcoef(mean[~(hot > 0)], shading[~(hot > 0)])[0, 1] > 0.99
    assert mean[3, 5] == pytest.approx(2 * (1000 * 1.0 + shading[3, 5]), rel=0.05)  # 1000 e⁻/s × 1 s


@pytest.mark.parametrize(("setup", "message"), [
    ({"s.npy": np.zeros((32, 48)), "h.npy": np.zeros((32, 46))}, r"the maps' shapes differ"),
    ({"s.npy": np.zeros((31, 48))}, r"dark_shading_map of a RGGB sensor must be a mosaic \(H, W\) of even sides"),
    ({"h.npy": -np.ones((32, 48))}, r"holds a negative dark current"),
    ({"s.npy": np.full((32, 48), np.nan)}, r"holds a NaN or an infinity"),
    ({"s.npy": np.zeros((2, 32, 48))}, r"must hold numbers of shape \(H, W\) or \(3, H, W\)"),
    ({}, r"dark_shading_map file not found"),
])
def test_bad_maps_are_refused(tmp_path, setup, message):
    for name, array in setup.items():
        np.save(tmp_path / name, array)
    keys = ('dark_shading_map = "s.npy"\n' if "h.npy" not in setup or "s.npy" in setup else "") + (
        'hot_pixel_map = "h.npy"\n' if "h.npy" in setup else "")
    path = _preset(tmp_path, POINT.format(iso=100) + keys)
    with pytest.raises(CamsimError, match=message):
        read_preset_file(path)


def test_bad_effect_values_are_refused(tmp_path):
    path = _preset(tmp_path, POINT.format(iso=100) + "column_fpn_e = -1.0\n")
    with pytest.raises(CamsimError, match=r"\[\[iso\]\] #1: .*column_fpn_e must be ≥ 0"):
        read_preset_file(path)


@pytest.mark.slow
def test_round_trip_three_chip(tmp_path, capsys):
    """A three-chip sensor (3-sample DNGs): maps of shape (3, H, W), hot pixels per chip, the colour offsets per chip;
    the same expectations as the mosaic's (map correlation σ_p/√(σ_p² + σ_t²/n) ≈ 0.99 per chip, recall and
    precision ≥ 0.95, σ_b within 4 standard errors of 1 DN), and the calibrated preset renders (3, H, W) frames."""
    import dataclasses

    from camsim.io.dng import write_dng

    shape = (128, 192)
    truth_sensor = dataclasses.replace(fx_sensor(dark_shading_e=3.0, hot_pixel_fraction=1e-3,
                                                 hot_pixel_dark_e_per_s=1000.0, black_level_error_dn=1.0), cfa=None)
    seeds = iter(np.random.SeedSequence(3).spawn(DARKS + 6))

    def shot(name, electrons):
        frame = render(truth_sensor, shape, electrons, next(seeds))
        write_dng(tmp_path / name, frame.digital_dn, white_level=truth_sensor.max_dn,
                  black_level_dn=truth_sensor.black_level_tag_dn, unique_camera_model="camsim stack test",
                  color_matrix1=np.eye(3), as_shot_neutral=[1, 1, 1], exposure_s=truth_sensor.exposure_s, iso=100)
        return str(tmp_path / name)

    darks = [shot(f"d{i:02d}.dng", [0.0, 0.0, 0.0]) for i in range(DARKS)]
    span = truth_sensor.max_dn - truth_sensor.pedestal_dn
    flats = [shot(f"f{j}_{i}.dng", [f * span] * 3) for j, f in enumerate((0.05, 0.15, 0.3)) for i in range(2)]
    out = tmp_path / "cal"
    preset, record = calibrate(capsys, darks, flats, out)
    truth = fixed_pattern(truth_sensor, shape)
    is_hot = np.asarray(truth.dark_gain, np.float64) > 1
    offset = np.asarray(truth.offset_e, np.float64)
    shading, hot = np.load(out / "dark_shading.npy"), np.load(out / "hot_pixels.npy")
    assert shading.shape == hot.shape == (3, *shape)
    sigma_t2 = 1.5**2 + 0.5 * 2 + 1 / 12
    for c in range(3):
        normal = ~is_hot[c]
        o = offset[c][normal]
        rho = np.corrcoef(shading[c][normal], o)[0, 1]
        assert rho > 0.95 and rho == pytest.approx(o.std() / np.sqrt(o.var() + sigma_t2 / DARKS), abs=0.005)
    found = hot > 0
    assert np.count_nonzero(found & is_hot) >= 0.95 * np.count_nonzero(is_hot) > 50
    assert np.count_nonzero(found & is_hot) >= 0.95 * np.count_nonzero(found)
    b = record["dark_effects"]["black_level_error_dn"]
    assert abs(b["value"] - 1.0) < 4 * b["standard_error"]
    assert preset["iso"][0]["hot_pixel_map"] == "hot_pixels.npy"
    again = sensor_preset(str(out / "preset.toml"), 100)
    assert render(again, shape, [0.0, 0.0, 0.0], 1).digital_dn.shape == (3, *shape)
