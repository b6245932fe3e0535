"""Raw scenes end to end through ``camsim render`` (issue 27, points 1 to 3), against expectations computed here.

The sources are phone-style DNGs written by the tests' own writer (:mod:`tests.support.phone_dng`, which does not import
camsim) with a constant value per CFA site, so each site's electrons s = (DN − black) / K are known exactly and the
frames' per-site statistics have a closed form. The frames' sensor is the source camera's preset at the file's ISO
(the default), its numbers taken from the preset's published figures (:meth:`CameraPreset.point_at`: K, the Tukey
law's shape and scale, the row σ, the pedestal) and the Tukey law's moments from scipy. Under ``add`` at intensity
F (exposure the source's), at each site

    DN = floor(P + ½ + K · Poisson(F s) + read + row),   read ~ σ-scaled Tukey λ, row ~ N(0, σ_row²) per row,

so, over a site's N pixels in R rows (the ADC's floor adds 1/12 DN² where the noise spans several DN, Sheppard),

    mean = P + K F s,   variance = K² F s + σ_read² + σ_row² (1 − 1/R) + 1/12.

Tolerances are five standard errors: the mean's √((variance − σ_row²) / N + σ_row² / R) (a row's offset is shared by
its pixels); the variance's √((κ₄ + 2 var²) / N) with κ₄ = K⁴ F s (Poisson's fourth cumulant) + the Tukey law's
excess kurtosis · σ_read⁴ − 1/120 (the rounding's), plus the row offsets' 2 σ_row⁴ / R.
"""

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import rawpy
import tifffile
from scipy import stats

from camsim.cli import main
from camsim.scene.scene_file import load_scene
from camsim.sensor.presets import camera_preset
from tests.support.helpers import ROOT
from tests.support.phone_dng import write_phone_dng

SIGMAS = 5.0
BLACK = 512
WHITE = 16383
ISO, EXPOSURE_S = 800, 0.1
#: Each site's electrons in the source (RGGB: R, Gr / Gb, B) at K = the A7S2's at ISO 800.
SITE_E = np.array([[4000.0, 8000.0], [7000.0, 3000.0]])
MATRIX1 = [[0.6, -0.1, -0.05], [-0.4, 1.3, 0.1], [-0.08, 0.2, 0.6]]
MATRIX2 = [[0.7, -0.2, -0.05], [-0.4, 1.2, 0.1], [-0.1, 0.25, 0.55]]
NEUTRAL = [0.5, 1.0, 0.7]
#: LibRaw's ``sizes.flip`` of each TIFF Orientation (rotations only).
LIBRAW_FLIP = {1: 0, 3: 3, 6: 6, 8: 5}


