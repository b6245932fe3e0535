"""A DNG says which camera, ISO and exposure made it, and ``camsim calibrate`` reads them back (real subprocesses).

Darks and flat pairs of the ``sony-a7s2`` preset at ISO 3200 are rendered by ``camsim render`` (black and grey
pictures as scenes; in this process: the files are what is tested), calibrated by ``camsim calibrate`` (a real
subprocess, as a user runs it), and the preset it writes is used again at ISO 3200. The
tags (the ISO and exposure in an EXIF IFD) are checked with ExifTool (skipped where it is not installed: its tag
values and its validation) and LibRaw (``rawpy``'s ``other.iso_speed`` and ``other.shutter_speed``).
"""

import json
import shutil
import sys
import tomllib

import numpy as np
import pytest
import rawpy
import tifffile

from camsim.cli import main
from camsim.io.dng import read_dng, write_dng, write_dng_cfa
from camsim.render.frame_files import camera_identity
from camsim.sensor.presets import camera_preset
from camsim.sensor.presets.data import build_presets
from tests.support import clock
from tests.support.helpers import ROOT

SCENE = """name = "{name}"
[image]
path = "{name}.png"
kind = "reflectance"
colourspace = "sRGB"
[light]
illuminants = ["D65"]
intensity_factors = [1.0]
"""


def _camsim(*argv, cpu_s=120):
    done = clock.run([sys.executable, "-m", "camsim", *map(str, argv)], cpu_s=cpu_s, cwd=ROOT, capture_output=True,
                     text=True)
    assert done.returncode == 0, done.stderr
    return done


@pytest.fixture(scope="module")
def sony_3200(tmp_path_factory):
    """4 darks and 4 flat pairs (64 × 64, RGGB, 14-bit) of sony-a7s2 at ISO 3200, rendered by camsim."""
    import imageio.v3 as iio

    folder = tmp_path_factory.mktemp("sony3200")
    for name, code in (("dark", 0), ("flat", 128)):
        iio.imwrite(folder / f"{name}.png", np.full((64, 64, 3), code, np.uint8))
        (folder / f"{name}.toml").write_text(SCENE.format(name=name))
    camera = ("--preset", "sony-a7s2", "--iso", "3200", "-q")

    def render(*argv):
        assert main([str(a) for a in ("render", *argv, *camera)]) == 0

    render(folder / "dark.toml", "--intensity", 1, 2, 3, 4, "--out", folder / "darks")
    for seed in (1, 2):
        render(folder / "flat.toml", "--intensity", 0.1, 0.3, 0.6, 1, "--seed", seed, "--out", folder / f"flats{seed}")
    return {"folder": folder, "dark": sorted((folder / "darks").glob("*.dng")),
            "flat": sorted((folder / "flats1").glob("*.dng")) + sorted((folder / "flats2").glob("*.dng"))}


@pytest.mark.slow  # the rendered darks and flats (once)
def test_the_files_carry_the_camera_iso_and_exposure(sony_3200):
    path = sony_3200["dark"][0]
    meta = json.loads(path.with_suffix(".json").read_text())
    _, info = read_dng(path)
    assert (info["make"], info["model"], info["unique_camera_model"]) == ("Sony", "ILCE-7SM2", "Sony ILCE-7SM2")
    assert info["iso"] == 3200 == meta["iso"]
    assert info["exposure_s"] == pytest.approx(meta["exposure_s"], rel=1e-9)
    with rawpy.imread(str(path)) as raw:
        assert raw.other.iso_speed == 3200
        assert raw.other.shutter_speed == pytest.approx(meta["exposure_s"], rel=1e-6)


