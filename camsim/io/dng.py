"""Three-chip LinearRaw and Bayer (CFA) DNG writers and reader (8-bit; 16-bit containers for ADCs of 9 to 16 bits).

The simulator's digital numbers are stored as an uncompressed, interleaved, 8-bit, 3-sample LinearRaw DNG (one
R, G and B value per pixel, no mosaic) written with :mod:`tifffile`, so that LibRaw (``rawpy``), dcraw-style raw
developers and Adobe tools read the exact numbers. Deflate compression is deliberately not used: LibRaw cannot
read deflate-compressed DNGs.

camsim writes the true black level (:attr:`camsim.sensor.params.SensorParams.black_level_dn`, the exact mean digital
number of an unlit pixel, clipped below the WhiteLevel) as BlackLevel: RATIONAL, one value per sample (LinearRaw,
without BlackLevelRepeatDim: its default 1 x 1) or per CFA position (Bayer, BlackLevelRepeatDim 2 x 2), within
1 / (2 D) of the value with the largest denominator D it allows (:func:`rational_bound`: below 7.63e-6 DN for any
level up to 65535 DN, 1e-9 DN for 8-bit levels). What the raw readers make of the files, measured
(``tools/raw_readers.py``, ``tests/end_to_end/test_raw_readers.py``; docs, reference 'File formats'): LibRaw takes a
LinearRaw file's three levels, rounded; RawTherapee 5.9 takes the three too (its pictures match LibRaw's), but only
without BlackLevelRepeatDim: with the tag it sets red's level from the per-position value, which a file of three
per-sample values does not have, to 0; dcraw 9.28 reads
BlackLevelRepeatRows × Cols values, so the first (red's) for all three samples; darktable 4.2 (rawspeed) reads no
BlackLevel of an image of more than one sample per pixel. All four truncate a CFA file's per-position levels.

The camera's identity (Make, Model, UniqueCameraModel) is in IFD0; its ISO (ISOSpeedRatings, EXIF 2.3
PhotographicSensitivity; above 65535 also SensitivityType 3 and ISOSpeed) and the exposure time (ExposureTime) are
in an EXIF IFD (with ExifVersion 0230), where EXIF puts them and LibRaw looks for them: ``rawpy``'s
``other.iso_speed`` (65535 for a higher ISO) and ``other.shutter_speed``; ExifTool validates the files without a
warning; :func:`shot_metadata` reads both.

What LibRaw 0.22 (rawpy 0.28) makes of these files, measured and pinned by ``tests/io/test_dng.py``:

* ``raw_type`` is ``RawType.Stack`` and ``raw_image`` (and ``raw_image_visible``) is an ``(H, W, 4)`` uint16 array:
  LibRaw always stores colour-stacked images with four channels. Channels 0..2 are exactly the written R, G, B
  numbers; channel 3 is all zeros. ``raw_colors`` raises (the image is not flat).
* ``black_level_per_channel`` is ``[b_R, b_G, b_B, 0]`` as integers: LibRaw rounds a fractional BlackLevel to the
  nearest integer with halves rounded up (``floor(b + 0.5)``: 16.4 -> 16, 16.5 -> 17). The exact fractional value
  stays in the file and :func:`read_dng` returns it too.
* ``white_level`` is the WhiteLevel written (e.g. 255).
* LibRaw rejects images smaller than 22 pixels in either dimension, so :func:`write_dng` refuses them.

An ADC of 9 to 16 bits is stored in a 16-bit container (BitsPerSample 16, uint16 samples, unpacked) whose
WhiteLevel is the ADC's top code 2^nb − 1 (16383 for 14 bits): LibRaw takes the WhiteLevel as ``white_level`` and
returns the samples unchanged (no scaling to 16 bits), for every nb from 9 to 16, LinearRaw and CFA alike, pinned by
``tests/sensor/test_noise_profile.py``. Samples above the WhiteLevel are not refused (a reader clips them).

The DNG NoiseProfile (tag 51041, DNG 1.3; the files say DNGVersion 1.4.0.0, DNGBackwardVersion 1.1.0.0, as a
reader that ignores the tag still renders them) is written when a ``noise_profile`` is given: pairs (S, O), one per
sample or CFA plane colour (R, G, B) or one for all, as DOUBLE, such that the temporal noise variance of the
normalised value x = (DN − BlackLevel) / (WhiteLevel − BlackLevel) is S · x + O
(:mod:`camsim.sensor.noise_profile` computes them from the model). LibRaw reads the files as it does without the tag;
ExifTool shows it as ``NoiseProfile``.

A Bayer sensor's mosaic (one digital number per pixel) is stored by :func:`write_dng_cfa` as an uncompressed
1-sample CFA DNG (PhotometricInterpretation 32803, a 2x2 CFAPattern). What LibRaw 0.22 makes of these files, pinned
by ``tests/io/test_dng_cfa.py``:

* ``raw_type`` is ``RawType.Flat``, ``num_colors`` is 3, ``color_desc`` is ``b"RGBG"`` and ``raw_image`` (and
  ``raw_image_visible``) is the ``(H, W)`` mosaic exactly (as uint16). LibRaw numbers the colours R = 0, G = 1,
  B = 2 and the green that shares its rows with blue 3, so ``raw_pattern`` (and the 2x2 cell of ``raw_colors``) is
  RGGB ``[[0, 1], [3, 2]]``, BGGR ``[[2, 3], [1, 0]]``, GRBG ``[[1, 0], [2, 3]]``, GBRG ``[[3, 2], [0, 1]]``.
* Per-colour black levels are written as BlackLevelRepeatDim (2, 2) with one BlackLevel per CFA position (or
  (1, 1) with a single value when R, G and B are equal); LibRaw applies them per position:
  ``black_level_per_channel[c]`` is the black level of the CFA positions of colour index ``c`` (both greens get
  the green value). Unlike for LinearRaw files LibRaw *truncates* a fractional black level of a CFA DNG
  (``floor(b)``: 16.99 -> 16, 16.5 -> 16); the exact value stays in the file and :func:`read_dng` returns it too.
* ``white_level`` is the (single) WhiteLevel written; ``postprocess()`` demosaics with ColorMatrix1 and
  AsShotNeutral (LibRaw scales by ``white - min(black)``, so a per-colour black level shifts the brightness of
  the developed picture slightly, not its colour balance).
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import struct
from fractions import Fraction
from typing import Any

import numpy as np
import tifffile

from camsim.core.errors import CamsimError
from camsim.core.input_files import check_input
from camsim.core.pixel_limit import check_pixel_count
from camsim.io.atomic import atomic_path
from camsim.sensor.cfa import CFA_PATTERNS

__all__ = ["write_dng", "write_dng_cfa", "read_dng", "shot_metadata", "rational_bound", "darktable_xmp",
           "DARKTABLE_XMP_SUFFIX", "MIN_SIZE", "CFA_PATTERNS"]

MIN_SIZE = 22  # LibRaw refuses raw images narrower or shorter than this (measured with LibRaw 0.22)

# DNG tag codes
_DNG_VERSION, _DNG_BACKWARD_VERSION, _UNIQUE_CAMERA_MODEL = 50706, 50707, 50708
_BLACK_LEVEL_REPEAT_DIM, _BLACK_LEVEL, _WHITE_LEVEL = 50713, 50714, 50717
_COLOR_MATRIX1, _AS_SHOT_NEUTRAL, _CALIBRATION_ILLUMINANT1 = 50721, 50728, 50778
_COLOR_MATRIX2, _CALIBRATION_ILLUMINANT2 = 50722, 50779
_MAKE, _MODEL, _ORIENTATION = 271, 272, 274
_CFA_REPEAT_PATTERN_DIM, _CFA_PATTERN, _CFA_PLANE_COLOR, _CFA_LAYOUT = 33421, 33422, 50710, 50711
_NOISE_PROFILE = 51041  # DNG 1.3: DOUBLE, (S, O) per colour plane
# the EXIF IFD (pointer tag ExifIFD in IFD0): ExposureTime RATIONAL [s], ISOSpeedRatings (EXIF 2.3:
# PhotographicSensitivity) SHORT, for an ISO above 65535 SensitivityType 3 (ISO speed) with ISOSpeed LONG, ExifVersion
_EXPOSURE_TIME, _ISO_SPEED_RATINGS, _SENSITIVITY_TYPE, _ISO_SPEED = 33434, 34855, 34864, 34867
_EXIF_IFD, _EXIF_VERSION = 34665, 36864
# tifffile does not write an ExifIFD tag: the writer has it write a LONG 0 under this neighbouring (unused) code, at
# ExifIFD's place in the sorted IFD, and then gives the entry its code and the appended EXIF IFD's offset
_EXIF_IFD_STAND_IN = 34664

_CFA_CODE = {"R": 0, "G": 1, "B": 2}  # DNG CFAPattern colour codes, in the CFAPlaneColor order (0, 1, 2)


#: Largest numerator (and denominator) of a TIFF RATIONAL (unsigned) and SRATIONAL (signed), by signedness.
_RATIONAL_TOP = {False: 2**32 - 1, True: 2**31 - 1}
#: The longest exposure a DNG records (its ExposureTime is a RATIONAL): 2³² − 2 s, 136 years. Unit: s.
MAX_EXPOSURE_S = _RATIONAL_TOP[False] - 1


def rational_bound(value: float, *, signed: bool = False) -> float:
    """The largest error of :func:`_rationals` for ``value``: 1 / (2 D), D = floor(top / (|value| + 1)).

    Parameters
    ----------
    value : float
        The value to be stored (e.g. a black level) [any unit; the bound is in the same unit].
    signed : bool
        SRATIONAL (top 2^31 − 1) rather than RATIONAL (top 2^32 − 1).

    Returns
    -------
    float
        The bound on |stored − value|: below 7.63e-6 for any |value| <= 65535 in a RATIONAL (a 16-bit black
        level), 1.2e-10 × (|value| + 1) in general.
    """
    top = _RATIONAL_TOP[signed]
    return 1.0 / (2 * min(top, int(top // (abs(float(value)) + 1))))


def _rationals(values: Any, name: str, *, signed: bool) -> tuple[int, ...]:
    """Flatten floats into TIFF (S)RATIONAL pairs ``(num0, den0, num1, den1, ...)``, exactly reproducibly.

    Each value gets the denominator its size allows: the closest fraction whose denominator is at most
    D = floor(top / (|v| + 1)) (top = 2^32 − 1, or 2^31 − 1 signed), so that its numerator, at most (|v| + 1) D,
    fits 32 bits; the error is at most 1 / (2 D) (:func:`rational_bound`): 7.63e-6 for a value of 65535, 1e-9
    for one of 5. A value that is a fraction with such a denominator (16.5, 804, 3/7) is stored exactly.
    """
    out: list[int] = []
    top = _RATIONAL_TOP[signed]
    for v in np.asarray(values, dtype=np.float64).ravel():
        if not math.isfinite(v) or (not signed and v < 0):
            raise CamsimError(f"{name} must be finite{'' if signed else ' and non-negative'}, got {v!r}")
        if abs(v) > top - 1:
            raise CamsimError(f"{name} value {v!r} does not fit a TIFF {'S' if signed else ''}RATIONAL "
                              f"(|value| <= {top - 1})")
        f = Fraction(float(v)).limit_denominator(min(top, int(top // (abs(float(v)) + 1))))
        out += [f.numerator, f.denominator]
    return tuple(out)


def _ascii(value: str, name: str) -> str:
    if not isinstance(value, str) or not value or not value.isascii() or "\x00" in value:
        raise CamsimError(f"{name} must be a non-empty ASCII string without NUL, got {value!r}")
    return value


def _per_sample(value: Any, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.ndim == 0:
        arr = np.full(3, float(arr))
    if arr.shape != (3,):
        raise CamsimError(f"{name} must be a scalar or 3 values (R, G, B), got shape {arr.shape}")
    return arr


def _noise_profile(value: Any) -> tuple[float, ...] | None:
    """Validate NoiseProfile pairs: one (S, O) for all planes or one per plane (R, G, B); flattened, or None.

    The DNG SDK takes a noise function as valid only with S > 0 and O >= 0 (``dng_noise_function::IsValid``).
    """
    if value is None:
        return None
    pairs = np.asarray(value, dtype=np.float64)
    if pairs.ndim != 2 or pairs.shape[0] not in (1, 3) or pairs.shape[1] != 2:
        raise CamsimError(f"noise_profile must be 1 or 3 pairs (S, O), got shape {pairs.shape}")
    if not (np.all(np.isfinite(pairs)) and np.all(pairs[:, 0] > 0) and np.all(pairs[:, 1] >= 0)):
        raise CamsimError(f"noise_profile pairs (S, O) must be finite with S > 0 and O >= 0, got {pairs.tolist()}")
    return tuple(float(v) for v in pairs.ravel())


def _check_three_chip(dn: Any) -> None:
    if (not isinstance(dn, np.ndarray) or dn.dtype not in (np.uint8, np.uint16) or dn.ndim != 3
            or dn.shape[0] != 3):
        raise CamsimError(f"dn must be a uint8 or uint16 array of shape (3, H, W), got "
                          f"{getattr(dn, 'dtype', type(dn).__name__)} {getattr(dn, 'shape', '')}")
    if min(dn.shape[1:]) < MIN_SIZE:
        raise CamsimError(f"frame {dn.shape[1]}x{dn.shape[2]} is smaller than {MIN_SIZE}x{MIN_SIZE}, which LibRaw "
                          "cannot read")


def _check_mosaic(mosaic: Any, pattern: Any) -> None:
    if pattern not in CFA_PATTERNS:  # also rejects non-strings
        raise CamsimError(f"pattern must be one of {', '.join(CFA_PATTERNS)}, got {pattern!r}")
    if not isinstance(mosaic, np.ndarray) or mosaic.dtype not in (np.uint8, np.uint16) or mosaic.ndim != 2:
        raise CamsimError(f"mosaic must be a uint8 or uint16 array of shape (H, W), got "
                          f"{getattr(mosaic, 'dtype', type(mosaic).__name__)} {getattr(mosaic, 'shape', '')}")
    h, w = mosaic.shape
    if min(h, w) < MIN_SIZE:
        raise CamsimError(f"mosaic {h}x{w} is smaller than {MIN_SIZE}x{MIN_SIZE}, which LibRaw cannot read")
    if h % 2 or w % 2:
        raise CamsimError(f"mosaic {h}x{w} must have an even height and width (whole 2x2 {pattern} cells)")


def _exif_entries(iso: Any, exposure_s: Any) -> list[tuple[int, int, int, bytes]]:
    """The EXIF IFD's entries ``(tag, TIFF type, count, little-endian value bytes)``, sorted by tag, for an exposure
    [s] and an ISO (each None to omit); none when both are None."""
    entries: list[tuple[int, int, int, bytes]] = []
    if exposure_s is not None:
        if not (isinstance(exposure_s, (int, float, np.number)) and math.isfinite(exposure_s) and exposure_s > 0):
            raise CamsimError(f"exposure_s must be a positive number of seconds, got {exposure_s!r}")
        entries.append((_EXPOSURE_TIME, 5, 1, struct.pack("<2I", *_rationals([exposure_s], "exposure_s",
                                                                                signed=False))))
    if iso is not None:
        if not (isinstance(iso, (int, float, np.number)) and math.isfinite(iso) and 0.5 <= iso < 2**32 - 0.5):
            raise CamsimError(f"iso must be a positive number below 2^32, got {iso!r}")
        speed = int(round(float(iso)))
        entries.append((_ISO_SPEED_RATINGS, 3, 1, struct.pack("<H", min(speed, 65535))))
        if speed > 65535:
            entries += [(_SENSITIVITY_TYPE, 3, 1, struct.pack("<H", 3)), (_ISO_SPEED, 4, 1, struct.pack("<I", speed))]
    if entries:
        entries.append((_EXIF_VERSION, 7, 4, b"0230"))
    return sorted(entries)


def _append_exif_ifd(path: str | os.PathLike[str], entries: list[tuple[int, int, int, bytes]]) -> None:
    """Append the EXIF IFD holding ``entries`` to the classic little-endian TIFF at ``path`` (as tifffile wrote
    it) and turn IFD0's stand-in entry (code ``_EXIF_IFD_STAND_IN``, LONG 0) into the ExifIFD tag pointing at it."""
    with open(path, "r+b") as fh:
        header = fh.read(8)
        if header[:4] != b"II*\x00":
            raise CamsimError(f"cannot add the EXIF IFD to {os.fspath(path)}: not a little-endian classic TIFF")
        ifd0 = struct.unpack("<I", header[4:])[0]
        fh.seek(ifd0)
        count = struct.unpack("<H", fh.read(2))[0]
        table = fh.read(12 * count)
        entry = next((ifd0 + 2 + 12 * i for i in range(count)
                      if struct.unpack("<H", table[12 * i: 12 * i + 2])[0] == _EXIF_IFD_STAND_IN), None)
        if entry is None:
            raise CamsimError(f"cannot add the EXIF IFD to {os.fspath(path)}: IFD0 has no ExifIFD stand-in")
        end = fh.seek(0, os.SEEK_END)
        start = end + end % 2  # IFDs begin on a word boundary
        data_at = start + 2 + 12 * len(entries) + 4
        ifd, data = struct.pack("<H", len(entries)), b""
        for tag, kind, n, value in entries:
            if len(value) <= 4:
                field = value.ljust(4, b"\x00")
            else:
                field = struct.pack("<I", data_at + len(data))
                data += value + b"\x00" * (len(value) % 2)
            ifd += struct.pack("<HHI", tag, kind, n) + field
        ifd += struct.pack("<I", 0)  # no next IFD
        fh.write(b"\x00" * (start - end) + ifd + data)
        fh.seek(entry)
        fh.write(struct.pack("<HHII", _EXIF_IFD, 4, 1, start))  # ExifIFD, LONG, 1: the IFD's offset


