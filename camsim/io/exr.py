"""Float EXR frames: a picture for viewers in ``R, G, B``, the noisy signal in ``noisy.R, noisy.G, noisy.B`` (or
``noisy.CFA``, a Bayer mosaic) and the noise-free signal in ``clean.R, clean.G, clean.B``.

Image viewers (OpenImageIO's ``iv`` and ``oiiotool``, and the OpenEXR convention that Nuke, Photoshop, Blender and
tev follow) show a file's unprefixed ``R, G, B`` channels as linear light with Rec. 709 / sRGB primaries, 1 being
white. :func:`write_exr` with a ``view`` stores that picture there and the numbers a program needs (DN) in the
``noisy`` and ``clean`` layers, bit for bit; without a ``view`` the noisy values themselves go into ``R, G, B``
(or ``CFA``): the layout of camsim's frames before the view existed, and of the EXR a denoiser command reads
(:mod:`camsim.denoise.denoisers`). The readers take the noisy values from the ``noisy`` layer where there is one,
else from ``R, G, B`` (or ``CFA``), so both layouts read the same way.

Written with the OpenEXR 3.x Python bindings (``OpenEXR.File``) as a single-part, scanline, 32-bit float file with
extra string header attributes and a lossless compression (:data:`EXR_COMPRESSIONS`; default
:data:`DEFAULT_EXR_COMPRESSION`). :func:`read_exr` reads it back with OpenEXR and :func:`read_exr_oiio` with
OpenImageIO, an independent reader used by the tests to cross-check pixels and metadata.

Compression choice, measured on a 1152 x 864 frame (``python tools/bench_exr_compression.py``, whose table is in
the docs' benchmarks page; one OpenEXR thread, as a dataset worker writes; OpenEXR 3.5.3): the noisy layer is noise down
to the last bits of the mantissa, and no lossless method takes much off it (ZIP 4 %, ZSTD 19 %, HTJ2K 27 %), while ZIP
spends 4 to 6 times the time of an uncompressed write on a frame (0.27 to 0.44 s against 0.07 to 0.08 s) and reads
2 to 3 times slower; a dataset on two processes makes about half the frames per second with it. The clean layer
compresses only without PRNU and DSNU (piecewise constant: ZIP makes it 1 % of its size);
with them it is as incompressible as the noisy one. ``none`` is the default: a dataset is then bound by the noise
draws and the disk, not by the encoder, and every EXR reader reads the files. Each lossless name of
:data:`EXR_COMPRESSIONS` that the installed OpenEXR offers can be chosen (``--exr-compression``: ``zip`` halves
the files of sensors without fixed-pattern noise, ``htj2k32`` and ``zstd`` are the smallest, for readers with
OpenEXR 3.4 / 3.5); those that are lossy for float32 (PXR24 rounds it to 24 bits; DWAA, DWAB and LJ2K are lossy
transforms) are refused, and so are B44 and B44A, which compress HALF channels only and store camsim's float32
channels uncompressed (bit-exact, no smaller than ``none``). Every offered method is byte-deterministic (identical
bytes on repeated writes and for any thread count).
"""

from __future__ import annotations

import errno
import functools
import os
from collections.abc import Mapping
from typing import Any

import numpy as np
import OpenEXR

from camsim.core.errors import CamsimError, output_error
from camsim.core.input_files import check_input
from camsim.core.pixel_limit import check_pixel_count
from camsim.io.atomic import atomic_path
from camsim.io.exr_compression import (
    DEFAULT_EXR_COMPRESSION,
    EXR_COMPRESSIONS,
    check_exr_compression,
    exr_compressions,
)
from camsim.io.library_stderr import library_stderr

__all__ = ["write_exr", "read_exr", "read_exr_header", "read_exr_oiio", "VIEW_CHANNELS", "NOISY_CHANNELS",
           "MOSAIC_CHANNELS", "CLEAN_CHANNELS",
           "EXR_COMPRESSIONS", "DEFAULT_EXR_COMPRESSION", "exr_compressions", "check_exr_compression",
           "set_exr_threads", "restore_exr_threads"]

#: The picture a viewer shows (written with a ``view``).
VIEW_CHANNELS = ("R", "G", "B")
#: The noisy values beside a view: R, G, B at every pixel, or a colour filter array's mosaic (one per pixel).
NOISY_CHANNELS = ("noisy.R", "noisy.G", "noisy.B")
MOSAIC_CHANNELS = ("noisy.CFA",)
#: The noisy values without a view (and in every camsim frame written before the view existed).
PLAIN_NOISY_CHANNELS = ("R", "G", "B")
PLAIN_MOSAIC_CHANNELS = ("CFA",)
CLEAN_CHANNELS = ("clean.R", "clean.G", "clean.B")

