"""A camera/phone-style Bayer DNG writer for the tests, independent of camsim's (:mod:`camsim.io.dng`).

It writes the tags a phone's or a camera's DNG carries (Android's DngCreator, Adobe DNG Converter) with
:mod:`tifffile` and this module's own tag codes, so that camsim's raw reader (:mod:`camsim.io.raw_capture`) is tested
against files it did not write itself: a thumbnail in IFD0 with the raw image in a SubIFD (or the raw in IFD0),
the CFA tags, BlackLevelRepeatDim 2 × 2 with four BlackLevel values (LONG, or RATIONAL when fractional), WhiteLevel,
ColorMatrix1/2, CalibrationIlluminant1/2, AsShotNeutral, Make, Model, UniqueCameraModel, Orientation, DNGVersion
1.4, an optional ActiveArea, and ExposureTime and ISOSpeedRatings either in an EXIF IFD (appended after tifffile's
write, its pointer patched in IFD0) or directly in IFD0, as Android does. Little- or big-endian.

Nothing here imports camsim.
"""

from __future__ import annotations

import os
import struct
from fractions import Fraction

import numpy as np
import tifffile

# TIFF / EXIF / DNG tag codes (TIFF 6.0, EXIF 2.32, DNG 1.4 specifications)
NEW_SUBFILE_TYPE = 254
MAKE, MODEL, ORIENTATION = 271, 272, 274
CFA_REPEAT_PATTERN_DIM, CFA_PATTERN = 33421, 33422
EXPOSURE_TIME, EXIF_IFD, ISO_SPEED_RATINGS, EXIF_VERSION = 33434, 34665, 34855, 36864
DNG_VERSION, DNG_BACKWARD_VERSION, UNIQUE_CAMERA_MODEL = 50706, 50707, 50708
CFA_PLANE_COLOR, CFA_LAYOUT = 50710, 50711
BLACK_LEVEL_REPEAT_DIM, BLACK_LEVEL, WHITE_LEVEL = 50713, 50714, 50717
BLACK_LEVEL_DELTA_H, BLACK_LEVEL_DELTA_V = 50715, 50716
COLOR_MATRIX1, COLOR_MATRIX2, AS_SHOT_NEUTRAL = 50721, 50722, 50728
CALIBRATION_ILLUMINANT1, CALIBRATION_ILLUMINANT2 = 50778, 50779
ACTIVE_AREA = 50829
EXIF_STAND_IN = 65000  # a private code, see _exif_ifd
PHOTOMETRIC_CFA = 32803

COLOUR_CODE = {"R": 0, "G": 1, "B": 2}

# TIFF field types
SHORT, LONG, RATIONAL, UNDEFINED, SRATIONAL = 3, 4, 5, 7, 10


def _fraction_pairs(values, *, signed: bool, denominator: int = 10000) -> tuple:
    """Values as (numerator, denominator) pairs: over ``denominator`` where that is exact (as cameras write
    matrices, in 10000ths), else the closest fraction with a denominator of at most 2^20."""
    out = []
    for v in np.asarray(values, dtype=np.float64).ravel():
        scaled = v * denominator
        if abs(scaled - round(scaled)) < 1e-9:
            out += [int(round(scaled)), denominator]
        else:
            f = Fraction(float(v)).limit_denominator(1 << 20)
            out += [f.numerator, f.denominator]
    if not signed and any(x < 0 for x in out):
        raise ValueError("negative value for an unsigned RATIONAL")
    return tuple(out)


