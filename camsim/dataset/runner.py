"""Rendering a dataset: every frame of a spec, in parallel, resumable, with a JSON Lines manifest.

:func:`run_dataset` checks which frames are complete and verified (:mod:`camsim.dataset.manifest`, which also
describes the layout of ``OUT``), renders the others with one of the back-ends (:mod:`camsim.dataset.backends`),
each frame by :func:`camsim.dataset.task.render_task`, and keeps the manifest up to date. A re-run skips complete
frames and renders the others; a frame's files do not depend on the back-end, the number of processes or
threads, or the order the frames are rendered in. One run at a time writes into ``OUT``
(:func:`camsim.io.output_folder.output_folder`: the lock every camsim run takes).
"""

from __future__ import annotations

import time
from pathlib import Path

from tqdm import tqdm

from camsim.dataset._pool import start_fork_server
from camsim.dataset.backends import run_dask, run_pool, run_serial
from camsim.dataset.manifest import (
    DONE_SUFFIX,
    FRAMES_DIR,
    VERIFY_MODES,
    store_result,
    verified_record,
    write_manifest,
)
from camsim.dataset.spec import DatasetSpec, FrameSpec, load_spec
from camsim.dataset.task import render_task
from camsim.errors import CamsimError
from camsim.io.output_folder import output_folder
from camsim.render import default_workers

__all__ = ["run_dataset"]


def run_dataset(
    spec: DatasetSpec | str | Path,
    out_dir: str | Path,
    *,
    workers: int | None = None,
    threads: int = 1,
    scheduler: str | None = None,
    verify: str = "sha256",
    progress: bool = True,
    echo=print,
) -> dict:
    """Render every frame of ``spec`` into ``out_dir`` that is not already complete and verified.

    Parameters
    ----------
    spec : DatasetSpec or path of a spec file
    out_dir : path
        Output folder (created if needed).
    workers : int, optional
        Local processes (default: the machine's cores); 1 renders in this process. Not with ``scheduler``.
    threads : int
        Threads per frame, for the noise draws and OpenEXR's compression (default 1: one core per frame; the
        files do not depend on it).
    scheduler : str, optional
        Address of a ``dask.distributed`` scheduler (e.g. ``tcp://10.0.0.5:8786``): one task per frame there.
    verify : {'sha256', 'size'}
        How a re-run checks a complete frame's files: size and SHA-256 (default), or size only (cheaper).
    progress : bool
        Show a progress bar.
    echo : callable or None
        Where the status lines go (None: nowhere).

    Returns
    -------
    dict
        ``frames``, ``skipped``, ``rendered``, ``seconds`` (rendering wall time), ``frames_per_second``,
        ``megapixels_per_second``, ``backend``, ``manifest`` (path).
    """
    say = echo or (lambda *a, **k: None)
    if verify not in VERIFY_MODES:
        raise CamsimError(f"verify must be one of {VERIFY_MODES}, got {verify!r}")
    if scheduler is not None and workers is not None:
        raise CamsimError("give either --workers (local processes) or --scheduler (a Dask cluster), not both")
    if workers is not None and not (isinstance(workers, int) and workers >= 1):
        raise CamsimError(f"workers must be an integer ≥ 1, got {workers!r}")
    if not (isinstance(threads, int) and threads >= 1):
        raise CamsimError(f"threads must be an integer ≥ 1, got {threads!r}")
    if scheduler is None and workers != 1:
        start_fork_server()  # it imports camsim while the spec is read and the frames are checked
    spec = spec if isinstance(spec, DatasetSpec) else load_spec(spec)
    frames_dir = Path(out_dir) / FRAMES_DIR
    # created, checked, locked against other runs, swept of temporaries left by killed runs
    with output_folder(out_dir, subfolders=(FRAMES_DIR,)) as out_dir:
        records = {}
        todo = []
        check = tqdm(spec.frames, desc="checking complete frames", unit="frame", leave=False,
                     disable=not progress or len(spec.frames) < 2)
        for frame in check:
            record = verified_record(out_dir, frame, verify)
            if record is None:
                todo.append(frame)
            else:
                records[frame.index] = record
        known = {frame.id for frame in spec.frames}
        strays = sum(1 for p in frames_dir.glob(f"*{DONE_SUFFIX}") if p.name[: -len(DONE_SUFFIX)] not in known)
        manifest = write_manifest(out_dir, records)
        if scheduler is not None:
            backend = f"dask {scheduler}"
        else:
            workers = min(workers or default_workers(), max(1, len(todo)))
            backend = "1 process" if workers == 1 else f"{workers} processes"
        say(f"dataset {spec.name}: {len(spec.frames)} frames of {spec.size_text}, "
            f"{len(records)} complete and verified, {len(todo)} to render ({backend}, {threads} thread(s) each)"
            + (f"; {strays} records of other specs left in {frames_dir}" if strays else ""))

        bars = []  # the progress bar starts with the first frame recorded

        def on_done(frame: FrameSpec, result: dict) -> None:
            records[frame.index] = store_result(out_dir, frame, result)
            if not bars:
                bars.append(tqdm(total=len(todo), desc=f"dataset {spec.name}", unit="frame", disable=not progress))
            bars[0].update()

        start = time.perf_counter()
        try:
            if not todo:
                pass
            elif scheduler is not None:
                run_dask(render_task, todo, scheduler, threads, on_done)
            elif workers == 1:
                run_serial(render_task, todo, out_dir, threads, on_done)
            else:
                run_pool(render_task, todo, out_dir, workers, threads, on_done)
        finally:
            seconds = time.perf_counter() - start
            for bar in bars:
                bar.close()
            write_manifest(out_dir, records)  # whatever happened, every complete frame is listed
        rendered = len(todo)
    megapixels = sum(frame.megapixels for frame in todo)
    summary = {
        "name": spec.name,
        "frames": len(spec.frames),
        "skipped": len(spec.frames) - rendered,
        "rendered": rendered,
        "seconds": seconds,
        "frames_per_second": rendered / seconds if rendered and seconds > 0 else None,
        "megapixels_per_second": megapixels / seconds if rendered and seconds > 0 else None,
        "backend": backend,
        "manifest": str(manifest),
    }
    rate = "" if not rendered else (f" in {seconds:.2f} s: {summary['frames_per_second']:.2f} frames/s, "
                                    f"{summary['megapixels_per_second']:.2f} MP/s")
    say(f"rendered {rendered} frames{rate} ({backend}); skipped {summary['skipped']} complete; "
        f"manifest: {manifest}")
    return summary