def source_mosaic(height: int, width: int, k_dn_per_e: float, black=BLACK) -> np.ndarray:
    """The constant-per-site RGGB mosaic of :data:`SITE_E` at gain ``k_dn_per_e`` over ``black`` (one level, or
    one per site of the 2 × 2 cell) (uint16 DN)."""
    cell = np.rint(np.asarray(black, dtype=np.float64) + SITE_E * k_dn_per_e).astype(np.uint16)
    return np.tile(cell, (height // 2, width // 2))


def write_source(path: Path, height: int = 512, width: int = 512, *, make="SONY", model="ILCE-7SM2",
                 unique=None, orientation: int = 6, mosaic=None, black=((BLACK, BLACK), (BLACK, BLACK))) -> Path:
    k = camera_preset("sony-a7s2").point_at(ISO).k_dn_per_e
    write_phone_dng(path, source_mosaic(height, width, k, black) if mosaic is None else mosaic, pattern="RGGB",
                    black_per_site=black, white=WHITE, iso=ISO, exposure_s=EXPOSURE_S, make=make,
                    model=model, unique_camera_model=unique, color_matrix1=MATRIX1, color_matrix2=MATRIX2,
                    illuminants=(17, 21), as_shot_neutral=NEUTRAL, orientation=orientation)
    return path


def write_scene(folder: Path, name: str, raw: str, factors, extra: str = "") -> Path:
    path = folder / f"{name}.toml"
    path.write_text(f'name = "{name}"\n[raw]\npath = "{raw}"\n{extra}\n[light]\nintensity_factors = '
                    f'[{", ".join(repr(float(f)) for f in factors)}]\n', encoding="utf-8")
    return path


def render(scene: Path, out: Path, *extra: str) -> int:
    return main(["render", str(scene), "--out", str(out), "-q", *extra])


def stem_of(out: Path, name: str, factor: float) -> str:
    return str(out / f"{name}_as-shot_F{factor:g}")


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    """A 512 × 512 A7S2 DNG (ISO 800, 0.1 s, Orientation 6) as a raw scene at F = 1, 0.1 and 1/300."""
    folder = tmp_path_factory.mktemp("raw_scene")
    write_source(folder / "a7s2.dng")
    factors = (1.0, 0.1, 1 / 300)
    scene = write_scene(folder, "a7", "a7s2.dng", factors)
    assert render(scene, folder / "out") == 0
    return folder, factors


def test_each_sites_mean_and_variance_follow_the_add_law(frames):
    folder, factors = frames
    point = camera_preset("sony-a7s2").point_at(ISO)
    pedestal = camera_preset("sony-a7s2").pedestal_dn
    k = point.k_dn_per_e
    tukey = stats.tukeylambda(point.tukey_lambda)
    read_sd = point.tukey_scale_dn * tukey.std()
    read_kurt = float(tukey.stats(moments="k"))
    row_var = point.row_sigma_dn ** 2
    source_e = (np.rint(BLACK + SITE_E * k) - BLACK) / k  # what the file holds, in electrons
    for factor in factors:
        stem = stem_of(folder / "out", "a7", factor)
        raw = rawpy.imread(stem + ".dng").raw_image.astype(np.float64)
        for dy in (0, 1):
            for dx in (0, 1):
                site = raw[dy::2, dx::2]
                n, rows = site.size, site.shape[0]
                mu_e = factor * source_e[dy, dx]
                mean = pedestal + k * mu_e
                var = k * k * mu_e + read_sd ** 2 + row_var * (1 - 1 / rows) + 1 / 12
                kappa4 = k ** 4 * mu_e + read_kurt * read_sd ** 4 - 1 / 120
                tol_mean = SIGMAS * np.sqrt((var - row_var) / n + row_var / rows)
                tol_var = SIGMAS * np.sqrt((kappa4 + 2 * var ** 2) / n + 2 * row_var ** 2 / rows)
                where = f"F = {factor:g}, site ({dy}, {dx}), {mu_e:.1f} e⁻"
                assert site.mean() == pytest.approx(mean, abs=tol_mean), where
                assert site.var(ddof=1) == pytest.approx(var, abs=tol_var), where
                assert tol_var < 0.04 * var  # a test that can fail: 4 % is below a missing read-noise term at 1/300


def test_the_sidecar_records_the_source(frames):
    folder, factors = frames
    k = camera_preset("sony-a7s2").point_at(ISO).k_dn_per_e
    for factor in factors:
        meta = json.loads(Path(stem_of(folder / "out", "a7", factor) + ".json").read_text(encoding="utf-8"))
        assert meta["scene_source"] == "raw" and meta["illuminant"] == "as-shot" and meta["method"] == "raw-add"
        assert meta["iso"] == ISO and meta["exposure_s"] == pytest.approx(EXPOSURE_S)
        assert meta["preset"] == "sony-a7s2" and meta["cfa_pattern"] == "RGGB"
        record = meta["raw_source"]
        assert record == {
            "file": "a7s2.dng", "crop_xywh": None, "full_size_wh": [512, 512], "cfa_pattern": "RGGB",
            "black_dn": [[512.0, 512.0], [512.0, 512.0]], "white_dn": 16383.0, "iso": ISO,
            "exposure_s": pytest.approx(EXPOSURE_S), "make": "SONY", "model": "ILCE-7SM2",
            "unique_camera_model": "SONY ILCE-7SM2", "preset": "sony-a7s2", "k_dn_per_e": pytest.approx(k),
            "photon_law": "add",
            "photon_law_formula": "Poisson(f·max(s, 0)·g + D̄·d): the source as noise-free (ELD/PMN)",
            "fraction": pytest.approx(factor), "masked_px": 0, "masked_fraction": 0.0}


def test_the_dng_stays_that_cameras(frames):
    folder, factors = frames
    stem = stem_of(folder / "out", "a7", factors[1])
    with rawpy.imread(stem + ".dng") as raw:
        assert raw.color_desc == b"RGBG" and raw.raw_pattern.tolist() == [[0, 1], [3, 2]]
        assert list(raw.black_level_per_channel) == [512] * 4 and raw.white_level == WHITE
        assert raw.sizes.flip == LIBRAW_FLIP[6]
        wb = np.array(raw.camera_whitebalance[:3])
        assert wb / wb[1] == pytest.approx(NEUTRAL[1] / np.array(NEUTRAL), rel=1e-4)  # LibRaw: 1 / AsShotNeutral
    with tifffile.TiffFile(stem + ".dng") as tif:  # Make and Model, which rawpy does not expose
        tags = tif.pages[0].tags
        assert (tags["Make"].value, tags["Model"].value, tags["Orientation"].value) == ("SONY", "ILCE-7SM2", 6)
    if shutil.which("exiftool") is None:
        pytest.skip("exiftool is not installed")
    tags = ["Make", "Model", "UniqueCameraModel", "Orientation", "ColorMatrix1", "ColorMatrix2",
            "CalibrationIlluminant1", "CalibrationIlluminant2", "AsShotNeutral", "ISO", "ExposureTime"]
    done = subprocess.run(["exiftool", "-j", "-n", *(f"-{t}" for t in tags), stem + ".dng"], capture_output=True,
                          text=True, check=True)
    (info,) = json.loads(done.stdout)

    def numbers(text):
        return [float(v) for v in str(text).split()]

    assert (info["Make"], info["Model"], info["Orientation"]) == ("SONY", "ILCE-7SM2", 6)
    assert info["UniqueCameraModel"] == "SONY ILCE-7SM2"
    assert numbers(info["ColorMatrix1"]) == pytest.approx(np.ravel(MATRIX1), abs=1e-4)
    assert numbers(info["ColorMatrix2"]) == pytest.approx(np.ravel(MATRIX2), abs=1e-4)
    assert (info["CalibrationIlluminant1"], info["CalibrationIlluminant2"]) == (17, 21)
    assert numbers(info["AsShotNeutral"]) == pytest.approx(NEUTRAL, abs=1e-4)
    assert info["ISO"] == ISO and info["ExposureTime"] == pytest.approx(EXPOSURE_S)


@pytest.mark.slow
@pytest.mark.parametrize("reader", ["darktable", "RawTherapee"])
def test_raw_developers_develop_it_as_that_cameras_raw(frames, reader):
    """darktable-cli and rawtherapee-cli (skipped where absent) develop a frame: the picture is the source's size
    turned by its Orientation 6 (a quarter turn: 512 wide, 512 high here, so a 480 × 320 crop tells), lit, and
    uniform, as the constant source is."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("raw_readers", ROOT / "tools" / "raw_readers.py")
    raw_readers = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(raw_readers)
    if not raw_readers.available(reader):
        pytest.skip(f"{reader} is not installed")
    folder, _ = frames
    scene = write_scene(folder, "wide", "a7s2.dng", [0.1], "crop = [0, 0, 480, 320]")
    assert render(scene, folder / "wide_out") == 0
    picture = raw_readers.develop(reader, Path(stem_of(folder / "wide_out", "wide", 0.1) + ".dng"))
    height, width = picture.shape[:2]
    assert height > width and abs(height - 480) <= 16 and abs(width - 320) <= 16, picture.shape
    centre = picture[height // 4: 3 * height // 4, width // 4: 3 * width // 4].reshape(-1, 3)
    assert np.all(centre.mean(0) > 10) and np.all(np.isfinite(centre))
    assert np.all(centre.std(0) < 0.25 * centre.mean(0) + 2)  # noise, no structure


@pytest.mark.parametrize(("x", "y", "pattern"), [(0, 0, "RGGB"), (1, 0, "GRBG"), (0, 1, "GBRG"), (1, 1, "BGGR")])
def test_a_crop_keeps_the_pixels_and_shifts_the_pattern(tmp_path, x, y, pattern):
    """A crop at an odd offset starts on another site: the frame's pattern is that site's cell, and each site of the
    frame carries its own source value less its own black level (four different ones, 88 DN or more apart: the
    means at F = 1, within 5 standard errors, about 17 DN)."""
    black = ((400, 512), (600, 700))
    write_source(tmp_path / "src.dng", 64, 96, black=black)
    scene = write_scene(tmp_path, "crop", "src.dng", [1.0], f"crop = [{x}, {y}, 48, 32]")
    assert render(scene, tmp_path / "out") == 0
    meta = json.loads(Path(stem_of(tmp_path / "out", "crop", 1.0) + ".json").read_text(encoding="utf-8"))
    assert meta["raw_source"]["crop_xywh"] == [x, y, 48, 32] and meta["raw_source"]["cfa_pattern"] == pattern
    assert meta["raw_source"]["black_dn"] == [[black[(dy + y) % 2][(dx + x) % 2] for dx in (0, 1)] for dy in (0, 1)]
    point = camera_preset("sony-a7s2").point_at(ISO)
    with rawpy.imread(stem_of(tmp_path / "out", "crop", 1.0) + ".dng") as raw:
        assert raw.raw_image.shape == (32, 48)
        assert "".join(raw.color_desc.decode()[c] for c in raw.raw_pattern.ravel()) == pattern
        image = raw.raw_image.astype(np.float64)
    for dy in (0, 1):
        for dx in (0, 1):
            electrons = SITE_E[(dy + y) % 2, (dx + x) % 2]
            mean = camera_preset("sony-a7s2").pedestal_dn + point.k_dn_per_e * electrons
            var = point.k_dn_per_e ** 2 * electrons + point.gaussian_sigma_dn ** 2 + point.row_sigma_dn ** 2
            tol = SIGMAS * np.sqrt(var / (16 * 24) + point.row_sigma_dn ** 2 / 16)  # 16 rows of 24 sites
            assert image[dy::2, dx::2].mean() == pytest.approx(mean, abs=tol), (dy, dx)


#: Make and Model as each built-in Bayer camera writes them into its raw files, and the preset they must name.
CAMERAS = [
    ("SONY", "ILCE-7SM2", "sony-a7s2"),
    ("NIKON CORPORATION", "NIKON D850", "nikon-d850"),
    ("Canon", "Canon EOS 5D Mark IV", "canon-eos-5d4"),
    ("Canon", "Canon EOS 70D", "canon-eos-70d"),
    ("Canon", "Canon EOS 700D", "canon-eos-700d"),
    ("Canon", "Canon EOS REBEL T5i", "canon-eos-700d"),
    ("Canon", "Canon EOS Kiss X7i", "canon-eos-700d"),
    ("SONY", "ILCE-7M4", "sony-a7m4"),
    ("Google", "Pixel 4a", "sony-imx363"),
]


@pytest.mark.parametrize(("make", "model", "preset"), CAMERAS)
def test_the_source_camera_is_found_from_make_and_model(tmp_path, make, model, preset):
    """Make and Model as each camera writes them into its raws (the UniqueCameraModel as Adobe's converter does,
    Make and Model joined) name the built-in preset; the frames' sensor is that preset at the file's ISO."""
    write_source(tmp_path / "src.dng", 64, 64, make=make, model=model)
    scene = load_scene(write_scene(tmp_path, "cam", "src.dng", [0.1]))
    assert scene.source.preset == preset and scene.preset_name == preset and scene.iso == ISO
    assert scene.sensor.cfa == "RGGB" and scene.sensor.exposure_s == pytest.approx(EXPOSURE_S)
    k = camera_preset(preset).point_at(ISO).k_dn_per_e
    assert scene.sensor.conversion_gain_v_per_e * scene.sensor.analog_gain_dn_per_v == pytest.approx(k, rel=1e-9)


def test_every_built_in_bayer_camera_has_its_raws_make_and_model_listed():
    """Each built-in Bayer camera preset is named by one of the Make/Model pairs tested above (none left out), but
    ``sony-a7s2-eld``, the A7S2 by other fits: ``sony-a7s2``, listed first, wins its files."""
    from camsim.sensor.presets import CAMERA_PRESETS

    bayer = {name for name, p in CAMERA_PRESETS.items() if p.cfa is not None}
    assert bayer - {preset for _, _, preset in CAMERAS} == {"sony-a7s2-eld"}


def tiff_dng(path: Path, photometric: int, extratags=()) -> Path:
    """A bare 64 × 64 DNG written with tifffile alone (Make Acme, Model X1, black 64, white 4095), its
    PhotometricInterpretation patched to ``photometric`` (tifffile refuses a one-sample LinearRaw)."""
    import struct

    tags = [(254, "I", 1, 0, True), (271, "s", 0, "Acme", True), (272, "s", 0, "X1", True),
            (50706, "B", 4, (1, 4, 0, 0), True), (50708, "s", 0, "Acme X1", True), (50714, "I", 1, 64, True),
            (50717, "I", 1, 4095, True), *extratags]
    tifffile.imwrite(path, np.full((64, 64), 1000, np.uint16), photometric="minisblack", extratags=tags,
                     metadata=None)
    with tifffile.TiffFile(path) as tif:
        offset = tif.pages[0].tags[262].valueoffset
    with open(path, "r+b") as fh:
        fh.seek(offset)
        fh.write(struct.pack("<H", photometric))
    return path


def cfa_tags(repeat, pattern, plane_colours=(0, 1, 2)):
    """CFARepeatPatternDim, CFAPattern and CFAPlaneColor (colour codes 0 R, 1 G, 2 B, 3 C, 4 M, 5 Y)."""
    return [(33421, "H", 2, tuple(repeat), True), (33422, "B", len(pattern), tuple(pattern), True),
            (50710, "B", len(plane_colours), tuple(plane_colours), True)]


def _bad_sources(folder: Path) -> dict:
    """Scene files that must be refused, each with the words its one-line error must hold."""
    write_source(folder / "ok.dng", 64, 64)
    write_source(folder / "acme.dng", 64, 64, make="Acme", model="X1")
    write_source(folder / "sat.dng", 64, 64, mosaic=np.full((64, 64), WHITE, np.uint16))
    (folder / "garbage.dng").write_bytes(b"not a raw file at all " * 20)
    assert main(["render", "macbeth_26", "-F", "1", "--illuminant", "D65", "--size", "64x48", "-q", "--out",
                 str(folder / "tc")]) == 0  # a camsim three-chip (LinearRaw) DNG
    xtrans = (1, 1, 0, 1, 1, 2, 1, 1, 2, 1, 1, 0, 2, 0, 1, 0, 2, 1,
              1, 1, 2, 1, 1, 0, 1, 1, 0, 1, 1, 2, 0, 2, 1, 2, 0, 1)
    tiff_dng(folder / "mono.dng", 34892)  # LinearRaw, one sample
    tiff_dng(folder / "xtrans.dng", 32803, cfa_tags((6, 6), xtrans))
    tiff_dng(folder / "cygm.dng", 32803, cfa_tags((2, 2), (3, 4, 1, 5), (3, 4, 1, 5)))
    tiff_dng(folder / "rggb.dng", 32803, cfa_tags((2, 2), (0, 1, 1, 2)))  # the same writer's Bayer file reads
    assert load_scene(write_scene(folder, "rggb", "rggb.dng", [0.1], 'preset = "sony-a7s2"\niso = 800\n'
                                  "exposure_s = 0.1")).source.cfa == "RGGB"
    return {
        "unreadable": (write_scene(folder, "unreadable", "garbage.dng", [0.1]), "not a raw file"),
        "missing": (write_scene(folder, "missing", "nothere.dng", [0.1]), "no such file"),
        "no_cfa": (write_scene(folder, "no_cfa", "tc/macbeth_26_D65_F1.dng", [0.1]), "no 2x2 colour filter array"),
        "mono": (write_scene(folder, "mono", "mono.dng", [0.1]), "no 2x2 colour filter array: a monochrome image"),
        "xtrans": (write_scene(folder, "xtrans", "xtrans.dng", [0.1]), "unsupported CFA layout"),
        "cygm": (write_scene(folder, "cygm", "cygm.dng", [0.1]), "unsupported CFA layout"),
        "unknown": (write_scene(folder, "unknown", "acme.dng", [0.1]), "unknown camera (Acme X1) and no preset given"),
        "saturated": (write_scene(folder, "saturated", "sat.dng", [0.1]), "every pixel is saturated"),
        "off_frame": (write_scene(folder, "off_frame", "ok.dng", [0.1], "crop = [10, 0, 64, 64]"),
                      "is off the 64x64 image"),
        "thin_brighter": (write_scene(folder, "thin_brighter", "ok.dng", [2.0], 'photon_law = "thin"'),
                          "cannot brighten"),
        # F · T = T_source, but PRNU gains above 1 would keep more than all of the source's electrons
        "thin_prnu": (write_scene(folder, "thin_prnu", "ok.dng", [1.0], 'photon_law = "thin"\n[sensor]\n'
                                  'prnu_percent = 1'), "times the largest PRNU gain"),
    }


@pytest.fixture(scope="module")
def bad_sources(tmp_path_factory):
    return _bad_sources(tmp_path_factory.mktemp("bad_raws"))


@pytest.mark.parametrize("case", ["unreadable", "missing", "no_cfa", "mono", "xtrans", "cygm", "unknown",
                                  "saturated", "off_frame", "thin_brighter", "thin_prnu"])
def test_bad_raws_give_one_line_and_write_nothing(bad_sources, case, tmp_path, capsys):
    scene, words = bad_sources[case]
    out = tmp_path / "out"
    assert render(scene, out) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("camsim: error: "), err
    assert words in lines[0] and "Traceback" not in err
    assert not out.exists() or not any(out.iterdir())


def test_iso_and_preset_given_for_the_frames_change_their_sensor_not_the_sources_gain(tmp_path):
    """``--iso`` and ``--preset`` set the frames' sensor; the source's electrons keep the source camera's K at the
    file's ISO, so a frame at ISO 3200 reads K₃₂₀₀ / K₈₀₀ times the DN above black of one at ISO 800."""
    write_source(tmp_path / "src.dng", 128, 128)
    scene = write_scene(tmp_path, "iso", "src.dng", [0.1])
    k800 = camera_preset("sony-a7s2").point_at(ISO).k_dn_per_e
    for preset, iso in (("sony-a7s2", 3200), ("nikon-d850", 1600)):
        out = tmp_path / f"{preset}-{iso}"
        assert render(scene, out, "--preset", preset, "--iso", str(iso)) == 0
        meta = json.loads(Path(stem_of(out, "iso", 0.1) + ".json").read_text(encoding="utf-8"))
        assert meta["iso"] == iso and meta["preset"] == preset
        assert meta["raw_source"]["preset"] == "sony-a7s2" and meta["raw_source"]["k_dn_per_e"] == pytest.approx(k800)
        point = camera_preset(preset).point_at(iso)
        with rawpy.imread(stem_of(out, "iso", 0.1) + ".dng") as raw:
            image = raw.raw_image.astype(np.float64)
        source_e = (np.rint(BLACK + SITE_E * k800) - BLACK) / k800
        for dy in (0, 1):
            for dx in (0, 1):
                mu_e = 0.1 * source_e[dy, dx]
                mean = camera_preset(preset).pedestal_dn + point.k_dn_per_e * mu_e
                var = point.k_dn_per_e ** 2 * mu_e + point.gaussian_sigma_dn ** 2 + point.row_sigma_dn ** 2
                tol = SIGMAS * np.sqrt(var / 64 ** 2 + point.row_sigma_dn ** 2 / 64)  # 64 rows of 64 sites
                assert image[dy::2, dx::2].mean() == pytest.approx(mean, abs=tol), (preset, dy, dx)


def test_a_camsim_frame_is_a_raw_scenes_source(tmp_path):
    """The guide's first raw scene: a ColorChecker rendered by the ``sony-a7s2`` preset at ISO 100 (its DNG names the
    camera ``Sony`` ``ILCE-7SM2``) made a hundred times darker at ISO 3200 by the same camera."""
    assert main(["render", "macbeth_26", "--preset", "sony-a7s2", "--iso", "100", "--illuminant", "D65", "-F", "1",
                 "--size", "96x64", "-q", "--out", str(tmp_path / "clean")]) == 0
    scene = write_scene(tmp_path, "dark_chart", "clean/macbeth_26_D65_F1.dng", [0.01], "[sensor]\niso = 3200")
    assert render(scene, tmp_path / "dark") == 0
    meta = json.loads(Path(stem_of(tmp_path / "dark", "dark_chart", 0.01) + ".json").read_text(encoding="utf-8"))
    record = meta["raw_source"]
    assert (record["make"], record["model"], record["preset"]) == ("Sony", "ILCE-7SM2", "sony-a7s2")
    assert record["k_dn_per_e"] == pytest.approx(camera_preset("sony-a7s2").point_at(100).k_dn_per_e)
    assert record["iso"] == 100 and meta["iso"] == 3200 and record["fraction"] == pytest.approx(0.01)
    assert meta["dn_per_electron"] == pytest.approx(camera_preset("sony-a7s2").point_at(3200).k_dn_per_e)


def test_size_is_refused_with_a_pointer_to_the_crop(tmp_path, capsys):
    write_source(tmp_path / "src.dng", 64, 64)
    scene = write_scene(tmp_path, "sized", "src.dng", [0.1])
    assert render(scene, tmp_path / "out", "--size", "32x32") == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "[raw] crop = [x, y, width, height]" in err and not (tmp_path / "out").exists()


@pytest.mark.slow
def test_the_exr_clean_layer_is_the_scaled_source(frames):
    """The EXR's clean layer holds each site's expectation above black, K · F · s, in its own colour exactly, and
    in the two others the bilinear interpolation of the neighbouring sites': away from the border, at an R site, G is
    the mean of its four G neighbours (two Gr, two Gb) and B of its four diagonal B neighbours."""
    from camsim.io.exr import read_exr

    folder, factors = frames
    k = camera_preset("sony-a7s2").point_at(ISO).k_dn_per_e
    source_e = (np.rint(BLACK + SITE_E * k) - BLACK) / k
    for factor in factors:
        noisy, clean, _ = read_exr(stem_of(folder / "out", "a7", factor) + ".exr")
        assert noisy.shape == (1, 512, 512) and clean.shape == (3, 512, 512)
        expect = k * factor * source_e  # (2, 2): R, Gr / Gb, B
        r, gr, gb, b = expect[0, 0], expect[0, 1], expect[1, 0], expect[1, 1]
        assert clean[0, 0::2, 0::2] == pytest.approx(r, rel=1e-6)
        assert clean[1, 0::2, 1::2] == pytest.approx(gr, rel=1e-6)
        assert clean[1, 1::2, 0::2] == pytest.approx(gb, rel=1e-6)
        assert clean[2, 1::2, 1::2] == pytest.approx(b, rel=1e-6)
        inner = (slice(2, -2), slice(2, -2))
        at_r = clean[:, 2:-2:2, 2:-2:2]
        assert at_r[1] == pytest.approx((gr + gb) / 2, rel=1e-6) and at_r[2] == pytest.approx(b, rel=1e-6)
        assert clean[0][inner][1::2, 1::2] == pytest.approx(r, rel=1e-6)  # R at B sites


def test_saturated_sites_are_masked_counted_and_drawn_from_their_lower_bound(tmp_path):
    """Sites at the white level are counted in ``raw_source.masked_px``, marked 255 in ``STEM_mask.png`` (0
    elsewhere), and drawn from (white − black) / K, their electrons' lower bound: at F = 0.1 their mean is
    P + K · 0.1 · (white − black) / K_source, within 5 standard errors."""
    import imageio.v3 as iio

    k = camera_preset("sony-a7s2").point_at(ISO).k_dn_per_e
    mosaic = source_mosaic(64, 64, k)
    saturated = np.zeros(mosaic.shape, bool)
    saturated[10:20, 20:36] = True  # 160 sites, 40 of each colour
    saturated[[3, 40, 41], [7, 50, 50]] = True
    mosaic[saturated] = WHITE
    write_source(tmp_path / "sat.dng", mosaic=mosaic)
    scene = write_scene(tmp_path, "sat", "sat.dng", [0.1])
    assert render(scene, tmp_path / "out") == 0
    stem = stem_of(tmp_path / "out", "sat", 0.1)
    meta = json.loads(Path(stem + ".json").read_text(encoding="utf-8"))
    assert meta["raw_source"]["masked_px"] == 163 and meta["raw_source"]["masked_fraction"] == pytest.approx(
        163 / 4096)
    assert meta["files"]["mask"] == Path(stem).name + "_mask.png"
    mask = iio.imread(stem + "_mask.png")
    assert mask.shape[:2] == (64, 64) and set(np.unique(mask)) == {0, 255}
    assert np.array_equal(mask.reshape(64, 64, -1)[..., 0] == 255, saturated)
    point = camera_preset("sony-a7s2").point_at(ISO)
    with rawpy.imread(stem + ".dng") as raw:
        block = raw.raw_image[10:20, 20:36].astype(np.float64)
    mu_e = 0.1 * (WHITE - BLACK) / k
    mean = camera_preset("sony-a7s2").pedestal_dn + point.k_dn_per_e * mu_e
    var = point.k_dn_per_e ** 2 * mu_e + point.gaussian_sigma_dn ** 2  # and the row offsets, shared by 16 sites
    assert block.mean() == pytest.approx(mean, abs=SIGMAS * np.sqrt(var / block.size + point.row_sigma_dn ** 2 / 10))


def test_analyze_and_develop_read_raw_frames(frames, tmp_path):
    """camsim analyze measures each frame's residual noisy − clean (the DNG's numbers less the pedestal) against the
    model: its mean within 5 standard errors of 0 and its variance's ratio to the prediction within 5 of its
    standard errors of 1, at every ratio (F = 1/300 too, a few DN above the pedestal); camsim develop makes a
    picture of the source's size."""
    import csv

    folder, factors = frames
    assert main(["analyze", str(folder / "out"), "--out", str(tmp_path / "ana"), "-q"]) == 0
    with open(tmp_path / "ana" / "frame_statistics.csv", newline="", encoding="utf-8") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 3 * len(factors)
    for row in rows:
        assert row["residual_status"] == "ok" and row["method"] == "raw-add"
        ratio = float(row["residual_var_dn2"]) / float(row["predicted_var_dn2"])
        se = float(row["residual_var_se_dn2"]) / float(row["predicted_var_dn2"])
        assert abs(ratio - 1) < 5 * se + 0.02, row
        assert abs(float(row["residual_mean_dn"])) < 5 * float(row["residual_mean_se_dn"]) + 0.05, row
    stem = stem_of(folder / "out", "a7", factors[1])
    assert main(["develop", stem + ".dng", "--out", str(tmp_path / "dev"), "-q"]) == 0
    import imageio.v3 as iio

    (png,) = (tmp_path / "dev").glob("*.png")
    assert iio.imread(png).shape[:2] == (512, 512)
