"""Camera presets (camsim.sensor.presets): the published figures, their conversion to the model's units, the ISO
axis and its interpolation, rendered dark frames against the published σ's, preset files, and bad input.

The published tables are read from ``../shared/data/cameras`` where present (skipped cleanly where not): the
presets must carry the same numbers without needing those files."""

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from camsim.core.errors import CamsimError
from camsim.sensor.presets import CAMERA_PRESETS, camera_preset, read_preset_file, sensor_preset
from tests.support.helpers import render, small_scene

DATA = Path(__file__).resolve().parents[3].parent / "shared" / "data" / "cameras"
needs_data = pytest.mark.skipif(not DATA.is_dir(), reason="../shared/data/cameras is absent")
ELD_NAMES = {"Sony A7S2": "sony-a7s2-eld", "Nikon D850": "nikon-d850", "Canon EOS 5D Mark IV": "canon-eos-5d4",
             "Canon EOS 70D": "canon-eos-70d", "Canon EOS 700D": "canon-eos-700d", "Sony A7M4": "sony-a7m4"}


def _rows(name):
    with open(DATA / name, newline="") as handle:
        return list(csv.DictReader(handle))


def tukey_sd(lam, scale):
    """The Tukey-λ law's standard deviation, from scipy's own variance (not camsim's formula)."""
    return scale * math.sqrt(stats.tukeylambda(lam).var())


def test_every_named_camera_of_the_issue_is_a_preset():
    for name in ("sony-a7s2", "nikon-d850", "canon-eos-5d4", "canon-eos-70d", "canon-eos-700d", "sony-a7m4",
                 "sony-imx363", "sony-imx174"):
        camera = CAMERA_PRESETS[name]
        assert camera.source and camera.notes
        assert any("spectral" in n for n in camera.notes)  # which curves it renders with


@needs_data
def test_the_a7s2_carries_pmns_table_and_converts_it_to_electrons():
    for row in _rows("pmn_sony_a7s2_per_iso.csv"):
        iso, k = float(row["iso"]), float(row["k_dn_per_e"])
        tukey = sensor_preset("sony-a7s2", iso)
        gauss = sensor_preset("sony-a7s2", iso, read_noise_model="gaussian")
        assert tukey.dn_per_electron == pytest.approx(k, rel=1e-12)
        # read noise in e⁻ = σ in DN / K: the Gaussian σ, and the Tukey law's standard deviation
        assert gauss.read_noise_e * k == pytest.approx(float(row["gaussian_sigma_dn"]), rel=1e-12)
        lam, scale = float(row["tukey_lambda"]), float(row["tukey_scale_dn"])
        assert tukey.read_noise_model == "tukey-lambda" and tukey.tukey_lambda == lam
        assert tukey.read_noise_e * k == pytest.approx(tukey_sd(lam, scale), rel=1e-9)
        assert tukey.row_noise_e * k == pytest.approx(float(row["row_sigma_dn"]), rel=1e-12)
        assert (tukey.bits, tukey.pedestal_dn, tukey.max_dn, tukey.cfa) == (14, 512, 16383, "RGGB")


@needs_data
def test_eld_fits_are_reproduced_at_every_iso():
    # ISO 100 ↔ K_min, K ∝ ISO, and each σ on its fit ln σ = slope · ln K + bias — also between the ISO points
    for row in _rows("eld_noise_fits.csv"):
        if row["profile"] != "Profile-1":
            continue
        camera = CAMERA_PRESETS[ELD_NAMES[row["camera"]]]
        k_min, k_max = float(row["k_min_dn_per_e"]), float(row["k_max_dn_per_e"])
        lo, hi = camera.iso_range
        assert lo == 100 and hi == pytest.approx(100 * k_max / k_min, rel=1e-12)
        for iso in (100.0, 137.0, 737.0, 2900.0, hi):
            point = camera.point_at(iso)
            k = k_min * iso / 100
            assert point.k_dn_per_e == pytest.approx(k, rel=1e-9)
            fit = math.exp(float(row["slope"]) * math.log(k) + float(row["bias"]))
            assert getattr(point, row["quantity"]) == pytest.approx(fit, rel=1e-9)


