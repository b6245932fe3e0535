"""camsim dataset with a [raws] folder: planning (ids, determinism, crops inside the files and aligned to the CFA,
flips that keep the pattern), frames rendered from a folder of phone-style DNGs written by an independent writer
(tests/support/phone_dng.py) against the closed form of their means, read back by rawpy, byte-identical on the same
seed, the SID-style pairs read by camsim.pairs and scored by denoise-eval, and one-line errors through the CLI."""

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest
import rawpy

from camsim.cli import main
from camsim.dataset import load_spec, read_manifest
from camsim.io.exr import read_exr
from tests.support.phone_dng import write_phone_dng

# the source files: Sony A7S II (the sony-a7s2 preset, found from Make/Model), ISO 100, 0.5 s
SOURCE_K = 0.09563  # sony-a7s2's gain at ISO 100 (DN/e-), the preset's published figure
TARGET_K = {"sony-a7s2": 0.09563, "nikon-d850": 0.4150393264348262}  # at ISO 100
T_SOURCE = 0.5
# per site of the top-left cell: black level and the flat signal above it (DN), all four different, so that a
# crop or flip that shifts the pattern puts the wrong value at a site
BLACK = np.array([[512.0, 510.0], [514.0, 508.0]])
SIGNAL = np.array([[2000.0, 1200.0], [900.0, 400.0]])
# LibRaw's colour index per 2x2 position (color_desc b"RGBG"): the pattern's letters
LETTERS = "RGBG"

SPEC = """
name = "raws"
seed = 7
repeats = {repeats}

[raws]
folder = "raws"
crop = [{crop}]
flips = {flips}
{raws_extra}

[fixed]
row_noise_e = 0.0
read_noise_model = "gaussian"
read_noise_e = 3.0
dark_current = false
{fixed_extra}

[grid]
{grid}

[random]
count = {count}
"""


def flat_mosaic(width: int, height: int, pattern_shift=(0, 0)) -> np.ndarray:
    """A mosaic whose every site of the 2 × 2 cell holds BLACK + SIGNAL of that site (shifted by ``pattern_shift``
    (dy, dx) for a file whose cell starts elsewhere)."""
    dy, dx = pattern_shift
    rows = (np.arange(height)[:, None] + dy) % 2
    cols = (np.arange(width)[None, :] + dx) % 2
    return (BLACK + SIGNAL)[rows, cols].astype(np.uint16)


def write_source(path: Path, width: int, height: int, pattern: str = "RGGB", mosaic=None, **kw) -> None:
    shift = {"RGGB": (0, 0), "GRBG": (0, 1)}[pattern]
    black = np.roll(BLACK, (-shift[0], -shift[1]), axis=(0, 1))
    write_phone_dng(path, flat_mosaic(width, height, shift) if mosaic is None else mosaic, pattern=pattern,
                    black_per_site=black, white=16383, iso=100, exposure_s=T_SOURCE,
                    **{"make": "SONY", "model": "ILCE-7SM2", "unique_camera_model": "Sony ILCE-7SM2",
                       "color_matrix1": [[0.6, -0.1, -0.05], [-0.4, 1.3, 0.1], [-0.08, 0.2, 0.6]],
                       "as_shot_neutral": [0.5, 1.0, 0.7], **kw})


def make_spec(tmp_path: Path, files=(("a.dng", 96, 80, "RGGB"), ("b.dng", 70, 104, "GRBG")), *, crop="32, 32",
              flips="true", count=4, repeats=1, grid='ratio = [1.0, 10.0, 300.0]', raws_extra="", fixed_extra="",
              random_mosaic=False) -> Path:
    folder = tmp_path / "raws"
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(3)
    for name, width, height, pattern in files:
        mosaic = None
        if random_mosaic:  # every pixel its own value: a crop's or flip's position shows in the clean layer
            mosaic = (520 + rng.integers(0, 1500, (height, width))).astype(np.uint16)
        write_source(folder / name, width, height, pattern, mosaic)
    path = tmp_path / "spec.toml"
    path.write_text(SPEC.format(crop=crop, flips=flips, count=count, repeats=repeats, grid=grid,
                                raws_extra=raws_extra, fixed_extra=fixed_extra))
    return path


