"""What a ``camsim render`` will write, known before the first frame: how many frames, of what size, how many bytes.

A scene file of two lines can ask for thousands of frames (26 illuminants × 200 intensity factors × a sequence of
100): :func:`estimate_render` counts them from the scene alone (the sizes an image's, a cube's or a raw's header
gives; nothing is decoded), and :func:`check_render_size` refuses a render above :data:`CONFIRM_FRAMES` frames or
:data:`CONFIRM_BYTES` bytes, or one larger than the output folder's free space, unless the user confirmed it
(``camsim render --yes``): a typo in a list should not fill a disk.

The bytes are an upper bound from the files' layouts (:func:`frame_bytes`), exact for the default uncompressed
EXR up to the sidecar's length: measured on a 600 × 400 ColorChecker frame (three-chip, 8-bit) the files are
720 662 B of DNG, 8 668 623 B of EXR, 29 459 B of JSON and 733 B of XMP against an estimate of 720 000, 8 640 000
and 65 536 (the sidecar's and the DNG's and EXR's headers' allowance).
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

from camsim.core.errors import CamsimError
from camsim.core.input_files import size_text

#: A render of more frames than this is refused unless confirmed (``--yes``).
CONFIRM_FRAMES = 1000
#: A render of more bytes than this is refused unless confirmed (``--yes``). Unit: bytes.
CONFIRM_BYTES = 10_000_000_000
#: What a frame writes beyond its pixels: the sidecar (a few kB per patch: 30 kB for 24 patches), the darktable
#: XMP, the DNG's and EXR's headers. Unit: bytes.
FRAME_OVERHEAD_BYTES = 65_536
#: The EXR's float32 layers besides the noisy one: the linear sRGB view (R, G, B) and the clean layer (3 planes).
EXR_OTHER_PLANES = 6


@dataclass(frozen=True)
class RenderEstimate:
    """What a render writes.

    Attributes
    ----------
    frames : int
        Frames written (a sequence's reference frames included).
    width_px, height_px : int
        Each frame's size. Unit: pixels.
    max_bytes : int
        At most this many bytes of files (uncompressed EXR; a compressed one is smaller). Unit: bytes.
    """

    frames: int
    width_px: int
    height_px: int
    max_bytes: int

    def text(self) -> str:
        """``"12 frames of 600x400, up to 112 MB"``."""
        return (f"{self.frames} frame{'' if self.frames == 1 else 's'} of {self.width_px}x{self.height_px}, "
                f"up to {size_text(self.max_bytes)}")


def frame_bytes(width: int, height: int, *, planes: int, bits: int, quantised: bool, preview: bool) -> int:
    """The most bytes one frame's files take: the DNG (``planes`` × 1 or 2 bytes per pixel, where quantised), the
    EXR (float32: the noisy planes and :data:`EXR_OTHER_PLANES`), an sRGB PNG preview (3 bytes per pixel, where
    asked) and :data:`FRAME_OVERHEAD_BYTES`. Unit: bytes."""
    pixels = width * height
    dng = pixels * planes * (1 if bits <= 8 else 2) if quantised else 0
    exr = pixels * 4 * (planes + EXR_OTHER_PLANES)
    return dng + exr + (3 * pixels if preview else 0) + FRAME_OVERHEAD_BYTES


def estimate_render(scene, *, preview: bool = False) -> RenderEstimate:
    """The frames and bytes ``scene`` renders to (every illuminant × intensity factor; a sequence's frames and its
    reference for each), from the scene and its source's header alone.

    Parameters
    ----------
    scene : camsim.scene.scene_file.Scene
    preview : bool
        Whether each frame also gets an sRGB PNG.
    """
    width, height = scene.source.own_size() if scene.source.has_own_size else (scene.width, scene.height)
    frames = len(scene.illuminants) * len(scene.intensity_factors)
    if scene.sequence is not None:
        frames *= scene.sequence.frames + 1  # each illuminant × F's frames and their reference
    sensor = scene.sensor
    one = frame_bytes(width, height, planes=1 if sensor.cfa is not None else 3, bits=sensor.bits,
                      quantised=sensor.quantisation, preview=preview)
    return RenderEstimate(frames, width, height, frames * one)


def _free_bytes(out_dir: Path) -> int | None:
    """The free space of the file system ``out_dir`` will be on (its nearest existing folder), or None."""
    folder = Path(out_dir).absolute()
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    try:
        return shutil.disk_usage(folder).free
    except OSError:
        return None


def check_render_size(estimate: RenderEstimate, out_dir, *, confirmed: bool) -> None:
    """Refuse a render above :data:`CONFIRM_FRAMES` frames or :data:`CONFIRM_BYTES` bytes, or larger than the free
    space where it is written, unless ``confirmed``.

    Raises
    ------
    CamsimError
        One line: what the render would write, the limit it passes, and ``--yes``.
    """
    if confirmed:
        return
    free = _free_bytes(out_dir)
    if free is not None and estimate.max_bytes > free:
        reason = f"more than the {size_text(free)} free there"
    elif estimate.frames > CONFIRM_FRAMES:
        reason = f"over {CONFIRM_FRAMES} frames"
    elif estimate.max_bytes > CONFIRM_BYTES:
        reason = f"over {size_text(CONFIRM_BYTES)}"
    else:
        return
    raise CamsimError(f"this render writes {estimate.text()}, to {out_dir}/: {reason}; check the scene's lists "
                      "(illuminants, intensity_factors, [sequence] frames), or pass --yes to write them")


__all__ = ["CONFIRM_BYTES", "CONFIRM_FRAMES", "RenderEstimate", "check_render_size", "estimate_render",
           "frame_bytes"]
