"""8-bit three-chip LinearRaw DNG: exact numbers through LibRaw, levels, colour metadata, determinism, errors."""

import errno
import math
import re

import numpy as np
import pytest
import rawpy
import tifffile

from camsim.core.errors import CamsimError, OutputError
from camsim.io import dng as dng_mod
from camsim.io.dng import read_dng, write_dng
from tests.support.hostile_files import HUGE_SIZES, no_hang, not_regular, one_error_line, with_tiff_size

H, W = 48, 64
# XYZ -> linear sRGB (D65); a camera whose XYZ -> camera matrix is diag(GAINS) @ this sees D65 white as GAINS.
XYZ_TO_SRGB = np.array([[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]])
GAINS = np.array([0.5, 1.0, 0.7])


def random_dn(seed, h=H, w=W):
    dn = np.random.default_rng(seed).integers(0, 256, size=(3, h, w), dtype=np.uint8)
    dn[:, 0, 0] = 0
    dn[:, -1, -1] = 255
    dn[0, 1, 2], dn[1, 1, 2], dn[2, 1, 2] = 0, 255, 0
    return dn


def write(path, dn, **overrides):
    kwargs = dict(black_level_dn=16.0, white_level=255, unique_camera_model="camsim test camera",
                  color_matrix1=np.diag(GAINS) @ XYZ_TO_SRGB, as_shot_neutral=GAINS)
    kwargs.update(overrides)
    write_dng(path, dn, **kwargs)
    return path


@pytest.mark.parametrize(("seed", "h", "w"), [(0, H, W), (1, 23, 37), (2, 22, 22)])
def test_rawpy_returns_exact_numbers(tmp_path, seed, h, w):
    dn = random_dn(seed, h, w)
    path = write(tmp_path / "f.dng", dn)
    with rawpy.imread(str(path)) as raw:
        assert raw.raw_type == rawpy.RawType.Stack and raw.num_colors == 3
        image = raw.raw_image
        # LibRaw stacks colour images in 4 channels: R, G, B exactly as written, and an all-zero 4th.
        assert image.shape == (h, w, 4)
        np.testing.assert_array_equal(image[..., :3], dn.transpose(1, 2, 0))
        assert not image[..., 3].any()
        np.testing.assert_array_equal(raw.raw_image_visible[..., :3], dn.transpose(1, 2, 0))
    back, info = read_dng(path)
    assert back.dtype == np.uint8 and back.shape == (3, h, w)
    np.testing.assert_array_equal(back, dn)
    assert info["unique_camera_model"] == "camsim test camera"
    assert info["make"] == "camsim" and info["model"] == "camsim test camera"


def test_16_bit_container_round_trip(tmp_path):
    """ADCs of more than 8 bits (e.g. 12) are stored in a 16-bit LinearRaw DNG, read back exactly."""
    dn = np.random.default_rng(5).integers(0, 4096, size=(3, H, W), dtype=np.uint16)
    dn[:, 0, 0] = 4095
    path = write(tmp_path / "f.dng", dn, white_level=4095)
    with rawpy.imread(str(path)) as raw:
        np.testing.assert_array_equal(raw.raw_image[..., :3], dn.transpose(1, 2, 0))
        assert raw.white_level == 4095
    back, info = read_dng(path)
    assert back.dtype == np.uint16
    np.testing.assert_array_equal(back, dn)


@pytest.mark.parametrize("black", [0.0, 16.0, 16.4, 16.5, 16.6, 3.25, (10.0, 12.25, 14.75)])
@pytest.mark.parametrize("white", [255, 250])
def test_black_and_white_level_as_libraw_reports_them(tmp_path, black, white):
    path = write(tmp_path / "f.dng", random_dn(3), black_level_dn=black, white_level=white)
    expected = np.broadcast_to(np.asarray(black, dtype=float), (3,))
    with rawpy.imread(str(path)) as raw:
        # LibRaw rounds a fractional black level to nearest, halves up.
        assert list(raw.black_level_per_channel) == [math.floor(b + 0.5) for b in expected] + [0]
        assert raw.white_level == white
    _, info = read_dng(path)
    assert info["black_level"] == [math.floor(b + 0.5) for b in expected]
    assert info["black_level_exact"] == expected.tolist()  # the tag keeps the exact fraction
    assert info["white_level"] == white