def _exif_ifd(path: str, order: str, iso, exposure_s) -> None:
    """Append an EXIF IFD (ExposureTime, ISOSpeedRatings, ExifVersion) to the TIFF at ``path`` and turn IFD0's
    stand-in entry (tifffile refuses to write an ExifIFD tag: code ``EXIF_STAND_IN``, LONG 0) into the ExifIFD
    pointer, re-sorting IFD0's entries by code as TIFF requires."""
    entries = []
    if exposure_s is not None:
        num, den = _fraction_pairs([exposure_s], signed=False, denominator=1_000_000)
        entries.append((EXPOSURE_TIME, RATIONAL, 1, struct.pack(order + "2I", num, den)))
    if iso is not None:
        entries.append((ISO_SPEED_RATINGS, SHORT, 1, struct.pack(order + "H", int(iso)).ljust(4, b"\0")))
    entries.append((EXIF_VERSION, UNDEFINED, 4, b"0231"))
    with open(path, "r+b") as fh:
        ifd0 = struct.unpack(order + "I", fh.read(8)[4:])[0]
        end = fh.seek(0, os.SEEK_END)
        start = end + (end % 2)
        data_at = start + 2 + 12 * len(entries) + 4
        table, data = struct.pack(order + "H", len(entries)), b""
        for tag, kind, count, value in sorted(entries):
            if len(value) > 4:
                field = struct.pack(order + "I", data_at + len(data))
                data += value
            else:
                field = value
            table += struct.pack(order + "HHI", tag, kind, count) + field
        table += struct.pack(order + "I", 0)
        fh.write(b"\0" * (start - end) + table + data)
        fh.seek(ifd0)
        count = struct.unpack(order + "H", fh.read(2))[0]
        rows = [fh.read(12) for _ in range(count)]
        codes = [struct.unpack(order + "H", row[:2])[0] for row in rows]
        i = codes.index(EXIF_STAND_IN)
        rows[i] = struct.pack(order + "HHII", EXIF_IFD, LONG, 1, start)
        rows.sort(key=lambda row: struct.unpack(order + "H", row[:2])[0])
        fh.seek(ifd0 + 2)
        fh.write(b"".join(rows))