# Header names the writer refuses: OpenEXR's standard attributes (they have fixed non-string types) and names
# OpenImageIO renames or drops on reading (owner -> Copyright, comments -> ImageDescription, capDate -> DateTime,
# ...), so that a written key reads back under the same name through both readers.
_RESERVED = frozenset({
    "channels", "compression", "dataWindow", "displayWindow", "lineOrder", "pixelAspectRatio", "screenWindowCenter",
    "screenWindowWidth", "tiles", "tiledesc", "type", "name", "version", "chunkCount", "view", "multiView",
    "maxSamplesPerPixel", "envmap", "wrapmodes", "chromaticities", "whiteLuminance", "adoptedNeutral",
    "renderingTransform", "lookModTransform", "xDensity", "owner", "comments", "capDate", "utcOffset", "longitude",
    "latitude", "altitude", "focus", "expTime", "aperture", "isoSpeed", "keyCode", "timeCode", "framesPerSecond",
    "cameraTransform", "worldToCamera", "worldToNDC", "deepImageState", "originalDataWindow", "dwaCompressionLevel",
    "zipCompressionLevel", "idManifest", "preview",
})
_RESERVED_PREFIXES = ("oiio:", "openexr:")


# String attributes OpenImageIO synthesises from the standard ones (besides the reserved prefixes).
_OIIO_SYNTHESISED = frozenset({"compression", "Copyright", "ImageDescription", "DateTime", "wrapmodes"})

_threads_configured = False


def _configure_threads() -> None:
    """Give OpenEXR's process-wide pool workers once (it defaults to 0 = single-threaded), unless the thread count
    was set (:func:`set_exr_threads`); output is unchanged."""
    global _threads_configured
    if not _threads_configured:
        if hasattr(OpenEXR, "set_global_thread_count") and OpenEXR.global_thread_count() == 0:
            OpenEXR.set_global_thread_count(min(os.cpu_count() or 1, 8))
        _threads_configured = True


def set_exr_threads(threads: int) -> tuple | None:
    """Have OpenEXR read and write with ``threads`` threads in all, process-wide: 1 = in the calling thread alone
    (no pool: measured 40 ms against 65 ms with one pool thread, for an uncompressed 1 MP frame), n > 1 = a pool of
    n threads while the caller waits. The files do not depend on it.

    Returns
    -------
    tuple or None
        The previous setting, for :func:`restore_exr_threads` (None where the bindings cannot set it).
    """
    global _threads_configured
    if not hasattr(OpenEXR, "set_global_thread_count"):
        return None
    previous = (OpenEXR.global_thread_count(), _threads_configured)
    size = 0 if threads == 1 else threads
    if previous[0] != size:
        OpenEXR.set_global_thread_count(size)
    _threads_configured = True
    return previous


def restore_exr_threads(previous: tuple | None) -> None:
    """Undo :func:`set_exr_threads` (``previous``: what it returned)."""
    global _threads_configured
    if previous is not None:
        count, _threads_configured = previous
        if OpenEXR.global_thread_count() != count:
            OpenEXR.set_global_thread_count(count)


def _check_frame(arr: Any, what: str, name: str, planes=(3,)) -> np.ndarray:
    if not isinstance(arr, np.ndarray) or arr.dtype.kind != "f" or arr.dtype.itemsize != 4 or arr.ndim != 3 \
            or arr.shape[0] not in planes or arr.shape[1] < 1 or arr.shape[2] < 1:
        shapes = " or ".join(f"({p}, H, W)" for p in planes)
        raise CamsimError(f"cannot write EXR {name}: {what} must be a float32 array of shape {shapes}, got "
                          f"{getattr(arr, 'dtype', type(arr).__name__)} {getattr(arr, 'shape', '')}")
    return arr.astype(np.float32, copy=False)  # native byte order


