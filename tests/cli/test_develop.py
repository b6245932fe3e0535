"""``camsim develop``: what it writes, that the same frame gives the same bytes, and hostile input on one line."""

import json
import os
import shutil
import sys

import numpy as np
import pytest

from camsim.cli import main
from camsim.isp import read_png_record
from tests.support.helpers import full_disk


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    """A small macbeth_26 render: a Bayer sony-a7s2 frame at F = 0.5 and a three-chip paper-table1 one."""
    out = tmp_path_factory.mktemp("develop")
    assert main(["render", "macbeth_26", "--preset", "sony-a7s2", "--size", "120x80", "-F", "0.5",
                 "--illuminant", "D65", "--out", str(out / "bayer"), "-q"]) == 0
    assert main(["render", "macbeth_26", "--size", "120x80", "-F", "1", "--illuminant", "A",
                 "--out", str(out / "chip3"), "-q"]) == 0
    return out


def _one_line_error(capsys, argv, phrase):
    status = main(argv)
    err = capsys.readouterr().err
    assert status == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("camsim: error: ") and phrase in lines[0], err


def test_a_folder_develops_every_frame_into_png_and_json(rendered, tmp_path, capsys):
    out = tmp_path / "dev"
    assert main(["develop", str(rendered / "bayer"), str(rendered / "chip3" / "macbeth_26_A_F1.exr"),
                 "--out", str(out), "--jpeg-quality", "90", "--gain", "auto", "-q"]) == 0
    assert "developed 2 frame(s)" in capsys.readouterr().out
    # the two frames share a stem: one was taken from a folder, one named; the names collide only if equal
    names = sorted(p.name for p in out.iterdir())
    assert names == ["macbeth_26_A_F1.jpg", "macbeth_26_A_F1.json", "macbeth_26_A_F1.png",
                     "macbeth_26_D65_F0.5.jpg", "macbeth_26_D65_F0.5.json", "macbeth_26_D65_F0.5.png"]
    record = json.loads((out / "macbeth_26_D65_F0.5.json").read_text())
    assert record == read_png_record(out / "macbeth_26_D65_F0.5.png")
    assert record["frame"] == "macbeth_26_D65_F0.5.dng" and record["frame_metadata"] == "sidecar"
    assert record["stages"]["gain"]["value"] == pytest.approx(2.0)  # auto: 1 / F
    assert record["stages"]["demosaic"]["method"] == "malvar2004"
    assert len(record["stages"]["matrix"]["matrix"]) == 3
    assert record["settings"]["tone"] == "srgb" and record["output"]["jpeg_quality"] == 90
    exr = json.loads((out / "macbeth_26_A_F1.json").read_text())
    assert exr["stages"]["demosaic"] is None and exr["facts"]["illuminant"] == "A"


def test_the_same_frame_gives_the_same_bytes(rendered, tmp_path):
    frame = str(rendered / "bayer" / "macbeth_26_D65_F0.5.dng")
    for name in ("a", "b"):
        assert main(["develop", frame, "--out", str(tmp_path / name), "--bits", "16", "--jpeg-quality", "80",
                     "-q"]) == 0
    for suffix in ("png", "jpg", "json"):
        first = (tmp_path / "a" / f"macbeth_26_D65_F0.5.{suffix}").read_bytes()
        assert first == (tmp_path / "b" / f"macbeth_26_D65_F0.5.{suffix}").read_bytes(), suffix


def test_the_options_reach_the_record(rendered, tmp_path):
    frame = str(rendered / "bayer" / "macbeth_26_D65_F0.5.dng")
    assert main(["develop", frame, "--out", str(tmp_path), "--white-balance", "A", "--demosaic", "menon2007",
                 "--matrix", "none", "--gain", "3", "--tone", "filmic", "--no-black", "-q"]) == 0
    record = read_png_record(tmp_path / "macbeth_26_D65_F0.5.png")
    assert record["settings"] == {"black": False, "white_balance": "A", "demosaic": "menon2007", "matrix": "none",
                                  "gain": 3.0, "tone": "filmic"}
    assert record["stages"]["black"]["black_dn"] == [0.0, 0.0, 0.0]


