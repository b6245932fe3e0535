"""The one limit on the size of what camsim renders or decodes: :data:`MAX_PIXELS`, checked by
:func:`check_pixel_count` wherever a size comes from the user or from a file's header — ``--size``, a scene's
``[frame] width/height`` and ``[image] size``, an image file's header (before its pixels are decoded), a cube
file's header (before its data is read), a dataset spec's ``[frame]`` and ``[images] crop``.

A 200-megapixel frame takes gigabytes to render; a file header that claims more (a "decompression bomb": a few
kilobytes of PNG that decode to 30 000 × 30 000 pixels) is refused from the header alone, in milliseconds.
"""

from __future__ import annotations

from camsim.core.errors import CamsimError

#: The most pixels (width × height) camsim renders, or decodes from an image or cube file.
MAX_PIXELS = 200_000_000
#: The most bytes an input image file may have: :data:`MAX_PIXELS` of four float32 channels (RGBA, uncompressed),
#: 3.2 GB, and 64 MB of header and metadata. A file larger than any image camsim may decode is refused before it is
#: read (a dataset hashes its images whole). Unit: bytes.
MAX_IMAGE_FILE_BYTES = MAX_PIXELS * 4 * 4 + 64_000_000


def check_pixel_count(width, height, what: str) -> tuple[int, int]:
    """Check that ``width`` × ``height`` is a size camsim may render or decode; returns (width, height).

    Parameters
    ----------
    width, height : int
        The size in pixels (positive integers; Python's, so that their product cannot overflow).
    what : str
        What has this size, for the message (e.g. ``"[frame]"``, ``"image /path/x.png"``).

    Raises
    ------
    CamsimError
        A size that is not two positive integers, or whose product is over :data:`MAX_PIXELS`.
    """
    for value in (width, height):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise CamsimError(f"{what}: width and height must be positive integers (pixels), got "
                              f"{width!r} × {height!r}")
    if width * height > MAX_PIXELS:
        raise CamsimError(f"{what} is {width} × {height} pixels, over camsim's limit of "
                          f"{MAX_PIXELS // 1_000_000} megapixels")
    return width, height