def _check_header(header: Mapping[str, str] | None, name: str) -> dict[str, str]:
    if header is not None and not isinstance(header, Mapping):
        raise CamsimError(f"cannot write EXR {name}: header must be a mapping str -> str, got {type(header).__name__}")
    out: dict[str, str] = {}
    for key, value in (header or {}).items():
        if not isinstance(key, str) or not key or "\x00" in key or key in _RESERVED \
                or key.startswith(_RESERVED_PREFIXES):
            raise CamsimError(f"cannot write EXR {name}: header key {key!r} is empty, reserved or not a string")
        # OpenImageIO drops empty string attributes; NUL would truncate them.
        if not isinstance(value, str) or not value or "\x00" in value:
            raise CamsimError(f"cannot write EXR {name}: header[{key!r}] must be a non-empty string without NUL, "
                              f"got {value!r}")
        out[key] = value
    return out


def write_exr(path: str | os.PathLike[str], noisy: np.ndarray, clean: np.ndarray | None,
              header: Mapping[str, str] | None, compression: str = DEFAULT_EXR_COMPRESSION,
              view: np.ndarray | None = None) -> None:
    """Write a float32 EXR with noisy and clean planes, optionally a viewer's picture, and string metadata,
    atomically and deterministically.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ``.exr`` file (its directory must exist).
    noisy : numpy.ndarray, shape (3, H, W) or (1, H, W), dtype float32
        Planar R, G, B of the simulated (noisy) signal, or a colour filter array's mosaic. Stored as channels
        ``noisy.R``, ``noisy.G``, ``noisy.B`` (a mosaic: ``noisy.CFA``) with a ``view``; without one as ``R``,
        ``G``, ``B`` (a mosaic: ``CFA``). Any float32 value (negative, inf, NaN) is stored bit-exactly. Unit: the
        caller's (camsim's frames: DN).
    clean : numpy.ndarray, shape (3, H, W), dtype float32, or None
        Planar noise-free signal, stored as ``clean.R``, ``clean.G``, ``clean.B``; omitted when None.
    header : Mapping[str, str] or None
        Extra header attributes, stored as EXR ``string`` attributes so that values survive byte-exactly. Keys
        must not be OpenEXR standard attribute names nor start with ``oiio:``/``openexr:``; values must be
        non-empty (OpenImageIO drops empty strings).
    compression : str
        A lossless name of :data:`EXR_COMPRESSIONS` (default :data:`DEFAULT_EXR_COMPRESSION`).
    view : numpy.ndarray, shape (3, H, W), dtype float32, or None
        The picture viewers show, stored as the unprefixed ``R``, ``G``, ``B`` (linear light, Rec. 709 / sRGB
        primaries, 1 = white, by the OpenEXR convention). None: no picture; the noisy values take ``R, G, B``.

    Raises
    ------
    CamsimError
        For arrays of the wrong dtype/shape, mismatched shapes, an unusable header entry or compression.

    Notes
    -----
    Single-part scanline file, 32-bit FLOAT channels (see the module docstring for the compression). The same
    inputs give byte-identical files.
    """
    name = os.fspath(path)
    try:
        constant = getattr(OpenEXR, EXR_COMPRESSIONS[check_exr_compression(compression)][0])
    except CamsimError as exc:
        raise CamsimError(f"cannot write EXR {name}: {exc}") from None
    noisy = _check_frame(noisy, "noisy", name, planes=(3, 1))
    channels = {}

    def add_layer(values, what, layer_names):  # a (3, H, W) layer beside ``noisy``, of its height and width
        values = _check_frame(values, what, name)
        if values.shape[1:] != noisy.shape[1:]:
            raise CamsimError(f"cannot write EXR {name}: {what} shape {values.shape} differs from noisy shape "
                              f"{noisy.shape}")
        channels.update({c: np.ascontiguousarray(values[i]) for i, c in enumerate(layer_names)})

    if view is not None:
        add_layer(view, "view", VIEW_CHANNELS)
        names = NOISY_CHANNELS if noisy.shape[0] == 3 else MOSAIC_CHANNELS
    else:
        names = PLAIN_NOISY_CHANNELS if noisy.shape[0] == 3 else PLAIN_MOSAIC_CHANNELS
    channels.update({c: np.ascontiguousarray(noisy[i]) for i, c in enumerate(names)})
    if clean is not None:
        add_layer(clean, "clean", CLEAN_CHANNELS)
    exr_header: dict[str, Any] = {"compression": constant, "type": OpenEXR.scanlineimage,
                                  "lineOrder": OpenEXR.INCREASING_Y}
    exr_header.update(_check_header(header, name))
    _configure_threads()
    with atomic_path(path) as tmp, OpenEXR.File(exr_header, channels) as exr:
        try:
            exr.write(str(tmp))
        except RuntimeError as exc:  # OpenEXR reports a failed write (no space, I/O error) as RuntimeError
            raise output_error(path, _exr_reason(exc)) from None


