"""Three-chip LinearRaw DNG writer and reader (8-bit; 16-bit containers for ADCs of more than 8 bits).

The simulator's digital numbers are stored as an uncompressed, interleaved, 8-bit, 3-sample LinearRaw DNG (one
R, G and B value per pixel, no mosaic) written with :mod:`tifffile`, so that LibRaw (``rawpy``), dcraw-style raw
developers and Adobe tools read the exact numbers. Deflate compression is deliberately not used: LibRaw cannot
read deflate-compressed DNGs.

What LibRaw 0.22 (rawpy 0.28) makes of these files, measured and pinned by ``tests/test_io_dng.py``:

* ``raw_type`` is ``RawType.Stack`` and ``raw_image`` (and ``raw_image_visible``) is an ``(H, W, 4)`` uint16 array:
  LibRaw always stores colour-stacked images with four channels. Channels 0..2 are exactly the written R, G, B
  numbers; channel 3 is all zeros. ``raw_colors`` raises (the image is not flat).
* ``black_level_per_channel`` is ``[b_R, b_G, b_B, 0]`` as integers: LibRaw rounds a fractional BlackLevel to the
  nearest integer with halves rounded up (``floor(b + 0.5)``: 16.4 -> 16, 16.5 -> 17). The exact fractional value
  stays in the file and :func:`read_dng` returns it too.
* ``white_level`` is the WhiteLevel written (e.g. 255).
* LibRaw rejects images smaller than 22 pixels in either dimension, so :func:`write_dng` refuses them.
"""

from __future__ import annotations

import math
import os
from fractions import Fraction
from typing import Any

import numpy as np
import tifffile

from camsim.errors import CamsimError
from camsim.io.atomic import atomic_path

__all__ = ["write_dng", "read_dng", "MIN_SIZE"]

MIN_SIZE = 22  # LibRaw refuses raw images narrower or shorter than this (measured with LibRaw 0.22)
_MAX_DEN = 1_000_000  # largest rational denominator: floats are stored with absolute error below 1e-6

# DNG tag codes
_DNG_VERSION, _DNG_BACKWARD_VERSION, _UNIQUE_CAMERA_MODEL = 50706, 50707, 50708
_BLACK_LEVEL_REPEAT_DIM, _BLACK_LEVEL, _WHITE_LEVEL = 50713, 50714, 50717
_COLOR_MATRIX1, _AS_SHOT_NEUTRAL, _CALIBRATION_ILLUMINANT1 = 50721, 50728, 50778
_MAKE, _MODEL, _ORIENTATION = 271, 272, 274


def _rationals(values: Any, name: str, *, signed: bool) -> tuple[int, ...]:
    """Flatten floats into TIFF (S)RATIONAL pairs ``(num0, den0, num1, den1, ...)``, exactly reproducibly."""
    out: list[int] = []
    for v in np.asarray(values, dtype=np.float64).ravel():
        if not math.isfinite(v) or (not signed and v < 0):
            raise CamsimError(f"{name} must be finite{'' if signed else ' and non-negative'}, got {v!r}")
        f = Fraction(float(v)).limit_denominator(_MAX_DEN)
        lo, hi = (-(2**31), 2**31 - 1) if signed else (0, 2**32 - 1)
        if not lo <= f.numerator <= hi:
            raise CamsimError(f"{name} value {v!r} does not fit a TIFF {'S' if signed else ''}RATIONAL")
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


