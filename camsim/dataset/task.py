"""The task a worker runs for one frame of a dataset (:func:`render_task`), in a local process or on a Dask
worker, and the OpenEXR thread setting it runs under."""

from __future__ import annotations

import hashlib
import tempfile
from pathlib import Path

from camsim.dataset.frame_render import render_files
from camsim.dataset.manifest import FRAMES_DIR, sha256_file
from camsim.dataset.spec import FrameSpec

__all__ = ["render_task", "exr_threads"]


def exr_threads(count: int) -> int | None:
    """Set OpenEXR's process-wide compression threads (camsim's EXR writer otherwise gives it every core);
    returns the previous count (None where the bindings cannot tell). The files do not depend on it."""
    try:
        import OpenEXR
    except ImportError:  # pragma: no cover - camsim needs OpenEXR
        return None
    if not hasattr(OpenEXR, "set_global_thread_count"):
        return None
    previous = OpenEXR.global_thread_count()
    if previous != count:
        OpenEXR.set_global_thread_count(count)
    return previous


def render_task(frame: FrameSpec, out_dir: str | None, threads: int = 1) -> dict:
    """A worker's task: render one frame on ``threads`` threads (the noise draws' and the EXR compression's).

    With ``out_dir``, the files go to ``out_dir/frames/`` and the result lists them (name relative to
    ``out_dir``, size, SHA-256). Without, they are rendered into a private temporary folder and the result also
    carries their bytes (``blobs``), for a worker that shares no file system with the caller.
    """
    exr_threads(threads)  # 1 thread: one compression thread while the caller waits, i.e. one core
    if out_dir is not None:
        folder = Path(out_dir) / FRAMES_DIR
        names = render_files(frame, folder, threads)
        files = {kind: None if name is None else
                 {"name": f"{FRAMES_DIR}/{name}", "bytes": (folder / name).stat().st_size,
                  "sha256": sha256_file(folder / name)}
                 for kind, name in names.items()}
        return {"id": frame.id, "files": files}
    with tempfile.TemporaryDirectory(prefix="camsim-frame-") as tmp:
        names = render_files(frame, Path(tmp), threads)
        blobs = {kind: (Path(tmp) / name).read_bytes() for kind, name in names.items() if name is not None}
    files = {kind: None if name is None else
             {"name": f"{FRAMES_DIR}/{name}", "bytes": len(blobs[kind]),
              "sha256": hashlib.sha256(blobs[kind]).hexdigest()}
             for kind, name in names.items()}
    return {"id": frame.id, "files": files, "blobs": blobs}