def _exr_reason(exc: RuntimeError) -> BaseException:
    """The reason inside OpenEXR's message (e.g. ``No space left on device``), as an OSError where one is named."""
    text = str(exc)
    for code in (errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EACCES, errno.EROFS, errno.EFBIG):
        if os.strerror(code) in text:
            return OSError(code, os.strerror(code))
    return exc


def _assemble(name: str, planes: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray | None]:
    names = _present_channels(name, list(planes))
    present = [c for c in CLEAN_CHANNELS if c in planes]
    if present and len(present) != 3:
        raise CamsimError(f"cannot read EXR {name}: has only some clean channels ({', '.join(present)})")
    for c in (*names, *present):
        if planes[c].dtype.kind != "f":
            raise CamsimError(f"cannot read EXR {name}: channel {c} is {planes[c].dtype}, expected float")
    noisy = np.stack([planes[c] for c in names]).astype(np.float32, copy=False)
    clean = np.stack([planes[c] for c in CLEAN_CHANNELS]).astype(np.float32, copy=False) if present else None
    return noisy, clean


def _string_attributes(header: Mapping[str, Any]) -> dict[str, str]:
    """The string-typed, non-standard attributes of an OpenEXR header, copied."""
    return {k: v for k, v in header.items() if isinstance(v, str) and k not in _RESERVED}


#: The most characters of OpenEXR's own messages added to a read error.
_LIBRARY_REASON_CHARS = 300


def _library_lines_into_the_error(read):
    """Run an EXR reader with what the OpenEXR library prints (``(EXR_ERR_CORRUPT_CHUNK) …`` lines on descriptor 2,
    the bindings' "Warning: Exception raised reading pixel data …" on descriptor 1, before their exception) captured
    (:func:`camsim.io.library_stderr.library_stderr`): a successful read drops them, a failed one adds their text to
    its one :class:`CamsimError` line."""

    @functools.wraps(read)
    def wrapper(path, *args, **kwargs):
        with library_stderr(stdout=True) as chatter:
            try:
                return read(path, *args, **kwargs)
            except CamsimError as exc:
                failure = exc
        reason = chatter.reason()[:_LIBRARY_REASON_CHARS]
        if reason and reason not in str(failure):
            raise type(failure)(f"{failure} (OpenEXR: {reason})") from failure
        raise failure

    return wrapper


@_library_lines_into_the_error
def read_exr(path: str | os.PathLike[str], *, clean: bool = True) \
        -> tuple[np.ndarray, np.ndarray | None, dict[str, str]]:
    """Read an EXR written by :func:`write_exr` with the OpenEXR bindings.

    Parameters
    ----------
    path : str or os.PathLike
        EXR file written by :func:`write_exr` (with or without a view).
    clean : bool, optional
        Also read the clean layer (default). False reads only the noisy channels, which for a frame with a
        clean layer takes half the memory: 12 B per pixel instead of 24 B (plus the returned array).

    Returns
    -------
    noisy : numpy.ndarray, shape (3, H, W) or (1, H, W), dtype float32
        The noisy values: channels ``noisy.R``, ``noisy.G``, ``noisy.B`` (a mosaic: ``noisy.CFA``) where the file
        has that layer, else ``R``, ``G``, ``B`` (a mosaic: ``CFA``). A viewer's picture is not returned.
    clean : numpy.ndarray, shape (3, H, W), dtype float32, or None
        Channels ``clean.R``, ``clean.G``, ``clean.B``, or None if the file has none of them or ``clean`` is
        False.
    header : dict of str to str
        The string-typed, non-standard header attributes.

    Raises
    ------
    CamsimError
        Naming ``path``, for a missing, unreadable, truncated or non-EXR file, or missing/partial channels.
    """
    name = _checked_name(path)
    _configure_threads()
    try:
        if not clean:
            return _read_noisy(name)
        _header(name)  # the size from the header, before OpenEXR.File decodes every channel
        with OpenEXR.File(name, separate_channels=True) as exr:
            # Copy everything before the file closes: closing empties the dict header() returned (measured with
            # the 3.5.3 bindings). _assemble's np.stack copies the pixel planes.
            header = _string_attributes(exr.header())
            noisy, clean_dn = _assemble(name, {k: v.pixels for k, v in exr.channels().items()})
    except CamsimError:
        raise
    except Exception as exc:  # the bindings raise RuntimeError or ValueError, depending on where the file breaks
        raise CamsimError(f"cannot read EXR {name}: {type(exc).__name__}: {exc}") from exc
    return noisy, clean_dn, header


