"""A real camera's raw file in: its Bayer mosaic, CFA pattern, black and white levels, and the shot's metadata.

Any file LibRaw (``rawpy``) reads — DNG, ARW, NEF, CR2, CR3, RAF, ... — whose sensor is a 2 × 2 RGB Bayer mosaic
(three-chip, monochrome, X-Trans and four-colour files are refused). LibRaw decodes the pixels: its visible area
(``raw_image_visible``: the sensor without its masked margins; a DNG's ActiveArea) is the image, optionally cropped.
What else the file says is read from its tags where the container is TIFF (DNG, NEF, CR2, ARW, ...), with tifffile,
else from LibRaw:

=============================  ===================================  ==========================================
field                          DNG (tags; levels from the raw IFD)  other raws (LibRaw)
=============================  ===================================  ==========================================
``cfa``                        CFARepeatPatternDim, CFAPattern      ``raw_colors_visible``, ``color_desc``
``black_dn``                   BlackLevelRepeatDim, BlackLevel      ``black_level_per_channel`` by site colour
``white_dn``                   WhiteLevel (default 2^bits − 1)      ``white_level``
``iso``                        ISOSpeedRatings (ISOSpeed > 65535)   TIFF tags, else ``other.iso_speed``
``exposure_s``                 ExposureTime (IFD0 or EXIF IFD)      TIFF tags, else ``other.shutter_speed``
``make``, ``model``            Make, Model, UniqueCameraModel       TIFF tags, else None
``color_matrix1/2``            ColorMatrix1/2                       ``rgb_xyz_matrix`` (Adobe's, D65)
``calibration_illuminant1/2``  CalibrationIlluminant1/2             21 (D65) for that matrix
``as_shot_neutral``            AsShotNeutral                        G / ``camera_whitebalance``
``orientation``                Orientation                          TIFF tag, else ``sizes.flip`` mapped
=============================  ===================================  ==========================================

A DNG's levels and pattern are checked against LibRaw's reading of the same file (one line naming both when they
disagree): the pattern exactly, the white level exactly, the black level of each site to within 1 DN (LibRaw
truncates fractional levels). The DNG specification anchors the CFA pattern and the black-level pattern at the
ActiveArea's top-left corner; LibRaw starts its visible area at even offsets (an odd ActiveArea origin is moved to
the next even row or column) and anchors the black pattern there, the CFA pattern at the ActiveArea: camsim follows
the specification for both (measured with LibRaw 0.22, ``tests/io/test_raw_capture.py``). BlackLevelDeltaH/V (per
column and per row black offsets) are refused: the black level is one value per site of the 2 × 2 cell here.

Limits of what rawpy exposes: a non-DNG camera's black-level pattern larger than 2 × 2 (LibRaw's ``cblack[6:]``
beyond a 2 × 2 cell) is not visible through ``black_level_per_channel``, which then holds its per-colour part only;
and a raw outside a TIFF container (CR3, RAF, RW2, ORF, ...) has no Make or Model here (rawpy does not expose
LibRaw's ``idata.make``/``model``), so a preset must be named for it. A DNG's AsShotWhiteXY is not read (LibRaw does
not read it either): ``as_shot_neutral`` is then None.

Threads: an uncompressed DNG, checked with tifffile first (its strips hold the pixels its dimensions declare, and the
file holds its strips), is decoded in parallel with other threads (rawpy releases the GIL); any other file, a
compressed DNG among them, is read with LibRaw's stderr captured (it prints data errors there, "Unexpected end of
file"; camsim's errors are one line), which redirects the process's descriptor 2, so those reads take turns.

The size is checked against :data:`camsim.core.pixel_limit.MAX_PIXELS` from the header alone, before any pixel is
decoded: the DNG raw IFD's dimensions (tifffile), then LibRaw's (``open_file`` parses the header only; rawpy
decodes on ``unpack``). :func:`raw_header` reads no pixels from a DNG; another format's CFA pattern and ISO are
known to rawpy only after ``unpack`` (LibRaw's ``filters`` and ``other`` are behind it), so it decodes those.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.input_files import open_input
from camsim.core.pixel_limit import check_pixel_count
from camsim.io import dng as _dng
from camsim.sensor.cfa import CFA_PATTERNS

__all__ = ["RawCapture", "RawHeader", "raw_header", "read_raw_capture", "crop_capture", "TiffShot", "tiff_shot",
           "camera_name", "libraw_cfa", "libraw_orientation", "unpacked_raw"]

#: LibRaw's (dcraw's) ``flip`` → TIFF Orientation: dcraw reads Orientation o as flip ``"50132467"[o % 8]``.
_FLIP_TO_ORIENTATION = {0: 1, 1: 2, 3: 3, 2: 4, 4: 5, 6: 6, 7: 7, 5: 8}
#: LibRaw's colour letters: a second green (``RGBG``) is G.
_LETTER = {"R": "R", "G": "G", "B": "B"}
# tag codes beyond those camsim.io.dng writes
_NEW_SUBFILE_TYPE, _BLACK_LEVEL_DELTA_H, _BLACK_LEVEL_DELTA_V, _ACTIVE_AREA = 254, 50715, 50716, 50829
_PHOTOMETRIC_CFA, _PHOTOMETRIC_LINEAR_RAW = 32803, 34892


# ------------------------------------------------------------------------------------------------ shared helpers

@dataclass(frozen=True)
class TiffShot:
    """What IFD0 (and its EXIF IFD) of a TIFF-based raw says about the camera and the shot; None where absent.

    Attributes
    ----------
    make, model, unique_camera_model : str or None
        TIFF Make and Model, DNG UniqueCameraModel (stripped; None when empty).
    iso : float or None
        ISOSpeedRatings, or ISOSpeed above 65535 (:func:`camsim.io.dng.shot_metadata`).
    exposure_s : float or None
        ExposureTime. Unit: s.
    orientation : int or None
        TIFF Orientation (1..8).
    """

    make: str | None
    model: str | None
    unique_camera_model: str | None
    iso: float | None
    exposure_s: float | None
    orientation: int | None


def _text(tag: Any) -> str | None:
    if tag is None:
        return None
    text = str(tag.value).strip()
    return text or None


def _shot_from_page(page: Any) -> TiffShot:
    tags = page.tags
    orientation = tags.get(_dng._ORIENTATION)
    value = orientation.value if orientation is not None else None
    return TiffShot(make=_text(tags.get(_dng._MAKE)), model=_text(tags.get(_dng._MODEL)),
                    unique_camera_model=_text(tags.get(_dng._UNIQUE_CAMERA_MODEL)),
                    orientation=int(value) if isinstance(value, int) and 1 <= int(value) <= 8 else None,
                    **_dng.shot_metadata(page))


def tiff_shot(name: str) -> TiffShot | None:
    """The camera and shot tags of a TIFF-based raw (DNG, NEF, CR2, ARW, ...) from its IFD0 and EXIF IFD, or None
    for a file tifffile cannot read as TIFF (CR3, RAF, ... or a damaged header)."""
    import tifffile

    try:
        with _dng._tifffile_quiet(), tifffile.TiffFile(name) as tif:
            return _shot_from_page(tif.pages.first)
    except Exception:  # not a TIFF container: LibRaw's metadata then stands alone
        return None


def camera_name(shot: TiffShot | None) -> str | None:
    """The camera's name for presets and messages: the DNG UniqueCameraModel, else Make and Model (the Make dropped
    where the Model starts with it, as ``"Canon" "Canon EOS 5D Mark IV"``); None where unknown."""
    if shot is None:
        return None
    if shot.unique_camera_model:
        return shot.unique_camera_model
    parts = [p for p in (shot.make, shot.model) if p]
    if len(parts) == 2 and parts[1].startswith(parts[0]):
        parts = parts[1:]
    return " ".join(parts) or None


def libraw_cfa(raw: Any, prefix: str, accepts: str) -> str:
    """The 2 × 2 Bayer pattern (e.g. ``"RGGB"``) at the top-left of LibRaw's visible image (``raw`` unpacked).

    Parameters
    ----------
    raw : rawpy.RawPy
    prefix : str
        The start of the error message, naming the file (``"cannot read raw file X"``).
    accepts : str
        What the caller reads, for the message.

    Raises
    ------
    CamsimError
        A colour filter array that is not a 2 × 2 R, G, B Bayer cell (X-Trans, four colours, none).
    """
    cell = raw.raw_pattern
    colours = raw.raw_colors_visible
    if cell is None or np.shape(cell) != (2, 2) or colours.shape[0] < 2 or colours.shape[1] < 2:
        shape = None if cell is None else np.shape(cell)
        raise CamsimError(f"{prefix}: its colour filter array (pattern {shape}) is not a 2x2 Bayer mosaic; "
                          f"{accepts}")
    desc = raw.color_desc.decode("ascii", "replace")
    letters = "".join(_LETTER.get(desc[int(i)], "?") if int(i) < len(desc) else "?" for i in colours[:2, :2].ravel())
    if letters not in CFA_PATTERNS:  # R, G, G, B with the greens on a diagonal
        raise CamsimError(f"{prefix}: its 2x2 colour filter array {letters!r} is not an RGB Bayer pattern")
    return letters


def libraw_orientation(flip: int) -> int:
    """TIFF Orientation (1..8) of LibRaw's ``sizes.flip``: 0 → 1, 3 → 3, 5 → 8, 6 → 6, and the mirrored ones."""
    return _FLIP_TO_ORIENTATION.get(int(flip), 1)