def render(spec: Path, out: Path, workers: int = 1) -> list:
    assert main(["dataset", str(spec), "--out", str(out), "--workers", str(workers), "--quiet"]) == 0
    return read_manifest(out)


def libraw_pattern(raw) -> str:
    return "".join(LETTERS[i] for i in raw.raw_pattern.ravel())


# --- planning ----------------------------------------------------------------------------------------------------


def test_plan_ids_are_deterministic_and_crops_aligned_inside_the_files(tmp_path):
    spec = make_spec(tmp_path, count=40)
    frames = load_spec(spec).frames
    again = load_spec(spec).frames
    assert [(f.id, f.seed) for f in frames] == [(f.id, f.seed) for f in again]
    assert len(frames) == 120 and len({f.id for f in frames}) == 120
    assert all(f.id.startswith(f"{f.index:05d}-") for f in frames)
    sizes = {"a.dng": (96, 80), "b.dng": (70, 104)}
    seen = set()
    for frame in frames:
        record = frame.record
        width, height = sizes[record["raw_file"]]
        x, y, flip_h, flip_v = (record[k] for k in ("crop_x", "crop_y", "flip_horizontal", "flip_vertical"))
        assert 0 <= x and x + 32 <= width and 0 <= y and y + 32 <= height
        # an unflipped axis starts on a cell; a flipped one a column (row) off it, so the mirror restores it
        assert x % 2 == int(flip_h) and y % 2 == int(flip_v)
        assert record["cfa"] == {"a.dng": "RGGB", "b.dng": "GRBG"}[record["raw_file"]]
        assert record["raw_sha256"] == hashlib.sha256((tmp_path / "raws" / record["raw_file"]).read_bytes()).hexdigest()
        assert record["exposure_s"] == pytest.approx(T_SOURCE / record["ratio"])
        assert frame.sensor_overrides == {"cfa": record["cfa"], "exposure_s": record["exposure_s"],
                                          "row_noise_e": 0.0, "read_noise_model": "gaussian", "read_noise_e": 3.0,
                                          "dark_current": False}
        seen.add((record["raw_file"], flip_h, flip_v))
    assert len(seen) == 8  # both files, every flip


def test_an_edited_file_changes_the_ids_of_its_frames_only(tmp_path):
    spec = make_spec(tmp_path, count=10)
    before = {f.index: (f.id, f.record["raw_file"]) for f in load_spec(spec).frames}
    mosaic = flat_mosaic(70, 104, (0, 1))
    mosaic[5, 5] += 1
    write_source(tmp_path / "raws" / "b.dng", 70, 104, "GRBG", mosaic)
    after = {f.index: f.id for f in load_spec(spec).frames}
    for index, (frame_id, name) in before.items():
        assert (after[index] == frame_id) == (name == "a.dng")


# --- rendering ---------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("raws")
    spec = make_spec(tmp, crop="64, 64", count=3, grid='ratio = [1.0, 10.0, 300.0]\npreset = ["sony-a7s2", '
                                                         '"nikon-d850"]')
    out = tmp / "out"
    return spec, out, render(spec, out, workers=2)


