"""The EXR compressions camsim knows, which of them it writes, and its default: light to import (no OpenEXR until a
name is checked), so that the command line can name them in its help.

See :mod:`camsim.io.exr` for the measurements behind the default (``python tools/bench_exr_compression.py``).
"""

from __future__ import annotations

from camsim.core.errors import CamsimError

__all__ = ["EXR_COMPRESSIONS", "DEFAULT_EXR_COMPRESSION", "LOSSLESS_EXR_COMPRESSIONS", "exr_compressions",
           "check_exr_compression"]

#: Every compression of OpenEXR 3.5, by camsim's name: (the bindings' constant, lossless for float32, note).
#: Lossless for float32: every bit of every FLOAT value (NaN payloads, -0, subnormals) reads back as written
#: (``tests/io/test_exr.py`` checks it through OpenEXR and OpenImageIO for each one offered).
EXR_COMPRESSIONS = {
    "none": ("NO_COMPRESSION", True, "uncompressed"),
    "rle": ("RLE_COMPRESSION", True, "run-length"),
    "zips": ("ZIPS_COMPRESSION", True, "zlib, one scanline a block"),
    "zip": ("ZIP_COMPRESSION", True, "zlib, 16 scanlines a block"),
    "piz": ("PIZ_COMPRESSION", True, "wavelet + Huffman"),
    "zstd": ("ZSTD_COMPRESSION", True, "Zstandard with byte shuffle (OpenEXR >= 3.5 reads it)"),
    "htj2k256": ("HTJ2K256_COMPRESSION", True, "High-Throughput JPEG 2000, 256 scanlines (OpenEXR >= 3.4)"),
    "htj2k32": ("HTJ2K32_COMPRESSION", True, "High-Throughput JPEG 2000, 32 scanlines (OpenEXR >= 3.4)"),
    "pxr24": ("PXR24_COMPRESSION", False, "lossy for float32: rounds it to 24 bits"),
    "b44": ("B44_COMPRESSION", False, "compresses HALF channels only, lossily: float32 is stored as with none"),
    "b44a": ("B44A_COMPRESSION", False, "compresses HALF channels only, lossily: float32 is stored as with none"),
    "dwaa": ("DWAA_COMPRESSION", False, "lossy: a DCT of the colour channels, 32 scanlines"),
    "dwab": ("DWAB_COMPRESSION", False, "lossy: a DCT of the colour channels, 256 scanlines"),
    "lj2k": ("LJ2K_COMPRESSION", False, "lossy: JPEG 2000 of the colour channels (OpenEXR >= 3.5)"),
}
#: The compression camsim writes unless told otherwise (:mod:`camsim.io.exr` says why).
DEFAULT_EXR_COMPRESSION = "none"
#: The names camsim writes where the installed OpenEXR offers them: lossless for float32.
LOSSLESS_EXR_COMPRESSIONS = tuple(name for name, (_, exact, _) in EXR_COMPRESSIONS.items() if exact)


def exr_compressions(lossless: bool = True) -> tuple[str, ...]:
    """The names of :data:`EXR_COMPRESSIONS` that the installed OpenEXR offers (only the lossless ones, by default)."""
    import OpenEXR

    return tuple(name for name, (constant, exact, _) in EXR_COMPRESSIONS.items()
                 if hasattr(OpenEXR, constant) and (exact or not lossless))


def check_exr_compression(name: str) -> str:
    """``name`` if camsim writes EXRs with it (lossless for float32 and offered by the installed OpenEXR), else
    :class:`CamsimError` saying why."""
    entry = EXR_COMPRESSIONS.get(name) if isinstance(name, str) else None
    if entry is None:
        raise CamsimError(f"unknown EXR compression {name!r}; lossless ones: {', '.join(exr_compressions())}")
    constant, exact, note = entry
    import OpenEXR

    if not exact:
        raise CamsimError(f"EXR compression {name!r} is refused: {note}; camsim's EXRs keep every float32 bit: "
                          f"use one of {', '.join(exr_compressions())}")
    if not hasattr(OpenEXR, constant):
        raise CamsimError(f"EXR compression {name!r} needs a newer OpenEXR than the installed "
                          f"{getattr(OpenEXR, '__version__', '?')}; this one offers {', '.join(exr_compressions())}")
    return name
