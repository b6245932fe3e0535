"""Raw files for ``camsim calibrate``: read through LibRaw (``rawpy``), split into the planes of one colour site each.

A Bayer mosaic (``raw_image_visible`` of shape (H, W), its 2 × 2 ``raw_pattern``) gives four planes, one per site of
the cell, named by colour (``R``, ``Gr``: the green on the red rows, ``Gb``, ``B``); a colour-stacked file (camsim's
3-sample LinearRaw DNGs, which LibRaw returns as (H, W, 4) with channel 3 unused) three planes ``R``, ``G``, ``B``;
a monochrome file one plane ``Y``. Other mosaics (X-Trans, 4-colour) are refused.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError
from camsim.io.raw_capture import camera_name, libraw_cfa, tiff_shot, unpacked_raw

#: What ``camsim calibrate`` reads, for the messages refusing other mosaics.
_ACCEPTS = "camsim calibrate reads 2x2 Bayer, 3-colour stacked and monochrome raws"


@dataclass(frozen=True)
class Layout:
    """How a raw image splits into planes.

    Attributes
    ----------
    kind : {"bayer", "stack", "mono"}
        A 2 × 2 mosaic, a colour stack (one value per colour per pixel: a three-chip sensor) or one channel.
    cfa : str or None
        The Bayer pattern (colours of the cell's sites, row by row), e.g. ``"RGGB"``; None otherwise.
    shape : tuple of int
        (H, W) of the image. Unit: pixels.
    white_level_dn : int
        LibRaw's white level. Unit: DN.
    """

    kind: str
    cfa: str | None
    shape: tuple
    white_level_dn: int

    @property
    def plane_names(self) -> tuple:
        """Names of the planes, in :meth:`planes` order."""
        if self.kind == "stack":
            return ("R", "G", "B")
        if self.kind == "mono":
            return ("Y",)
        names = []
        for i, colour in enumerate(self.cfa):
            if colour == "G":  # named after the colour its row shares
                colour = "Gr" if self.cfa[2 * (i // 2) + 1 - i % 2] == "R" else "Gb"
            names.append(colour)
        return tuple(names)

    @property
    def plane_colours(self) -> tuple:
        """The colour (``R``, ``G``, ``B``, or ``Y``) of each plane."""
        return tuple(name[0] for name in self.plane_names)

    @property
    def plane_shape(self) -> tuple:
        """(H', W') of one plane. Unit: pixels."""
        h, w = self.shape
        return (h // 2, w // 2) if self.kind == "bayer" else (h, w)

    @property
    def bits(self) -> int:
        """The ADC's bits, ceil(log2(white + 1))."""
        return max(1, math.ceil(math.log2(self.white_level_dn + 1)))

    def planes(self, image: np.ndarray) -> list:
        """The planes of ``image`` (views): the four sites of the cell, the stack's colours, or the image."""
        if self.kind == "bayer":
            return [image[dy::2, dx::2] for dy in (0, 1) for dx in (0, 1)]
        if self.kind == "stack":
            return [image[..., c] for c in range(3)]
        return [image]

    def rows(self, image: np.ndarray) -> np.ndarray:
        """The physical rows' images, (rows, values per row): a Bayer row holds both colours of its sites (one
        readout), a stack's planes are separate sensors (each of their rows is a row); shape (R, V)."""
        if self.kind == "stack":
            return np.concatenate([image[..., c] for c in range(3)], axis=0)
        return image

    def describe(self) -> str:
        """E.g. ``"1024x512 RGGB mosaic, 14-bit"``."""
        what = {"bayer": f"{self.cfa} mosaic", "stack": "3-colour stack", "mono": "monochrome"}[self.kind]
        return f"{self.shape[1]}x{self.shape[0]} {what}, white level {self.white_level_dn} DN"


@dataclass(frozen=True)
class RawFrame:
    """One raw file's pixels and what calibration needs of its metadata.

    Attributes
    ----------
    path : str
    image : numpy.ndarray
        (H, W) mosaic or (H, W, 3) stack, uint16. Unit: DN.
    layout : Layout
    iso : float or None
        The ISO speed: the TIFF/EXIF tags' (ISOSpeedRatings, or ISOSpeed above 65535, which LibRaw does not read),
        else LibRaw's; None where the file has none.
    model : str or None
        The camera: the DNG UniqueCameraModel, or Make and Model of a TIFF-based raw (None where unknown).
    exposure_s : float or None
        The exposure time: the ExposureTime tag's (exact), else LibRaw's; None where the file has none. Unit: s.
    """

    path: str
    image: np.ndarray
    layout: Layout
    iso: float | None
    model: str | None
    exposure_s: float | None = None


def _tiff_metadata(name: str) -> dict:
    """``model`` (UniqueCameraModel, else Make + Model: :func:`camsim.io.raw_capture.camera_name`), ``iso`` and
    ``exposure_s`` (s) of a TIFF-based raw (DNG, NEF, CR2, ARW, ...) from its first IFD and EXIF IFD; None for what
    it lacks, all None for other containers."""
    shot = tiff_shot(name)
    if shot is None:  # not a TIFF container (CR3, RAF, ...): the model is then unknown
        return {"model": None, "iso": None, "exposure_s": None}
    return {"model": camera_name(shot), "iso": shot.iso, "exposure_s": shot.exposure_s}


def _finite_number(value) -> float | None:
    """``value`` as a finite float, or None for anything else (a string, a bool, NaN, ±inf, an int beyond floats)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if number == number and abs(number) != float("inf") else None


def _with_sidecar(name: str, iso: float | None, exposure_s: float | None) -> tuple:
    """The ISO and exposure [s] of a raw file, checked against a camsim sidecar (``STEM.json`` beside it): a value
    both give must agree (else CamsimError); one only the sidecar gives (a DNG of an older camsim, without the
    tags) is taken from it. Files without a camsim sidecar keep their own values."""
    import json
    from pathlib import Path

    from camsim.core.input_files import read_input
    from camsim.render.sidecar_schema import MAX_SIDECAR_BYTES

    sidecar = Path(name).with_suffix(".json")
    try:  # CamsimError: a FIFO, device or folder by that name, or a file over the sidecar's limit
        meta = json.loads(read_input(sidecar, "sidecar", MAX_SIDECAR_BYTES).decode("utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):  # ValueError: also int()'s digit limit
        return iso, exposure_s  # no sidecar (a camera's raw), or not one camsim can read: the file's tags stand alone
    if not isinstance(meta, dict) or "camsim_version" not in meta:
        return iso, exposure_s
    said_iso, said_t = meta.get("iso"), meta.get("exposure_s")
    said_iso, said_t = map(_finite_number, (said_iso, said_t))  # a NaN, infinity or string in a sidecar says nothing
    if said_iso is not None and said_iso > 0:
        if iso is not None and round(float(said_iso)) != round(iso):
            raise CamsimError(f"{name} says ISO {iso:g} but its sidecar {sidecar} says ISO {float(said_iso):g}: "
                              "wrong sidecar, or a file edited since?")
        iso = iso if iso is not None else float(said_iso)
    if said_t is not None and said_t > 0:
        if exposure_s is not None and abs(exposure_s / float(said_t) - 1) > 1e-6:
            raise CamsimError(f"{name} says exposure {exposure_s:g} s but its sidecar {sidecar} says "
                              f"{float(said_t):g} s: wrong sidecar, or a file edited since?")
        exposure_s = exposure_s if exposure_s is not None else float(said_t)
    return iso, exposure_s


def read_raw(path, *, metadata: bool = False) -> RawFrame:
    """Read a raw file's visible pixels through LibRaw.

    Parameters
    ----------
    path : str or os.PathLike
    metadata : bool
        Kept for callers; the tags (camera model, ISO, exposure) are read for every file (a second open, with
        tifffile, of the header only). A camsim frame's sidecar beside the file must agree with its ISO and
        exposure, and gives them where the file has no tag (:func:`_with_sidecar`).

    Returns
    -------
    RawFrame

    Raises
    ------
    CamsimError
        Naming the file, on one line, if it is missing, not a regular file (a FIFO, a device), unreadable or not a
        raw LibRaw decodes, if its header declares more pixels than camsim's limit or than its data holds (both
        refused before LibRaw decodes: :func:`camsim.io.raw_capture.unpacked_raw`), or if it is not one of the
        layouts (2 × 2 Bayer, 3-colour stack, monochrome).
    """
    name = str(os.fspath(path))
    try:
        with unpacked_raw(name) as raw:
            image = raw.raw_image_visible
            if image.ndim == 3:
                if raw.num_colors != 3 or image.shape[2] < 3:
                    raise CamsimError(f"cannot calibrate from {name}: a stacked image of {raw.num_colors} colours "
                                      "(expected 3)")
                layout_kind, cfa = "stack", None
                image = np.array(image[..., :3], dtype=np.uint16, copy=True)
            elif raw.num_colors == 1:
                layout_kind, cfa = "mono", None
                image = np.array(image, dtype=np.uint16, copy=True)
            else:
                layout_kind, cfa = "bayer", libraw_cfa(raw, f"cannot calibrate from {name}", _ACCEPTS)
                image = np.array(image, dtype=np.uint16, copy=True)
            white = int(raw.white_level)
            iso = float(raw.other.iso_speed) if raw.other.iso_speed and raw.other.iso_speed > 0 else None
            shutter = float(raw.other.shutter_speed) if raw.other.shutter_speed > 0 else None
    except CamsimError:
        raise
    except Exception as exc:  # rawpy.LibRawError on reading an unpacked file's fields, OSError
        reason = str(exc) or type(exc).__name__
        raise CamsimError(f"cannot read raw file {name}: {reason}") from None
    h, w = image.shape[:2]
    if layout_kind == "bayer" and (h % 2 or w % 2):
        image = image[: h - h % 2, : w - w % 2]  # whole 2x2 cells only
    layout = Layout(layout_kind, cfa, tuple(image.shape[:2]), white)
    tags = _tiff_metadata(name)
    iso = tags["iso"] if tags["iso"] is not None else iso  # LibRaw says 65535 for an ISO above it
    exposure_s = tags["exposure_s"] if tags["exposure_s"] is not None else shutter
    iso, exposure_s = _with_sidecar(name, iso, exposure_s)
    return RawFrame(name, image, layout, iso, tags["model"], exposure_s)


def check_same_layout(first: RawFrame, frame: RawFrame) -> None:
    """Refuse a frame whose size, mosaic, white level or ISO (where both files say) differs from the first's (one
    message naming both)."""
    if frame.layout != first.layout:
        raise CamsimError(f"mixed frames: {frame.path} is {frame.layout.describe()} but {first.path} is "
                          f"{first.layout.describe()}; every dark and flat frame must come from the same camera "
                          "mode")
    if frame.iso is not None and first.iso is not None and frame.iso != first.iso:
        raise CamsimError(f"mixed ISO: {frame.path} is ISO {frame.iso:g} but {first.path} is ISO {first.iso:g}; "
                          "noise parameters belong to one ISO: calibrate each ISO on its own")


def check_same_exposure(first: RawFrame, frame: RawFrame, what: str) -> None:
    """Refuse ``frame`` whose exposure differs from ``first``'s where both files say (``what``: "dark frames",
    "the two flats of a pair"): dark current grows with the exposure, and a pair's difference holds the noise of
    one exposure only if both had it."""
    a, b = first.exposure_s, frame.exposure_s
    if a is not None and b is not None and abs(a / b - 1) > 1e-6:
        raise CamsimError(f"mixed exposures: {frame.path} was exposed {b:g} s but {first.path} {a:g} s; {what} "
                          "must share one exposure")