def _dng_tags(dn: Any, black_level_dn: Any, white_level: Any, unique_camera_model: str, color_matrix1: Any,
              as_shot_neutral: Any, calibration_illuminant1: int, make: str, model: str | None) -> list[tuple]:
    """Validate :func:`write_dng`'s inputs and return tifffile ``extratags`` for the DNG tags."""
    if (not isinstance(dn, np.ndarray) or dn.dtype not in (np.uint8, np.uint16) or dn.ndim != 3
            or dn.shape[0] != 3):
        raise CamsimError(f"dn must be a uint8 or uint16 array of shape (3, H, W), got "
                          f"{getattr(dn, 'dtype', type(dn).__name__)} {getattr(dn, 'shape', '')}")
    if min(dn.shape[1:]) < MIN_SIZE:
        raise CamsimError(f"frame {dn.shape[1]}x{dn.shape[2]} is smaller than {MIN_SIZE}x{MIN_SIZE}, which LibRaw "
                          "cannot read")
    black = _per_sample(black_level_dn, "black_level_dn")
    white = _per_sample(white_level, "white_level")
    top = np.iinfo(dn.dtype).max
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
    ucm = _ascii(unique_camera_model, "unique_camera_model")
    return [  # (code, dtype, count, value, write-once); tifffile sorts tags by code
        (_MAKE, "s", 0, _ascii(make, "make"), True),
        (_MODEL, "s", 0, _ascii(ucm if model is None else model, "model"), True),
        (_ORIENTATION, "H", 1, 1, True),
        (_DNG_VERSION, "B", 4, (1, 4, 0, 0), True),
        (_DNG_BACKWARD_VERSION, "B", 4, (1, 1, 0, 0), True),
        (_UNIQUE_CAMERA_MODEL, "s", 0, ucm, True),
        (_BLACK_LEVEL_REPEAT_DIM, "H", 2, (1, 1), True),
        (_BLACK_LEVEL, "2I", 3, _rationals(black, "black_level_dn", signed=False), True),
        (_WHITE_LEVEL, "I", 3, tuple(int(w) for w in white), True),
        (_COLOR_MATRIX1, "2i", 9, _rationals(cm, "color_matrix1", signed=True), True),
        (_AS_SHOT_NEUTRAL, "2I", 3, _rationals(neutral, "as_shot_neutral", signed=False), True),
        (_CALIBRATION_ILLUMINANT1, "H", 1, int(calibration_illuminant1), True),
    ]


def write_dng(path: str | os.PathLike[str], dn: np.ndarray, *, black_level_dn: float | Any, white_level: int | Any,
              unique_camera_model: str, color_matrix1: Any, as_shot_neutral: Any, calibration_illuminant1: int = 21,
              make: str = "camsim", model: str | None = None, software: str | None = None) -> None:
    """Write an uncompressed 8-bit three-chip LinearRaw DNG, atomically and byte-deterministically.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ``.dng`` file (its directory must exist).
    dn : numpy.ndarray, shape (3, H, W), dtype uint8 (uint16 for a 16-bit DNG)
        Planar R, G, B digital numbers [DN]. ``H, W >= 22`` (LibRaw's minimum size).
    black_level_dn : float or array_like, shape (3,)
        Black level per sample [DN]; fractional values are stored exactly as RATIONAL (LibRaw rounds them, see
        the module docstring).
    white_level : int or array_like of int, shape (3,)
        Saturation level per sample [DN], ``<= 255`` and above the black level.
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

    Raises
    ------
    CamsimError
        If ``dn`` is not a ``(3, H, W)`` uint8 array with ``H, W >= 22``, or a metadata value is out of range.

    Notes
    -----
    The file has no date/time or other varying content: the same inputs give byte-identical files.
    """
    name = os.fspath(path)
    try:
        extratags = _dng_tags(dn, black_level_dn, white_level, unique_camera_model, color_matrix1, as_shot_neutral,
                              calibration_illuminant1, make, model)
        software_tag = _ascii(software, "software") if software is not None else False
    except (TypeError, ValueError) as exc:  # CamsimError is a ValueError; so are numpy's failed conversions
        raise CamsimError(f"cannot write DNG {name}: {exc}") from None
    pixels = np.ascontiguousarray(dn.transpose(1, 2, 0))  # (H, W, 3) interleaved
    with atomic_path(path) as tmp:
        tifffile.imwrite(
            tmp, pixels, photometric=tifffile.PHOTOMETRIC.LINEAR_RAW, planarconfig="contig", subfiletype=0,
            compression=None, rowsperstrip=pixels.shape[0], extratags=extratags, software=software_tag,
            datetime=False, metadata=None,  # no DateTime tag, no tifffile JSON ImageDescription
        )


def _tag(page: Any, code: int) -> Any:
    tag = page.tags.get(code)
    return None if tag is None else tag.value


