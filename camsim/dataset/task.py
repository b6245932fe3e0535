"""The tasks a worker runs for one frame of a dataset, in a local process or on a Dask worker: :func:`render_task`
(the file layout, with OpenEXR set to the task's ``threads``: :func:`camsim.io.exr.set_exr_threads`) and
:func:`zarr_task` (a Zarr store)."""

from __future__ import annotations

import hashlib
import json
import tempfile
from pathlib import Path

from camsim.dataset.frame_render import render_burst, render_files, render_frame
from camsim.dataset.manifest import FRAMES_DIR, sha256_file
from camsim.dataset.spec_parts import FrameSpec
from camsim.io.exr import set_exr_threads
from camsim.io.exr_compression import DEFAULT_EXR_COMPRESSION

__all__ = ["render_task", "zarr_task"]


def render_task(frame: FrameSpec, out_dir: str | None, threads: int = 1,
                exr_compression: str = DEFAULT_EXR_COMPRESSION, srgb: str = "none") -> dict:
    """A worker's task: render one frame on ``threads`` threads (the noise draws' and the EXR compression's), its
    EXR compressed with ``exr_compression``, with its developed sRGB PNGs for ``srgb`` other than ``none``
    (:mod:`camsim.dataset.srgb`; the result's ``srgb`` says what they hold).

    With ``out_dir``, the files go to ``out_dir/frames/`` and the result lists them (name relative to
    ``out_dir``, size, SHA-256). Without, they are rendered into a private temporary folder and the result also
    carries their bytes (``blobs``), for a worker that shares no file system with the caller.
    """
    set_exr_threads(threads)  # 1 thread: OpenEXR works in this thread, i.e. one core
    if out_dir is not None:
        folder = Path(out_dir) / FRAMES_DIR
        names, srgb_record = render_files(frame, folder, threads, exr_compression, srgb)
        burst = _burst_entry(names)
        files = {kind: None if name is None else
                 {"name": f"{FRAMES_DIR}/{name}", "bytes": (folder / name).stat().st_size,
                  "sha256": sha256_file(folder / name)}
                 for kind, name in names.items()}
        return ({"id": frame.id, "exr_compression": exr_compression, "files": files} | _srgb_entry(srgb_record)
                | burst)
    with tempfile.TemporaryDirectory(prefix="camsim-frame-") as tmp:
        names, srgb_record = render_files(frame, Path(tmp), threads, exr_compression, srgb)
        burst = _burst_entry(names)
        blobs = {kind: (Path(tmp) / name).read_bytes() for kind, name in names.items() if name is not None}
    files = {kind: None if name is None else
             {"name": f"{FRAMES_DIR}/{name}", "bytes": len(blobs[kind]),
              "sha256": hashlib.sha256(blobs[kind]).hexdigest()}
             for kind, name in names.items()}
    return ({"id": frame.id, "exr_compression": exr_compression, "files": files, "blobs": blobs}
            | _srgb_entry(srgb_record) | burst)


def _burst_entry(names: dict) -> dict:
    """The result's ``burst`` (which frames make a burst: :func:`camsim.dataset.frame_render.render_burst_files`),
    taken out of ``names``; nothing for a single frame."""
    burst = names.pop("burst", None)
    return {} if burst is None else {"burst": burst}


def _srgb_entry(record: dict | None) -> dict:
    """The result's ``srgb`` (what the sRGB outputs hold), or nothing without them."""
    return {} if record is None else {"srgb": record}


def zarr_task(frame: FrameSpec, out_dir: str | None, threads: int = 1, *, layout) -> dict:
    """A worker's task for a Zarr store (:mod:`camsim.dataset.zarr_store`, whose ``layout`` it is): render one
    frame on ``threads`` threads and write its chunks into the store (with ``out_dir``; the result lists them), or,
    without, send its arrays and sidecar back (``data``, ``sidecar``) for the caller to write."""
    from camsim.dataset.zarr_store import STORE_NAME, burst_arrays, frame_arrays, write_frame_arrays
    from camsim.render.frame_files import sidecar

    where = {"store": STORE_NAME, "index": frame.index}
    if frame.burst is not None:  # a burst: its frames stacked, its reference, and one sidecar of them all
        frames, extras, metas, reference, srgb_record = [], [], [], None, None
        for index, _, rendered, info, extra in render_burst(frame, threads):
            meta = sidecar(rendered, info, None)
            if index == "ref":
                reference, reference_info, reference_meta = rendered, info, meta | {"zarr": where}
            else:
                frames.append(rendered)
                extras.append(extra)
                metas.append(meta | {"zarr": where | {"burst_frame": index}})
        data, srgb_record = burst_arrays(frames, reference, layout, extras, reference_info)
        meta = {"reference": reference_meta, "frames": metas}
    else:
        rendered, info = render_frame(frame, threads)
        data, srgb_record = frame_arrays(rendered, layout, info)
        meta = sidecar(rendered, info, None) | {"zarr": where}
    text = json.dumps(meta, ensure_ascii=False, allow_nan=False)
    if out_dir is None:
        return {"id": frame.id, "data": data, "sidecar": text} | _srgb_entry(srgb_record)
    return ({"id": frame.id, "arrays": write_frame_arrays(layout, frame.index, data, text, threads)}
            | _srgb_entry(srgb_record))
