"""Every black level a sensor can have (0 to 65535 DN) and every ColorMatrix value fits the DNG's RATIONALs.

The stored fractions are read back with tifffile (the raw numerator and denominator, integer arithmetic) and with
rawpy (LibRaw's own reading), against the value written; the bound is the writer's stated one, 1 / (2 D) with
D = floor((2^32 − 1) / 65536) = 65535 for the largest black level: below 7.63e-6 DN.
"""

import json
import math
from fractions import Fraction

import numpy as np
import rawpy
import tifffile
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from camsim.cli import main
from camsim.io.dng import write_dng, write_dng_cfa
from tests.support.helpers import libraw_black_levels
from tests.support.profiles import examples

# the writer's bound for any value up to 65535 (docs reference "File formats", camsim.io.dng)
BLACK_BOUND_DN = 1 / (2 * 65535)
SIZE = 22  # LibRaw's smallest frame
SRGB_TO_XYZ = np.array([[0.412453, 0.357580, 0.180423], [0.212671, 0.715160, 0.072169],
                        [0.019334, 0.119193, 0.950227]])  # dcraw's and LibRaw's xyz_rgb
XYZ_TO_SRGB = np.array([[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]])

blacks = st.floats(min_value=0.0, max_value=65534.0, allow_nan=False, allow_infinity=False)
# the same 60 examples on every run and machine (derandomize; no example database): a fresh clone's suite is
# reproducible
FILES = settings(max_examples=examples(60), deadline=None, derandomize=True, database=None,
                 suppress_health_check=[HealthCheck.function_scoped_fixture])


def _stored(path, code):
    """The (numerator, denominator) pairs of tag ``code`` as the file holds them."""
    with tifffile.TiffFile(path) as tif:
        page = tif.pages.first
        tag = page.tags[code]
        assert tag.dtype in (5, 10)  # RATIONAL, SRATIONAL
        values = np.asarray(tag.value, dtype=object).ravel()
    return [(int(n), int(d)) for n, d in zip(values[0::2], values[1::2])]


def _frame(dtype=np.uint16):
    return np.random.default_rng(0).integers(0, 60000, size=(3, SIZE, SIZE)).astype(dtype)


def _libraw_rounds(v: float) -> int | None:
    """LibRaw's integer for a LinearRaw level near ``v`` (halves up), or None where v is within the writer's
    bound of a half (the stored fraction may fall either side)."""
    if abs((v + 0.5) - round(v + 0.5)) <= BLACK_BOUND_DN:
        return None
    return math.floor(v + 0.5)


@FILES
@given(black=st.tuples(blacks, blacks, blacks))
def test_any_16_bit_black_level_round_trips_through_tifffile_and_rawpy(tmp_path, black):
    path = tmp_path / "f.dng"
    write_dng(path, _frame(), black_level_dn=black, white_level=65535, unique_camera_model="camsim test",
              color_matrix1=XYZ_TO_SRGB, as_shot_neutral=(1, 1, 1))
    pairs = _stored(path, 50714)
    assert len(pairs) == 3
    for (n, d), v in zip(pairs, black):
        assert 0 <= n < 2**32 and 0 < d < 2**32
        assert abs(Fraction(n, d) - Fraction(v)) <= BLACK_BOUND_DN
    with rawpy.imread(str(path)) as raw:
        got = [int(b) for b in raw.black_level_per_channel[:3]]
    assert got == libraw_black_levels(path)  # LibRaw reads the stored fraction ...
    for g, v in zip(got, black):  # ... which is the value's: rounded, halves up, for a LinearRaw file
        if _libraw_rounds(v) is not None:
            assert g == _libraw_rounds(v)


@FILES
@given(black=st.tuples(blacks, blacks, blacks))
def test_any_16_bit_black_level_of_a_bayer_file_round_trips(tmp_path, black):
    path = tmp_path / "f.dng"
    mosaic = np.random.default_rng(1).integers(0, 60000, size=(SIZE, SIZE)).astype(np.uint16)
    write_dng_cfa(path, mosaic, pattern="RGGB", black_level_dn=black, white_level=65535,
                  unique_camera_model="camsim test", color_matrix1=XYZ_TO_SRGB, as_shot_neutral=(1, 1, 1))
    pairs = _stored(path, 50714)
    expected = [black[0]] if black[0] == black[1] == black[2] else [black[0], black[1], black[1], black[2]]
    assert len(pairs) == len(expected)
    for (n, d), v in zip(pairs, expected):
        assert 0 <= n < 2**32 and 0 < d < 2**32
        assert abs(Fraction(n, d) - Fraction(v)) <= BLACK_BOUND_DN
    with rawpy.imread(str(path)) as raw:
        desc = raw.color_desc.decode()
        got = {c: int(raw.black_level_per_channel[i]) for i, c in enumerate(desc[:3])}
    for colour, v in zip("RGB", black):  # LibRaw truncates a CFA file's levels
        if abs(v - round(v)) > BLACK_BOUND_DN:
            assert got[colour] == math.floor(v)