def _dng_tags(dtype: np.dtype, black_level_dn: Any, white_level: Any, unique_camera_model: str, color_matrix1: Any,
              as_shot_neutral: Any, calibration_illuminant1: int, make: str, model: str | None,
              pattern: str | None = None, noise_profile: Any = None, iso: Any = None,
              exposure_s: Any = None, color_matrix2: Any = None, calibration_illuminant2: Any = None,
              orientation: Any = 1) -> list[tuple]:
    """Validate the metadata shared by both writers and return tifffile ``extratags`` for the DNG tags.

    ``pattern`` None gives the tags of a 3-sample LinearRaw DNG (one BlackLevel and WhiteLevel per sample); a
    CFA pattern (one of :data:`CFA_PATTERNS`, already validated) gives those of a 1-sample CFA DNG: the CFA tags,
    one WhiteLevel, and the per-colour black levels mapped onto the 2x2 CFA positions. ``noise_profile`` (pairs
    (S, O), see :func:`_noise_profile`) adds the NoiseProfile tag; None omits it; ``iso`` or ``exposure_s``
    add the ExifIFD pointer's stand-in (:func:`_append_exif_ifd` makes it the pointer after the write).
    ``color_matrix2`` with ``calibration_illuminant2`` (both or neither) add ColorMatrix2 and
    CalibrationIlluminant2; ``orientation`` is the TIFF Orientation (1..8).
    """
    black = _per_sample(black_level_dn, "black_level_dn")
    white = _per_sample(white_level, "white_level")
    top = np.iinfo(dtype).max
    if np.any(white != np.round(white)) or np.any(white > top) or np.any(white <= black):
        raise CamsimError(f"white_level must be integers <= {top} above the black level, got {white.tolist()} "
                          f"(black level {black.tolist()})")
    cm = np.asarray(color_matrix1, dtype=np.float64)
    if cm.shape != (3, 3):
        raise CamsimError(f"color_matrix1 must be 3x3, got shape {cm.shape}")
    neutral = np.asarray(as_shot_neutral, dtype=np.float64)
    if neutral.shape != (3,) or not np.all(neutral > 0):
        raise CamsimError(f"as_shot_neutral must be 3 positive values, got {neutral.tolist()}")
    if not (isinstance(calibration_illuminant1, (int, np.integer)) and 0 <= calibration_illuminant1 <= 65535):
        raise CamsimError(f"calibration_illuminant1 must be an EXIF LightSource code, got {calibration_illuminant1!r}")
    second: list[tuple] = []
    if color_matrix2 is not None or calibration_illuminant2 is not None:
        cm2 = np.asarray(color_matrix2 if color_matrix2 is not None else np.nan, dtype=np.float64)
        if color_matrix2 is None or calibration_illuminant2 is None or cm2.shape != (3, 3):
            raise CamsimError("color_matrix2 (3x3) and calibration_illuminant2 go together, got "
                              f"{'no matrix' if color_matrix2 is None else f'shape {cm2.shape}'} and "
                              f"{calibration_illuminant2!r}")
        if (isinstance(calibration_illuminant2, bool) or not isinstance(calibration_illuminant2, (int, np.integer))
                or not 0 <= calibration_illuminant2 <= 65535):
            raise CamsimError(f"calibration_illuminant2 must be an EXIF LightSource code, got "
                              f"{calibration_illuminant2!r}")
        second = [(_COLOR_MATRIX2, "2i", 9, _rationals(cm2, "color_matrix2", signed=True), True),
                  (_CALIBRATION_ILLUMINANT2, "H", 1, int(calibration_illuminant2), True)]
    if not (isinstance(orientation, (int, np.integer)) and not isinstance(orientation, bool)
            and 1 <= orientation <= 8):
        raise CamsimError(f"orientation must be a TIFF Orientation, 1 to 8, got {orientation!r}")
    ucm = _ascii(unique_camera_model, "unique_camera_model")
    profile = _noise_profile(noise_profile)
    profile_tags = [] if profile is None else [(_NOISE_PROFILE, "d", len(profile), profile, True)]
    if pattern is None:
        layout_tags: list[tuple] = []
        # no BlackLevelRepeatDim: its default, 1 x 1, is the layout (one value per sample). RawTherapee 5.9 reads
        # the three values only without the tag: with it, it takes red's black from the (absent) per-position
        # value, 0 (docs, reference 'File formats')
        black_dim, black_values = None, black
        white_values = tuple(int(w) for w in white)
    else:
        if np.any(white != white[0]):
            raise CamsimError(f"white_level of a CFA DNG must be one value for all colours, got {white.tolist()}")
        codes = tuple(_CFA_CODE[c] for c in pattern)
        layout_tags = [
            (_CFA_REPEAT_PATTERN_DIM, "H", 2, (2, 2), True),
            (_CFA_PATTERN, "B", 4, codes, True),
            (_CFA_PLANE_COLOR, "B", 3, (0, 1, 2), True),
            (_CFA_LAYOUT, "H", 1, 1, True),  # rectangular (Cartesian) layout
        ]
        if np.all(black == black[0]):
            black_dim, black_values = (1, 1), black[:1]
        else:  # one value per CFA position, row by row
            black_dim, black_values = (2, 2), black[list(codes)]
        white_values = (int(white[0]),)
    return [  # (code, dtype, count, value, write-once); tifffile sorts tags by code
        (_MAKE, "s", 0, _ascii(make, "make"), True),
        (_MODEL, "s", 0, _ascii(ucm if model is None else model, "model"), True),
        (_ORIENTATION, "H", 1, int(orientation), True),
        *layout_tags,
        (_DNG_VERSION, "B", 4, (1, 4, 0, 0), True),
        (_DNG_BACKWARD_VERSION, "B", 4, (1, 1, 0, 0), True),
        (_UNIQUE_CAMERA_MODEL, "s", 0, ucm, True),
        *([] if black_dim is None else [(_BLACK_LEVEL_REPEAT_DIM, "H", 2, black_dim, True)]),
        (_BLACK_LEVEL, "2I", len(black_values), _rationals(black_values, "black_level_dn", signed=False), True),
        (_WHITE_LEVEL, "I", len(white_values), white_values, True),
        (_COLOR_MATRIX1, "2i", 9, _rationals(cm, "color_matrix1", signed=True), True),
        (_AS_SHOT_NEUTRAL, "2I", 3, _rationals(neutral, "as_shot_neutral", signed=False), True),
        (_CALIBRATION_ILLUMINANT1, "H", 1, int(calibration_illuminant1), True),
        *second,
        *profile_tags,
        *([(_EXIF_IFD_STAND_IN, "I", 1, 0, True)] if iso is not None or exposure_s is not None else []),
    ]