@needs_data
def test_eld_tukey_shapes_lowest_iso_first():
    shapes = {}
    for row in _rows("eld_tukey_shapes.csv"):
        shapes.setdefault(row["camera"], []).append(float(row["tukey_lambda"]))
    for camera, values in shapes.items():
        preset = CAMERA_PRESETS[ELD_NAMES[camera]]
        assert [p.tukey_lambda for p in preset.iso_points] == values
        assert preset.point_at(100).tukey_lambda == values[0]


def test_interpolation_between_published_points_is_log_log():
    camera = CAMERA_PRESETS["sony-a7s2"]
    a, b = camera.point_at(1000), camera.point_at(1250)
    p = camera.point_at(1100)
    t = math.log(1100 / 1000) / math.log(1250 / 1000)
    for name in ("k_dn_per_e", "gaussian_sigma_dn", "tukey_scale_dn", "row_sigma_dn"):
        expected = getattr(a, name) ** (1 - t) * getattr(b, name) ** t
        assert getattr(p, name) == pytest.approx(expected, rel=1e-12)
        assert min(getattr(a, name), getattr(b, name)) < getattr(p, name) < max(getattr(a, name), getattr(b, name))
    assert p.tukey_lambda == pytest.approx((1 - t) * a.tukey_lambda + t * b.tukey_lambda, abs=1e-15)


def test_the_a7s2_dual_conversion_gain_step():
    camera = CAMERA_PRESETS["sony-a7s2"]
    low, high = camera.point_at(1600), camera.point_at(2000)
    assert low.gaussian_sigma_dn == 6.299 and high.gaussian_sigma_dn == 2.654
    # in electrons the step is larger still: K grows by 2000/1600 while σ_DN falls
    assert sensor_preset("sony-a7s2", 2000).read_noise_e < 0.36 * sensor_preset("sony-a7s2", 1600).read_noise_e
    # between 1600 and 2000 the camera is still in its low-gain mode (extended along its last segment)
    mid = camera.point_at(1800)
    assert mid.gaussian_sigma_dn > low.gaussian_sigma_dn > high.gaussian_sigma_dn
    t = math.log(1800 / 1250) / math.log(1600 / 1250)
    assert mid.gaussian_sigma_dn == pytest.approx(5.178 ** (1 - t) * 6.299 ** t, rel=1e-12)


def _dark_statistics(frame):
    """Per-pixel variance about its row's mean, and the row means' variance, with standard errors (DN)."""
    dn = frame.digital_dn[0].astype(np.float64)
    rows = dn.mean(axis=1, keepdims=True)
    dev = (dn - rows).ravel()
    var, n = dev.var(), dev.size
    var_se = np.sqrt(np.var(dev**2) / n)
    row_means = rows.ravel()
    return var, var_se, row_means.var(ddof=1), row_means.var(ddof=1) * np.sqrt(2 / (row_means.size - 1)), dn.shape


@pytest.mark.parametrize("name, iso, model", [
    ("sony-a7s2", 400, "gaussian"), ("sony-a7s2", 3200, "tukey-lambda"), ("sony-a7s2", 12800, "gaussian"),
    ("nikon-d850", 800, "tukey-lambda"), ("canon-eos-70d", 1600, "gaussian")])
def test_rendered_dark_frames_have_the_published_sigmas(name, iso, model):
    camera = CAMERA_PRESETS[name]
    point = camera.point_at(iso)
    sensor = sensor_preset(name, iso, read_noise_model=model)
    frame, _ = render(small_scene(width=400, height=600), sensor, factor=1e-30, seed=11)
    read_dn = point.read_sigma_dn(model)
    var, var_se, row_var, row_se, (h, w) = _dark_statistics(frame)
    # the quantiser adds 1/12 DN² to a smooth law of σ ≳ 1 DN (Sheppard); a row's mean takes 1/w of the rest
    assert abs(var - (read_dn**2 * (1 - 1 / w) + 1 / 12)) < 5 * var_se, (var, read_dn**2 + 1 / 12, var_se)
    expected_row = point.row_sigma_dn**2 + (read_dn**2 + 1 / 12) / w
    assert abs(row_var - expected_row) < 5 * row_se + 1e-3, (row_var, expected_row, row_se)
    # the published black level: the pedestal exactly (rows are independent: the mean's SE from the row means)
    assert frame.digital_dn.mean() == pytest.approx(camera.pedestal_dn, abs=5 * np.sqrt(row_var / h))