@FILES
@given(matrix=st.lists(st.floats(min_value=-1000.0, max_value=1000.0, allow_nan=False), min_size=9, max_size=9),
       neutral=st.lists(st.floats(min_value=1e-3, max_value=1.0), min_size=3, max_size=3))
def test_colour_matrix_and_neutral_values_round_trip(tmp_path, matrix, neutral):
    path = tmp_path / "f.dng"
    write_dng(path, _frame(np.uint8), black_level_dn=0, white_level=255, unique_camera_model="camsim test",
              color_matrix1=np.reshape(matrix, (3, 3)), as_shot_neutral=neutral)
    for code, values, top in ((50721, matrix, 2**31), (50728, neutral, 2**32)):
        for (n, d), v in zip(_stored(path, code), values):
            assert -top <= n < top and 0 < d < top
            # the bound 1 / (2 D), D = floor((top − 1) / (|v| + 1)): 2.4e-7 at |v| = 1000, 1.2e-10 at 0
            assert abs(Fraction(n, d) - Fraction(v)) <= 1 / (2 * ((top - 1) // (abs(v) + 1)))


@FILES
@given(scale=st.floats(min_value=1e-3, max_value=300.0),
       gains=st.lists(st.floats(min_value=0.2, max_value=1.0), min_size=3, max_size=3),
       jitter=st.lists(st.floats(min_value=-0.02, max_value=0.02), min_size=9, max_size=9))
def test_camera_like_colour_matrices_through_rawpy(tmp_path, scale, gains, jitter):
    """A camera's XYZ -> camera matrix at any scale reads back through LibRaw as written: LibRaw's camera ->
    sRGB matrix is dcraw's ``cam_xyz_coeff`` of it (rows of M · xyz_rgb normalised to sum 1, inverted)."""
    matrix = scale * (np.diag(gains) @ XYZ_TO_SRGB + np.reshape(jitter, (3, 3)))
    path = tmp_path / "f.dng"
    write_dng(path, _frame(np.uint8), black_level_dn=0, white_level=255, unique_camera_model="camsim test",
              color_matrix1=matrix, as_shot_neutral=gains)
    cam_rgb = matrix @ SRGB_TO_XYZ
    cam_rgb /= cam_rgb.sum(axis=1, keepdims=True)
    with rawpy.imread(str(path)) as raw:
        rgb_cam = raw.color_matrix[:3, :3].astype(np.float64)
    # LibRaw inverts in single precision: its matrix is as good as float32 and the matrix's condition allow
    np.testing.assert_allclose(np.linalg.inv(rgb_cam), cam_rgb, rtol=1e-3, atol=1e-4)


def test_the_cli_writes_a_5000_dn_pedestal_of_a_16_bit_adc(tmp_path):
    """``render … --sensor bits=16 --sensor pedestal_dn=5000`` (a black level of about 5005 DN) is written, and
    rawpy reads it as the sidecar's level rounded (a LinearRaw file)."""
    out = tmp_path / "out"
    assert main(["render", "macbeth_26", "--illuminant", "D65", "--intensity", "1", "--sensor", "bits=16",
                 "--sensor", "pedestal_dn=5000", "--size", "66x44", "--out", str(out), "-q"]) == 0
    path = out / "macbeth_26_D65_F1.dng"
    meta = json.loads(path.with_suffix(".json").read_text())
    black = meta.get("black_level_tag_dn", meta["black_level_dn"])
    assert all(5000 <= b < 5010 for b in black)
    for (n, d), v in zip(_stored(path, 50714), black):
        assert abs(Fraction(n, d) - Fraction(v)) <= BLACK_BOUND_DN
    with rawpy.imread(str(path)) as raw:
        got = [int(b) for b in raw.black_level_per_channel[:3]]
        assert raw.white_level == 65535
    assert got == libraw_black_levels(path)
    assert all(g == _libraw_rounds(v) for g, v in zip(got, black) if _libraw_rounds(v) is not None)