def _write(path: str | os.PathLike[str], frame: Any, cfa: bool, pattern: Any, black_level_dn: Any, white_level: Any,
           unique_camera_model: str, color_matrix1: Any, as_shot_neutral: Any, calibration_illuminant1: int,
           make: str, model: str | None, software: str | None, noise_profile: Any = None, iso: Any = None,
           exposure_s: Any = None, color_matrix2: Any = None, calibration_illuminant2: Any = None,
           orientation: Any = 1) -> None:
    """Validate everything, then write a three-chip (``cfa`` False, ``pattern`` None) or CFA DNG atomically."""
    name = os.fspath(path)
    try:
        if cfa:
            _check_mosaic(frame, pattern)
        else:
            _check_three_chip(frame)
        exif = _exif_entries(iso, exposure_s)
        extratags = _dng_tags(frame.dtype, black_level_dn, white_level, unique_camera_model, color_matrix1,
                              as_shot_neutral, calibration_illuminant1, make, model, pattern, noise_profile, iso,
                              exposure_s, color_matrix2, calibration_illuminant2, orientation)
        software_tag = _ascii(software, "software") if software is not None else False
    except (TypeError, ValueError) as exc:  # CamsimError is a ValueError; so are numpy's failed conversions
        raise CamsimError(f"cannot write DNG {name}: {exc}") from None
    if not cfa:
        pixels = np.ascontiguousarray(frame.transpose(1, 2, 0))  # (H, W, 3) interleaved
        layout: dict[str, Any] = dict(photometric=tifffile.PHOTOMETRIC.LINEAR_RAW, planarconfig="contig")
    else:
        pixels = np.ascontiguousarray(frame)  # (H, W), one sample per pixel
        layout = dict(photometric=tifffile.PHOTOMETRIC.CFA)
    with atomic_path(path) as tmp:
        tifffile.imwrite(
            tmp, pixels, subfiletype=0, compression=None, rowsperstrip=pixels.shape[0], extratags=extratags,
            software=software_tag, datetime=False, metadata=None,  # no DateTime tag, no tifffile JSON description
            byteorder="<", **layout,
        )
        if exif:
            _append_exif_ifd(tmp, exif)