def test_frames_means_follow_the_closed_form_and_keep_the_files_pattern(rendered):
    spec, out, records = rendered
    assert len(records) == 18
    for record in records:
        source_pattern = {"a.dng": "RGGB", "b.dng": "GRBG"}[record["raw_file"]]
        with rawpy.imread(str(out / record["files"]["dng"]["name"])) as raw:
            assert libraw_pattern(raw) == source_pattern  # flipped or not, the file's pattern
            digital = raw.raw_image_visible.astype(np.float64)
            black = np.asarray(raw.black_level_per_channel, dtype=np.float64)
            site_black = black[raw.raw_colors_visible[:2, :2]]
        assert digital.shape == (64, 64)
        # the source's cell at the frame's top-left: the file's at an even offset (the flips keep it)
        file_signal = np.roll(SIGNAL, (0, -1 if record["raw_file"] == "b.dng" else 0), axis=(0, 1))
        fraction = 1.0 / record["ratio"]  # F = 1, T = T_source / ratio
        k_target = TARGET_K[record["preset"]]
        read_var = 3.0 ** 2
        for dy in (0, 1):
            for dx in (0, 1):
                expected_e = fraction * file_signal[dy, dx] / SOURCE_K
                expected = expected_e * k_target + site_black[dy, dx]
                assert site_black[dy, dx] == record["pedestal_dn"]
                site = digital[dy::2, dx::2]
                sigma = k_target * np.sqrt(expected_e + read_var) / np.sqrt(site.size) + 0.3 / np.sqrt(site.size)
                assert abs(site.mean() - expected) < 5 * sigma + 0.02, (record["id"], dy, dx, site.mean(), expected)
                # and its variance: Poisson of the expectation plus the read noise, times K² (plus rounding)
                var = k_target ** 2 * (expected_e + read_var) + 1 / 12
                assert site.var(ddof=1) == pytest.approx(var, rel=6 * np.sqrt(2 / site.size))


def test_the_clean_layer_is_the_scaled_source(rendered):
    spec, out, records = rendered
    for record in records[:6]:
        _, clean_planes, _ = read_exr(out / record["files"]["exr"]["name"])
        k_target = TARGET_K[record["preset"]]
        pattern = record["cfa"]
        file_signal = np.roll(SIGNAL, (0, -1 if record["raw_file"] == "b.dng" else 0), axis=(0, 1))
        for dy in (0, 1):
            for dx in (0, 1):
                colour = pattern[2 * dy + dx]
                clean = clean_planes["RGB".index(colour), dy::2, dx::2]
                expected = file_signal[dy, dx] / SOURCE_K / record["ratio"] * k_target
                np.testing.assert_allclose(clean, expected, rtol=1e-5)


def test_flipped_frames_are_the_window_mirrored(tmp_path):
    spec = make_spec(tmp_path, count=12, random_mosaic=True, grid="ratio = [2.0]")
    out = tmp_path / "out"
    records = render(spec, out)
    assert any(r["flip_horizontal"] for r in records) and any(r["flip_vertical"] for r in records)
    assert not all(r["flip_horizontal"] and r["flip_vertical"] for r in records)
    for record in records:
        with rawpy.imread(str(tmp_path / "raws" / record["raw_file"])) as raw:
            source = raw.raw_image_visible.astype(np.float64)
            black = np.asarray(raw.black_level_per_channel, dtype=np.float64)[raw.raw_colors_visible]
        x, y = record["crop_x"], record["crop_y"]
        window = (source - black)[y:y + 32, x:x + 32]
        if record["flip_horizontal"]:
            window = window[:, ::-1]
        if record["flip_vertical"]:
            window = window[::-1, :]
        _, clean_planes, _ = read_exr(out / record["files"]["exr"]["name"])
        clean = np.zeros((32, 32))
        for dy in (0, 1):
            for dx in (0, 1):
                clean[dy::2, dx::2] = clean_planes["RGB".index(record["cfa"][2 * dy + dx]), dy::2, dx::2]
        np.testing.assert_allclose(clean, window / record["ratio"], rtol=1e-5, atol=1e-3)
        sidecar = json.loads((out / record["files"]["json"]["name"]).read_text())
        assert sidecar["raw_source"]["crop_xywh"] == [x, y, 32, 32]
        assert sidecar["raw_source"]["flip_horizontal"] == record["flip_horizontal"]