def test_a_dng_without_its_sidecar_is_developed_from_its_tags(rendered, tmp_path):
    alone = tmp_path / "alone.dng"
    shutil.copy(rendered / "bayer" / "macbeth_26_D65_F0.5.dng", alone)
    assert main(["develop", str(alone), "--out", str(tmp_path / "out"), "-q"]) == 0
    record = read_png_record(tmp_path / "out" / "alone.png")
    assert record["frame_metadata"] == "dng-tags"
    assert record["facts"]["colour_source"] == "color_matrix1"
    assert record["stages"]["matrix"]["camera_to_xyz"] == "inverse of ColorMatrix1"


def test_a_non_frame_is_one_line(rendered, tmp_path, capsys):
    text = tmp_path / "notes.txt"
    text.write_text("hello")
    _one_line_error(capsys, ["develop", str(text), "--out", str(tmp_path / "o")], "not a frame file")
    fake = tmp_path / "fake.dng"
    fake.write_bytes(b"II*\x00" + bytes(100))
    _one_line_error(capsys, ["develop", str(fake), "--out", str(tmp_path / "o")], "fake.dng")
    assert not (tmp_path / "o").exists()


def test_a_truncated_dng_is_one_line_and_writes_nothing(rendered, tmp_path, capsys):
    source = rendered / "bayer" / "macbeth_26_D65_F0.5.dng"
    cut = tmp_path / "in" / "macbeth_26_D65_F0.5.dng"
    cut.parent.mkdir()
    cut.write_bytes(source.read_bytes()[: source.stat().st_size // 2])
    shutil.copy(source.with_suffix(".json"), cut.with_suffix(".json"))
    _one_line_error(capsys, ["develop", str(cut), "--out", str(tmp_path / "o")], "truncated")
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


@pytest.mark.parametrize("extra, phrase", [
    (["--demosaic", "ahd"], "invalid choice"),
    (["--tone", "reinhard"], "invalid choice"),
    (["--gain", "0"], "gain must be a positive number"),
    (["--gain", "nan"], "gain must be a positive number"),
    (["--jpeg-quality", "101"], "JPEG quality"),
    (["--bits", "12"], "invalid choice"),
    (["--white-balance", "no-such-light"], "no-such-light"),
])
def test_bad_options_are_one_line(rendered, tmp_path, capsys, extra, phrase):
    frame = str(rendered / "bayer" / "macbeth_26_D65_F0.5.dng")
    _one_line_error(capsys, ["develop", frame, "--out", str(tmp_path / "o"), *extra], phrase)
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_gain_auto_without_a_sidecar_is_one_line(rendered, tmp_path, capsys):
    alone = tmp_path / "alone.dng"
    shutil.copy(rendered / "bayer" / "macbeth_26_D65_F0.5.dng", alone)
    _one_line_error(capsys, ["develop", str(alone), "--out", str(tmp_path / "o"), "--gain", "auto"],
                    "intensity factor")


@pytest.mark.skipif(sys.platform == "win32" or os.geteuid() == 0, reason="root writes into read-only folders")
def test_an_unwritable_out_is_one_line(rendered, tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        _one_line_error(capsys, ["develop", str(rendered / "bayer"), "--out", str(locked / "o")], str(locked))
    finally:
        locked.chmod(0o700)


def test_an_out_that_is_a_file_or_under_one_is_one_line(rendered, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    _one_line_error(capsys, ["develop", str(rendered / "bayer"), "--out", str(blocker)], str(blocker))
    _one_line_error(capsys, ["develop", str(rendered / "bayer"), "--out", str(blocker / "sub")], str(blocker))
    assert blocker.read_text() == "x"


def test_two_frames_with_one_stem_are_refused(rendered, tmp_path, capsys):
    frame = rendered / "bayer" / "macbeth_26_D65_F0.5.dng"
    other = tmp_path / "other"
    other.mkdir()
    for suffix in (".dng", ".json"):
        shutil.copy(frame.with_suffix(suffix), other / frame.with_suffix(suffix).name)
    _one_line_error(capsys, ["develop", str(frame), str(other), "--out", str(tmp_path / "o")], "same outputs")
    assert not (tmp_path / "o").exists()


def test_a_16_bit_png_holds_the_developed_image(rendered, tmp_path):
    import camsim.isp as isp
    from camsim.render.frame_files import load_frame

    frame = rendered / "bayer" / "macbeth_26_D65_F0.5.dng"
    assert main(["develop", str(frame), "--out", str(tmp_path), "--bits", "16", "-q"]) == 0
    import OpenImageIO as oiio

    reader = oiio.ImageInput.open(str(tmp_path / "macbeth_26_D65_F0.5.png"))
    pixels = reader.read_image(0, 0, 0, 3, "uint16")
    reader.close()
    loaded = load_frame(frame)
    image = isp.develop(loaded.pixels_dn, isp.facts_of(loaded)).image
    assert np.array_equal(pixels, np.floor(np.moveaxis(image, 0, -1) * 65535 + 0.5).astype(np.uint16))


def test_a_bad_frame_after_good_ones_leaves_nothing_written(rendered, tmp_path, capsys):
    """The outputs of one run are one unit: a failure on the second frame removes the first frame's files."""
    source = rendered / "bayer" / "macbeth_26_D65_F0.5.dng"
    folder = tmp_path / "in"
    folder.mkdir()
    for name in ("a", "b"):
        shutil.copy(source.with_suffix(".json"), folder / f"{name}.json")
    shutil.copy(source, folder / "a.dng")
    (folder / "b.dng").write_bytes(source.read_bytes()[:5000])
    out = tmp_path / "o"
    _one_line_error(capsys, ["develop", str(folder / "a.dng"), str(folder / "b.dng"), "--out", str(out)],
                    "b.dng")
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize("suffix", [None, "json", "jpg"])
def test_a_full_disk_is_one_line_and_leaves_nothing(rendered, tmp_path, capsys, monkeypatch, suffix):
    """Every write fails with ENOSPC when it flushes its file (or only the JSON records, the last written, or the
    JPEGs): one line naming the folder, and none of the run's files are left."""
    full_disk(monkeypatch, only_suffix=suffix)
    out = tmp_path / "out"
    _one_line_error(capsys, ["develop", str(rendered / "bayer"), str(rendered / "chip3"), "--out", str(out),
                             "--jpeg-quality", "90"], "No space left on device")
    assert not out.exists() or not any(out.rglob("*"))


def test_a_dng_tag_with_a_zero_denominator_is_one_line_without_warnings(rendered, tmp_path, capsys):
    """A damaged DNG alone (no sidecar: its own tags are read) whose AsShotNeutral has a zero denominator: one
    error line, no numpy warning on stderr (found by tools/fuzz_cli.py --kinds dng: the division warned)."""
    import tifffile

    source = rendered / "bayer" / "macbeth_26_D65_F0.5.dng"
    with tifffile.TiffFile(source) as tif:
        tag = next(t for p in tif.pages for t in p.tags.values() if t.code == 50728)  # AsShotNeutral
        offset = tag.valueoffset
    body = bytearray(source.read_bytes())
    body[offset + 4:offset + 8] = bytes(4)  # the first rational's denominator
    damaged = tmp_path / "in" / "damaged.dng"
    damaged.parent.mkdir()
    damaged.write_bytes(bytes(body))
    _one_line_error(capsys, ["develop", str(damaged), "--out", str(tmp_path / "o"), "-q"], "damaged.dng")
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())