@pytest.mark.parametrize("name", sorted(n for n, c in CAMERA_PRESETS.items() if c.pedestal_dn))
def test_an_unlit_pixel_reads_the_published_black_level(name):
    """With no dark charge, a preset's exact unlit mean is its published black level (PMN's and ELD's 512 for
    the A7S2, say), at its lowest and highest ISO: the ADC's offset P + ½ before the floor centres the read noise's
    rounding on P."""
    camera = CAMERA_PRESETS[name]
    checked = []
    for point in camera.iso_points:
        sensor = sensor_preset(name, point.iso, dark_current=False)
        # where the read noise's tail below −P (scipy's Tukey λ or normal law, 1e-13 quantile) plus 8 σ of row noise
        # stays above the zero clip, nothing lifts the mean: it is P (beyond that, the clip at 0 DN adds its share)
        law = (stats.tukeylambda(sensor.tukey_lambda) if sensor.read_noise_model == "tukey-lambda"
               else stats.norm())
        low_dn = (law.ppf(1e-13) / law.std() * sensor.read_noise_e - 8 * sensor.row_noise_e) * sensor.dn_per_electron
        if low_dn > -camera.pedestal_dn + 1:
            np.testing.assert_allclose(sensor.black_level_dn, camera.pedestal_dn, rtol=0, atol=1e-9)
            checked.append(point.iso)
    assert camera.iso_points[0].iso in checked


def test_quantisation_with_a_pedestal_rounds_exactly():
    """floor(dn + ½) + P in float32, checked against float64 (where dn + ½ is exact for float32 dn) at the
    values next to each half-integer, where a float32 dn + ½ would round."""
    from camsim.sensor.stages import quantise_dn

    halves = np.arange(-3, 4100, dtype=np.float64) + 0.5
    dn = np.concatenate([np.nextafter(halves.astype(np.float32), np.float32(-np.inf)), halves.astype(np.float32),
                         np.nextafter(halves.astype(np.float32), np.float32(np.inf))])
    got = quantise_dn(dn, 14, pedestal_dn=64)
    expected = np.clip(np.floor(dn.astype(np.float64) + 0.5) + 64, 0, 16383)
    np.testing.assert_array_equal(got, expected)
    assert got[halves.size + 3] == 64 + 1  # 0.5 rounds up: 1 + P
    np.testing.assert_array_equal(quantise_dn(dn, 14), np.clip(np.floor(dn.astype(np.float64)), 0, 16383))


def test_dark_frames_show_the_dual_gain_step():
    sigmas = []
    for iso in (1600, 2000):
        frame, _ = render(small_scene(width=300, height=200), sensor_preset("sony-a7s2", iso), factor=1e-30, seed=2)
        sigmas.append(_dark_statistics(frame)[0] ** 0.5)
    assert sigmas[1] < 0.5 * sigmas[0]  # 6.3 DN → 2.7 DN


def test_the_default_iso_and_the_well():
    camera = CAMERA_PRESETS["nikon-d850"]
    assert camera.default_iso == 100
    sensor = sensor_preset("nikon-d850")  # ISO 100
    # the well fills the raw at ISO 100: K · FW = white − black
    assert sensor.dn_per_electron * sensor.full_well_e == pytest.approx(16383 - 400, rel=1e-12)
    assert sensor.dn_per_electron == pytest.approx(0.4150393264348262, rel=1e-12)


PRESET_FILE = """
[preset]
name = "bench-camera"
source = "a test"
bits = 12
pedestal_dn = 256
cfa = "GRBG"
read_noise_model = "gaussian"

[[iso]]
iso = 800
k_dn_per_e = 0.8
tukey_lambda = -0.05
tukey_scale_dn = 1.5
gaussian_sigma_dn = 2.4
row_sigma_dn = 0.3
dsnu_dn = 0.4
prnu_percent = 0.5

[[iso]]
iso = 200
k_dn_per_e = 0.2
tukey_lambda = 0.05
tukey_scale_dn = 0.9
gaussian_sigma_dn = 1.2
row_sigma_dn = 0.1
"""