def _shift(cell: np.ndarray, dy: int, dx: int) -> np.ndarray:
    """The 2 × 2 cell seen from an origin moved by (dy, dx): ``out[i, j] = cell[(i + dy) % 2, (j + dx) % 2]``."""
    return np.roll(np.asarray(cell), (-(dy % 2), -(dx % 2)), axis=(0, 1))


def _pattern_shift(pattern: str, dy: int, dx: int) -> str:
    return "".join(_shift(np.array(list(pattern)).reshape(2, 2), dy, dx).ravel())


# ------------------------------------------------------------------------------------------------ the records

@dataclass(frozen=True)
class RawHeader:
    """What loading a raw scene needs before its pixels: the size, pattern, ISO, exposure and camera.

    Attributes
    ----------
    path : str
    size : tuple of int
        (W, H) of LibRaw's visible image. Unit: pixels.
    cfa : str
        The Bayer pattern at the visible image's top-left (one of :data:`camsim.sensor.cfa.CFA_PATTERNS`).
    iso : float or None
    exposure_s : float or None
        Unit: s.
    make, model, unique_camera_model : str or None
    """

    path: str
    size: tuple
    cfa: str
    iso: float | None
    exposure_s: float | None
    make: str | None
    model: str | None
    unique_camera_model: str | None


