"""camsim dataset with an [images] folder: the table's keys and errors, seeded crops and flips within the images
and covering them, the frames' clean layers following the image's pixels at the recorded crop and flips,
noise2noise repeats, ids that follow the images' bytes, and the example spec end to end."""

import hashlib
import json
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.dataset import load_spec, read_manifest, run_dataset
from camsim.io.exr import read_exr
from camsim.scene.builtin_scenes import SCENES_DIR, builtin_scene_names

ROOT = Path(__file__).resolve().parents[2]
SCENE = (ROOT / "scenes" / "macbeth_26.toml").as_posix()

# no fixed-pattern maps (DSNU, PRNU, row noise), no CFA: each pixel's clean value is its colour's alone
SPEC = f"""
name = "crops"
scene = "{SCENE}"
seed = 5
repeats = {{repeats}}

[images]
folder = "pictures"
crop = [{{crop}}]
flips = {{flips}}

[fixed]
preset = "emva-12bit"
illuminant = "D65"
intensity_factor = 0.5
dsnu_e = 0.0
prnu_percent = 0.0

[random]
count = {{count}}
read_noise_e = {{{{ uniform = [1.5, 6.0] }}}}
"""


def grey_picture(width: int, height: int, seed: int) -> np.ndarray:
    """An 8-bit grey RGB picture of random codes 10 … 245 (R = G = B): a pixel's code says where it came from."""
    codes = np.random.default_rng(seed).integers(10, 246, size=(height, width), dtype=np.uint8)
    return np.repeat(codes[:, :, None], 3, axis=2)


def make_folder(tmp_path: Path, sizes=((96, 64), (80, 56)), **spec) -> Path:
    """A spec in ``tmp_path`` and a ``pictures/`` folder of grey pictures ``a.png``, ``b.png`` … of ``sizes``."""
    folder = tmp_path / "pictures"
    folder.mkdir(parents=True, exist_ok=True)
    for i, (width, height) in enumerate(sizes):
        iio.imwrite(folder / f"{'abcdefgh'[i]}.png", grey_picture(width, height, i))
    values = {"repeats": 1, "crop": "48, 32", "flips": "true", "count": 6, **spec}
    path = tmp_path / "spec.toml"
    path.write_text(SPEC.format(**values), encoding="utf-8")
    return path


# --- the spec ------------------------------------------------------------------------------------------------


def test_frames_record_their_image_crop_and_flips(tmp_path):
    spec = load_spec(make_folder(tmp_path))
    assert len(spec) == 6 and (spec.width, spec.height) == (48, 32) and spec.size_text == "48x32"
    pictures = tmp_path / "pictures"
    digests = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in pictures.iterdir()}
    for frame in spec.frames:
        record = frame.record
        assert record["image_folder"] == "pictures" and record["image_file"] in digests
        assert record["image_sha256"] == digests[record["image_file"]]
        assert (record["width_px"], record["height_px"]) == (48, 32)
        assert isinstance(record["flip_horizontal"], bool) and isinstance(record["flip_vertical"], bool)
        crop = frame.image
        assert Path(crop.path) == pictures / record["image_file"]
        assert (crop.x, crop.y, crop.width, crop.height) == (record["crop_x"], record["crop_y"], 48, 32)
        assert frame.sensor_overrides == {"dsnu_e": 0.0, "prnu_percent": 0.0, "read_noise_e": record["read_noise_e"]}
    assert spec.axes["image_file"] == spec.axes["crop_x"] == spec.axes["flip_vertical"] == "images"
    assert len({f.id for f in spec.frames}) == 6


def test_same_spec_same_frames_and_more_draws_extend_them(tmp_path):
    path = make_folder(tmp_path)
    a, b = load_spec(path), load_spec(path)
    assert [(f.id, f.seed, f.record) for f in a.frames] == [(f.id, f.seed, f.record) for f in b.frames]
    path.write_text(path.read_text().replace("count = 6", "count = 9"))
    longer = load_spec(path)
    keys = ("image_file", "crop_x", "crop_y", "flip_horizontal", "flip_vertical")
    assert [[f.record[k] for k in keys] for f in longer.frames[:6]] == [[f.record[k] for k in keys] for f in a.frames]


