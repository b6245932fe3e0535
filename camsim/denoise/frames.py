"""The frames ``camsim denoise-eval`` scores: camsim EXR frames found under folders (searched recursively, committed
frames only: :func:`camsim.render.frame_files.search_frames`) and files — layer ``noisy.R/G/B`` = the noisy DN before
quantisation (a Bayer frame's ``noisy.CFA``: the mosaic), layer ``clean.R/G/B`` = their expected value (for a Bayer
frame, of every colour at every pixel), header ``camsim:metadata`` = the sidecar. Three-chip and Bayer (CFA) frames
are both scored (a Bayer frame as :mod:`camsim.denoise.bayer` says). Bayer frames of an odd width or height, EXRs
without a clean layer, uncommitted EXRs and other files are skipped, each with its reason.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.render.frame_files import load_frame, search_frames

#: Why an EXR in a folder that no sidecar claims is not scored.
UNCOMMITTED = "uncommitted: no sidecar claims it (a frame being written, or left by an interrupted writer)"


@dataclass
class DatasetFrame:
    """A usable frame of a dataset: its path, its path relative to the dataset folder, and its sidecar."""

    path: Path
    name: str
    meta: dict


@dataclass
class Dataset:
    """The scorable frames found, the files skipped (with the reason) and the folders and files searched."""

    frames: list[DatasetFrame]
    skipped: list[dict]  # {"file", "reason"}
    roots: list[str]


def _relative(path: Path, root: Path) -> str:
    try:
        return str(path.relative_to(root))
    except ValueError:
        return str(path)


def find_dataset(paths) -> Dataset:
    """The EXR frames under ``paths`` (folders searched recursively, or files) that can be scored.

    In folders only committed frames count (the sidecar, written last, names the EXR); hidden files are passed
    over. Bayer (CFA) frames of an odd width or height (they cannot be packed into 2 × 2 cells), EXRs without a
    clean layer, uncommitted EXRs, unreadable sidecars and files that are not camsim frames are skipped, each with
    its reason.

    Raises
    ------
    CamsimError
        A path that does not exist, or no usable frame at all.
    """
    from camsim.io.exr import read_exr

    frames, skipped, roots = [], [], []
    for entry in paths:
        entry = Path(entry)
        if entry.is_dir():
            search, root = search_frames([entry], "exr"), entry
            candidates = [p for p in search.files if p.suffix.lower() == ".exr"]
            skipped += [{"file": _relative(p, root), "reason": f"not a readable camsim frame: {reason}"}
                        for p, reason in search.bad]
            skipped += [{"file": _relative(p, root), "reason": UNCOMMITTED}
                        for p in search.uncommitted if p.suffix.lower() == ".exr"]
        elif entry.is_file():
            candidates, root = [entry], entry.parent
        else:
            raise CamsimError(f"no such file or folder: {entry}")
        roots.append(str(entry))
        for path in candidates:
            name = _relative(path, root)
            try:
                frame = load_frame(path)
            except CamsimError as exc:
                skipped.append({"file": name, "reason": f"not a readable camsim frame: {exc}"})
                continue
            height, width = frame.pixels_dn.shape[1:]
            if frame.cfa_pattern and (height % 2 or width % 2):
                skipped.append({"file": name, "reason": f"Bayer (CFA {frame.cfa_pattern}) mosaic of {width}x{height} "
                                                        "pixels: an odd width or height cannot be packed into 2 × 2 "
                                                        "cells (R, G1, G2, B)"})
                continue
            _, clean, _ = read_exr(path)
            if clean is None:
                skipped.append({"file": name, "reason": "no clean layer (clean.R/G/B) to score against"})
                continue
            if not (np.isfinite(frame.pixels_dn).all() and np.isfinite(clean).all()):  # a damaged file's values
                skipped.append({"file": name, "reason": "non-finite values (NaN or infinity) in its noisy or clean "
                                                        "layer"})
                continue
            frames.append(DatasetFrame(path, name, frame.meta))
    if not frames:
        reasons = "; ".join(f"{s['file']}: {s['reason']}" for s in skipped[:3])
        raise CamsimError(f"no scorable frames (camsim EXR with a clean layer) in "
                          f"{', '.join(str(p) for p in paths)}" + (f" — skipped {reasons}" if reasons else ""))
    return Dataset(frames, skipped, roots)