def test_dng_tags(tmp_path):
    cm = np.diag(GAINS) @ XYZ_TO_SRGB
    path = write(tmp_path / "f.dng", random_dn(4), as_shot_neutral=[0.512345, 1.0, 0.7], software="camsim 0.1.0",
                 calibration_illuminant1=17, model="sim-1")
    with tifffile.TiffFile(path) as tif:
        assert len(tif.pages) == 1
        page = tif.pages.first
        tags = {t.code: t.value for t in page.tags}
    assert page.photometric == 34892 and page.samplesperpixel == 3 and page.bitspersample == 8
    assert page.planarconfig == tifffile.PLANARCONFIG.CONTIG and page.compression == tifffile.COMPRESSION.NONE
    assert tags[254] == 0  # NewSubFileType: main image
    assert bytes(tags[50706]) == bytes([1, 4, 0, 0]) and bytes(tags[50707]) == bytes([1, 1, 0, 0])
    assert tags[50708] == "camsim test camera" and tags[271] == "camsim" and tags[272] == "sim-1"
    assert tags[305] == "camsim 0.1.0" and tags[50778] == 17
    # BlackLevelRepeatDim absent, i.e. its default 1 x 1, with one BlackLevel per sample (RawTherapee 5.9 drops red's
    # level when the tag is written: docs, reference 'File formats')
    assert 50713 not in tags and len(tags[50714]) == 2 * 3 and tuple(tags[50717]) == (255, 255, 255)
    assert 306 not in tags and 270 not in tags  # no DateTime, no ImageDescription
    _, info = read_dng(path)
    np.testing.assert_allclose(info["color_matrix1"], cm, rtol=0, atol=1e-6)
    np.testing.assert_allclose(info["as_shot_neutral"], [0.512345, 1.0, 0.7], rtol=0, atol=1e-9)
    assert info["calibration_illuminant1"] == 17


def test_same_input_gives_identical_bytes(tmp_path):
    dn = random_dn(5)
    a = write(tmp_path / "a.dng", dn, black_level_dn=16.5).read_bytes()
    b = write(tmp_path / "b.dng", dn.copy(), black_level_dn=16.5).read_bytes()
    assert a == b
    dn2 = dn.copy()
    dn2[1, 10, 10] ^= 1
    assert write(tmp_path / "c.dng", dn2, black_level_dn=16.5).read_bytes() != a