def _read_noisy(name: str) -> tuple[np.ndarray, None, dict[str, str]]:
    """The noisy channels and the string attributes only.

    ``OpenEXR.File`` decodes every channel into memory; the bindings' older ``OpenEXR.InputFile`` decodes only
    the channels asked for, as bytes, which are copied into one (planes, H, W) array and freed one by one. Its
    header gives strings as bytes, so the header comes from ``OpenEXR.File(header_only=True)``.
    """
    import Imath  # the older bindings' types, installed with OpenEXR

    header, (n_planes, height, width) = _header(name)
    exr = OpenEXR.InputFile(name)
    try:
        channels = exr.header()["channels"]
        names = _present_channels(name, list(channels))
        for c in names:  # as _assemble: float channels only (HALF is widened to float32, as OpenEXR.File does)
            if channels[c].type.v == Imath.PixelType.UINT:
                raise CamsimError(f"cannot read EXR {name}: channel {c} is uint32, expected float")
        if not exr.isComplete():
            raise CamsimError(f"cannot read EXR {name}: the file is incomplete (truncated?)")
        planes = exr.channels(list(names), Imath.PixelType(Imath.PixelType.FLOAT))
        noisy = np.empty((n_planes, height, width), dtype=np.float32)
        for i in range(n_planes):
            noisy[i] = np.frombuffer(planes[i], dtype=np.float32).reshape(height, width)
            planes[i] = None  # free each plane's bytes once copied
        return noisy, None, header
    finally:
        exr.close()


@_library_lines_into_the_error
def read_exr_clean(path: str | os.PathLike[str]) -> tuple[np.ndarray | None, dict[str, str]]:
    """The clean layer and the string attributes of an EXR written by :func:`write_exr`, without its noisy image.

    As :func:`read_exr` with ``clean=False`` reads the noisy channels only, this decodes only ``clean.R``,
    ``clean.G``, ``clean.B`` (12 B per pixel, freed plane by plane).

    Returns
    -------
    clean : numpy.ndarray, shape (3, H, W), dtype float32, or None
        None if the file has no clean layer (or only part of it).
    header : dict of str to str

    Raises
    ------
    CamsimError
        Naming ``path``, for a missing, unreadable, truncated or non-EXR file.
    """
    import Imath  # the older bindings' types, installed with OpenEXR

    name = _checked_name(path)
    _configure_threads()
    try:
        header, (_, height, width) = _header(name)
        exr = OpenEXR.InputFile(name)
        try:
            channels = exr.header()["channels"]
            if any(c not in channels or channels[c].type.v == Imath.PixelType.UINT for c in CLEAN_CHANNELS):
                return None, header
            if not exr.isComplete():
                raise CamsimError(f"cannot read EXR {name}: the file is incomplete (truncated?)")
            planes = exr.channels(list(CLEAN_CHANNELS), Imath.PixelType(Imath.PixelType.FLOAT))
            clean = np.empty((len(CLEAN_CHANNELS), height, width), dtype=np.float32)
            for i in range(len(CLEAN_CHANNELS)):
                clean[i] = np.frombuffer(planes[i], dtype=np.float32).reshape(height, width)
                planes[i] = None
            return clean, header
        finally:
            exr.close()
    except CamsimError:
        raise
    except Exception as exc:  # the bindings raise RuntimeError or ValueError, depending on where the file breaks
        raise CamsimError(f"cannot read EXR {name}: {type(exc).__name__}: {exc}") from exc


def _present_channels(name: str, channels: list[str]) -> tuple[str, ...]:
    """The noisy channels of a file with ``channels``: the ``noisy`` layer's (``noisy.R, noisy.G, noisy.B`` or the
    mosaic's ``noisy.CFA``) where it has one, else ``R, G, B`` or the mosaic's ``CFA``; else CamsimError."""
    if any(c.startswith("noisy.") for c in channels):
        names = MOSAIC_CHANNELS if MOSAIC_CHANNELS[0] in channels and NOISY_CHANNELS[0] not in channels \
            else NOISY_CHANNELS
    else:
        names = PLAIN_MOSAIC_CHANNELS if PLAIN_MOSAIC_CHANNELS[0] in channels and "R" not in channels \
            else PLAIN_NOISY_CHANNELS
    missing = [c for c in names if c not in channels]
    if missing:
        raise CamsimError(f"cannot read EXR {name}: lacks channel(s) {', '.join(missing)} "
                          f"(has {', '.join(sorted(channels)) or 'none'})")
    return names