@pytest.mark.skipif(shutil.which("exiftool") is None, reason="exiftool is not installed")
@pytest.mark.slow  # the rendered darks and flats (once)
def test_exiftool_reads_the_camera_iso_and_exposure(sony_3200):
    path = sony_3200["flat"][0]
    meta = json.loads(path.with_suffix(".json").read_text())
    done = clock.run(["exiftool", "-j", "-n", "-Make", "-Model", "-UniqueCameraModel", "-ISO", "-ExposureTime",
                      str(path)], cpu_s=60, capture_output=True, text=True, check=True)
    tags = json.loads(done.stdout)[0]
    assert tags["Make"] == "Sony" and tags["Model"] == "ILCE-7SM2" and tags["UniqueCameraModel"] == "Sony ILCE-7SM2"
    assert tags["ISO"] == 3200
    assert tags["ExposureTime"] == pytest.approx(meta["exposure_s"], rel=1e-6)
    done = clock.run(["exiftool", "-validate", "-warning", "-a", "-s3", str(path)], cpu_s=60, capture_output=True,
                     text=True, check=True)
    assert done.stdout.strip() == "OK", done.stdout


@pytest.mark.slow  # the rendered darks and flats (once)
def test_calibrate_takes_the_files_iso_and_its_preset_renders_at_that_iso(sony_3200, tmp_path):
    out = tmp_path / "cal"
    _camsim("calibrate", "--dark", *sony_3200["dark"], "--flat", *sony_3200["flat"], "--out", out, "-q")
    preset = tomllib.loads((out / "preset.toml").read_text())
    assert preset["iso"][0]["iso"] == 3200
    assert preset["preset"]["name"] == "Sony ILCE-7SM2"
    again = tmp_path / "again"
    assert main(["render", "macbeth_26", "--illuminant", "D65", "--intensity", "1", "--size", "64x44", "--preset",
                 str(out / "preset.toml"), "--iso", "3200", "--out", str(again), "-q"]) == 0
    _, info = read_dng(again / "macbeth_26_D65_F1.dng")
    assert info["iso"] == 3200 and info["make"] == "Sony"