@dataclass(frozen=True)
class RawCapture:
    """A raw file's mosaic (cropped) with its levels and metadata (see the module docstring for the sources).

    Attributes
    ----------
    path : str
    mosaic : numpy.ndarray
        (H, W) uint16, the visible area after the crop; H, W even. Unit: DN.
    cfa : str
        One of :data:`camsim.sensor.cfa.CFA_PATTERNS`: the cell at the (cropped) mosaic's top-left.
    black_dn : numpy.ndarray
        (2, 2) float64, the black level of each site of that cell. Unit: DN.
    white_dn : float
        Saturation level: values >= it are saturated. Unit: DN.
    iso : float or None
    exposure_s : float or None
        Unit: s.
    make, model, unique_camera_model : str or None
    color_matrix1, color_matrix2 : numpy.ndarray or None
        (3, 3) XYZ → camera (DNG ColorMatrix1/2, or LibRaw's ``rgb_xyz_matrix`` as the first, None where it is 0).
    calibration_illuminant1, calibration_illuminant2 : int or None
        EXIF LightSource codes of the matrices (21, D65, for LibRaw's).
    as_shot_neutral : numpy.ndarray or None
        (3,) camera R, G, B of white (DNG AsShotNeutral, or G / LibRaw's as-shot white balance).
    orientation : int
        TIFF Orientation 1..8 (the tag, or from LibRaw's flip).
    full_size : tuple of int
        (W, H) of the visible image before the crop. Unit: pixels.
    crop : tuple of int or None
        (x, y, w, h) applied, or None. A visible image of odd height or width read without a crop loses its
        last row or column (whole 2 × 2 cells only): ``crop`` is then that (0, 0, W − W % 2, H − H % 2).
    """

    path: str
    mosaic: np.ndarray
    cfa: str
    black_dn: np.ndarray
    white_dn: float
    iso: float | None
    exposure_s: float | None
    make: str | None
    model: str | None
    unique_camera_model: str | None
    color_matrix1: np.ndarray | None
    color_matrix2: np.ndarray | None
    calibration_illuminant1: int | None
    calibration_illuminant2: int | None
    as_shot_neutral: np.ndarray | None
    orientation: int
    full_size: tuple
    crop: tuple | None

    def site_black_dn(self) -> np.ndarray:
        """(H, W) float32: the black level of every pixel of :attr:`mosaic` (:attr:`black_dn` tiled). Unit: DN.

        A new array of 4 bytes per pixel; a caller that can broadcast needs only ``black_dn`` and
        ``mosaic.reshape(H // 2, 2, W // 2, 2)``.
        """
        h, w = self.mosaic.shape
        return np.tile(self.black_dn.astype(np.float32), (h // 2, w // 2))


# ------------------------------------------------------------------------------------------------ DNG tags

@dataclass(frozen=True)
class _DngRaw:
    """What a DNG's raw IFD says: size, ActiveArea origin, CFA pattern and black cell at that origin, white."""

    width: int
    height: int
    active_top: int
    active_left: int
    cfa: str
    black: np.ndarray  # (2, 2) float64 at the ActiveArea's origin
    white: float
    colour: dict        # ColorMatrix1/2, CalibrationIlluminant1/2, AsShotNeutral (IFD0)
    checked: bool = False  # uncompressed, its strips holding every pixel: LibRaw decodes it without a complaint


def _numbers(tag: Any) -> np.ndarray | None:
    """A numeric tag's values as float64 (RATIONAL and SRATIONAL pairs divided)."""
    if tag is None:
        return None
    values = np.atleast_1d(np.asarray(tag.value, dtype=np.float64)).ravel()
    if int(tag.dtype) in (5, 10):  # RATIONAL, SRATIONAL: (numerator, denominator) pairs
        with np.errstate(divide="ignore", invalid="ignore"):
            values = values[0::2] / values[1::2]
    return values


def _raw_page(tif: Any, name: str) -> Any:
    """The DNG's raw image IFD: among IFD0 and its SubIFDs, the full-resolution one (NewSubFileType 0) with a
    CFA or LinearRaw image, the largest if several."""
    first = tif.pages.first
    subifds = getattr(first, "pages", None)
    candidates = [first, *(subifds if subifds is not None else [])]
    raws = []
    for page in candidates:
        kind = page.tags.get(_NEW_SUBFILE_TYPE)
        if (kind is None or int(kind.value) == 0) and int(page.photometric) in (_PHOTOMETRIC_CFA,
                                                                              _PHOTOMETRIC_LINEAR_RAW):
            raws.append(page)
    if not raws:
        raise CamsimError(f"cannot read raw file {name}: the DNG has no full-resolution raw image (no IFD of "
                          "NewSubFileType 0 with a CFA or LinearRaw image)")
    return max(raws, key=lambda p: p.imagewidth * p.imagelength)


def _dng_black(page: Any, name: str) -> np.ndarray:
    """The black level of each site of the 2 × 2 cell at the ActiveArea's origin (BlackLevelRepeatDim/BlackLevel;
    0 without them)."""
    values = _numbers(page.tags.get(_dng._BLACK_LEVEL))
    dim = page.tags.get(_dng._BLACK_LEVEL_REPEAT_DIM)
    rows, cols = (1, 1) if dim is None else tuple(int(v) for v in dim.value)
    for code, what in ((_BLACK_LEVEL_DELTA_H, "BlackLevelDeltaH"), (_BLACK_LEVEL_DELTA_V, "BlackLevelDeltaV")):
        deltas = _numbers(page.tags.get(code))
        if deltas is not None and np.any(deltas != 0):
            raise CamsimError(f"cannot read raw file {name}: it has per-column or per-row black levels ({what}); "
                              "camsim reads one black level per site of the 2x2 cell")
    if values is None:
        return np.zeros((2, 2))
    if rows < 1 or cols < 1 or values.size != rows * cols or not np.all(np.isfinite(values)):
        raise CamsimError(f"cannot read raw file {name}: BlackLevel holds {values.size} values for a "
                          f"BlackLevelRepeatDim of {rows}x{cols}")
    grid = values.reshape(rows, cols)
    if rows % 2 == 0 and cols % 2 == 0:
        cell = grid[:2, :2]
        periodic = np.array_equal(np.tile(cell, (rows // 2, cols // 2)), grid)
    elif rows <= 2 and cols <= 2:
        cell, periodic = np.tile(grid, (2 // rows, 2 // cols)), True
    else:
        cell, periodic = grid, False
    if not periodic:
        raise CamsimError(f"cannot read raw file {name}: its {rows}x{cols} black level pattern does not repeat "
                          "every 2x2 cell")
    return np.array(cell, dtype=np.float64)


def _matrix(page: Any, code: int, what: str, name: str) -> np.ndarray | None:
    values = _numbers(page.tags.get(code))
    if values is None:
        return None
    if values.size != 9 or not np.all(np.isfinite(values)):
        raise CamsimError(f"cannot read raw file {name}: its {what} holds {values.size} values (finite: "
                          f"{bool(np.all(np.isfinite(values)))}), expected 3x3")
    return values.reshape(3, 3)


def _dng_colour(ifd0: Any, name: str) -> dict:
    """ColorMatrix1/2, CalibrationIlluminant1/2 and AsShotNeutral of a DNG's IFD0 (None where absent)."""
    def code(tag_code: int) -> int | None:
        tag = ifd0.tags.get(tag_code)
        return int(tag.value) if tag is not None and isinstance(tag.value, int) else None

    neutral = _numbers(ifd0.tags.get(_dng._AS_SHOT_NEUTRAL))
    if neutral is not None and (neutral.size != 3 or not np.all(np.isfinite(neutral)) or np.any(neutral <= 0)):
        raise CamsimError(f"cannot read raw file {name}: its AsShotNeutral {neutral.tolist()[:6]} is not 3 positive "
                          "values")
    return {"color_matrix1": _matrix(ifd0, _dng._COLOR_MATRIX1, "ColorMatrix1", name),
            "color_matrix2": _matrix(ifd0, _dng._COLOR_MATRIX2, "ColorMatrix2", name),
            "calibration_illuminant1": code(_dng._CALIBRATION_ILLUMINANT1),
            "calibration_illuminant2": code(_dng._CALIBRATION_ILLUMINANT2),
            "as_shot_neutral": neutral}


def _read_tiff(name: str) -> tuple:
    """(TiffShot or None, _DngRaw or None): the container's tags; the DNG raw IFD's levels, checked, and its size
    checked against the pixel limit, before LibRaw opens the file."""
    import tifffile

    with contextlib.ExitStack() as stack:
        try:
            stack.enter_context(_dng._tifffile_quiet())
            tif = stack.enter_context(tifffile.TiffFile(name))
            ifd0 = tif.pages.first
            shot = _shot_from_page(ifd0)
        except Exception:  # not a TIFF container (CR3, RAF, a PNG, text): LibRaw decides
            return None, None
        if ifd0.tags.get(_dng._DNG_VERSION) is None:
            return shot, None
        try:
            return shot, _dng_raw(tif, ifd0, name)
        except CamsimError as exc:
            raise CamsimError(str(exc).replace(f"cannot read DNG {name}:", f"cannot read raw file {name}:")) from None
        except Exception as exc:  # a damaged IFD or tag
            raise CamsimError(f"cannot read raw file {name}: damaged DNG tags ({type(exc).__name__}: {exc})") from None


def _holds_its_pixels(page: Any, name: str) -> bool:
    """Whether the raw IFD ``page`` is uncompressed (Compression 1), once its strips or tiles are known to hold at
    least the bytes its dimensions take; False for a compressed one, whose decoded size only LibRaw knows.

    LibRaw reads an uncompressed image by its dimensions from the first strip on: a header that declares more
    rows or columns than the strips hold makes it read past them to the file's end, print "Unexpected end of file"
    on stderr and fail. Refused here from the header instead, on one line.
    """
    if int(page.compression) != 1:
        return False
    needed = page.imagewidth * page.imagelength * page.samplesperpixel * page.bitspersample // 8
    held = sum(int(count) for count in page.databytecounts)
    if held < needed:
        raise CamsimError(f"cannot read raw file {name}: its header declares a {page.imagewidth}x{page.imagelength} "
                          f"image of {page.samplesperpixel} sample(s) of {page.bitspersample} bits ({needed} bytes), "
                          f"but its uncompressed pixel data holds {held} bytes")
    return True


def _checked_raw_page(tif: Any, name: str) -> tuple:
    """(the DNG's raw IFD, whether LibRaw decodes it without a complaint): its size checked against the pixel
    limit, the file holding its pixel data and, uncompressed, that data holding its pixels; all from the header."""
    page = _raw_page(tif, name)
    check_pixel_count(page.imagewidth, page.imagelength, f"raw file {name}")
    _dng._check_complete(page, tif.filehandle.size, name)
    _dng.check_active_area(page, name)
    return page, _holds_its_pixels(page, name)


def _dng_raw(tif: Any, ifd0: Any, name: str) -> _DngRaw:
    """The raw IFD's size (checked against the pixel limit), pattern, levels and ActiveArea, and IFD0's colour."""
    page, checked = _checked_raw_page(tif, name)
    if int(page.photometric) != _PHOTOMETRIC_CFA or page.samplesperpixel != 1:
        what = ("a monochrome image" if page.samplesperpixel == 1 else
                f"a {page.samplesperpixel}-sample LinearRaw image, a three-chip or demosaiced raw")
        raise CamsimError(f"cannot read raw file {name}: it has no 2x2 colour filter array: {what}; camsim "
                          "reads RGB Bayer raws")
    pattern = _dng._cfa_pattern(page, name)
    black = _dng_black(page, name)
    white_tag = _numbers(page.tags.get(_dng._WHITE_LEVEL))
    white = float(white_tag[0]) if white_tag is not None and white_tag.size else float(
        2 ** int(page.bitspersample) - 1)
    area = _numbers(page.tags.get(_ACTIVE_AREA))
    top, left = (int(area[0]), int(area[1])) if area is not None and area.size == 4 else (0, 0)
    colour = _dng_colour(ifd0, name)
    return _DngRaw(page.imagewidth, page.imagelength, top, left, pattern, black, white, colour, checked)


# ------------------------------------------------------------------------------------------------ LibRaw

_ACCEPTS = "camsim reads raws of a 2x2 RGB Bayer mosaic"


#: :func:`camsim.io.library_stderr.library_stderr` redirects the process's descriptor 2: one such call at a time
_STDERR_LOCK = threading.Lock()


@contextlib.contextmanager
def _stderr_of(capture: bool):
    """What LibRaw prints on stderr during the block (a CapturedStderr), where ``capture``; else None.

    LibRaw prints a data error ("Unexpected end of file") on stderr besides failing; camsim's errors are one line.
    A DNG is checked (complete, its tags read) before LibRaw sees it and is read without the capture, in parallel
    with other threads (rawpy releases the GIL while it decodes); other files are read under the capture, one at a
    time."""
    if not capture:
        yield None
        return
    from camsim.io.library_stderr import library_stderr

    with _STDERR_LOCK, library_stderr() as chatter:
        yield chatter


@contextlib.contextmanager
def _libraw(name: str, capture: bool, bayer: bool = True):
    """The file opened by LibRaw (header parsed, nothing decoded), its size checked; LibRaw's errors (and what it
    prints on stderr, with ``capture``) as one CamsimError line naming the file. ``bayer``: refuse a file of fewer
    than three colours or colours other than R, G, B."""
    import rawpy

    raw = rawpy.RawPy()
    try:
        try:
            with _stderr_of(capture) as chatter:
                raw.open_file(name)
        except Exception as exc:  # rawpy.LibRawFileUnsupportedError, LibRawIOError, ...
            raise CamsimError(f"cannot read raw file {name}: not a raw file LibRaw reads ({_reason(chatter, exc)})"
                              ) from None
        sizes = raw.sizes
        check_pixel_count(int(sizes.raw_width), int(sizes.raw_height), f"raw file {name}")
        if int(sizes.width) < 2 or int(sizes.height) < 2:
            raise CamsimError(f"cannot read raw file {name}: its visible image is {sizes.width}x{sizes.height} "
                              "pixels, smaller than one 2x2 cell")
        desc = raw.color_desc.decode("ascii", "replace")
        if bayer and (raw.num_colors < 3 or not all(c in "RGB" for c in desc[:raw.num_colors])):
            raise CamsimError(f"cannot read raw file {name}: LibRaw sees {raw.num_colors} colour(s) "
                              f"({raw.color_desc.decode('ascii', 'replace')!r}); {_ACCEPTS}")
        yield raw
    finally:
        raw.close()


def _reason(chatter: Any, exc: Exception) -> str:
    """LibRaw's complaint: what it printed, else the exception's text (rawpy's are ``b'...'`` byte strings)."""
    reason = (chatter.reason() if chatter is not None else "") or str(exc) or type(exc).__name__
    if len(reason) > 3 and reason[:2] in ("b'", 'b"') and reason[-1] == reason[1]:
        reason = reason[2:-1]
    return reason


def _unpack(raw: Any, name: str, capture: bool) -> None:
    try:
        with _stderr_of(capture) as chatter:
            raw.unpack()
    except Exception as exc:  # truncated or damaged pixel data
        raise CamsimError(f"cannot read raw file {name}: LibRaw cannot decode its pixels ({_reason(chatter, exc)})"
                          ) from None


def _check_name(path: Any) -> str:
    """``path`` as a string once it names a non-empty regular file (a FIFO or a device would block tifffile and
    LibRaw, which open it by name: :func:`camsim.core.input_files.open_input`)."""
    try:
        name = str(os.fspath(path))
    except TypeError:
        raise CamsimError(f"a raw file's path must be a string or path, got {type(path).__name__}") from None
    if "\x00" not in name and not os.path.exists(name):
        raise CamsimError(f"cannot read raw file {name}: no such file")
    with open_input(name, "raw file") as fh:
        try:
            empty = not fh.read(1)
        except OSError as exc:
            raise CamsimError(f"cannot read raw file {name}: {exc.strerror or exc}") from None
    if empty:
        raise CamsimError(f"cannot read raw file {name}: the file is empty")
    return name


def _dng_origin(raw: Any, dng: _DngRaw, name: str) -> tuple:
    """(dy, dx): LibRaw's visible origin from the ActiveArea's, where the DNG's patterns are anchored."""
    sizes = raw.sizes
    if (int(sizes.raw_width), int(sizes.raw_height)) != (dng.width, dng.height):
        raise CamsimError(f"cannot read raw file {name}: LibRaw decodes a {sizes.raw_width}x{sizes.raw_height} image "
                          f"but the DNG's raw IFD is {dng.width}x{dng.height}")
    dy, dx = int(sizes.top_margin) - dng.active_top, int(sizes.left_margin) - dng.active_left
    if dy < 0 or dx < 0:
        raise CamsimError(f"cannot read raw file {name}: LibRaw's visible image starts at ({sizes.left_margin}, "
                          f"{sizes.top_margin}), outside the DNG's ActiveArea from ({dng.active_left}, "
                          f"{dng.active_top})")
    return dy, dx


def _shot_values(shot: TiffShot | None, raw: Any | None) -> dict:
    """ISO and exposure: the tags', else LibRaw's (``raw`` unpacked, or None for tags only)."""
    iso = shot.iso if shot is not None else None
    exposure_s = shot.exposure_s if shot is not None else None
    if raw is not None and (iso is None or exposure_s is None):
        other = raw.other
        if iso is None and other.iso_speed and other.iso_speed > 0:
            iso = float(other.iso_speed)
        if exposure_s is None and other.shutter_speed and other.shutter_speed > 0:
            exposure_s = float(other.shutter_speed)
    return {"iso": iso, "exposure_s": exposure_s,
            "make": None if shot is None else shot.make, "model": None if shot is None else shot.model,
            "unique_camera_model": None if shot is None else shot.unique_camera_model}


def raw_header(path) -> RawHeader:
    """The size, CFA pattern, ISO, exposure and camera of a raw file, without decoding a DNG's pixels.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    RawHeader

    Raises
    ------
    CamsimError
        As :func:`read_raw_capture` (one line naming the file); a DNG's levels are checked against LibRaw's only
        by :func:`read_raw_capture`, which decodes.
    """
    name = _check_name(path)
    shot, dng = _read_tiff(name)
    capture = dng is None or not dng.checked
    with _libraw(name, capture) as raw:
        sizes = raw.sizes
        if dng is not None:
            dy, dx = _dng_origin(raw, dng, name)
            cfa = _pattern_shift(dng.cfa, dy, dx)
            values = _shot_values(shot, None)
            if values["iso"] is None or values["exposure_s"] is None:
                _unpack(raw, name, capture)
                values = _shot_values(shot, raw)
        else:
            _unpack(raw, name, True)  # rawpy gives the pattern (and ``other``) only after unpack
            cfa = libraw_cfa(raw, f"cannot read raw file {name}", _ACCEPTS)
            values = _shot_values(shot, raw)
        return RawHeader(path=name, size=(int(sizes.width), int(sizes.height)), cfa=cfa, **values)


def _dng_checked(name: str) -> bool:
    """Whether ``name`` is a DNG that LibRaw decodes without a complaint (:func:`_checked_raw_page`), its raw IFD
    of any layout (Bayer, colour stack, monochrome); False for any other file (LibRaw then decides, its stderr
    captured)."""
    import tifffile

    with contextlib.ExitStack() as stack:
        try:
            stack.enter_context(_dng._tifffile_quiet())
            tif = stack.enter_context(tifffile.TiffFile(name))
            is_dng = tif.pages.first.tags.get(_dng._DNG_VERSION) is not None
        except Exception:  # not a TIFF container (CR3, RAF, a PNG, text): LibRaw decides
            return False
        if not is_dng:
            return False
        try:
            return _checked_raw_page(tif, name)[1]
        except CamsimError as exc:
            raise CamsimError(str(exc).replace(f"cannot read DNG {name}:", f"cannot read raw file {name}:")) from None
        except Exception as exc:  # a damaged IFD or tag
            raise CamsimError(f"cannot read raw file {name}: damaged DNG tags ({type(exc).__name__}: {exc})") from None


@contextlib.contextmanager
def unpacked_raw(path):
    """Any raw file LibRaw reads (a Bayer mosaic, a colour stack, a monochrome image), opened and unpacked as a
    ``rawpy.RawPy`` for the block, after the checks that need no pixel: a regular, non-empty file; a DNG's raw IFD
    within the pixel limit and holding its pixel data (from its tags); any file's size in LibRaw's header within
    the limit (before ``unpack``).

    Parameters
    ----------
    path : str or os.PathLike

    Yields
    ------
    rawpy.RawPy
        Unpacked (``raw_image_visible`` and the levels are there); closed when the block ends.

    Raises
    ------
    CamsimError
        One line naming the file: missing, not a regular file, empty, not a raw LibRaw reads, a size above the
        pixel limit, truncated or damaged pixel data (what LibRaw prints on stderr goes into the line).
    """
    name = _check_name(path)
    capture = not _dng_checked(name)
    with _libraw(name, capture, bayer=False) as raw:
        _unpack(raw, name, capture)
        yield raw


def _check_crop(crop: Any, size: tuple, name: str) -> tuple:
    """``crop`` as (x, y, w, h) ints inside the visible image of ``size`` (W, H), w and h even and > 0."""
    width, height = size
    try:
        values = tuple(crop)
    except TypeError:
        values = ()
    if len(values) != 4 or not all(isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))
                                   for v in values):
        raise CamsimError(f"cannot read raw file {name}: crop must be 4 integers (x, y, w, h) in pixels, got {crop!r}")
    x, y, w, h = (int(v) for v in values)
    if w <= 0 or h <= 0 or w % 2 or h % 2:
        raise CamsimError(f"cannot read raw file {name}: crop ({x}, {y}, {w}, {h}) must have an even width and height "
                          "above 0 (whole 2x2 cells)")
    if x < 0 or y < 0 or x + w > width or y + h > height:
        raise CamsimError(f"cannot read raw file {name}: crop ({x}, {y}, {w}, {h}) is off the frame of "
                          f"{width}x{height} pixels (x + w <= width, y + h <= height, x, y >= 0)")
    return x, y, w, h


def read_raw_capture(path, crop=None) -> RawCapture:
    """Read a raw file's Bayer mosaic (its visible area, optionally cropped), levels and metadata.

    Parameters
    ----------
    path : str or os.PathLike
        Any raw file LibRaw reads with a 2 × 2 RGB Bayer mosaic.
    crop : (x, y, w, h) or None
        A window of the visible image in pixels: x, y >= 0 any (an odd offset shifts the pattern: ``cfa`` and
        ``black_dn`` are the cropped cell's), w, h even and > 0, inside the frame. None: the whole visible image
        (less a last odd row or column).

    Returns
    -------
    RawCapture

    Raises
    ------
    CamsimError
        One line naming the file: missing, unreadable, truncated or not a raw; no 2 × 2 RGB Bayer CFA (three-chip,
        monochrome, X-Trans, four colours); a size above the pixel limit (from the header, before decoding); a crop
        off the frame or of odd size; a DNG whose levels or pattern LibRaw reads otherwise than its tags say.
    """
    name = _check_name(path)
    shot, dng = _read_tiff(name)
    capture = dng is None or not dng.checked
    with _libraw(name, capture) as raw:
        sizes = raw.sizes
        full = (int(sizes.width), int(sizes.height))
        box = _check_crop(crop, full, name) if crop is not None else None
        origin = _dng_origin(raw, dng, name) if dng is not None else (0, 0)
        _unpack(raw, name, capture)
        libraw_pattern = libraw_cfa(raw, f"cannot read raw file {name}", _ACCEPTS)
        cell_index = np.asarray(raw.raw_colors_visible[:2, :2], dtype=np.intp)
        per_channel = np.asarray(raw.black_level_per_channel, dtype=np.float64)
        libraw_black = per_channel[cell_index]  # LibRaw's black of each visible site (cblack by colour index)
        libraw_white = float(raw.white_level)
        if dng is not None:
            dy, dx = origin
            cfa0, black0, white = _pattern_shift(dng.cfa, dy, dx), _shift(dng.black, dy, dx), dng.white
            if cfa0 != libraw_pattern:
                raise CamsimError(f"cannot read raw file {name}: LibRaw decodes a {libraw_pattern} mosaic but the "
                                  f"DNG's CFA tags say {cfa0}")
            # LibRaw anchors the black pattern at its visible origin (the CFA pattern at the ActiveArea)
            if np.any(np.abs(libraw_black - np.floor(dng.black)) >= 1) or libraw_white != white:
                raise CamsimError(f"cannot read raw file {name}: LibRaw reads black levels "
                                  f"{libraw_black.ravel().tolist()} and white {libraw_white:g} but the DNG's tags "
                                  f"say {dng.black.ravel().tolist()} and {white:g}")
            colour = dict(dng.colour)
        else:
            cfa0, black0, white = libraw_pattern, libraw_black, libraw_white
            colour = {"color_matrix1": None, "color_matrix2": None, "calibration_illuminant1": None,
                      "calibration_illuminant2": None, "as_shot_neutral": None}
        if colour["color_matrix1"] is None:
            matrix = np.asarray(raw.rgb_xyz_matrix, dtype=np.float64)[:3]
            if np.all(np.isfinite(matrix)) and np.any(matrix != 0):
                colour["color_matrix1"], colour["calibration_illuminant1"] = matrix, 21  # Adobe's D65 matrices
        if colour["as_shot_neutral"] is None:
            multipliers = np.asarray(raw.camera_whitebalance, dtype=np.float64)[:3]
            if np.all(np.isfinite(multipliers)) and np.all(multipliers > 0):
                colour["as_shot_neutral"] = multipliers[1] / multipliers
        image = raw.raw_image_visible
        if image.ndim != 2 or image.shape != (full[1], full[0]):
            raise CamsimError(f"cannot read raw file {name}: LibRaw decoded an image of shape {image.shape}, not the "
                              f"{full[0]}x{full[1]} mosaic its header gives")
        if box is None and (full[0] % 2 or full[1] % 2):
            box = (0, 0, full[0] - full[0] % 2, full[1] - full[1] % 2)  # whole 2x2 cells only
        x, y, w, h = box if box is not None else (0, 0, full[0], full[1])
        mosaic = np.array(image[y: y + h, x: x + w], dtype=np.uint16, copy=True)  # LibRaw's buffer dies with raw
        values = _shot_values(shot, raw)
        orientation = shot.orientation if shot is not None and shot.orientation is not None else \
            libraw_orientation(sizes.flip)
    return RawCapture(
        path=name, mosaic=mosaic, cfa=_pattern_shift(cfa0, y, x), black_dn=_shift(black0, y, x).astype(np.float64),
        white_dn=float(white), orientation=int(orientation), full_size=full, crop=box, **values, **colour)


def crop_capture(capture: RawCapture, crop) -> RawCapture:
    """A window of a capture read before (without a crop, or with one that holds the window): what
    :func:`read_raw_capture` with ``crop`` gives, without decoding the file again (a dataset's crops of one file).

    Parameters
    ----------
    capture : RawCapture
    crop : (x, y, w, h)
        In pixels of the visible image (as :func:`read_raw_capture`'s): x, y any (an odd offset shifts the pattern),
        w, h even and > 0, inside the capture's own window.

    Raises
    ------
    CamsimError
        A crop of odd size or off the capture's window, naming the file.
    """
    x0, y0 = (0, 0) if capture.crop is None else capture.crop[:2]
    h0, w0 = capture.mosaic.shape
    x, y, w, h = _check_crop(crop, capture.full_size, capture.path)
    if x < x0 or y < y0 or x + w > x0 + w0 or y + h > y0 + h0:
        raise CamsimError(f"cannot crop raw file {capture.path}: crop ({x}, {y}, {w}, {h}) is off the window "
                          f"({x0}, {y0}, {w0}, {h0}) read")
    dy, dx = y - y0, x - x0
    return dataclasses.replace(capture, mosaic=capture.mosaic[dy: dy + h, dx: dx + w],
                               cfa=_pattern_shift(capture.cfa, dy, dx),
                               black_dn=_shift(capture.black_dn, dy, dx).astype(np.float64), crop=(x, y, w, h))
