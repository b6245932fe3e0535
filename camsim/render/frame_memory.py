"""The memory a scene's frame needs, estimated from its size before anything is decoded, and the check of it
against the memory free (:mod:`camsim.core.memory_limit`, whose figures are measured).

The size comes from the scene: ``[frame]`` (or ``--size``) for a chart or a target, the file's header for an image or
a cube (read by the source's ``own_size``, which the render's checks read anyway, and cached). An image's
distinct colours are bounded by its codes (2²⁴ for 8-bit RGB, 256 for 8-bit grey; by its pixels for float codes or
once resampled: :func:`camsim.scene.sources.image.image_colour_limit`), a cube's
spectra are its pixels, and a lens (``[optics]``) adds its FFTs. A raw scene (``[raw]``) is not estimated here: its
frame is a camera's, read by :mod:`camsim.io.raw_capture`.
"""

from __future__ import annotations

from camsim.core.memory_limit import (
    COLOUR_BYTES,
    CUBE_BYTES_PER_PIXEL,
    FRAME_BYTES_PER_PIXEL,
    OPTICS_BYTES_PER_PIXEL,
    RESIZE_BYTES_PER_SOURCE_PIXEL,
    FrameNeed,
    check_frame_memory,
)


def frame_need(scene) -> FrameNeed | None:
    """The size of ``scene``'s frame and the memory rendering one needs; None for a raw scene.

    Parameters
    ----------
    scene : camsim.scene.scene_file.Scene
        The scene as it will be rendered (command-line options applied).

    Raises
    ------
    CamsimError
        Where the source's file cannot be read or its header is over a limit (as the render would say).
    """
    source = scene.source
    per_pixel = OPTICS_BYTES_PER_PIXEL if getattr(scene, "optics", None) is not None else FRAME_BYTES_PER_PIXEL
    if source.table == "raw":
        return None
    if source.table == "image":
        from camsim.scene.sources.image import image_colour_limit, image_file_size

        width, height = source.own_size()  # the crop's and size's checks, from the header
        path = str(source.path)
        file_width, file_height = image_file_size(path)
        limit = image_colour_limit(path)
        cropped = (source.crop[2], source.crop[3]) if source.crop is not None else (file_width, file_height)
        pixels = width * height
        decoded = cropped[1] * file_width  # whole rows are decoded, the crop's columns kept
        resampled = source.size is not None and tuple(source.size) != cropped
        if resampled:  # float colours, up to one per pixel; the file's pixels in float64 for the filter
            colours = pixels
            extra = decoded * RESIZE_BYTES_PER_SOURCE_PIXEL
        else:
            colours = pixels if limit is None else min(pixels, limit)
            code_bytes = 4 if limit is None else 2  # float32 codes, else uint16 at most
            extra = (decoded - pixels) * 3 * code_bytes  # the decoded rows' columns outside the crop
        plain = source.crop is None and not resampled
        what = f"image {path}" if plain else f"the frame of image {path} ([image] crop or size)"
        return FrameNeed(what, width, height, pixels * per_pixel + colours * COLOUR_BYTES + extra)
    if source.table == "cube":
        from camsim.io.cube_files import cube_header

        header = cube_header(source.path, variable=getattr(source, "variable", None))
        pixels = header.width * header.height
        resident = pixels * (per_pixel - FRAME_BYTES_PER_PIXEL + CUBE_BYTES_PER_PIXEL)
        if header.mapped:
            return FrameNeed(f"cube {source.path}", header.width, header.height, resident, header.data_bytes)
        return FrameNeed(f"cube {source.path}", header.width, header.height, resident + header.data_bytes)
    width, height = scene.width, scene.height
    return FrameNeed("frame", width, height, width * height * per_pixel)


def check_scene_memory(scene, max_megapixels: float | None = None) -> None:
    """Refuse ``scene`` before anything is decoded or drawn where its frame does not fit in the memory free, or is
    over ``max_megapixels`` where that is given (:func:`camsim.core.memory_limit.check_frame_memory`).

    Parameters
    ----------
    scene : camsim.scene.scene_file.Scene
        The scene as it will be rendered.
    max_megapixels : float, optional
        ``--max-megapixels``: the largest frame allowed, whatever the memory free. Unit: megapixels.

    Raises
    ------
    CamsimError
        One line naming the frame's size, the memory it needs, the memory free and the ``--max-megapixels`` that
        allows it.
    """
    need = frame_need(scene)
    if need is not None:
        check_frame_memory(need, max_megapixels)


__all__ = ["check_scene_memory", "frame_need"]