def write_dng(path: str | os.PathLike[str], dn: np.ndarray, *, black_level_dn: float | Any, white_level: int | Any,
              unique_camera_model: str, color_matrix1: Any, as_shot_neutral: Any, calibration_illuminant1: int = 21,
              make: str = "camsim", model: str | None = None, software: str | None = None,
              noise_profile: Any = None, iso: float | None = None, exposure_s: float | None = None) -> None:
    """Write an uncompressed 8- or 16-bit three-chip LinearRaw DNG, atomically and byte-deterministically.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ``.dng`` file (its directory must exist).
    dn : numpy.ndarray, shape (3, H, W), dtype uint8 (uint16 for a 16-bit DNG)
        Planar R, G, B digital numbers [DN]. ``H, W >= 22`` (LibRaw's minimum size).
    black_level_dn : float or array_like, shape (3,)
        Black level per sample [DN], ``0 <= b < white_level``; stored as RATIONAL within :func:`rational_bound`
        (< 7.63e-6 DN up to 65535 DN), one value per sample without BlackLevelRepeatDim (LibRaw rounds them, see
        the module docstring).
    white_level : int or array_like of int, shape (3,)
        Saturation level per sample [DN], ``<= 255`` (``<= 65535`` for uint16: 2^nb − 1 for an nb-bit ADC) and
        above the black level.
    unique_camera_model : str
        DNG UniqueCameraModel (ASCII).
    color_matrix1 : array_like, shape (3, 3)
        XYZ -> camera matrix for ``calibration_illuminant1`` (DNG ColorMatrix1), stored as SRATIONAL.
    as_shot_neutral : array_like, shape (3,)
        Camera-space values of the scene white (DNG AsShotNeutral), positive, usually with max 1.
    calibration_illuminant1 : int, optional
        EXIF LightSource code of ``color_matrix1``'s illuminant; 21 = D65 (default), 17 = Standard light A.
    make, model, software : str, optional
        TIFF Make, Model (default: ``unique_camera_model``) and Software (omitted when None).
    noise_profile : array_like, shape (3, 2) or (1, 2), optional
        DNG NoiseProfile: per sample (R, G, B), or one for all, the pair (S, O) such that the temporal noise
        variance of a normalised value x = (DN − BlackLevel) / (WhiteLevel − BlackLevel) is S · x + O (unitless;
        :func:`camsim.sensor.noise_profile.dng_noise_profile`). S > 0, O >= 0, stored as DOUBLE. None (default): no tag.
    iso : float, optional
        The camera's ISO setting: ISOSpeedRatings (EXIF PhotographicSensitivity, tag 34855, SHORT, rounded; above
        65535 it holds 65535 and SensitivityType 3 with ISOSpeed, tag 34867, the value), in the EXIF IFD. None
        (default): no tag.
    exposure_s : float, optional
        Exposure time [s], > 0: ExposureTime (tag 33434, RATIONAL), in the EXIF IFD. None (default): no tag.

    Raises
    ------
    CamsimError
        If ``dn`` is not a ``(3, H, W)`` uint8 or uint16 array with ``H, W >= 22``, or a metadata value (the
        noise profile included) is out of range.

    Notes
    -----
    The file has no date/time or other varying content: the same inputs give byte-identical files.
    """
    _write(path, dn, False, None, black_level_dn, white_level, unique_camera_model, color_matrix1, as_shot_neutral,
           calibration_illuminant1, make, model, software, noise_profile, iso, exposure_s)