def write_phone_dng(path, mosaic: np.ndarray, *, pattern: str, black_per_site, white: int, iso=None,
                    exposure_s=None, make: str = "Google", model: str = "Pixel 7",
                    unique_camera_model: str | None = None, color_matrix1=None, color_matrix2=None,
                    illuminants=(17, 21), as_shot_neutral=None, orientation: int = 1, exif_ifd: bool = True,
                    thumbnail: bool = True, active_area=None, big_endian: bool = False,
                    extra_raw_tags=(), tile=None) -> str:
    """Write ``mosaic`` (H, W) uint16 as a phone-style CFA DNG; returns the path.

    Parameters
    ----------
    pattern : str
        The 2 × 2 CFA cell at the top-left of the active area, e.g. ``"GRBG"`` (36 letters: a 6 × 6 cell, as
        Fujifilm's X-Trans).
    black_per_site : array_like, shape (2, 2)
        BlackLevel of each site of that cell (BlackLevelRepeatDim 2 × 2): LONG when all are integers, else
        RATIONAL. Unit: DN.
    white : int
        WhiteLevel. Unit: DN.
    iso, exposure_s
        ISOSpeedRatings (SHORT) and ExposureTime (RATIONAL, s); in an EXIF IFD (``exif_ifd``) or in IFD0.
    illuminants : (int, int)
        CalibrationIlluminant1 and 2 (EXIF LightSource codes); the second is written only with ``color_matrix2``.
    thumbnail : bool
        IFD0 a small RGB preview (NewSubFileType 1) and the raw in its SubIFD, as phones and Adobe DNG Converter
        write; else the raw in IFD0.
    active_area : (top, left, bottom, right) or None
        The DNG ActiveArea (the pattern and the black levels start at its top-left corner).
    extra_raw_tags : sequence of tifffile extratags
        More tags for the raw image's IFD (e.g. BlackLevelDeltaH).
    tile : (rows, columns) or None
        The raw image in tiles of this size (multiples of 16), as Adobe DNG Converter writes it; None: one strip.
    """
    mosaic = np.asarray(mosaic)
    assert mosaic.ndim == 2 and mosaic.dtype == np.uint16
    order = ">" if big_endian else "<"
    black = np.asarray(black_per_site, dtype=np.float64).reshape(2, 2)
    if np.all(black == np.round(black)):
        black_tag = (BLACK_LEVEL, LONG, 4, tuple(int(b) for b in black.ravel()), True)
    else:
        black_tag = (BLACK_LEVEL, RATIONAL, 4, _fraction_pairs(black, signed=False), True)
    ucm = unique_camera_model or f"{make} {model}"
    common = [  # tags of IFD0 (the whole file's)
        (MAKE, "s", 0, make, True),
        (MODEL, "s", 0, model, True),
        (ORIENTATION, SHORT, 1, int(orientation), True),
        (DNG_VERSION, "B", 4, (1, 4, 0, 0), True),
        (DNG_BACKWARD_VERSION, "B", 4, (1, 1, 0, 0), True),
        (UNIQUE_CAMERA_MODEL, "s", 0, ucm, True),
    ]
    if color_matrix1 is not None:
        common.append((COLOR_MATRIX1, SRATIONAL, 9, _fraction_pairs(color_matrix1, signed=True), True))
        common.append((CALIBRATION_ILLUMINANT1, SHORT, 1, int(illuminants[0]), True))
    if color_matrix2 is not None:
        common.append((COLOR_MATRIX2, SRATIONAL, 9, _fraction_pairs(color_matrix2, signed=True), True))
        common.append((CALIBRATION_ILLUMINANT2, SHORT, 1, int(illuminants[1]), True))
    if as_shot_neutral is not None:
        common.append((AS_SHOT_NEUTRAL, RATIONAL, 3, _fraction_pairs(as_shot_neutral, signed=False), True))
    shot = []
    if exif_ifd and (iso is not None or exposure_s is not None):
        common.append((EXIF_STAND_IN, LONG, 1, 0, True))  # made the ExifIFD pointer by _exif_ifd
    elif not exif_ifd:
        if exposure_s is not None:
            shot.append((EXPOSURE_TIME, RATIONAL, 1,
                         _fraction_pairs([exposure_s], signed=False, denominator=1_000_000), True))
        if iso is not None:
            shot.append((ISO_SPEED_RATINGS, SHORT, 1, int(iso), True))
    raw_tags = [
        (CFA_REPEAT_PATTERN_DIM, SHORT, 2, (2, 2) if len(pattern) == 4 else (6, 6), True),
        (CFA_PATTERN, "B", len(pattern), tuple(COLOUR_CODE[c] for c in pattern), True),
        (CFA_PLANE_COLOR, "B", 3, (0, 1, 2), True),
        (CFA_LAYOUT, SHORT, 1, 1, True),
        (BLACK_LEVEL_REPEAT_DIM, SHORT, 2, (2, 2), True),
        black_tag,
        (WHITE_LEVEL, LONG, 1, int(white), True),
    ]
    raw_tags += list(extra_raw_tags)
    if active_area is not None:
        raw_tags.append((ACTIVE_AREA, LONG, 4, tuple(int(v) for v in active_area), True))
    name = os.fspath(path)
    layout = dict(tile=tuple(tile)) if tile is not None else dict(rowsperstrip=mosaic.shape[0])
    with tifffile.TiffWriter(name, byteorder=order) as tw:
        if thumbnail:
            thumb = np.zeros((16, 24, 3), np.uint8)
            thumb[..., 1] = 128
            tw.write(thumb, photometric="rgb", subfiletype=1, subifds=1, extratags=common + shot,
                     metadata=None, software=False, datetime=False)
            tw.write(mosaic, photometric=PHOTOMETRIC_CFA, subfiletype=0, extratags=raw_tags, metadata=None,
                     software=False, datetime=False, compression=None, **layout)
        else:
            tw.write(mosaic, photometric=PHOTOMETRIC_CFA, subfiletype=0, extratags=common + shot + raw_tags,
                     metadata=None, software=False, datetime=False, compression=None, **layout)
    if exif_ifd and (iso is not None or exposure_s is not None):
        _exif_ifd(name, order, iso, exposure_s)
    return name