def _floats(rationals: Any) -> list[float] | None:
    if rationals is None:
        return None
    vals = np.atleast_1d(np.asarray(rationals, dtype=np.float64)).ravel()
    return (vals[0::2] / vals[1::2]).tolist()


def read_dng(path: str | os.PathLike[str]) -> tuple[np.ndarray, dict[str, Any]]:
    """Read a DNG written by :func:`write_dng`; pixels and levels through LibRaw (``rawpy``).

    Parameters
    ----------
    path : str or os.PathLike
        A three-sample 8-bit LinearRaw DNG.

    Returns
    -------
    dn : numpy.ndarray, shape (3, H, W), dtype uint8 (uint16 for a 16-bit DNG)
        Planar R, G, B digital numbers [DN], as decoded by LibRaw.
    info : dict
        ``black_level`` (list of 3 int, LibRaw's rounded per-channel black level [DN]), ``black_level_exact``
        (list of 3 float, the BlackLevel tag), ``white_level`` (int [DN], LibRaw), ``unique_camera_model``,
        ``make``, ``model`` (str or None), ``as_shot_neutral`` (list of 3 float), ``color_matrix1`` (3x3 nested
        list, XYZ -> camera) and ``calibration_illuminant1`` (int or None), from the DNG tags.

    Raises
    ------
    CamsimError
        Naming ``path``, if the file is missing, unreadable, truncated, not a DNG, or not 3-sample 8-bit LinearRaw.
    """
    import rawpy  # imported lazily: only readers of DNGs need LibRaw

    name = os.fspath(path)
    try:
        with tifffile.TiffFile(name) as tif:
            page = tif.pages.first
            if _tag(page, _DNG_VERSION) is None:
                raise CamsimError(f"cannot read DNG {name}: not a DNG (no DNGVersion tag)")
            if (page.photometric != tifffile.PHOTOMETRIC.LINEAR_RAW or page.samplesperpixel != 3
                    or page.bitspersample not in (8, 16)):
                raise CamsimError(f"cannot read DNG {name}: not an 8/16-bit 3-sample LinearRaw DNG (photometric "
                                  f"{int(page.photometric)}, {page.samplesperpixel} samples, "
                                  f"{page.bitspersample} bits)")
            bits = page.bitspersample
            cm = _floats(_tag(page, _COLOR_MATRIX1))
            info: dict[str, Any] = {
                "unique_camera_model": _tag(page, _UNIQUE_CAMERA_MODEL),
                "make": _tag(page, _MAKE),
                "model": _tag(page, _MODEL),
                "black_level_exact": _floats(_tag(page, _BLACK_LEVEL)),
                "as_shot_neutral": _floats(_tag(page, _AS_SHOT_NEUTRAL)),
                "color_matrix1": None if cm is None else np.reshape(cm, (3, 3)).tolist(),
                "calibration_illuminant1": _tag(page, _CALIBRATION_ILLUMINANT1),
            }
        with rawpy.imread(name) as raw:
            image = raw.raw_image  # (H, W, 4) uint16 for a 3-colour stack: channel 3 is unused
            if raw.raw_type != rawpy.RawType.Stack or raw.num_colors != 3 or image.ndim != 3 or image.shape[2] < 3:
                raise CamsimError(f"cannot read DNG {name}: LibRaw did not decode a 3-colour stacked image")
            black = [int(b) for b in raw.black_level_per_channel[:3]]
            white = int(raw.white_level)
            pixels = image[..., :3]
            dtype = np.uint8 if bits == 8 else np.uint16
            if pixels.max(initial=0) > np.iinfo(dtype).max:
                raise CamsimError(f"cannot read DNG {name}: decoded values exceed {bits} bits")
            dn = np.ascontiguousarray(pixels.transpose(2, 0, 1), dtype=dtype)
    except CamsimError:
        raise
    except Exception as exc:  # rawpy.LibRawError, tifffile.TiffFileError, OSError, struct errors on truncation...
        raise CamsimError(f"cannot read DNG {name}: {type(exc).__name__}: {exc}") from exc
    info["black_level"] = black
    info["white_level"] = white
    return dn, info