def write_dng_cfa(path: str | os.PathLike[str], mosaic: np.ndarray, *, pattern: str, black_level_dn: float | Any,
                  white_level: int, unique_camera_model: str, color_matrix1: Any, as_shot_neutral: Any,
                  calibration_illuminant1: int = 21, make: str = "camsim", model: str | None = None,
                  software: str | None = None, noise_profile: Any = None, iso: float | None = None,
                  exposure_s: float | None = None, color_matrix2: Any = None,
                  calibration_illuminant2: int | None = None, orientation: int = 1) -> None:
    """Write an uncompressed Bayer (CFA) DNG, atomically and byte-deterministically.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ``.dng`` file (its directory must exist).
    mosaic : numpy.ndarray, shape (H, W), dtype uint8 (uint16 for a 16-bit DNG)
        One digital number per pixel [DN], each of the colour its CFA position has. ``H, W`` even and ``>= 22``
        (LibRaw's minimum size).
    pattern : {"RGGB", "BGGR", "GRBG", "GBRG"}
        Colours of the 2x2 cell's top-left, top-right, bottom-left and bottom-right pixels; the cell at the
        mosaic's top-left corner.
    black_level_dn : float or array_like, shape (3,)
        Black level per colour (R, G, B) [DN], stored as RATIONAL (within :func:`rational_bound`) per CFA position
        (BlackLevelRepeatDim (2, 2)), or as one value when all three are equal. LibRaw truncates fractional
        values (module docstring).
    white_level : int
        Saturation level [DN] of all pixels, ``<= 255`` (``<= 65535`` for uint16) and above the black levels; 3
        equal values are accepted too.
    unique_camera_model, color_matrix1, as_shot_neutral, calibration_illuminant1, make, model, software, iso, exposure_s
        As for :func:`write_dng`; ``color_matrix1`` maps XYZ to the camera's R, G, B (CFAPlaneColor order).
    noise_profile : array_like, shape (3, 2) or (1, 2), optional
        As for :func:`write_dng`, per colour plane in CFAPlaneColor order (R, G, B); None (default): no tag.
    color_matrix2 : array_like, shape (3, 3), optional
        A second XYZ -> camera matrix (DNG ColorMatrix2), for ``calibration_illuminant2``; both or neither (None,
        the default: no tags), so that a file made from a camera's raw keeps both of its matrices.
    calibration_illuminant2 : int, optional
        EXIF LightSource code of ``color_matrix2``'s illuminant (DNG CalibrationIlluminant2).
    orientation : int, optional
        TIFF Orientation, 1 (default: as stored) to 8, how a reader turns the stored image to show it.

    Raises
    ------
    CamsimError
        Naming ``path``, if ``mosaic`` is not an ``(H, W)`` uint8/uint16 array with even ``H, W >= 22``,
        ``pattern`` is not one of the four, or a metadata value is out of range. No file is created then.

    Notes
    -----
    The file has no date/time or other varying content: the same inputs give byte-identical files.
    """
    _write(path, mosaic, True, pattern, black_level_dn, white_level, unique_camera_model, color_matrix1,
           as_shot_neutral, calibration_illuminant1, make, model, software, noise_profile, iso, exposure_s,
           color_matrix2, calibration_illuminant2, orientation)