def test_an_edited_image_changes_the_ids_of_its_frames_only(tmp_path):
    path = make_folder(tmp_path, count=12)
    before = load_spec(path)
    picture = tmp_path / "pictures" / "a.png"
    iio.imwrite(picture, 255 - iio.imread(picture))  # same size, other bytes
    after = load_spec(path)
    assert [f.record["crop_x"] for f in after.frames] == [f.record["crop_x"] for f in before.frames]
    uses_a = [f.record["image_file"] == "a.png" for f in before.frames]
    assert any(uses_a) and not all(uses_a)
    for old, new, changed in zip(before.frames, after.frames, uses_a):
        assert (old.id != new.id) == changed


def test_crops_lie_inside_the_images_and_cover_them(tmp_path):
    sizes = ((96, 64), (80, 56), (48, 40))
    spec = load_spec(make_folder(tmp_path, sizes=sizes, count=3000))
    size = {f"{'abc'[i]}.png": s for i, s in enumerate(sizes)}
    records = [f.record for f in spec.frames]
    files = [r["image_file"] for r in records]
    for name, (width, height) in size.items():
        xs = np.array([r["crop_x"] for r in records if r["image_file"] == name])
        ys = np.array([r["crop_y"] for r in records if r["image_file"] == name])
        assert 850 < len(xs) < 1150  # each image about a third of the draws
        assert xs.min() == 0 and xs.max() == width - 48 and ys.min() == 0 and ys.max() == height - 32
        # every offset is drawn, about equally often (a uniform draw over width - 48 + 1 positions)
        counts = np.bincount(xs, minlength=width - 47)
        assert np.all(counts > 0) and counts.max() < 3.5 * len(xs) / len(counts)
    assert set(files) == set(size)
    flips_h = np.array([r["flip_horizontal"] for r in records])
    flips_v = np.array([r["flip_vertical"] for r in records])
    assert 0.45 < flips_h.mean() < 0.55 and 0.45 < flips_v.mean() < 0.55
    assert 0.2 < np.mean(flips_h & flips_v) < 0.3  # independent
    unflipped = load_spec(make_folder(tmp_path / "no", flips="false", count=50))
    assert not any(f.record["flip_horizontal"] or f.record["flip_vertical"] for f in unflipped.frames)


