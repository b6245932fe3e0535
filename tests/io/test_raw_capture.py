"""Reading real cameras' raw files (camsim.io.raw_capture): every RawCapture field read back from phone-style DNGs
written by an independent writer (tests/support/phone_dng.py, tifffile) and from DNGs camsim writes, crops that shift
the pattern, ActiveArea, orientation, and the one-line errors.

The expected values are computed here from what was written: the pattern of a crop is read off a colour map tiled
from the written cell (not by rolling the cell, as the reader does), the black level of each site likewise.
"""

import hashlib
import os
import struct
import time
import zlib

import numpy as np
import pytest
import rawpy
import tifffile
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from camsim.core.errors import CamsimError
from camsim.io.dng import read_dng, write_dng, write_dng_cfa
from camsim.io.raw_capture import (
    RawCapture,
    libraw_orientation,
    raw_header,
    read_raw_capture,
    unpacked_raw,
)
from camsim.sensor.cfa import CFA_PATTERNS
from tests.support.hostile_files import (
    COMPRESSION,
    HUGE_SIZES,
    no_hang,
    not_regular,
    one_error_line,
    with_tiff_size,
)
from tests.support.phone_dng import BLACK_LEVEL_DELTA_H, write_phone_dng
from tests.support.profiles import examples

H, W = 40, 56
CM1 = np.array([[0.6722, -0.1882, -0.0712], [-0.4131, 1.2493, 0.1813], [-0.0667, 0.2111, 0.6166]])
CM2 = np.array([[0.7013, -0.2127, -0.0513], [-0.3802, 1.1854, 0.2176], [-0.0441, 0.1503, 0.6541]])
NEUTRAL = np.array([0.4921, 1.0, 0.6125])
# black level of each site of the written 2 x 2 cell, all four different (a half to test exact fractions)
BLACK = np.array([[64.0, 65.5], [63.0, 66.0]])
# LibRaw's colour index per position of each pattern (color_desc b"RGBG", the blue rows' green is 3)
LIBRAW_INDEX = {"RGGB": [[0, 1], [3, 2]], "BGGR": [[2, 3], [1, 0]], "GRBG": [[1, 0], [2, 3]],
                "GBRG": [[3, 2], [0, 1]]}


def mosaic(seed, h=H, w=W, top=1023):
    m = np.random.default_rng(seed).integers(0, top + 1, size=(h, w), dtype=np.uint16)
    m[0, 0], m[-1, -1] = 0, top
    return m