def grey_and_red_frame(black=16.0):
    dn = np.empty((3, H, W))
    dn[:, :, : W // 2] = (black + 120 * GAINS)[:, None, None]  # neutral: camera values proportional to neutral
    dn[:, :, W // 2:] = (black + 200 * GAINS * np.array([1.0, 0.05, 0.05]))[:, None, None]  # saturated red
    return np.round(dn).astype(np.uint8)


def test_postprocess_gives_neutral_grey_and_red(tmp_path):
    path = write(tmp_path / "f.dng", grey_and_red_frame())
    with rawpy.imread(str(path)) as raw:
        rgb = raw.postprocess()
    assert rgb.shape == (H, W, 3) and rgb.dtype == np.uint8
    grey = rgb[4:-4, 4: W // 2 - 4].reshape(-1, 3).astype(int)
    red = rgb[4:-4, W // 2 + 4: -4].reshape(-1, 3).astype(int)
    assert 60 < grey.mean() < 250
    assert np.ptp(grey.mean(axis=0)) <= 3 and np.ptp(grey, axis=0).max() <= 2
    assert np.all(red[:, 0] > red[:, 1] + 100) and np.all(red[:, 0] > red[:, 2] + 100)


def test_postprocess_linear_uses_color_matrix_and_neutral(tmp_path):
    path = write(tmp_path / "f.dng", grey_and_red_frame())
    with rawpy.imread(str(path)) as raw:
        # camera = diag(GAINS) @ sRGB, white-balanced by AsShotNeutral: LibRaw's camera -> sRGB matrix is identity
        np.testing.assert_allclose(raw.color_matrix[:, :3], np.eye(3), atol=2e-3)
        rgb = raw.postprocess(gamma=(1, 1), no_auto_bright=True, use_camera_wb=True).astype(float)
    grey, red = rgb[H // 2, W // 4], rgb[H // 2, 3 * W // 4]
    assert np.ptp(grey) <= 1
    np.testing.assert_allclose(red[1:] / red[0], 0.05, atol=0.01)


@pytest.mark.parametrize("dn", [
    np.zeros((3, H, W), np.int16), np.zeros((3, H, W), np.float32), np.zeros((3, H, W), np.int8),
    np.zeros((H, W, 3), np.uint8), np.zeros((4, H, W), np.uint8), np.zeros((H, W), np.uint8),
    np.zeros((3, 21, W), np.uint8), np.zeros((3, H, 10), np.uint8), [[[0]]],
])
def test_rejects_bad_frames_without_writing(tmp_path, dn):
    path = tmp_path / "bad.dng"
    with pytest.raises(CamsimError, match=re.escape(str(path))):
        write(path, dn)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("overrides", [
    dict(black_level_dn=-1), dict(black_level_dn=float("nan")), dict(black_level_dn=(1, 2)),
    dict(white_level=256), dict(white_level=15), dict(white_level=200.5),
    dict(color_matrix1=np.eye(2)), dict(color_matrix1=[[1, 0, 0], [0, 1, 0], [0, 0, np.inf]]),
    dict(as_shot_neutral=[1, 0, 1]), dict(as_shot_neutral="white"), dict(unique_camera_model="Kamera ü"),
    dict(unique_camera_model=""), dict(calibration_illuminant1=-1),
])
def test_rejects_bad_metadata(tmp_path, overrides):
    path = tmp_path / "bad.dng"
    with pytest.raises(CamsimError, match=re.escape(str(path))):
        write(path, random_dn(6), **overrides)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("keep", [0.5, 0.05, 100])
def test_truncated_file_is_a_user_error(tmp_path, keep):
    good = write(tmp_path / "good.dng", random_dn(7)).read_bytes()
    bad = tmp_path / "truncated.dng"
    bad.write_bytes(good[: int(len(good) * keep) if keep < 1 else keep])
    with pytest.raises(CamsimError, match=re.escape(str(bad))):
        read_dng(bad)


def test_a_file_cut_in_its_pixels_is_called_truncated_and_libraw_stays_quiet(tmp_path, capfd):
    good = write(tmp_path / "good.dng", random_dn(7)).read_bytes()
    bad = tmp_path / "truncated.dng"
    bad.write_bytes(good[:-10])  # the tags are whole, the last pixels missing
    with pytest.raises(CamsimError, match=re.escape(f"cannot read DNG {bad}: truncated: the file has "
                                                    f"{len(good) - 10} bytes")):
        read_dng(bad)
    assert capfd.readouterr() == ("", "")


def test_text_missing_and_non_dng_files_are_user_errors(tmp_path):
    text = tmp_path / "notes.dng"
    text.write_text("this is not a raw file\n")
    plain = tmp_path / "plain.tif"
    tifffile.imwrite(plain, np.zeros((H, W, 3), np.uint8))
    for path in (text, plain, tmp_path / "missing.dng"):
        with pytest.raises(CamsimError, match=re.escape(str(path))):
            read_dng(path)


def test_exception_mid_write_leaves_no_file(tmp_path, monkeypatch):
    final = tmp_path / "f.dng"
    write(final, random_dn(8))
    before = final.read_bytes()

    def half_write(path, data, **kwargs):
        with open(path, "wb") as fh:
            fh.write(b"II*\x00partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(dng_mod.tifffile, "imwrite", half_write)
    with pytest.raises(OutputError, match=f"cannot write {re.escape(str(final))}: No space left on device"):
        write(final, random_dn(9))
    assert final.read_bytes() == before  # old complete file untouched
    with pytest.raises(OutputError, match="No space left on device"):
        write(tmp_path / "new.dng", random_dn(9))
    assert [p.name for p in tmp_path.iterdir()] == ["f.dng"]


@pytest.mark.parametrize("black, white", [((5.0254, 6.0175, 5.6830), 255), ((0.0, 0.0, 0.0), 255),
                                          ((511.5, 511.5, 511.5), 16383), ((65533.9, 65534.2, 65534.4), 65535),
                                          (7.125, 4095)])
def test_the_darktable_sidecar_holds_the_mean_black_level_and_the_white_point(black, white):
    """darktable's ``rawprepare`` subtracts the mean of its four levels from every channel of an image without a
    CFA: the four integers' mean is the samples' mean level to 1/8 DN (a quarter step, rounded)."""
    import struct
    import xml.etree.ElementTree as ET

    from camsim.io.dng import darktable_xmp

    ns = {"rdf": "http://www.w3.org/1999/02/22-rdf-syntax-ns#", "darktable": "http://darktable.sf.net/"}
    root = ET.fromstring(darktable_xmp(black, white))
    items = root.findall(".//darktable:history/rdf:Seq/rdf:li", ns)
    assert len(items) == 1
    item = items[0].attrib
    d = "{http://darktable.sf.net/}"
    assert item[d + "operation"] == "rawprepare" and item[d + "modversion"] == "2" and item[d + "enabled"] == "1"
    crop, levels, white_point, flat_field = (lambda v: (v[:4], v[4:8], v[8], v[9]))(
        struct.unpack("<4i4HHxxi", bytes.fromhex(item[d + "params"])))
    assert crop == (0, 0, 0, 0) and flat_field == 0 and white_point == white
    assert abs(sum(levels) / 4 - float(np.mean(black))) <= 1 / 8 and max(levels) - min(levels) <= 1


# --- hostile headers and paths -------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["fifo", "device", "directory"])
def test_a_path_that_is_no_regular_file_is_refused_not_waited_on(tmp_path, kind):
    """tifffile and LibRaw open a FIFO by name and wait for a writer that never comes; /dev/zero never ends."""
    path = not_regular(tmp_path / "frame.dng", kind)
    with no_hang(f"read_dng of a {kind}"), pytest.raises(CamsimError) as exc:
        read_dng(path)
    assert f"cannot read DNG {path}: it is a" in str(exc.value) and "not a regular file" in str(exc.value)


@pytest.mark.parametrize("size", [*HUGE_SIZES, (10000, 10001)])
def test_a_huge_declared_size_is_refused_from_the_tags_and_libraw_stays_quiet(tmp_path, capfd, size):
    """ImageWidth × ImageLength of 10⁸ to 10¹⁰ pixels over a 48 × 64 frame's strips: over the pixel limit, or (10⁸
    pixels) more than the strips hold; refused on one line from the tags, before LibRaw allocates or reads."""
    good = write(tmp_path / "good.dng", random_dn(7)).read_bytes()
    bad = tmp_path / "huge.dng"
    bad.write_bytes(with_tiff_size(good, *size))
    capfd.readouterr()
    with pytest.raises(CamsimError) as exc:
        read_dng(bad)
    message = str(exc.value)
    assert "\n" not in message and str(bad) in message
    assert ("over camsim's limit" if size[0] * size[1] > 200_000_000 else "strip(s) hold") in message, message
    assert capfd.readouterr() == ("", "")


@pytest.mark.parametrize("size", [*HUGE_SIZES, (10000, 10001)])
def test_develop_refuses_a_huge_dng_header_on_one_line(tmp_path, capfd, size):
    from camsim.cli import main

    good = write(tmp_path / "good.dng", random_dn(7)).read_bytes()
    bad = tmp_path / "huge.dng"
    bad.write_bytes(with_tiff_size(good, *size))
    capfd.readouterr()
    assert main(["develop", str(bad), "--out", str(tmp_path / "out"), "-q"]) == 2
    out, err = capfd.readouterr()
    assert str(bad) in one_error_line(err) and out == ""