@pytest.mark.slow  # the rendered darks and flats (once)
def test_a_sidecar_that_disagrees_with_its_file_is_refused(sony_3200, tmp_path, capsys):
    darks = []
    for i, path in enumerate(sony_3200["dark"]):  # copies with their sidecars; the last sidecar says ISO 100
        darks.append(tmp_path / f"d{i}.dng")
        shutil.copy(path, darks[-1])
        meta = json.loads(path.with_suffix(".json").read_text())
        meta["iso"] = 100 if i == len(sony_3200["dark"]) - 1 else meta["iso"]
        darks[-1].with_suffix(".json").write_text(json.dumps(meta))
    out = tmp_path / "o"
    assert main(["calibrate", "--dark", *map(str, darks), "--flat", *map(str, sony_3200["flat"]), "--out", str(out),
                 "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error: ") and err.count("\n") == 1
    assert "says ISO 3200 but its sidecar" in err and "says ISO 100" in err
    assert not out.exists()


@pytest.mark.slow  # the rendered darks and flats (once)
def test_a_flat_pair_of_two_exposures_is_refused(sony_3200, tmp_path, capsys):
    flats = list(sony_3200["flat"])
    partner = flats[4]  # seed 2's F = 0.1: the pair of flats[0]; rewritten, tagged 2 s, without a sidecar
    dn, info = read_dng(partner)
    black = info["black_level_exact"]
    flats[4] = tmp_path / partner.name
    write_dng_cfa(flats[4], dn[0], pattern=info["cfa_pattern"], black_level_dn=black,
                  white_level=info["white_level"], unique_camera_model=info["unique_camera_model"],
                  color_matrix1=info["color_matrix1"], as_shot_neutral=info["as_shot_neutral"], iso=3200,
                  exposure_s=2.0)
    out = tmp_path / "o"
    assert main(["calibrate", "--dark", *map(str, sony_3200["dark"]), "--flat", *map(str, flats), "--out", str(out),
                 "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error: mixed exposures: ") and err.count("\n") == 1, err
    assert "2 s" in err and "must share one exposure" in err
    assert not out.exists()


@pytest.mark.parametrize("name", sorted(build_presets()))
def test_every_built_in_preset_has_an_ascii_camera_identity(name):
    from camsim.render.frame_files import FrameInfo

    title = camera_preset(name).title
    info = FrameInfo.__new__(FrameInfo)
    object.__setattr__(info, "preset", {"preset": name, "preset_title": title, "iso": 100.0})
    object.__setattr__(info, "camera", "Nikon 5100 (NPL)")
    ident = camera_identity(info)
    assert all(v and v.isascii() and v == v.strip() for v in ident.values())
    assert title.startswith(ident["make"]) and ident["model"] in title
    assert ident["unique_camera_model"].startswith(ident["make"])
    # a gain set on top of the preset (a virtual camera): no ISO of the camera, so camsim's own identity
    object.__setattr__(info, "preset", {"preset": name, "preset_title": title, "iso": None})
    assert camera_identity(info) == {"make": "camsim", "model": "Nikon 5100 (NPL)",
                                     "unique_camera_model": "camsim Nikon 5100 (NPL)"}


@pytest.mark.parametrize("iso", [100, 3200, 65535, 409600])
def test_iso_tags_hold_any_speed(tmp_path, iso):
    """ISOSpeedRatings is a SHORT: above 65535 it says 65535, SensitivityType 3 and ISOSpeed (LONG) the speed; all
    in the EXIF IFD, where LibRaw reads the ISO (not ISOSpeed: 65535 above it) and the exposure."""
    path = tmp_path / "f.dng"
    write_dng(path, np.zeros((3, 22, 22), np.uint8), black_level_dn=0, white_level=255, unique_camera_model="t",
              color_matrix1=np.eye(3), as_shot_neutral=(1, 1, 1), iso=iso, exposure_s=1 / 8000)
    with tifffile.TiffFile(path) as tif:
        ifd0 = tif.pages.first.tags
        exif = ifd0[34665].value  # tifffile reads the EXIF IFD into a dict
        assert not {33434, 34855, 34864, 34867} & set(ifd0.keys())
    assert exif["ISOSpeedRatings"] == min(iso, 65535) and exif["ExifVersion"] == "0230"
    assert ("ISOSpeed" in exif) == (iso > 65535) and exif.get("SensitivityType", 3) == 3
    assert iso <= 65535 or exif["ISOSpeed"] == iso
    n, d = exif["ExposureTime"]
    assert n / d == pytest.approx(1 / 8000, rel=1e-12)
    with rawpy.imread(str(path)) as raw:
        assert raw.other.iso_speed == min(iso, 65535)
        assert raw.other.shutter_speed == pytest.approx(1 / 8000, rel=1e-6)
    assert read_dng(path)[1]["iso"] == iso
    if shutil.which("exiftool"):
        done = clock.run(["exiftool", "-j", "-n", "-ISO", "-ISOSpeed", "-ExposureTime", "-Validate", str(path)],
                         cpu_s=60, capture_output=True, text=True, check=True)
        tags = json.loads(done.stdout)[0]
        assert tags.get("ISOSpeed", tags["ISO"]) == iso and tags["ExposureTime"] == pytest.approx(1 / 8000)
        assert tags["Validate"] == "0 0 0"  # -n: errors, warnings, minor warnings


@pytest.mark.slow  # the rendered darks and flats (once), calibrated
def test_files_without_the_tags_take_iso_and_exposure_from_their_sidecars(sony_3200, tmp_path):
    """DNGs of an older camsim (no ISO, no ExposureTime) with their sidecars calibrate at the sidecars' ISO."""
    def untagged(path, folder):
        dn, info = read_dng(path)
        folder.mkdir(exist_ok=True)
        out = folder / path.name
        write_dng_cfa(out, dn[0], pattern=info["cfa_pattern"], black_level_dn=info["black_level_exact"],
                      white_level=info["white_level"], unique_camera_model=info["unique_camera_model"],
                      color_matrix1=info["color_matrix1"], as_shot_neutral=info["as_shot_neutral"])
        shutil.copy(path.with_suffix(".json"), out.with_suffix(".json"))
        assert read_dng(out)[1]["iso"] is None and read_dng(out)[1]["exposure_s"] is None
        return str(out)

    darks = [untagged(p, tmp_path / "d") for p in sony_3200["dark"]]
    flats = [untagged(p, tmp_path / f"f{i // 4}") for i, p in enumerate(sony_3200["flat"])]
    out = tmp_path / "cal"
    assert main(["calibrate", "--dark", *darks, "--flat", *flats, "--out", str(out), "-q"]) == 0
    assert tomllib.loads((out / "preset.toml").read_text())["iso"][0]["iso"] == 3200