@pytest.mark.parametrize(("change", "message"), [
    (lambda t: t.replace('folder = "pictures"', 'folder = "nowhere"'), r"\[images\] folder 'nowhere' is not a folder"),
    (lambda t: t.replace('folder = "pictures"', 'folder = "empty"'), r"\[images\] folder .*empty holds no image"),
    (lambda t: t.replace('folder = "pictures"', 'folder = "pictures"\npattern = "*.jpg"'),
     r"holds no image files matching '\*\.jpg'"),
    (lambda t: t.replace("crop = [48, 32]", "crop = [90, 32]"),
     r"\[images\] image .*b\.png is 80x56 pixels, smaller than the crop 90x32"),
    (lambda t: t.replace("crop = [48, 32]", 'crop = "48x32"'), r"\[images\] needs crop = \[width, height\]"),
    (lambda t: t.replace("crop = [48, 32]", "crop = [48, 0]"), r"\[images\] needs crop = \[width, height\]"),
    (lambda t: t.replace("crop = [48, 32]", ""), r"\[images\] needs crop = \[width, height\]"),
    (lambda t: t.replace("flips = true", 'flips = "yes"'), r"\[images\] flips must be true or false"),
    (lambda t: t.replace('folder = "pictures"', "folder = 3"), r"\[images\] needs folder"),
    (lambda t: t.replace("flips = true", "flip = true"), r"unknown key\(s\) in \[images\]: flip"),
    (lambda t: t + "\n[frame]\nwidth = 48\n", r"\[frame\] sets a size, but the frames are \[images\] crops"),
    (lambda t: t.replace("crop = [48, 32]", "crop = [48, 16]"), r"crop 48x16 is smaller than 22x22"),
    (lambda t: t.replace('illuminant = "D65"', 'illuminant = "D65"\ncfa = "RGGB"').replace("[48, 32]", "[47, 32]"),
     r"RGGB colour filter array needs an even frame size"),
])
def test_bad_images_tables_are_one_line_errors(tmp_path, capsys, change, message):
    path = make_folder(tmp_path)
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("not an image")
    path.write_text(change(path.read_text()))
    with pytest.raises(CamsimError, match=message):
        load_spec(path)
    assert main(["dataset", str(path), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error: ") and err.count("\n") == 1 and "Traceback" not in err


def test_a_file_that_is_not_an_image_is_named(tmp_path):
    path = make_folder(tmp_path)
    (tmp_path / "pictures" / "broken.png").write_bytes(b"not a png")
    with pytest.raises(CamsimError, match=r"\[images\] .*broken\.png"):
        load_spec(path)


def test_an_image_larger_than_any_camsim_decodes_is_refused_not_hashed(tmp_path):
    """A valid PNG followed by 8 GiB of holes (a sparse file: nothing on disk): a dataset hashes its images whole,
    so one larger than the largest image camsim may decode is refused from its size, not read for seconds."""
    import time

    from camsim.core.pixel_limit import MAX_IMAGE_FILE_BYTES

    path = make_folder(tmp_path)
    with open(tmp_path / "pictures" / "a.png", "r+b") as handle:
        handle.truncate(8 * 2**30)
    start = time.process_time()
    with pytest.raises(CamsimError, match=r"a\.png is 8\.59 GB, over the limit of 3\.26 GB"):
        load_spec(path)
    assert time.process_time() - start < 2.0
    assert MAX_IMAGE_FILE_BYTES == 3_264_000_000


# --- the frames ----------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """A rendered spec: 8 draws x 2 repeats of 48 x 32 crops, flips on; and a second run of it."""
    tmp = tmp_path_factory.mktemp("crops")
    path = make_folder(tmp, repeats=2, count=8)
    runs = []
    for name in ("a", "b"):
        run_dataset(path, tmp / name, workers=1, progress=False, echo=None)
        runs.append(tmp / name)
    return tmp, runs


def clean_layer(out: Path, record: dict) -> np.ndarray:
    return read_exr(out / record["files"]["exr"]["name"])[1]


def test_same_seed_gives_bit_identical_files(rendered):
    _, (a, b) = rendered
    files_a = {p.relative_to(a).as_posix(): p.read_bytes() for p in sorted(a.rglob("*")) if p.is_file()}
    files_b = {p.relative_to(b).as_posix(): p.read_bytes() for p in sorted(b.rglob("*")) if p.is_file()}
    assert len(files_a) == 1 + 16 * 5 and files_a == files_b  # manifest; dng, dng.xmp, exr, json, done per frame


def test_the_clean_layer_is_the_picture_at_the_recorded_crop_and_flips(rendered):
    """Every pixel's clean value is a non-decreasing function of its code in the picture file, read at the
    recorded offset and flipped as recorded (by NumPy here): one code, one value; a higher code, a higher value."""
    tmp, (out, _) = rendered
    records = read_manifest(out)
    assert {(r["flip_horizontal"], r["flip_vertical"]) for r in records} == {(False, False), (True, False),
                                                                             (False, True), (True, True)}
    for record in records:
        x, y = record["crop_x"], record["crop_y"]
        codes = iio.imread(tmp / "pictures" / record["image_file"])[y:y + 32, x:x + 48, 0]
        if record["flip_horizontal"]:
            codes = codes[:, ::-1]
        if record["flip_vertical"]:
            codes = codes[::-1, :]
        clean = clean_layer(out, record)
        assert clean.shape == (3, 32, 48)
        for channel in clean:
            order = np.argsort(codes, axis=None, kind="stable")
            sorted_codes, values = codes.ravel()[order], channel.ravel()[order]
            assert np.all(np.diff(values) >= 0)  # non-decreasing in the code
            same = sorted_codes[1:] == sorted_codes[:-1]
            assert np.array_equal(values[1:][same], values[:-1][same])  # one code, one value
            assert np.all(np.diff(values)[~same] > 0)  # a higher code is brighter (no saturation at F = 0.5)


def test_a_flipped_frame_is_the_unflipped_one_reversed(tmp_path):
    """A picture exactly the crop's size: every frame is the whole picture, so the flips are all that differ."""
    path = make_folder(tmp_path, sizes=((48, 32),), count=10)
    out = tmp_path / "out"
    run_dataset(path, out, workers=1, progress=False, echo=None)
    clean = {(r["flip_horizontal"], r["flip_vertical"]): clean_layer(out, r) for r in read_manifest(out)}
    assert len(clean) == 4  # every combination drawn
    plain = clean[(False, False)]
    assert not np.array_equal(plain, plain[:, :, ::-1]) and not np.array_equal(plain, plain[:, ::-1, :])
    assert np.array_equal(clean[(True, False)], plain[:, :, ::-1])
    assert np.array_equal(clean[(False, True)], plain[:, ::-1, :])
    assert np.array_equal(clean[(True, True)], plain[:, ::-1, ::-1])


def test_repeats_are_noise2noise_pairs(rendered):
    _, (out, _) = rendered
    records = read_manifest(out)
    assert len(records) == 16
    for first, second in zip(records[::2], records[1::2]):
        assert (first["repeat"], second["repeat"]) == (0, 1) and first["seed"] != second["seed"]
        keys = ("image_file", "crop_x", "crop_y", "flip_horizontal", "flip_vertical", "read_noise_e")
        assert all(first[k] == second[k] for k in keys)
        noisy_a, clean_a, _ = read_exr(out / first["files"]["exr"]["name"])
        noisy_b, clean_b, _ = read_exr(out / second["files"]["exr"]["name"])
        assert clean_a.tobytes() == clean_b.tobytes()  # the same target, bit for bit
        assert np.mean(noisy_a == noisy_b) < 0.2  # independent noise
        difference = noisy_a.astype(np.float64) - noisy_b
        # independent draws around the same mean: their difference is centred (to 5 standard errors)
        assert abs(difference.mean()) < 5 * difference.std() / np.sqrt(difference.size)


# --- the example ---------------------------------------------------------------------------------------------


def test_the_example_images_ship_beside_the_scenes():
    images = SCENES_DIR / "images"
    pictures = sorted(p.name for p in images.glob("*.png"))
    assert pictures == ["astronaut.png", "chelsea.png", "coffee.png"]
    for name in pictures:
        assert (images / name).stat().st_size < 300_000
        height, width = iio.imread(images / name).shape[:2]
        assert max(width, height) == 432 and min(width, height) >= 192
    readme = (images / "README.md").read_text(encoding="utf-8")
    assert "public domain" in readme and readme.count("CC0") >= 2
    assert builtin_scene_names() == ("astronaut", "chelsea", "coffee", "dark", "dead_leaves", "flat", "macbeth_26",
                                     "slanted_edge", "slanted_edge_lens")  # the images folder holds no scene


def test_example_spec_plan():
    spec = load_spec(ROOT / "scenes" / "denoise_small.toml")
    assert len(spec) == 96 and (spec.width, spec.height) == (256, 192)
    records = [f.record for f in spec.frames]
    assert {r["image_file"] for r in records} == {"astronaut.png", "chelsea.png", "coffee.png"}
    assert {r["illuminant"] for r in records} == {"D65", "A", "FL2"}
    assert all(r["flip_horizontal"] is not None for r in records)


@pytest.mark.slow
def test_example_spec_renders_end_to_end(tmp_path, capsys):
    out = tmp_path / "denoise_small"
    assert main(["dataset", str(ROOT / "scenes" / "denoise_small.toml"), "--out", str(out), "--workers", "2",
                 "-q"]) == 0
    assert "rendered 96 frames" in capsys.readouterr().out
    records = read_manifest(out)
    assert [r["index"] for r in records] == list(range(96))
    for record in records[:4]:
        noisy, clean, _ = read_exr(out / record["files"]["exr"]["name"])
        assert noisy.shape == clean.shape == (3, 192, 256)
        assert np.all(np.isfinite(noisy)) and clean.std() > 0  # a photograph, not a flat field
        sidecar = json.loads((out / record["files"]["json"]["name"]).read_text())
        assert sidecar["illuminant"] == record["illuminant"]