def tiled(cell, h, w):
    """The 2 x 2 ``cell`` (array or 4-letter string) repeated over h x w pixels from (0, 0)."""
    cell = np.array(list(cell)).reshape(2, 2) if isinstance(cell, str) else np.asarray(cell)
    return np.tile(cell, (h // 2 + 1, w // 2 + 1))[:h, :w]


def phone(path, pattern="GRBG", m=None, **kw):
    args = dict(pattern=pattern, black_per_site=BLACK, white=1023, iso=640, exposure_s=1 / 120, make="Google",
                model="Pixel 7", color_matrix1=CM1, color_matrix2=CM2, illuminants=(17, 21),
                as_shot_neutral=NEUTRAL)
    args.update(kw)
    return write_phone_dng(str(path), mosaic(1) if m is None else m, **args)


def one_line_error(exc_info, path):
    message = str(exc_info.value)
    assert "\n" not in message and str(path) in message, message
    return message


# ------------------------------------------------------------------------------------------ the test writer

@pytest.mark.parametrize("pattern", CFA_PATTERNS)
def test_phone_writer_decodes_exactly_in_libraw(tmp_path, pattern):
    """The independent writer's files are what a camera's are to LibRaw: the mosaic exactly, the pattern, the four
    black levels by colour (LibRaw truncates 65.5 to 65), the white level, ISO and exposure."""
    m = mosaic(2)
    path = phone(tmp_path / "p.dng", pattern, m)
    with rawpy.imread(path) as raw:
        np.testing.assert_array_equal(raw.raw_image_visible, m)
        assert raw.raw_pattern.tolist() == LIBRAW_INDEX[pattern]
        index = np.array(LIBRAW_INDEX[pattern])
        for i in range(2):
            for j in range(2):
                assert raw.black_level_per_channel[index[i, j]] == np.floor(BLACK[i, j])
        assert raw.white_level == 1023
        assert raw.other.iso_speed == 640 and raw.other.shutter_speed == pytest.approx(1 / 120, rel=1e-6)
    with tifffile.TiffFile(path) as tif:  # a thumbnail in IFD0, the raw in its SubIFD, an EXIF IFD
        first = tif.pages.first
        assert first.tags[254].value == 1 and first.subifds and first.pages[0].tags[254].value == 0
        assert first.tags[34665].value["ISOSpeedRatings"] == 640


# ------------------------------------------------------------------------------------------ every field

def check_fields(cap, m, pattern, *, iso=640, exposure_s=1 / 120, orientation=1, make="Google", model="Pixel 7",
                 ucm="Google Pixel 7", cm2=CM2, ill2=21, black=BLACK, white=1023.0, ill1=17, cm1=CM1,
                 neutral=NEUTRAL):
    assert isinstance(cap, RawCapture)
    assert cap.mosaic.dtype == np.uint16 and cap.mosaic.shape == m.shape
    np.testing.assert_array_equal(cap.mosaic, m)
    assert cap.cfa == pattern
    assert cap.black_dn.dtype == np.float64 and cap.black_dn.shape == (2, 2)
    np.testing.assert_array_equal(cap.black_dn, black)
    assert cap.white_dn == white
    assert cap.iso == iso
    assert cap.exposure_s == pytest.approx(exposure_s, rel=1e-12)
    assert (cap.make, cap.model, cap.unique_camera_model) == (make, model, ucm)
    np.testing.assert_allclose(cap.color_matrix1, cm1, rtol=0, atol=1e-9)
    if cm2 is None:
        assert cap.color_matrix2 is None and cap.calibration_illuminant2 is None
    else:
        np.testing.assert_allclose(cap.color_matrix2, cm2, rtol=0, atol=1e-9)
        assert cap.calibration_illuminant2 == ill2
    assert cap.calibration_illuminant1 == ill1
    np.testing.assert_allclose(cap.as_shot_neutral, neutral, rtol=1e-6)
    assert cap.orientation == orientation
    assert cap.full_size == (m.shape[1], m.shape[0]) and cap.crop is None


@pytest.mark.parametrize("pattern", CFA_PATTERNS)
@pytest.mark.parametrize("layout", [dict(), dict(thumbnail=False, exif_ifd=False), dict(big_endian=True),
                                    dict(tile=(16, 32))], ids=["subifd+exif", "ifd0", "big-endian", "tiled"])
def test_phone_dng_fields(tmp_path, pattern, layout):
    m = mosaic(sum(map(ord, pattern)))
    path = phone(tmp_path / "p.dng", pattern, m, **layout)
    cap = read_raw_capture(path)
    check_fields(cap, m, pattern)
    assert cap.path == path
    header = raw_header(path)
    assert header.size == cap.full_size and header.cfa == cap.cfa and header.path == path
    assert (header.iso, header.exposure_s, header.make, header.model, header.unique_camera_model) == (
        cap.iso, cap.exposure_s, cap.make, cap.model, cap.unique_camera_model)


def test_iso_in_ifd0_which_libraw_does_not_read(tmp_path):
    """Android writes ISOSpeedRatings in IFD0, where LibRaw does not look (it says 0): the tag is read."""
    path = phone(tmp_path / "p.dng", exif_ifd=False, iso=3200)
    with rawpy.imread(path) as raw:
        assert raw.other.iso_speed == 0
    assert read_raw_capture(path).iso == 3200 and raw_header(path).iso == 3200


def test_missing_metadata_is_none(tmp_path):
    path = phone(tmp_path / "p.dng", iso=None, exposure_s=None, color_matrix2=None, as_shot_neutral=None)
    cap = read_raw_capture(path)
    assert cap.iso is None and cap.exposure_s is None and cap.color_matrix2 is None
    assert cap.calibration_illuminant2 is None


def test_site_black_map(tmp_path):
    path = phone(tmp_path / "p.dng", "BGGR")
    cap = read_raw_capture(path, crop=(1, 2, 8, 6))
    site = cap.site_black_dn()
    assert site.shape == (6, 8) and site.dtype == np.float32
    np.testing.assert_array_equal(site, tiled(BLACK, 8, 10)[2:8, 1:9])


# ------------------------------------------------------------------------------------------ crops

@pytest.mark.parametrize("pattern", CFA_PATTERNS)
@pytest.mark.parametrize("x, y", [(0, 0), (1, 0), (0, 1), (1, 1), (6, 3), (5, 10)])
def test_crop_shifts_the_pattern(tmp_path, pattern, x, y):
    m = mosaic(7)
    path = phone(tmp_path / "p.dng", pattern, m)
    w, h = 20, 14
    cap = read_raw_capture(path, crop=(x, y, w, h))
    np.testing.assert_array_equal(cap.mosaic, m[y:y + h, x:x + w])
    colours = tiled(pattern, H, W)
    assert cap.cfa == "".join(colours[y:y + 2, x:x + 2].ravel())
    np.testing.assert_array_equal(cap.black_dn, tiled(BLACK, H, W)[y:y + 2, x:x + 2])
    assert cap.crop == (x, y, w, h) and cap.full_size == (W, H)


@pytest.fixture(scope="module")
def one_phone_file(tmp_path_factory):
    m = mosaic(11)
    return phone(tmp_path_factory.mktemp("hyp") / "p.dng", "GBRG", m), m


@settings(max_examples=examples(60), deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_random_crops(one_phone_file, data):
    """Any crop inside the frame gives the mosaic's slice, the pattern and black levels of its top-left cell."""
    path, m = one_phone_file
    w = 2 * data.draw(st.integers(1, W // 2))
    h = 2 * data.draw(st.integers(1, H // 2))
    x = data.draw(st.integers(0, W - w))
    y = data.draw(st.integers(0, H - h))
    cap = read_raw_capture(path, crop=(x, y, w, h))
    np.testing.assert_array_equal(cap.mosaic, m[y:y + h, x:x + w])
    assert cap.cfa == "".join(tiled("GBRG", H, W)[y:y + 2, x:x + 2].ravel())
    np.testing.assert_array_equal(cap.black_dn, tiled(BLACK, H, W)[y:y + 2, x:x + 2])
    np.testing.assert_array_equal(cap.site_black_dn(), tiled(BLACK, H, W)[y:y + h, x:x + w])


# ------------------------------------------------------------------------------------------ ActiveArea, orientation

def test_even_active_area(tmp_path):
    m = mosaic(3)
    path = phone(tmp_path / "p.dng", "RGGB", m, active_area=(2, 4, 38, 52))
    cap = read_raw_capture(path)
    check_fields(cap, m[2:38, 4:52], "RGGB")
    assert raw_header(path).size == (48, 36)


def test_odd_active_area_follows_the_dng_specification(tmp_path):
    """ActiveArea from (1, 3): LibRaw's visible image starts at (2, 4) (even) and is 51 x 37. The DNG
    specification anchors the CFA and black patterns at the ActiveArea's corner, so the visible image's first
    cell is the written cell seen from (1, 1): GRBG -> GBRG, and its black levels likewise."""
    m = mosaic(4)
    path = phone(tmp_path / "p.dng", "GRBG", m, active_area=(1, 3, 39, 55))
    cap = read_raw_capture(path)
    assert cap.full_size == (51, 37) and cap.crop == (0, 0, 50, 36)
    np.testing.assert_array_equal(cap.mosaic, m[2:38, 4:54])
    active_colours = tiled("GRBG", 38, 52)  # anchored at the ActiveArea's corner (1, 3)
    assert cap.cfa == "".join(active_colours[1:3, 1:3].ravel()) == "GBRG"
    np.testing.assert_array_equal(cap.black_dn, tiled(BLACK, 38, 52)[1:3, 1:3])
    with rawpy.imread(path) as raw:
        assert "".join("RGBG"[i] for i in raw.raw_pattern.ravel()) == "GBRG"  # LibRaw agrees on the pattern
    assert raw_header(path).cfa == "GBRG" and raw_header(path).size == (51, 37)


@pytest.mark.parametrize("orientation", range(1, 9))
def test_orientation(tmp_path, orientation):
    """The Orientation tag read back; and LibRaw's flip of the same file maps back to it (the table checked
    against LibRaw, for the formats whose orientation only LibRaw knows)."""
    path = phone(tmp_path / "p.dng", orientation=orientation)
    assert read_raw_capture(path).orientation == orientation
    with rawpy.imread(path) as raw:
        assert libraw_orientation(raw.sizes.flip) == orientation


# ------------------------------------------------------------------------------------------ camsim's own DNGs

@pytest.mark.parametrize("pattern", CFA_PATTERNS)
@pytest.mark.parametrize("dtype, white", [(np.uint8, 255), (np.uint16, 4095)])
def test_camsim_dng_fields(tmp_path, pattern, dtype, white):
    m = mosaic(5, top=white).astype(dtype)
    black_rgb = (16.0, 12.25, 20.0)
    path = tmp_path / "c.dng"
    write_dng_cfa(path, m, pattern=pattern, black_level_dn=black_rgb, white_level=white,
                  unique_camera_model="camsim test camera", color_matrix1=CM1, as_shot_neutral=NEUTRAL,
                  calibration_illuminant1=17, make="camsim", model="test camera", iso=102400, exposure_s=0.25,
                  color_matrix2=CM2, calibration_illuminant2=21, orientation=6)
    cap = read_raw_capture(path)
    black = np.array([black_rgb["RGB".index(c)] for c in pattern]).reshape(2, 2)
    check_fields(cap, m.astype(np.uint16), pattern, iso=102400, exposure_s=0.25, orientation=6, make="camsim",
                 model="test camera", ucm="camsim test camera", black=black, white=float(white))
    _, info = read_dng(path)
    np.testing.assert_allclose(info["color_matrix2"], CM2, atol=1e-9)
    assert info["calibration_illuminant2"] == 21 and info["orientation"] == 6


def test_camsim_dng_defaults_have_no_new_tags(tmp_path):
    """Without the new arguments a file has exactly the tags it had (Orientation 1, no ColorMatrix2 or
    CalibrationIlluminant2); with them, those tags and nothing else change."""
    m = mosaic(6, top=255).astype(np.uint8)
    kw = dict(pattern="RGGB", black_level_dn=16.0, white_level=255, unique_camera_model="cam", color_matrix1=CM1,
              as_shot_neutral=NEUTRAL, iso=100, exposure_s=0.01)
    write_dng_cfa(tmp_path / "a.dng", m, **kw)
    write_dng_cfa(tmp_path / "b.dng", m, **kw, color_matrix2=None, calibration_illuminant2=None, orientation=1)
    write_dng_cfa(tmp_path / "c.dng", m, **kw, color_matrix2=CM2, calibration_illuminant2=17, orientation=3)
    a, b = ((tmp_path / n).read_bytes() for n in ("a.dng", "b.dng"))
    assert hashlib.sha256(a).digest() == hashlib.sha256(b).digest()

    def tags(name):
        with tifffile.TiffFile(tmp_path / name) as tif:
            return {t.code: t.value for t in tif.pages.first.tags if t.code not in (273, 279, 34665)}

    ta, tc = tags("a.dng"), tags("c.dng")
    assert ta[274] == 1 and 50722 not in ta and 50779 not in ta
    assert set(tc) - set(ta) == {50722, 50779} and tc[274] == 3 and tc[50779] == 17
    assert {k: v for k, v in tc.items() if k in ta and k != 274} == {k: v for k, v in ta.items() if k != 274}
    _, info = read_dng(tmp_path / "a.dng")
    assert info["color_matrix2"] is None and info["calibration_illuminant2"] is None and info["orientation"] == 1


@pytest.mark.parametrize("bad", [dict(color_matrix2=CM2), dict(calibration_illuminant2=21),
                                 dict(color_matrix2=np.eye(2), calibration_illuminant2=21),
                                 dict(orientation=0), dict(orientation=9), dict(orientation=True)])
def test_camsim_dng_new_args_refused(tmp_path, bad):
    with pytest.raises(CamsimError) as exc:
        write_dng_cfa(tmp_path / "x.dng", mosaic(1, top=255).astype(np.uint8), pattern="RGGB", black_level_dn=16,
                      white_level=255, unique_camera_model="cam", color_matrix1=CM1, as_shot_neutral=NEUTRAL, **bad)
    one_line_error(exc, tmp_path / "x.dng")
    assert not (tmp_path / "x.dng").exists()


# ------------------------------------------------------------------------------------------ errors

def png_bytes():
    raw = b"".join(b"\x00" + bytes([128] * 3 * 8) for _ in range(8))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 8, 8, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def patch_raw_size(path, width, height):
    """Make the raw IFD's header declare another size (its pixel data unchanged)."""
    with tifffile.TiffFile(path) as tif:
        page = tif.pages.first.pages[0]
        offsets = [page.tags[256].valueoffset, page.tags[257].valueoffset]
        kinds = [int(page.tags[256].dtype), int(page.tags[257].dtype)]
    with open(path, "r+b") as fh:
        for offset, kind, value in zip(offsets, kinds, (width, height)):
            fh.seek(offset)
            fh.write(struct.pack("<I" if kind == 4 else "<H", value))


@pytest.mark.parametrize("case", ["missing", "directory", "text", "png", "truncated", "truncated header",
                                  "three-chip", "mono", "not bayer", "x-trans", "huge", "black deltas", "empty"])
def test_errors(tmp_path, case):
    path = tmp_path / "bad.dng"
    expect = {"missing": "no such file", "directory": "it is a directory, not a regular file",
              "text": "not a raw file LibRaw reads",
              "png": "not a raw file LibRaw reads", "truncated": "truncated", "truncated header": "cannot read",
              "three-chip": "no 2x2 colour filter array", "huge": "over camsim's limit",
              "black deltas": "BlackLevelDeltaH", "empty": "the file is empty",
              "mono": "no 2x2 colour filter array: a monochrome image", "not bayer": "unsupported CFA layout",
              "x-trans": "unsupported CFA layout (CFARepeatPatternDim (6, 6)"}[case]
    if case == "directory":
        path.mkdir()
    elif case == "text":
        path.write_text("not a raw file\n" * 20)
    elif case == "empty":
        path.write_bytes(b"")
    elif case == "png":
        path.write_bytes(png_bytes())
    elif case in ("truncated", "truncated header"):
        good = open(phone(tmp_path / "good.dng"), "rb").read()
        path.write_bytes(good[: len(good) - 500] if case == "truncated" else good[:60])
    elif case == "three-chip":
        write_dng(path, np.zeros((3, 24, 24), np.uint8), black_level_dn=16, white_level=255,
                  unique_camera_model="cam", color_matrix1=CM1, as_shot_neutral=NEUTRAL)
    elif case == "mono":  # a LinearRaw DNG of one sample per pixel (tifffile writes it as BlackIsZero: patched)
        tifffile.imwrite(path, np.zeros((24, 24), np.uint16), photometric="minisblack", metadata=None,
                         extratags=[(50706, "B", 4, (1, 4, 0, 0), True)])
        with tifffile.TiffFile(path) as tif:
            at = tif.pages.first.tags[262].valueoffset
        with open(path, "r+b") as fh:
            fh.seek(at)
            fh.write(struct.pack("<H", 34892))
    elif case == "not bayer":
        phone(path, pattern="RRGB")
    elif case == "x-trans":  # Fujifilm's 6 x 6 cell
        phone(path, pattern="GGRGGBGGBGGRBRGRBGGGBGGRGGRGGBRBGBRG", m=mosaic(1, 36, 36))
    elif case == "huge":
        phone(path)
        patch_raw_size(path, 20000, 20000)
    elif case == "black deltas":
        phone(path, extra_raw_tags=[(BLACK_LEVEL_DELTA_H, 10, W, (0, 1) * (W - 1) + (1, 2), True)])
    for read in (read_raw_capture, raw_header):
        with pytest.raises(CamsimError) as exc:
            read(path)
        assert expect in one_line_error(exc, path)


def test_unreadable_file(tmp_path):
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        pytest.skip("root reads a file of mode 000")
    path = phone(tmp_path / "p.dng")
    os.chmod(path, 0)
    try:
        with pytest.raises(CamsimError) as exc:
            read_raw_capture(path)
        one_line_error(exc, path)
    finally:
        os.chmod(path, 0o644)


def test_zero_black_deltas_are_accepted(tmp_path):
    path = phone(tmp_path / "p.dng", extra_raw_tags=[(BLACK_LEVEL_DELTA_H, 10, W, (0, 1) * W, True)])
    np.testing.assert_array_equal(read_raw_capture(path).black_dn, BLACK)


@pytest.mark.parametrize("crop, expect", [
    ((0, 0, 58, 40), "off the frame of 56x40"), ((2, 2, 56, 4), "off the frame"), ((0, 38, 4, 4), "off the frame"),
    ((-1, 0, 4, 4), "off the frame"), ((0, 0, 3, 4), "even width and height"), ((0, 0, 4, 5), "even"),
    ((0, 0, 0, 4), "above 0"), ((0, 0, 4), "4 integers"), ((0, 0, 4.0, 4), "4 integers"),
    ((True, 0, 4, 4), "4 integers"), ("0,0,4,4", "4 integers"), (7, "4 integers")])
def test_bad_crops(tmp_path, crop, expect):
    path = phone(tmp_path / "p.dng")
    with pytest.raises(CamsimError) as exc:
        read_raw_capture(path, crop=crop)
    message = one_line_error(exc, path)
    assert expect in message
    if "off the frame" in expect:  # names the crop and the frame's size
        assert f"crop {tuple(crop)}" in message and "56x40" in message


def test_numpy_integer_crop(tmp_path):
    m = mosaic(9)
    path = phone(tmp_path / "p.dng", m=m)
    cap = read_raw_capture(path, crop=tuple(np.array([3, 1, 6, 4])))
    np.testing.assert_array_equal(cap.mosaic, m[1:5, 3:9])


def test_colour_matrix_from_libraw_where_the_dng_has_none(tmp_path):
    """A DNG without ColorMatrix1 from a camera LibRaw knows gets LibRaw's matrix: Adobe's D65 matrix of the Canon
    EOS 5D Mark IV as dcraw's table lists it (6446, -366, -864, -4436, 12204, 2513, -952, 2496, 6348, / 10000),
    CalibrationIlluminant 21; no AsShotNeutral and no LibRaw white balance: None."""
    path = phone(tmp_path / "p.dng", make="Canon", model="EOS 5D Mark IV", color_matrix1=None, color_matrix2=None,
                 as_shot_neutral=None)
    cap = read_raw_capture(path)
    adobe = np.array([6446, -366, -864, -4436, 12204, 2513, -952, 2496, 6348]).reshape(3, 3) / 10000
    np.testing.assert_allclose(cap.color_matrix1, adobe, atol=1e-7)
    assert cap.calibration_illuminant1 == 21 and cap.color_matrix2 is None and cap.as_shot_neutral is None
    assert (cap.make, cap.model, cap.unique_camera_model) == ("Canon", "EOS 5D Mark IV", "Canon EOS 5D Mark IV")


def test_threads_read_as_one(tmp_path):
    """Reads from a thread pool (LibRaw decodes without the GIL) give what serial reads give; errors too."""
    from concurrent.futures import ThreadPoolExecutor

    m = mosaic(12)
    good = phone(tmp_path / "p.dng", "BGGR", m)
    bad = tmp_path / "bad.dng"
    bad.write_text("not a raw\n")
    crops = [(x, y, 10, 8) for x in range(0, 8) for y in range(0, 4)]

    def read(crop):
        cap = read_raw_capture(good, crop=crop)
        with pytest.raises(CamsimError):
            read_raw_capture(bad)
        return cap.mosaic, cap.cfa

    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(read, crops))
    for (x, y, w, h), (got, cfa) in zip(crops, results):
        np.testing.assert_array_equal(got, m[y:y + h, x:x + w])
        assert cfa == "".join(tiled("BGGR", H, W)[y:y + 2, x:x + 2].ravel())


def test_size_checked_from_libraws_header_before_decoding(tmp_path, monkeypatch):
    """For a file that is not a DNG (here a DNG whose tags are hidden from the reader), LibRaw's header size is
    checked against the pixel limit before anything is unpacked."""
    import camsim.core.pixel_limit as pixel_limit
    import camsim.io.raw_capture as raw_capture

    path = phone(tmp_path / "p.dng")
    unpacked = []
    real_unpack = raw_capture._unpack
    monkeypatch.setattr(raw_capture, "_unpack", lambda *a: (unpacked.append(a), real_unpack(*a)))
    monkeypatch.setattr(raw_capture, "_read_tiff", lambda name: (None, None))
    assert read_raw_capture(path).full_size == (W, H) and len(unpacked) == 1  # the route works as a non-DNG
    unpacked.clear()
    monkeypatch.setattr(pixel_limit, "MAX_PIXELS", W * H - 1)
    for read in (read_raw_capture, raw_header):
        with pytest.raises(CamsimError) as exc:
            read(path)
        assert f"{W} × {H} pixels, over camsim's limit" in one_line_error(exc, path)
    assert unpacked == []


@pytest.mark.parametrize("pattern", CFA_PATTERNS)
def test_libraw_route_fields(tmp_path, monkeypatch, pattern):
    """The route of raws that are not DNGs (every value from LibRaw), taken by a phone DNG whose tags are hidden
    from the reader: the mosaic, the pattern, the black levels truncated as LibRaw does (65.5 -> 65), the white
    level, ISO and exposure from the EXIF IFD as LibRaw reads it, the as-shot neutral back from LibRaw's
    multipliers (G / multiplier), the orientation from LibRaw's flip, no camera name."""
    import camsim.io.raw_capture as raw_capture

    m = mosaic(13)
    path = phone(tmp_path / "p.dng", pattern, m, orientation=8)
    monkeypatch.setattr(raw_capture, "_read_tiff", lambda name: (None, None))
    cap = read_raw_capture(path, crop=(1, 1, 12, 10))
    np.testing.assert_array_equal(cap.mosaic, m[1:11, 1:13])
    assert cap.cfa == "".join(tiled(pattern, H, W)[1:3, 1:3].ravel())
    np.testing.assert_array_equal(cap.black_dn, np.floor(tiled(BLACK, H, W)[1:3, 1:3]))
    assert cap.white_dn == 1023 and cap.iso == 640 and cap.exposure_s == pytest.approx(1 / 120, rel=1e-6)
    np.testing.assert_allclose(cap.as_shot_neutral, NEUTRAL, rtol=1e-6)
    assert cap.orientation == 8
    assert (cap.make, cap.model, cap.unique_camera_model) == (None, None, None)
    header = raw_header(path)
    assert header.cfa == pattern and header.size == (W, H) and header.iso == 640


def test_libraw_route_refuses_x_trans(tmp_path, monkeypatch):
    """An X-Trans mosaic as LibRaw decodes it (the non-DNG route): refused on one line by its 6 x 6 pattern."""
    import camsim.io.raw_capture as raw_capture

    path = phone(tmp_path / "x.dng", pattern="GGRGGBGGBGGRBRGRBGGGBGGRGGRGGBRBGBRG", m=mosaic(1, 36, 36))
    monkeypatch.setattr(raw_capture, "_read_tiff", lambda name: (None, None))
    for read in (read_raw_capture, raw_header):
        with pytest.raises(CamsimError) as exc:
            read(path)
        assert "(pattern (6, 6)) is not a 2x2 Bayer mosaic" in one_line_error(exc, path)


# ------------------------------------------------------------------------------------------ hostile headers, paths
READS = {"read_raw_capture": read_raw_capture, "raw_header": raw_header,
         "unpacked_raw": lambda path: unpacked_raw(path).__enter__()}


@pytest.mark.parametrize("read", READS)
@pytest.mark.parametrize("kind", ["fifo", "device", "directory"])
def test_a_path_that_is_no_regular_file_is_refused_not_waited_on(tmp_path, read, kind):
    """tifffile and LibRaw open a FIFO by name and wait for a writer that never comes; /dev/zero never ends."""
    path = not_regular(tmp_path / "raw.dng", kind)
    with no_hang(f"{read} of a {kind}"), pytest.raises(CamsimError) as exc:
        READS[read](path)
    assert f"cannot read raw file {path}: it is a" in one_line_error(exc, path)


@pytest.mark.parametrize("read", READS)
@pytest.mark.parametrize("size", [*HUGE_SIZES, (10000, 10001)])
def test_a_huge_declared_size_is_refused_from_the_tags_and_libraw_stays_quiet(tmp_path, capfd, read, size):
    """A phone DNG's raw IFD (and thumbnail) declaring 10⁸ to 10¹⁰ pixels over 56 × 40 pixels of data: over the
    pixel limit, or (10⁸ pixels, under it) more than the uncompressed strip holds, which LibRaw would read past
    to the file's end and print "Unexpected end of file" about. One line, from the tags, LibRaw silent."""
    path = tmp_path / "huge.dng"
    path.write_bytes(with_tiff_size(open(phone(tmp_path / "good.dng"), "rb").read(), *size))
    capfd.readouterr()
    start = time.process_time()
    with pytest.raises(CamsimError) as exc:
        READS[read](path)
    message = one_line_error(exc, path)
    assert (f"{size[0]} × {size[1]} pixels, over camsim's limit" if size[0] * size[1] > 200_000_000 else
            f"declares a {size[0]}x{size[1]} image of 1 sample(s) of 16 bits") in message, message
    assert time.process_time() - start < 5
    assert capfd.readouterr() == ("", "")


@pytest.mark.parametrize("read", READS)
def test_libraws_complaint_about_compressed_data_goes_into_the_one_line(tmp_path, capfd, read):
    """A DNG whose raw IFD says Deflate (8) over uncompressed data: only LibRaw can tell, by decoding; what it
    prints on stderr is captured into camsim's one line."""
    path = tmp_path / "deflate.dng"
    good = open(phone(tmp_path / "good.dng", thumbnail=False), "rb").read()
    path.write_bytes(with_tiff_size(good, W, H, {COMPRESSION: 8}))
    capfd.readouterr()
    if read == "raw_header":  # the header alone (no pixels decoded) does not see it
        READS[read](path)
    else:
        with pytest.raises(CamsimError) as exc:
            READS[read](path)
        assert "LibRaw cannot decode its pixels" in one_line_error(exc, path)
    assert capfd.readouterr() == ("", "")


def test_unpacked_raw_reads_stacks_and_mosaics(tmp_path):
    """The route of ``camsim calibrate``: any layout LibRaw decodes, a three-chip LinearRaw DNG included."""
    m = mosaic(3)
    with unpacked_raw(phone(tmp_path / "p.dng", m=m)) as raw:
        np.testing.assert_array_equal(raw.raw_image_visible, m)
    stack = np.random.default_rng(2).integers(0, 256, (3, 24, 24)).astype(np.uint8)
    write_dng(tmp_path / "s.dng", stack, black_level_dn=16, white_level=255, unique_camera_model="cam",
              color_matrix1=CM1, as_shot_neutral=NEUTRAL)
    with unpacked_raw(tmp_path / "s.dng") as raw:
        np.testing.assert_array_equal(raw.raw_image_visible[..., :3], stack.transpose(1, 2, 0))


@pytest.fixture(scope="module")
def camera_dng(tmp_path_factory):
    """A Bayer DNG of a camera preset camsim knows (Sony ILCE-7SM2), 48 × 32: a [raw] scene's file."""
    from camsim.cli import main

    out = tmp_path_factory.mktemp("camera") / "frames"
    assert main(["render", "macbeth_26", "--size", "48x32", "--illuminant", "D65", "--intensity", "1", "--preset",
                 "sony-a7s2", "--iso", "100", "-q", "--workers", "1", "--out", str(out)]) == 0
    (dng,) = out.glob("*.dng")
    return dng.read_bytes()


def raw_scene(folder, raw: bytes | None):
    """A [raw] scene file in ``folder`` over ``src.dng`` holding ``raw`` (None: leave what is there)."""
    from tests.support.fuzz import RAW_SCENE, to_toml

    folder.mkdir(exist_ok=True)
    if raw is not None:
        (folder / "src.dng").write_bytes(raw)
    (folder / "scene.toml").write_text(to_toml(RAW_SCENE), encoding="utf-8")
    return folder / "scene.toml"


@pytest.mark.parametrize("size", [*HUGE_SIZES, (10000, 10001)])
def test_render_of_a_raw_scene_with_a_huge_header_is_one_line(tmp_path, capfd, camera_dng, size):
    from camsim.cli import main

    scene = raw_scene(tmp_path / "scene", with_tiff_size(camera_dng, *size))
    capfd.readouterr()
    assert main(["render", str(scene), "--out", str(tmp_path / "out"), "-q"]) == 2
    out, err = capfd.readouterr()
    line = one_error_line(err)
    assert "src.dng" in line and ("over camsim's limit" in line or "uncompressed pixel data holds" in line), line
    assert not (tmp_path / "out").exists()


def test_render_of_a_raw_scene_whose_raw_is_a_fifo_is_one_line(tmp_path):
    """End to end, in a process of its own (a reader blocked in C on the FIFO would not notice an alarm): refused
    at once, on one line, nothing written."""
    import sys

    from tests.support import clock

    scene = raw_scene(tmp_path / "scene", None)
    not_regular(tmp_path / "scene" / "src.dng", "fifo")
    done = clock.run([sys.executable, "-m", "camsim", "render", str(scene), "--out", str(tmp_path / "out"), "-q"],
                     cpu_s=60, capture_output=True, text=True)
    assert done.returncode == 2 and "it is a FIFO (named pipe)" in one_error_line(done.stderr), done.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("area", [(0, 0, 100000, 1000), (0, 0, 10, 100000), (8, 8, 4, 4), (-1, 0, 8, 8)])
def test_an_active_area_outside_the_image_is_refused_from_the_header(tmp_path, capfd, area):
    """LibRaw crops by the ActiveArea and reads past the pixel data (printing "Unexpected end of file"); a
    rectangle that is not inside the raw image is refused from the header, on one line, by both readers."""
    path = phone(tmp_path / "area.dng", active_area=(0, 0, 8, 8), thumbnail=False)  # read_dng reads IFD0
    data = bytearray(open(path, "rb").read())
    good = struct.pack("<4I", 0, 0, 8, 8)
    at = data.find(good)
    assert at > 0
    data[at:at + 16] = struct.pack("<4i", *area)
    (tmp_path / "bad.dng").write_bytes(bytes(data))
    capfd.readouterr()
    for read in (read_raw_capture, read_dng):
        with pytest.raises(CamsimError, match=r"its ActiveArea .* is not inside its \d+x\d+ image") as exc:
            read(tmp_path / "bad.dng")
        assert "\n" not in str(exc.value)
    assert capfd.readouterr() == ("", "")