@_library_lines_into_the_error
def read_exr_header(path: str | os.PathLike[str]) -> tuple[dict[str, str], tuple[int, int, int]]:
    """The string attributes and the noisy image's shape of an EXR, without reading its pixels.

    Parameters
    ----------
    path : str or os.PathLike
        EXR file written by :func:`write_exr`.

    Returns
    -------
    header : dict of str to str
        The string-typed, non-standard header attributes (as :func:`read_exr` returns them).
    shape : tuple of int
        ``(planes, H, W)`` of the noisy image :func:`read_exr` would return: 3 planes (R, G, B) or 1 (a mosaic).
        Unit: pixels.

    Raises
    ------
    CamsimError
        Naming ``path``, for a missing, unreadable or non-EXR file, one without the noisy channels, or one whose
        data window is over the pixel limit (:func:`camsim.core.pixel_limit.check_pixel_count`).
    """
    name = _checked_name(path)
    try:
        return _header(name)
    except CamsimError:
        raise
    except Exception as exc:  # the bindings raise RuntimeError for a missing or foreign file
        raise CamsimError(f"cannot read EXR {name}: {type(exc).__name__}: {exc}") from exc


def _checked_name(path) -> str:
    """``path`` as a string once it names a regular file (:func:`camsim.core.input_files.check_input`): OpenEXR
    and OpenImageIO open a FIFO or a device by name and wait on it, or read it without end."""
    return os.fspath(check_input(path, "EXR"))


def _header(name: str) -> tuple[dict[str, str], tuple[int, int, int]]:
    """:func:`read_exr_header` without the translation of the bindings' exceptions; the data window's size is
    checked against the pixel limit, so that every reader refuses a header that declares more pixels than camsim
    decodes before it allocates or reads them."""
    with OpenEXR.File(name, header_only=True) as exr:
        raw = exr.header()
        header = _string_attributes(raw)
        names = _present_channels(name, [c.name for c in raw["channels"]])
        (x0, y0), (x1, y1) = ((int(v) for v in corner) for corner in raw["dataWindow"])
    check_pixel_count(x1 - x0 + 1, y1 - y0 + 1, f"EXR {name}")
    return header, (len(names), y1 - y0 + 1, x1 - x0 + 1)


def read_exr_oiio(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray | None, dict[str, str]]:
    """Read an EXR written by :func:`write_exr` with OpenImageIO; same returns and errors as :func:`read_exr`.

    Channels are mapped by name (OpenImageIO reorders them: ``R, G, B`` first, then the rest in name order). OpenImageIO
    synthesises string attributes of its own (``compression``, ``oiio:*``, ``openexr:*``, renamed standard
    attributes), which are left out of ``header``.
    """
    import OpenImageIO as oiio  # imported lazily: only the cross-check needs it

    name = _checked_name(path)
    inp = oiio.ImageInput.open(name)
    if inp is None:  # OpenImageIO's reasons run over several lines ("Uncompressed image size … exceeds …")
        reason = "; ".join(line.strip() for line in oiio.geterror().splitlines() if line.strip())
        raise CamsimError(f"cannot read EXR {name}: {reason or 'OpenImageIO could not open it'}")
    try:
        if inp.format_name() != "openexr":
            raise CamsimError(f"cannot read EXR {name}: OpenImageIO reads it as {inp.format_name()}, not OpenEXR")
        spec = inp.spec()
        check_pixel_count(spec.width, spec.height, f"EXR {name}")  # from the header, before the pixels
        pixels = inp.read_image(0, 0, 0, spec.nchannels, "float")  # (H, W, C) float32
        if pixels is None:
            reason = "; ".join(line.strip() for line in inp.geterror().splitlines() if line.strip())
            raise CamsimError(f"cannot read EXR {name}: {reason or 'pixel data unreadable'}")
        pixels = np.asarray(pixels).reshape(spec.height, spec.width, spec.nchannels)
        planes = {c: pixels[..., i] for i, c in enumerate(spec.channelnames)}
        header = {a.name: a.value for a in spec.extra_attribs
                  if a.type == "string" and a.name not in _OIIO_SYNTHESISED and a.name not in _RESERVED
                  and not a.name.startswith(_RESERVED_PREFIXES)}
    finally:
        inp.close()
    return (*_assemble(name, planes), header)