def test_a_preset_file_is_read_and_converted(tmp_path):
    path = tmp_path / "cam.toml"
    path.write_text(PRESET_FILE)
    camera = read_preset_file(path)
    assert camera.iso_range == (200, 800)  # sorted
    sensor = sensor_preset(str(path), 800)
    assert (sensor.bits, sensor.pedestal_dn, sensor.cfa, sensor.read_noise_model) == (12, 256, "GRBG", "gaussian")
    assert sensor.dn_per_electron == pytest.approx(0.8)
    assert sensor.read_noise_e == pytest.approx(2.4 / 0.8)
    assert sensor.row_noise_e == pytest.approx(0.3 / 0.8)
    assert sensor.dsnu_e == pytest.approx(0.4 / 0.8)
    assert sensor.prnu_percent == pytest.approx(0.5)
    # ISO 400: halfway in log ISO
    assert sensor_preset(str(path), 400).dn_per_electron == pytest.approx(0.4, rel=1e-12)
    # relative to a scene file's folder
    assert camera_preset("cam.toml", base_dir=tmp_path).name == "bench-camera"


def test_a_scene_file_names_a_camera_preset_and_iso(tmp_path):
    from camsim.scene.scene_file import load_scene

    scene = tmp_path / "s.toml"
    scene.write_text('[chart]\nreflectances = "macbeth"\n[sensor]\npreset = "sony-a7s2"\niso = 3200\n'
                     'read_noise_model = "gaussian"\n')
    sensor = load_scene(scene).sensor
    assert sensor.dn_per_electron == pytest.approx(3.06)
    assert sensor.read_noise_e * 3.06 == pytest.approx(3.919)


@pytest.mark.parametrize("text, message", [
    ("[preset]\nname = 'x'\nbits = 12\n", "lacks source"),
    (PRESET_FILE.replace("k_dn_per_e = 0.8", "k_dn_per_e = -1"), "k_dn_per_e must be positive"),
    (PRESET_FILE.replace("cfa = \"GRBG\"", "cfa = \"XYZW\""), "cfa must be one of"),
    (PRESET_FILE.replace("[[iso]]\niso = 200", "[[iso]]\nisso = 200"), "unknown key"),
    (PRESET_FILE.replace("[preset]", "[presett]"), "unknown table"),
    ("not toml [", "cannot read"),
])
def test_bad_preset_files(tmp_path, text, message):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(CamsimError, match=message):
        read_preset_file(path)


def test_bad_isos():
    with pytest.raises(CamsimError, match="outside preset sony-a7s2's range ISO 50–25600"):
        sensor_preset("sony-a7s2", 40)
    with pytest.raises(CamsimError, match="no ISO axis"):
        sensor_preset("paper-table1", 800)
    with pytest.raises(CamsimError, match="outside"):
        sensor_preset("sony-imx174", 200)  # one published setting


def test_a_preset_render_writes_a_14_bit_bayer_dng_raw_readers_understand(tmp_path):
    import json

    import rawpy

    from camsim.cli import main

    out = tmp_path / "o"
    assert main(["render", "macbeth_26", "--preset", "sony-a7s2", "--iso", "3200", "--illuminant", "D65",
                 "--intensity", "0.01", "--size", "96x64", "--out", str(out), "-q"]) == 0
    sidecar = json.loads((out / "macbeth_26_D65_F0.01.json").read_text())
    assert (sidecar["preset"], sidecar["iso"], sidecar["bits"],
            sidecar["pedestal_dn"]) == ("sony-a7s2", 3200.0, 14, 512)
    assert sidecar["dn_per_electron"] == pytest.approx(3.06)
    with rawpy.imread(str(out / "macbeth_26_D65_F0.01.dng")) as raw:
        assert raw.white_level == 16383
        assert raw.raw_image_visible.shape == (64, 96)  # one mosaic: RGGB
        # the exact black level (512 plus a dark charge of < 0.01 DN at 1/30 s) stored, truncated by LibRaw (CFA)
        assert list(raw.black_level_per_channel) == [512] * 4
        np.testing.assert_allclose(sidecar["black_level_dn"], 512, atol=0.01)
        assert 400 < raw.raw_image_visible.mean() < 16383
