"""Bayer (CFA) DNG: exact mosaic through LibRaw, pattern numbering, per-colour black levels, development, errors."""

import errno
import itertools
import math
import re

import numpy as np
import pytest
import rawpy
import tifffile

from camsim.core.errors import CamsimError, OutputError
from camsim.io import dng as dng_mod
from camsim.io.dng import CFA_PATTERNS, read_dng, write_dng, write_dng_cfa

H, W = 48, 64
# XYZ -> linear sRGB (D65); a camera whose XYZ -> camera matrix is diag(GAINS) @ this sees D65 white as GAINS.
XYZ_TO_SRGB = np.array([[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]])
GAINS = np.array([0.5, 1.0, 0.7])
CODE = {"R": 0, "G": 1, "B": 2}

# LibRaw's colour index per 2x2 position (color_desc b"RGBG": the green in the blue rows is colour 3), measured.
LIBRAW_PATTERN = {
    "RGGB": [[0, 1], [3, 2]],
    "BGGR": [[2, 3], [1, 0]],
    "GRBG": [[1, 0], [2, 3]],
    "GBRG": [[3, 2], [0, 1]],
}


def colour_map(pattern, h=H, w=W):
    """(h, w) array of the colour (0 = R, 1 = G, 2 = B) of each pixel."""
    cell = np.array([CODE[c] for c in pattern]).reshape(2, 2)
    return np.tile(cell, (h // 2, w // 2))


def random_mosaic(seed, h=H, w=W, top=255, dtype=np.uint8):
    m = np.random.default_rng(seed).integers(0, top + 1, size=(h, w), dtype=dtype)
    m[0, 0], m[-1, -1], m[0, 1] = 0, top, top
    return m


def write(path, mosaic, pattern="RGGB", **overrides):
    kwargs = dict(pattern=pattern, black_level_dn=16.0, white_level=255, unique_camera_model="camsim test camera",
                  color_matrix1=np.diag(GAINS) @ XYZ_TO_SRGB, as_shot_neutral=GAINS)
    kwargs.update(overrides)
    write_dng_cfa(path, mosaic, **kwargs)
    return path


def test_patterns_are_every_bayer_cell_once():
    """The patterns offered (and tested below, one by one) are all the 2 × 2 Bayer cells: R, G, G, B read row by
    row with the two greens on a diagonal, enumerated here independently, each exactly once."""
    cells = {"".join(p) for p in itertools.permutations("RGGB") if p[0] == p[3] == "G" or p[1] == p[2] == "G"}
    assert len(cells) == 4
    assert len(CFA_PATTERNS) == len(set(CFA_PATTERNS)) == 4 and set(CFA_PATTERNS) == cells
    assert CFA_PATTERNS == ("RGGB", "BGGR", "GRBG", "GBRG")  # in the order the README and --help list them


@pytest.mark.parametrize("pattern", CFA_PATTERNS)
@pytest.mark.parametrize(("h", "w"), [(H, W), (22, 22), (30, 52)])
def test_rawpy_returns_exact_mosaic_and_pattern(tmp_path, pattern, h, w):
    mosaic = random_mosaic(sum(map(ord, pattern)) + h, h, w)
    path = write(tmp_path / "f.dng", mosaic, pattern)
    with rawpy.imread(str(path)) as raw:
        assert raw.raw_type == rawpy.RawType.Flat and raw.num_colors == 3
        assert raw.raw_image.shape == (h, w)
        np.testing.assert_array_equal(raw.raw_image, mosaic)
        np.testing.assert_array_equal(raw.raw_image_visible, mosaic)
        assert raw.color_desc == b"RGBG"
        assert raw.raw_pattern.tolist() == LIBRAW_PATTERN[pattern]
        desc = raw.color_desc.decode()
        assert "".join(desc[i] for i in raw.raw_pattern.ravel()) == pattern
        # raw_colors: LibRaw's colour index of every pixel, the 2x2 cell tiled; 1 -> G, 3 -> G as well
        colours = raw.raw_colors
        np.testing.assert_array_equal(colours, np.tile(raw.raw_pattern, (h // 2, w // 2)))
        np.testing.assert_array_equal(np.where(colours == 3, 1, colours), colour_map(pattern, h, w))
        # the green LibRaw numbers 3 shares its row with blue, green 1 shares its row with red
        for row in raw.raw_pattern:
            assert set(row) in ({0, 1}, {2, 3})
    back, info = read_dng(path)
    assert back.dtype == np.uint8 and back.shape == (1, h, w)
    np.testing.assert_array_equal(back[0], mosaic)
    assert info["cfa_pattern"] == pattern
    assert info["unique_camera_model"] == "camsim test camera"
    assert info["make"] == "camsim" and info["model"] == "camsim test camera"


def test_three_chip_files_have_no_cfa_pattern(tmp_path):
    path = tmp_path / "rgb.dng"
    write_dng(path, np.zeros((3, H, W), np.uint8), black_level_dn=16.0, white_level=255,
              unique_camera_model="camsim test camera", color_matrix1=np.diag(GAINS) @ XYZ_TO_SRGB,
              as_shot_neutral=GAINS)
    dn, info = read_dng(path)
    assert dn.shape == (3, H, W) and info["cfa_pattern"] is None


def test_16_bit_container_round_trip(tmp_path):
    """ADCs of more than 8 bits (e.g. 12) are stored in a 16-bit CFA DNG, read back exactly."""
    mosaic = random_mosaic(5, top=4095, dtype=np.uint16)
    path = write(tmp_path / "f.dng", mosaic, "GRBG", white_level=4095, black_level_dn=(64, 60, 68))
    with tifffile.TiffFile(path) as tif:
        assert tif.pages.first.bitspersample == 16
    with rawpy.imread(str(path)) as raw:
        np.testing.assert_array_equal(raw.raw_image, mosaic)
        assert raw.white_level == 4095
        assert list(raw.black_level_per_channel) == [64, 60, 68, 60]
    back, info = read_dng(path)
    assert back.dtype == np.uint16 and back.shape == (1, H, W)
    np.testing.assert_array_equal(back[0], mosaic)
    assert info["cfa_pattern"] == "GRBG" and info["white_level"] == 4095
    assert info["black_level"] == [64, 60, 68] and info["black_level_exact"] == [64.0, 60.0, 68.0]


@pytest.mark.parametrize("pattern", CFA_PATTERNS)
@pytest.mark.parametrize("black", [0.0, 16.0, (10.0, 16.0, 22.0), (16.99, 0.5, 3.25), 16.5])
@pytest.mark.parametrize("white", [255, 250])
def test_black_and_white_level_as_libraw_reports_them(tmp_path, pattern, black, white):
    path = write(tmp_path / "f.dng", random_mosaic(3), pattern, black_level_dn=black, white_level=white)
    per_colour = np.broadcast_to(np.asarray(black, dtype=float), (3,))
    with rawpy.imread(str(path)) as raw:
        # per LibRaw colour index (R, G, B, second G); LibRaw truncates fractional CFA black levels
        expected = [math.floor(per_colour[CODE[c]]) for c in raw.color_desc.decode()]
        assert list(raw.black_level_per_channel) == expected
        assert raw.white_level == white
    _, info = read_dng(path)
    assert info["black_level"] == [math.floor(b) for b in per_colour]
    assert info["black_level_exact"] == per_colour.tolist()  # the tag keeps the exact fraction
    assert info["white_level"] == white


@pytest.mark.parametrize("pattern", CFA_PATTERNS)
def test_dng_tags(tmp_path, pattern):
    path = write(tmp_path / "f.dng", random_mosaic(4), pattern, black_level_dn=(10, 12.25, 14), white_level=250,
                 software="camsim 0.1.0", calibration_illuminant1=17, model="sim-1", as_shot_neutral=[0.5, 1, 0.7])
    with tifffile.TiffFile(path) as tif:
        assert len(tif.pages) == 1
        page = tif.pages.first
        tags = {t.code: t.value for t in page.tags}
    assert page.photometric == 32803 and page.samplesperpixel == 1 and page.bitspersample == 8
    assert page.compression == tifffile.COMPRESSION.NONE and page.shape == (H, W)
    assert tags[254] == 0  # NewSubFileType: main image
    assert tuple(tags[33421]) == (2, 2)  # CFARepeatPatternDim
    assert tuple(bytes(tags[33422])) == tuple(CODE[c] for c in pattern)  # CFAPattern
    assert tuple(bytes(tags[50710])) == (0, 1, 2) and tags[50711] == 1  # CFAPlaneColor, CFALayout
    assert bytes(tags[50706]) == bytes([1, 4, 0, 0]) and bytes(tags[50707]) == bytes([1, 1, 0, 0])
    assert tags[50708] == "camsim test camera" and tags[271] == "camsim" and tags[272] == "sim-1"
    assert tags[305] == "camsim 0.1.0" and tags[50778] == 17
    # one black level per CFA position, row by row
    by_colour = {"R": (10, 1), "G": (49, 4), "B": (14, 1)}
    assert tuple(tags[50713]) == (2, 2)
    assert tuple(tags[50714]) == tuple(x for c in pattern for x in by_colour[c])
    assert tags[50717] == 250  # one WhiteLevel (SamplesPerPixel = 1)
    assert 306 not in tags and 270 not in tags  # no DateTime, no ImageDescription
    _, info = read_dng(path)
    np.testing.assert_allclose(info["color_matrix1"], np.diag(GAINS) @ XYZ_TO_SRGB, rtol=0, atol=1e-6)
    assert info["as_shot_neutral"] == [0.5, 1.0, 0.7] and info["calibration_illuminant1"] == 17


def test_equal_black_levels_are_one_value(tmp_path):
    path = write(tmp_path / "f.dng", random_mosaic(4), "BGGR", black_level_dn=(16.5, 16.5, 16.5),
                 white_level=(255,) * 3)
    with tifffile.TiffFile(path) as tif:
        tags = {t.code: t.value for t in tif.pages.first.tags}
    assert tuple(tags[50713]) == (1, 1) and tuple(tags[50714]) == (33, 2) and tags[50717] == 255


def test_same_input_gives_identical_bytes(tmp_path):
    mosaic = random_mosaic(5)
    kw = dict(black_level_dn=(10.5, 16, 22))
    a = write(tmp_path / "a.dng", mosaic, "GBRG", **kw).read_bytes()
    b = write(tmp_path / "b.dng", mosaic.copy(), "GBRG", **kw).read_bytes()
    assert a == b
    changed = mosaic.copy()
    changed[10, 10] ^= 1
    assert write(tmp_path / "c.dng", changed, "GBRG", **kw).read_bytes() != a
    assert write(tmp_path / "d.dng", mosaic, "RGGB", **kw).read_bytes() != a


def grey_and_red_mosaic(pattern, black):
    """Left half neutral grey (camera values proportional to AsShotNeutral), right half saturated red."""
    colour = colour_map(pattern)
    black = np.broadcast_to(np.asarray(black, dtype=float), (3,))
    grey = black[colour] + 120 * GAINS[colour]
    red = black[colour] + 200 * (GAINS * np.array([1.0, 0.05, 0.05]))[colour]
    return np.round(np.where(np.arange(W) < W // 2, grey, red)).astype(np.uint8)


@pytest.mark.parametrize("pattern", CFA_PATTERNS)
@pytest.mark.parametrize("black", [16.0, (10.0, 16.0, 22.0)])
def test_postprocess_gives_neutral_grey_and_red(tmp_path, pattern, black):
    path = write(tmp_path / "f.dng", grey_and_red_mosaic(pattern, black), pattern, black_level_dn=black)
    with rawpy.imread(str(path)) as raw:
        rgb = raw.postprocess()
    assert rgb.shape == (H, W, 3) and rgb.dtype == np.uint8
    grey = rgb[4:-4, 4: W // 2 - 4].reshape(-1, 3).astype(int)
    red = rgb[4:-4, W // 2 + 4: -4].reshape(-1, 3).astype(int)
    assert 60 < grey.mean() < 250
    assert np.ptp(grey.mean(axis=0)) <= 3 and np.ptp(grey, axis=0).max() <= 2
    assert np.all(red[:, 0] > red[:, 1] + 100) and np.all(red[:, 0] > red[:, 2] + 100)


@pytest.mark.parametrize("pattern", CFA_PATTERNS)
def test_postprocess_linear_uses_color_matrix_and_neutral(tmp_path, pattern):
    path = write(tmp_path / "f.dng", grey_and_red_mosaic(pattern, 16.0), pattern)
    with rawpy.imread(str(path)) as raw:
        # camera = diag(GAINS) @ sRGB, white-balanced by AsShotNeutral: LibRaw's camera -> sRGB matrix is identity
        np.testing.assert_allclose(raw.color_matrix[:, :3], np.eye(3), atol=2e-3)
        np.testing.assert_allclose(raw.camera_whitebalance[:3], 1 / GAINS, rtol=1e-6)
        rgb = raw.postprocess(gamma=(1, 1), no_auto_bright=True, use_camera_wb=True).astype(float)
    grey, red = rgb[H // 2, W // 4], rgb[H // 2, 3 * W // 4]
    assert np.ptp(grey) <= 1
    np.testing.assert_allclose(red[1:] / red[0], 0.05, atol=0.01)


@pytest.mark.parametrize("mosaic", [
    np.zeros((47, W), np.uint8), np.zeros((H, 63), np.uint8), np.zeros((23, 23), np.uint8),  # odd
    np.zeros((20, W), np.uint8), np.zeros((H, 20), np.uint8), np.zeros((21, 21), np.uint8),  # too small
    np.zeros((H, W), np.int16), np.zeros((H, W), np.float32), np.zeros((H, W), np.int8),  # dtype
    np.zeros((1, H, W), np.uint8), np.zeros((3, H, W), np.uint8), np.zeros(W, np.uint8), [[0] * W] * H,  # shape
])
def test_rejects_bad_mosaics_without_writing(tmp_path, mosaic):
    path = tmp_path / "bad.dng"
    with pytest.raises(CamsimError, match=re.escape(str(path))):
        write(path, mosaic)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("pattern", ["rggb", "RGBG", "RGB", "RGGBB", "XXXX", "", None, 3, ("R", "G", "G", "B")])
def test_rejects_bad_patterns_without_writing(tmp_path, pattern):
    path = tmp_path / "bad.dng"
    with pytest.raises(CamsimError, match=re.escape(str(path)) + ".*pattern"):
        write(path, random_mosaic(6), pattern)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("overrides", [
    dict(white_level=(250, 251, 252)), dict(white_level=256), dict(white_level=16), dict(white_level=200.5),
    dict(black_level_dn=(1, 2)), dict(black_level_dn=-1), dict(black_level_dn=(10, 260, 10)),
    dict(color_matrix1=np.eye(2)), dict(as_shot_neutral=[1, 0, 1]), dict(unique_camera_model=""),
    dict(calibration_illuminant1=70000), dict(software="Kamera ü"),
])
def test_rejects_bad_metadata_without_writing(tmp_path, overrides):
    path = tmp_path / "bad.dng"
    with pytest.raises(CamsimError, match=re.escape(str(path))):
        write(path, random_mosaic(6), **overrides)
    assert list(tmp_path.iterdir()) == []


def test_16_bit_white_level_limit(tmp_path):
    with pytest.raises(CamsimError, match="65535"):
        write(tmp_path / "bad.dng", random_mosaic(6, top=100, dtype=np.uint16), white_level=65536)
    write(tmp_path / "ok.dng", random_mosaic(6, top=100, dtype=np.uint16), white_level=65535)
    assert [p.name for p in tmp_path.iterdir()] == ["ok.dng"]


def test_exception_mid_write_leaves_no_file(tmp_path, monkeypatch):
    final = tmp_path / "f.dng"
    write(final, random_mosaic(8))
    before = final.read_bytes()

    def half_write(path, data, **kwargs):
        with open(path, "wb") as fh:
            fh.write(b"II*\x00partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(dng_mod.tifffile, "imwrite", half_write)
    with pytest.raises(OutputError, match=f"cannot write {re.escape(str(final))}: No space left on device"):
        write(final, random_mosaic(9))
    assert final.read_bytes() == before  # old complete file untouched
    with pytest.raises(OutputError, match="No space left on device"):
        write(tmp_path / "new.dng", random_mosaic(9))
    assert [p.name for p in tmp_path.iterdir()] == ["f.dng"]


@pytest.mark.parametrize("keep", [0.5, 0.05, 100])
def test_truncated_file_is_a_user_error(tmp_path, keep):
    good = write(tmp_path / "good.dng", random_mosaic(7)).read_bytes()
    bad = tmp_path / "truncated.dng"
    bad.write_bytes(good[: int(len(good) * keep) if keep < 1 else keep])
    with pytest.raises(CamsimError, match=re.escape(str(bad))):
        read_dng(bad)


@pytest.mark.parametrize(("dim", "codes"), [((2, 2), (0, 0, 1, 2)), ((2, 2), (0, 1, 1, 3)), ((1, 2), (0, 1))])
def test_reader_rejects_other_cfa_layouts(tmp_path, dim, codes):
    """A CFA DNG that is not a 2x2 R/G/B Bayer pattern is refused with a message naming the file."""
    path = write(tmp_path / "f.dng", random_mosaic(10))
    with tifffile.TiffFile(path) as tif:
        page = tif.pages.first
        tags = [(t.code, t.dtype, t.count, t.value, True) for t in page.tags
                if t.code >= 33421 and t.code not in (33421, 33422)]
        tags += [(33421, "H", 2, dim, True), (33422, "B", len(codes), codes, True)]
        tags += [(c, page.tags[c].dtype, page.tags[c].count, page.tags[c].value, True) for c in (271, 272, 274)]
    other = tmp_path / "other.dng"
    tifffile.imwrite(other, random_mosaic(10), photometric=32803, compression=None, extratags=tags, datetime=False,
                     metadata=None)
    with pytest.raises(CamsimError, match=re.escape(str(other)) + ".*CFA"):
        read_dng(other)