#: darktable's sidecar of ``NAME.dng``: ``NAME.dng.xmp`` (its default naming, read on import and by darktable-cli).
DARKTABLE_XMP_SUFFIX = ".dng.xmp"

_DARKTABLE_XMP = """<?xml version="1.0" encoding="UTF-8"?>
<x:xmpmeta xmlns:x="adobe:ns:meta/">
 <rdf:RDF xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">
  <rdf:Description rdf:about=""
    xmlns:darktable="http://darktable.sf.net/"
   darktable:xmp_version="5"
   darktable:history_end="1"
   darktable:auto_presets_applied="0">
   <darktable:history>
    <rdf:Seq>
     <rdf:li
      darktable:num="0"
      darktable:operation="rawprepare"
      darktable:enabled="1"
      darktable:modversion="2"
      darktable:params="{params}"
      darktable:multi_name=""
      darktable:multi_priority="0"/>
    </rdf:Seq>
   </darktable:history>
  </rdf:Description>
 </rdf:RDF>
</x:xmpmeta>
"""


def darktable_xmp(black_level_dn: Any, white_level: Any) -> str:
    """darktable's sidecar (``NAME.dng.xmp``) for a three-chip DNG: its black levels in the "raw black/white point"
    module, which darktable cannot take from the DNG.

    darktable's raw decoder (rawspeed, ``DngDecoder::decodeBlackLevels``) reads no BlackLevel of an image of more
    than one sample per pixel, so it develops a three-chip DNG from black 0. The sidecar holds one history item,
    the ``rawprepare`` module (parameters version 2, darktable 4.2 and later: crop 0, 0, 0, 0; four 16-bit black
    levels; the white point); darktable applies its default modules as well (``auto_presets_applied`` 0). For an
    image without a colour filter array ``rawprepare`` subtracts one level from all channels, the mean of its four
    (``commit_params``), so the four are integers whose mean is the mean of the three samples' levels to 1/8 DN:
    each channel is then off by its level's distance from that mean (docs, reference 'File formats'),
    where darktable without the sidecar is off by the whole level. Other readers ignore the file; the DNG is
    unchanged.

    Parameters
    ----------
    black_level_dn : float or array_like, shape (3,)
        The DNG's BlackLevel per sample R, G, B [DN], ``< 65535.5``.
    white_level : int or array_like of int, shape (3,)
        The DNG's WhiteLevel [DN], ``<= 65535`` (the largest of three is taken: darktable keeps one).

    Returns
    -------
    str
        The XMP text (UTF-8).
    """
    quarters = math.floor(4 * float(np.mean(_per_sample(black_level_dn, "black_level_dn"))) + 0.5)
    black = [quarters // 4 + (i < quarters % 4) for i in range(4)]  # four integers, mean quarters / 4
    white = int(np.max(_per_sample(white_level, "white_level")))
    if not (all(0 <= b <= 65535 for b in black) and 0 < white <= 65535):
        raise CamsimError(f"darktable keeps 16-bit levels: black {black}, white {white}")
    params = struct.pack("<4i4HHxxi", 0, 0, 0, 0, *black, white, 0)  # flat field off
    return _DARKTABLE_XMP.format(params=params.hex())


def _tag(page: Any, code: int) -> Any:
    tag = page.tags.get(code)
    return None if tag is None else tag.value


def _floats(rationals: Any) -> list[float] | None:
    if rationals is None:
        return None
    vals = np.atleast_1d(np.asarray(rationals, dtype=np.float64)).ravel()
    with np.errstate(divide="ignore", invalid="ignore"):  # a zero denominator (a damaged file): inf or NaN, which
        return (vals[0::2] / vals[1::2]).tolist()           # the readers' checks then refuse on one line


def _pairs(values: Any) -> list[list[float]] | None:
    """The NoiseProfile tag's DOUBLEs as pairs [S, O]."""
    if values is None:
        return None
    return np.reshape(np.atleast_1d(np.asarray(values, dtype=np.float64)), (-1, 2)).tolist()


def _cfa_pattern(page: Any, name: str) -> str:
    """The 2x2 CFA pattern of a CFA DNG page, e.g. ``"RGGB"``; CamsimError for any other CFA layout."""
    dim = _tag(page, _CFA_REPEAT_PATTERN_DIM)
    codes = _tag(page, _CFA_PATTERN)
    planes = _tag(page, _CFA_PLANE_COLOR)
    letters = "".join("RGB"[c] if c < 3 else "?" for c in bytes(codes)) if codes is not None else None
    if (dim is None or tuple(dim) != (2, 2) or letters not in CFA_PATTERNS
            or (planes is not None and bytes(planes) != bytes((0, 1, 2)))):
        raise CamsimError(f"cannot read DNG {name}: unsupported CFA layout (CFARepeatPatternDim {dim}, CFAPattern "
                          f"{None if codes is None else tuple(bytes(codes))}, CFAPlaneColor "
                          f"{None if planes is None else tuple(bytes(planes))}); expected a 2x2 Bayer pattern "
                          f"({', '.join(CFA_PATTERNS)})")
    return letters


def _cfa_black_per_colour(page: Any, pattern: str, name: str) -> list[float] | None:
    """The BlackLevel tag of a CFA DNG as R, G, B values (from the first CFA position of each colour)."""
    values = _floats(_tag(page, _BLACK_LEVEL))
    if values is None:
        return None
    dim = tuple(_tag(page, _BLACK_LEVEL_REPEAT_DIM) or (1, 1))
    if dim == (1, 1) and len(values) == 1:
        return values * 3
    if dim == (2, 2) and len(values) == 4:
        return [values[pattern.index(c)] for c in "RGB"]
    raise CamsimError(f"cannot read DNG {name}: unsupported BlackLevel layout (repeat {dim}, {len(values)} values)")


def shot_metadata(page: Any) -> dict[str, Any]:
    """``iso`` (float or None: ISOSpeed where SensitivityType is 3 and ISOSpeedRatings says 65535, else
    ISOSpeedRatings) and ``exposure_s`` (float [s] or None: ExposureTime) of a TIFF page (a tifffile page, IFD0 or
    its EXIF IFD), as :func:`write_dng` writes them and cameras do."""
    tags = dict(page.tags.items())
    exif = _tag(page, 34665)  # the EXIF IFD, which tifffile reads into a dict by tag name
    named = exif if isinstance(exif, dict) else {}

    def first(code: int, name: str) -> Any:
        tag = tags.get(code)
        return tag.value if tag is not None else named.get(name)

    ratings = first(_ISO_SPEED_RATINGS, "ISOSpeedRatings")
    if isinstance(ratings, (tuple, list)):
        ratings = ratings[0] if ratings else None
    speed = first(_ISO_SPEED, "ISOSpeed")
    iso = float(speed) if (ratings in (None, 65535) and speed and first(_SENSITIVITY_TYPE, "SensitivityType") in
                           (2, 3, 6, 7)) else (float(ratings) if ratings else None)
    exposure = first(_EXPOSURE_TIME, "ExposureTime")
    if isinstance(exposure, (tuple, list)) and len(exposure) == 2 and exposure[1]:
        exposure = exposure[0] / exposure[1]
    exposure_s = float(exposure) if isinstance(exposure, (int, float)) and exposure > 0 else None
    return {"iso": iso, "exposure_s": exposure_s}


def _check_complete(page: Any, size: int, name: str) -> None:
    """Refuse a file that ends before its pixel data does (a truncated copy), before LibRaw reads it: LibRaw
    would print its own complaint on stderr besides failing."""
    end = max((o + c for o, c in zip(page.dataoffsets, page.databytecounts)), default=0)
    if end > size:
        raise CamsimError(f"cannot read DNG {name}: truncated: the file has {size} bytes but its pixel data runs to "
                          f"byte {end}")


#: The ActiveArea tag (top, left, bottom, right): the part of the raw IFD that holds image pixels.
ACTIVE_AREA_TAG = 50829


def check_active_area(page: Any, name: str) -> None:
    """Refuse an ActiveArea that is not a rectangle inside the raw IFD's image, from the header: LibRaw crops by it
    and reads past the pixel data (printing "Unexpected end of file" on stderr besides failing)."""
    tag = page.tags.get(ACTIVE_AREA_TAG)
    if tag is None:
        return
    try:
        top, left, bottom, right = (int(v) for v in np.ravel(tag.value))
    except (TypeError, ValueError):
        raise CamsimError(f"cannot read DNG {name}: its ActiveArea is not 4 numbers (top, left, bottom, right)") \
            from None
    if not (0 <= top < bottom <= page.imagelength and 0 <= left < right <= page.imagewidth):
        raise CamsimError(f"cannot read DNG {name}: its ActiveArea ({top}, {left}, {bottom}, {right}) is not inside "
                          f"its {page.imagewidth}x{page.imagelength} image")


@contextlib.contextmanager
def _tifffile_quiet():
    """tifffile's logger silenced: its complaints about a damaged header ("incorrect StripByteCounts count") would
    reach stderr as extra lines; the reader reports what is wrong on one line itself."""
    logger = logging.getLogger("tifffile")
    disabled, logger.disabled = logger.disabled, True
    try:
        yield
    finally:
        logger.disabled = disabled


def _check_storage(page: Any, name: str) -> None:
    """Refuse, from the header alone, a pixel layout this reader does not decode as written: any Compression but
    1 (uncompressed; LibRaw would decode uncompressed bytes under a JPEG tag as zeros), BitsPerSample values that
    differ between samples, planar (not interleaved) samples, and strips or tiles whose byte counts do not add up
    to the image's size."""
    compression = int(page.compression)
    if compression != 1:
        try:
            what = tifffile.COMPRESSION(compression).name
        except ValueError:
            what = "unknown"
        raise CamsimError(f"cannot read DNG {name}: Compression tag {compression} ({what}); camsim reads "
                          "uncompressed DNGs (Compression 1) only")
    bits_tag = _tag(page, 258)
    bits_each = tuple(bits_tag) if isinstance(bits_tag, (tuple, list)) else (bits_tag,)
    if len(set(bits_each)) != 1 or (len(bits_each) != 1 and len(bits_each) != page.samplesperpixel):
        raise CamsimError(f"cannot read DNG {name}: BitsPerSample {list(bits_each)} for {page.samplesperpixel} "
                          "sample(s); expected one depth for every sample")
    if page.samplesperpixel > 1 and int(page.planarconfig) != 1:
        raise CamsimError(f"cannot read DNG {name}: planar samples (PlanarConfiguration {int(page.planarconfig)}); "
                          "expected interleaved (1)")
    sample_bytes = page.samplesperpixel * page.bitspersample // 8
    if page.is_tiled:
        tiles = -(-page.imagelength // page.tilelength) * -(-page.imagewidth // page.tilewidth)
        expected = [page.tilelength * page.tilewidth * sample_bytes] * tiles
        what = "tile(s)"
    else:
        rows = page.rowsperstrip if 0 < page.rowsperstrip < page.imagelength else page.imagelength
        expected = [min(rows, page.imagelength - start) * page.imagewidth * sample_bytes
                    for start in range(0, page.imagelength, rows)]
        what = "strip(s)"
    counts = [int(c) for c in page.databytecounts]
    if counts != expected:
        raise CamsimError(f"cannot read DNG {name}: its {len(counts)} {what} hold {sum(counts)} bytes, but a "
                          f"{page.imagewidth}x{page.imagelength} image of {page.samplesperpixel} sample(s) of "
                          f"{page.bitspersample} bits in {len(expected)} {what} takes {sum(expected)} "
                          f"({', '.join(map(str, expected[:4]))}{' …' if len(expected) > 4 else ''})")


def read_dng(path: str | os.PathLike[str]) -> tuple[np.ndarray, dict[str, Any]]:
    """Read a DNG written by :func:`write_dng` or :func:`write_dng_cfa`; pixels and levels through LibRaw.

    Parameters
    ----------
    path : str or os.PathLike
        A three-sample LinearRaw DNG or a 2x2 Bayer CFA DNG, 8- or 16-bit, uncompressed.

    Returns
    -------
    dn : numpy.ndarray, shape (3, H, W) or (1, H, W), dtype uint8 (uint16 for a 16-bit DNG)
        Planar R, G, B digital numbers [DN] of a three-chip file, or the mosaic of a CFA file, as decoded by
        LibRaw (``rawpy``).
    info : dict
        ``cfa_pattern`` (str such as ``"RGGB"`` for a CFA file, None for a three-chip one), ``black_level`` (list
        of 3 int, LibRaw's per-channel black level for R, G, B [DN], rounded for LinearRaw and truncated for CFA
        files), ``black_level_exact`` (list of 3 float, the BlackLevel tag; for a CFA file per colour R, G, B),
        ``white_level`` (int [DN], LibRaw), ``unique_camera_model``, ``make``, ``model`` (str or None),
        ``as_shot_neutral`` (list of 3 float), ``color_matrix1`` (3x3 nested list, XYZ -> camera) and
        ``calibration_illuminant1`` (int or None), ``color_matrix2`` and ``calibration_illuminant2`` (None where
        the file has no second matrix), ``orientation`` (int, the TIFF Orientation, 1 where absent),
        ``noise_profile`` (list of [S, O] pairs, per sample or CFA
        plane colour, or None), ``iso`` (float or None) and ``exposure_s`` (float [s] or None), from the DNG tags
        (:func:`shot_metadata`).

    Raises
    ------
    CamsimError
        Naming ``path``, if the file is missing, not a regular file (a FIFO, a device, a directory), unreadable,
        truncated, not a DNG, or neither 3-sample LinearRaw
        nor 1-sample 2x2 Bayer CFA of 8 or 16 bits, or its header declares a storage this reader does not decode
        (compressed, planar, byte counts that do not fit the dimensions: :func:`_check_storage`), before any
        pixel is decoded.
    """
    import rawpy  # imported lazily: only readers of DNGs need LibRaw

    name = os.fspath(check_input(path, "DNG"))  # a FIFO or a device would block tifffile and LibRaw
    try:
        with _tifffile_quiet(), tifffile.TiffFile(name) as tif:
            page = tif.pages.first
            if _tag(page, _DNG_VERSION) is None:
                raise CamsimError(f"cannot read DNG {name}: not a DNG (no DNGVersion tag)")
            if (page.photometric == tifffile.PHOTOMETRIC.CFA and page.samplesperpixel == 1
                    and page.bitspersample in (8, 16)):
                pattern: str | None = _cfa_pattern(page, name)
                black_exact = _cfa_black_per_colour(page, pattern, name)
            elif (page.photometric == tifffile.PHOTOMETRIC.LINEAR_RAW and page.samplesperpixel == 3
                    and page.bitspersample in (8, 16)):
                pattern = None
                black_exact = _floats(_tag(page, _BLACK_LEVEL))
            else:
                raise CamsimError(f"cannot read DNG {name}: not an 8/16-bit 3-sample LinearRaw or 1-sample CFA DNG "
                                  f"(photometric {int(page.photometric)}, {page.samplesperpixel} samples, "
                                  f"{page.bitspersample} bits)")
            bits = page.bitspersample
            shape = (page.imagelength, page.imagewidth)
            check_pixel_count(page.imagewidth, page.imagelength, f"DNG {name}")  # from the header, before decoding
            _check_storage(page, name)
            _check_complete(page, tif.filehandle.size, name)
            check_active_area(page, name)
            cm = _floats(_tag(page, _COLOR_MATRIX1))
            cm2 = _floats(_tag(page, _COLOR_MATRIX2))
            info: dict[str, Any] = {
                "cfa_pattern": pattern,
                "unique_camera_model": _tag(page, _UNIQUE_CAMERA_MODEL),
                "make": _tag(page, _MAKE),
                "model": _tag(page, _MODEL),
                "black_level_exact": black_exact,
                "as_shot_neutral": _floats(_tag(page, _AS_SHOT_NEUTRAL)),
                "color_matrix1": None if cm is None else np.reshape(cm, (3, 3)).tolist(),
                "calibration_illuminant1": _tag(page, _CALIBRATION_ILLUMINANT1),
                "color_matrix2": None if cm2 is None else np.reshape(cm2, (3, 3)).tolist(),
                "calibration_illuminant2": _tag(page, _CALIBRATION_ILLUMINANT2),
                "orientation": int(_tag(page, _ORIENTATION) or 1),
                "noise_profile": _pairs(_tag(page, _NOISE_PROFILE)),
                **shot_metadata(page),
            }
        with rawpy.imread(name) as raw:
            image = raw.raw_image
            if pattern is None:  # (H, W, 4) uint16 for a 3-colour stack: channel 3 is unused
                if (raw.raw_type != rawpy.RawType.Stack or raw.num_colors != 3 or image.ndim != 3
                        or image.shape[2] < 3):
                    raise CamsimError(f"cannot read DNG {name}: LibRaw did not decode a 3-colour stacked image")
                black = [int(b) for b in raw.black_level_per_channel[:3]]
                planes = image[..., :3].transpose(2, 0, 1)
            else:  # (H, W) uint16 mosaic; LibRaw's colour indices name colours through color_desc (b"RGBG")
                desc = raw.color_desc.decode("ascii", "replace")
                cell = raw.raw_pattern
                decoded = ("".join(desc[i] if i < len(desc) else "?" for i in cell.ravel())
                           if cell is not None and cell.shape == (2, 2) else None)
                if (raw.raw_type != rawpy.RawType.Flat or raw.num_colors != 3 or image.shape != shape
                        or decoded != pattern):
                    raise CamsimError(f"cannot read DNG {name}: LibRaw did not decode a {shape[0]}x{shape[1]} "
                                      f"{pattern} mosaic (got {image.shape}, pattern {decoded})")
                black = [int(raw.black_level_per_channel[desc.index(c)]) for c in "RGB"]
                planes = image[None]
            white = int(raw.white_level)
            dtype = np.uint8 if bits == 8 else np.uint16
            if planes.max(initial=0) > np.iinfo(dtype).max:
                raise CamsimError(f"cannot read DNG {name}: decoded values exceed {bits} bits")
            # always a copy: raw_image is a view of LibRaw's buffer, freed when the file is closed (for a uint16
            # mosaic a mere ascontiguousarray would return that view itself)
            dn = np.array(planes, dtype=dtype, order="C", copy=True)
    except CamsimError:
        raise
    except Exception as exc:  # rawpy.LibRawError, tifffile.TiffFileError, OSError, struct errors on truncation...
        raise CamsimError(f"cannot read DNG {name}: {type(exc).__name__}: {exc}") from exc
    info["black_level"] = black
    info["white_level"] = white
    return dn, info
