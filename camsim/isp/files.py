"""Developing frame files: a camsim DNG (with its sidecar, or from its own tags), or EXR, into a PNG (and JPEG) and
a JSON record in an output folder."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.names import MAX_STEM_BYTES, safe_component
from camsim.isp.develop import IspSettings, develop
from camsim.isp.facts import IspFacts, facts_from_dng_tags, facts_of
from camsim.isp.writers import write_jpeg, write_png

__all__ = ["FrameToDevelop", "read_frame_to_develop", "output_names", "develop_file"]


@dataclass(frozen=True, eq=False)
class FrameToDevelop:
    """A frame file's numbers and facts.

    Attributes
    ----------
    path : Path
    raw : numpy.ndarray, shape (3, H, W) or (1, H, W)
        The numbers: a DNG's quantised digital numbers, an EXR's float values before quantisation. Unit: DN.
    facts : IspFacts
    source : str
        ``"sidecar"`` (a camsim DNG with its sidecar, or an EXR with its metadata) or ``"dng-tags"`` (a DNG
        without a sidecar, developed from its own tags).
    """

    path: Path
    raw: np.ndarray
    facts: IspFacts
    source: str


def read_frame_to_develop(path) -> FrameToDevelop:
    """Read a frame for the ISP: a ``.dng`` with its ``.json`` sidecar beside it, a ``.dng`` without one (its tags:
    BlackLevel, WhiteLevel, CFAPattern, AsShotNeutral, ColorMatrix1), or an ``.exr`` (its header's metadata).

    Raises
    ------
    CamsimError
        Not a frame file, unreadable, truncated or foreign, a sidecar that does not fit.
    """
    from camsim.render.frame_files import SIDECAR_SUFFIX, load_frame

    path = Path(path)
    kind = path.suffix.lower()
    if kind == ".dng" and not path.with_suffix(SIDECAR_SUFFIX).exists():
        from camsim.io.dng import read_dng

        raw, tags = read_dng(path)
        try:
            facts = facts_from_dng_tags(tags)
        except CamsimError as exc:  # a tag out of range: say which file
            raise CamsimError(f"{path}: {exc}") from None
        return FrameToDevelop(path, raw, facts, "dng-tags")
    loaded = load_frame(path)
    return FrameToDevelop(path, loaded.pixels_dn, facts_of(loaded), "sidecar")


def output_names(paths) -> list[str]:
    """The output stem of each frame file: its own stem, checked as a safe file name
    (:func:`camsim.core.names.safe_component`); two frames with the same stem are refused (their outputs would
    overwrite each other)."""
    stems: dict[str, Path] = {}
    out = []
    for path in map(Path, paths):
        stem = safe_component(path.stem, "frame file name", MAX_STEM_BYTES)
        if stem in stems:
            raise CamsimError(f"two frames would write the same outputs {stem}.png: {stems[stem]} and {path}; "
                              "develop them into different --out folders")
        stems[stem] = path
        out.append(stem)
    return out


def develop_file(frame: FrameToDevelop, out_dir, stem: str, settings: IspSettings, *, bits: int = 8,
                 jpeg_quality: int | None = None) -> dict:
    """Develop one frame into ``out_dir``: ``STEM.png`` (``bits`` 8 or 16; the record in its text chunk), with
    ``jpeg_quality`` ``STEM.jpg``, and ``STEM.json`` (the record), each written atomically. Returns the record
    written (with ``files``: the names written, and ``frame``: the frame file developed)."""
    from camsim.io.atomic import write_json_atomic

    out_dir = Path(out_dir)
    developed = develop(frame.raw, frame.facts, settings)
    files = {"png": f"{stem}.png", **({"jpeg": f"{stem}.jpg"} if jpeg_quality is not None else {}),
             "json": f"{stem}.json"}
    record = {**developed.record, "frame": frame.path.name, "frame_metadata": frame.source,
              "output": {"png_bits": bits, "jpeg_quality": jpeg_quality,
                         "encoding": "round(v * (2^bits - 1)) of the toned values clipped to [0, 1]"},
              "files": files}
    write_png(out_dir / files["png"], developed.image, bits, record)
    if jpeg_quality is not None:
        write_jpeg(out_dir / files["jpeg"], developed.image, jpeg_quality, record)
    write_json_atomic(out_dir / files["json"], record)
    return record