def test_the_same_seed_gives_byte_identical_files(rendered, tmp_path):
    spec, out, records = rendered
    again = render(spec, tmp_path / "again", workers=1)
    assert [r["id"] for r in again] == [r["id"] for r in records]
    for first, second in zip(records, again):
        for kind, entry in first["files"].items():
            again_file = tmp_path / "again" / second["files"][kind]["name"]
            assert (out / entry["name"]).read_bytes() == again_file.read_bytes()


def test_written_pairs_and_denoise_eval_read_the_dataset(rendered, tmp_path):
    from camsim.pairs import WrittenPairs

    spec, out, records = rendered
    pairs = WrittenPairs(out)
    assert len(pairs) == len(records)
    noisy, clean, meta = pairs[0]
    assert noisy.shape == clean.shape == (1, 64, 64)
    assert meta["record"]["raw_file"] == records[0]["raw_file"]
    assert main(["denoise-eval", str(out), "--denoiser", "identity", "--out", str(tmp_path / "eval"),
                 "--quiet"]) == 0
    rows = (tmp_path / "eval" / "frames.csv").read_text().splitlines()
    assert len(rows) == 1 + len(records)  # a row per frame


# --- errors ------------------------------------------------------------------------------------------------------


def _refused(tmp_path, capsys, spec: Path, message: str) -> None:
    out = tmp_path / "out"
    assert main(["dataset", str(spec), "--out", str(out), "--workers", "1", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1, err
    assert not out.exists()  # nothing written


def test_an_empty_folder_is_refused(tmp_path, capsys):
    spec = make_spec(tmp_path, files=())
    _refused(tmp_path, capsys, spec, "holds no raw files")


def test_a_crop_larger_than_a_file_is_refused(tmp_path, capsys):
    spec = make_spec(tmp_path, crop="72, 32")
    _refused(tmp_path, capsys, spec, "b.dng is 70x104 pixels, smaller than the crop 72x32")


def test_an_unreadable_file_is_named(tmp_path, capsys):
    spec = make_spec(tmp_path)
    (tmp_path / "raws" / "c.dng").write_bytes(b"not a raw file at all" * 10)
    _refused(tmp_path, capsys, spec, "c.dng")


def test_an_unknown_camera_without_a_preset_is_refused(tmp_path, capsys):
    spec = make_spec(tmp_path)
    write_source(tmp_path / "raws" / "c.dng", 64, 64, make="Acme", model="Obscura 1", unique_camera_model="Acme X")
    _refused(tmp_path, capsys, spec, "unknown camera")
    # naming the source camera in [raws] takes it
    spec.write_text(spec.read_text().replace('folder = "raws"', 'folder = "raws"\npreset = "sony-a7s2"'))
    assert len(load_spec(spec)) == 12


@pytest.mark.parametrize("change, message", [
    (dict(grid='ratio = [10.0]\nexposure_s = [0.1]'), "either ratio"),
    (dict(raws_extra='photon_law = "thin"', grid="ratio = [0.5]"), "thin' cannot brighten"),
    (dict(grid='illuminant = ["D65"]'), "illuminant does not apply"),
    (dict(crop="31, 32"), "even positive integers"),
    (dict(raws_extra='cropp = 1'), "unknown key(s) in [raws]: cropp"),
])
def test_bad_raws_specs_are_one_line_errors(tmp_path, capsys, change, message):
    spec = make_spec(tmp_path, **change)
    _refused(tmp_path, capsys, spec, message)


def test_ratio_is_refused_outside_raws_specs(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text('scene = "macbeth_26"\n[fixed]\nratio = 10.0\n')
    _refused(tmp_path, capsys, spec, "ratio applies to the frames of a [raws] spec")


def test_virtual_cameras_and_thin_frames_plan_and_render(tmp_path):
    spec = make_spec(tmp_path, count=3, grid="ratio = [4.0]", raws_extra='photon_law = "thin"',
                     fixed_extra="").read_text()
    spec = spec.replace('row_noise_e = 0.0\nread_noise_model = "gaussian"\nread_noise_e = 3.0\n', "")
    spec += '\n[virtual_camera]\ncameras = ["sony-a7s2", "nikon-d850"]\n'
    path = tmp_path / "spec.toml"
    path.write_text(spec)
    records = render(path, tmp_path / "out")
    assert len(records) == 3
    for record in records:
        assert record["preset"] in ("sony-a7s2", "nikon-d850") and "iso" not in record  # the virtual camera's
        assert record["photon_law"] == "thin" and record["exposure_s"] == pytest.approx(T_SOURCE / 4)
        sidecar = json.loads((tmp_path / "out" / record["files"]["json"]["name"]).read_text())
        assert sidecar["method"] == "raw-thin" and sidecar["raw_source"]["fraction"] == pytest.approx(0.25)
        assert sidecar["dn_per_electron"] == pytest.approx(record["dn_per_electron"])


def test_srgb_outputs_develop_every_ratio_as_bright_as_its_source(tmp_path):
    from camsim.pairs import WrittenPairs

    spec = make_spec(tmp_path, files=(("a.dng", 96, 80, "RGGB"),), flips="false", count=1,
                     grid="ratio = [10.0, 300.0]")
    out = tmp_path / "out"
    assert main(["dataset", str(spec), "--out", str(out), "--workers", "1", "--quiet", "--srgb", "png16"]) == 0
    pairs = WrittenPairs(out, domain="srgb")
    assert len(pairs) == 2
    cleans = [pairs[i][1] for i in range(2)]
    assert cleans[0].shape == (3, 32, 32)
    # the flat source's clean frame, developed with gain = ratio: the same picture at both ratios
    np.testing.assert_allclose(cleans[0].mean(axis=(1, 2)), cleans[1].mean(axis=(1, 2)), atol=2e-3)
    assert 0.05 < float(cleans[0].mean()) < 0.95
    noisy = [pairs[i][0] for i in range(2)]
    assert float(noisy[1].std()) > float(noisy[0].std())  # ratio 300 is the noisier once developed


def test_a_zarr_store_is_refused_by_the_run_and_the_dry_run(tmp_path, capsys):
    spec = make_spec(tmp_path, count=1)
    out = tmp_path / "out"
    for extra in ([], ["--dry-run"]):
        assert main(["dataset", str(spec), "--out", str(out), "--format", "zarr", "--quiet", *extra]) == 2
        err = capsys.readouterr().err.strip()
        assert "--format zarr is not made for it" in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_saturated_source_sites_are_masked_and_counted(tmp_path, capsys):
    import imageio.v3 as iio

    spec = make_spec(tmp_path, files=(("a.dng", 96, 80, "RGGB"),), count=6, grid="ratio = [10.0]")
    mosaic = flat_mosaic(96, 80)
    mosaic[:, :40] = 16383  # the file's white level: the left columns saturated
    write_source(tmp_path / "raws" / "a.dng", 96, 80, "RGGB", mosaic)
    out = tmp_path / "out"
    records = render(spec, out)
    for record in records:
        x, flipped = record["crop_x"], record["flip_horizontal"]
        window = np.zeros((32, 32), bool)
        window[:, :max(0, min(32, 40 - x))] = True  # the saturated columns of the window, before any mirror
        expected = window[:, ::-1] if flipped else window
        sidecar = json.loads((out / record["files"]["json"]["name"]).read_text())
        assert sidecar["raw_source"]["masked_px"] == int(expected.sum())
        if expected.any():
            mask = iio.imread(out / record["files"]["mask"]["name"])[..., 0] == 255
            np.testing.assert_array_equal(mask, expected)
        else:
            assert "mask" not in record["files"]
    assert any("mask" in r["files"] for r in records)
    render(spec, out)  # a rerun verifies every file, the masks too, and renders nothing
    assert "rendered 0 frames" in capsys.readouterr().out
