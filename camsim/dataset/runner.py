"""Rendering a dataset: every frame of a spec, in parallel, resumable, with a JSON Lines manifest.

:func:`run_dataset` checks which frames are complete and verified (:mod:`camsim.dataset.manifest`, which also
describes the layout of ``OUT``; :mod:`camsim.dataset.zarr_store` for a Zarr store), renders the others with one of
the back-ends (:mod:`camsim.dataset.backends`), each frame by :func:`camsim.dataset.task.render_task` (or
:func:`~camsim.dataset.task.zarr_task`), and keeps the manifest up to date. A re-run skips complete frames and
renders the others; a frame's files (or chunks) do not depend on the back-end, the number of processes or
threads, or the order the frames are rendered in. One run at a time writes into ``OUT``
(:func:`camsim.io.output_folder.output_folder`: the lock every camsim run takes).

What depends only on the scene, illuminant, camera and sensor (the lit scene, the camera's curves, the DNG colour
tags, the fixed-pattern maps) is computed once per worker process and kept (:mod:`camsim.dataset.frame_render`);
the workers start from a fork server that imported camsim (and colour-science, and zarr for a store) while the
spec was read, so that no frame pays for imports.
"""

from __future__ import annotations

import time
from functools import partial
from pathlib import Path

from tqdm import tqdm

from camsim.core.errors import CamsimError
from camsim.dataset import zarr_store  # light: zarr itself is imported when a store is opened
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
from camsim.dataset.spec import check_srgb, load_spec
from camsim.dataset.spec_parts import DatasetSpec, FrameSpec
from camsim.dataset.srgb import srgb_bits
from camsim.dataset.task import render_task, zarr_task
from camsim.io.exr_compression import DEFAULT_EXR_COMPRESSION, check_exr_compression
from camsim.io.output_folder import output_folder
from camsim.render.frame import default_workers

__all__ = ["run_dataset", "check_settings", "check_output_of", "FORMATS"]

#: Output formats: ``files`` (a DNG, an EXR and a JSON sidecar per frame) or ``zarr`` (one Zarr store).
FORMATS = ("files", "zarr")


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
    exr_compression: str | None = None,
    output: str = "files",
    srgb: str | None = None,
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
    exr_compression : str, optional
        The EXR files' compression (a lossless name of :data:`camsim.io.exr.EXR_COMPRESSIONS`); default the spec's
        ``exr_compression``, else :data:`camsim.io.exr.DEFAULT_EXR_COMPRESSION`. Frames already complete keep
        theirs. Not with ``output="zarr"``.
    output : {'files', 'zarr'}
        ``files``: ``OUT/frames/ID.{dng,exr,json}`` (:mod:`camsim.dataset.manifest`); ``zarr``: one Zarr store,
        ``OUT/dataset.zarr`` (:mod:`camsim.dataset.zarr_store`).
    srgb : {'none', 'png', 'png16'}, optional
        Each frame's noisy and clean layers developed through one camera ISP as 8-bit (``png``) or 16-bit
        (``png16``) sRGB (:mod:`camsim.dataset.srgb`): ``ID_srgb_noisy.png`` and ``ID_srgb_clean.png``, or the
        store's arrays ``srgb_noisy`` and ``srgb_clean``. Default the spec's ``srgb``, else (a Zarr store) the
        existing store's, else ``none``. Complete frames of the file layout without it are rendered again (the same
        bytes) with it; a store holds one sRGB output (another is refused).

    Returns
    -------
    dict
        ``frames``, ``skipped``, ``rendered``, ``seconds`` (rendering wall time), ``frames_per_second`` (items: a
        burst counts once; ``megapixels_per_second`` counts each of its frames),
        ``megapixels_per_second``, ``backend``, ``manifest`` (path), ``format``, ``exr_compression`` (None for
        a store), ``store`` (the store's path, or None), ``srgb`` (the sRGB output).
    """
    say = echo or (lambda *a, **k: None)
    check_settings(workers=workers, threads=threads, scheduler=scheduler, verify=verify,
                   exr_compression=exr_compression, output=output, srgb=srgb)
    if scheduler is None and workers != 1:
        start_fork_server(zarr=output == "zarr")  # it imports camsim while the spec is read and frames checked
    spec = spec if isinstance(spec, DatasetSpec) else load_spec(spec)
    if output == "zarr" and not (srgb or spec.srgb):
        srgb = zarr_store.held_srgb(out_dir)  # a store keeps its sRGB arrays when a re-run does not name them
    srgb = check_srgb(srgb or spec.srgb or "none")
    check_output_of(spec, output, srgb)
    if output == "files":
        exr_compression = check_exr_compression(exr_compression or spec.exr_compression or DEFAULT_EXR_COMPRESSION)
    records_dir = FRAMES_DIR if output == "files" else zarr_store.RECORDS_DIR
    # created, checked, locked against other runs, swept of temporaries left by killed runs
    with output_folder(out_dir, subfolders=(records_dir,)) as out_dir:
        _check_format(out_dir, output)
        store = layout = None
        if output == "zarr":
            layout = zarr_store.store_layout(spec, out_dir, srgb)
            store = zarr_store.open_store(layout, spec)
            verified = partial(zarr_store.verified_record, out_dir, store)
        else:
            verified = partial(verified_record, out_dir, srgb=srgb)
        records = {}
        todo = []
        check = tqdm(spec.frames, desc="checking complete frames", unit="frame", leave=False,
                     disable=not progress or len(spec.frames) < 2)
        for frame in check:
            record = verified(frame, verify=verify)
            if record is None:
                todo.append(frame)
            else:
                records[frame.index] = record
        known = {frame.id for frame in spec.frames}
        strays = sum(1 for p in (out_dir / records_dir).glob(f"*{DONE_SUFFIX}")
                     if p.name[: -len(DONE_SUFFIX)] not in known)
        manifest = write_manifest(out_dir, records)
        if store is not None:
            zarr_store.write_done(store, records)
        if scheduler is not None:
            backend = f"dask {scheduler}"
        else:
            workers = min(workers or default_workers(), max(1, len(todo)))
            backend = "1 process" if workers == 1 else f"{workers} processes"
        where = (f"into {layout.path}" if store is not None
                 else f"EXR compression {exr_compression}" + _kept_compressions(records, exr_compression))
        if srgb != "none":
            where += f"; sRGB {srgb_bits(srgb)}-bit, noisy and clean through one ISP"
        bursts = {frame.burst.frames for frame in spec.frames if frame.burst is not None}
        kind = "frames" if not bursts else f"bursts of {'/'.join(map(str, sorted(bursts)))} frames"
        say(f"dataset {spec.name}: {len(spec.frames)} {kind} of {spec.size_text}, "
            f"{len(records)} complete and verified, {len(todo)} to render ({backend}, {threads} thread(s) each; "
            f"{where})"
            + (f"; {strays} records of other specs left in {out_dir / records_dir}" if strays else ""))

        bars = []  # the progress bar starts with the first frame recorded

        def on_done(frame: FrameSpec, result: dict) -> None:
            if store is not None:
                records[frame.index] = zarr_store.store_result(out_dir, store, layout, frame, result, threads)
            else:
                records[frame.index] = store_result(out_dir, frame, result)
            if not bars:
                bars.append(tqdm(total=len(todo), desc=f"dataset {spec.name}", unit="frame", disable=not progress))
            bars[0].update()

        task = (partial(zarr_task, layout=layout) if store is not None
                else partial(render_task, exr_compression=exr_compression, srgb=srgb))
        start = time.perf_counter()
        try:
            if not todo:
                pass
            elif scheduler is not None:
                run_dask(task, todo, scheduler, threads, on_done)
            elif workers == 1:
                run_serial(task, todo, out_dir, threads, on_done)
            else:
                run_pool(task, todo, out_dir, workers, threads, on_done)
        finally:
            seconds = time.perf_counter() - start
            for bar in bars:
                bar.close()
            write_manifest(out_dir, records)  # whatever happened, every complete frame is listed
            if store is not None:
                zarr_store.write_done(store, records)
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
        "format": output,
        "exr_compression": exr_compression if store is None else None,
        "store": None if layout is None else layout.path,
        "srgb": srgb,
    }
    drawn = sum(1 if frame.burst is None else frame.burst.frames for frame in todo)  # a burst's frames, each
    items = f"{rendered} frames" if drawn == rendered else f"{rendered} bursts ({drawn} frames)"
    rate = "" if not rendered else (f" in {seconds:.2f} s: {drawn / seconds:.2f} frames/s, "
                                    f"{summary['megapixels_per_second']:.2f} MP/s")
    say(f"rendered {items}{rate} ({backend}); skipped {summary['skipped']} complete; manifest: {manifest}")
    return summary


def check_settings(*, workers: int | None = None, threads: int = 1, scheduler: str | None = None,
                   verify: str = "sha256", exr_compression: str | None = None, output: str = "files",
                   srgb: str | None = None) -> None:
    """Refuse settings of :func:`run_dataset` (its parameters of these names) that cannot run, before the spec is
    read: what the run checks first, and ``camsim dataset --dry-run`` too, so that it refuses what the run would.

    Raises
    ------
    CamsimError
    """
    if verify not in VERIFY_MODES:
        raise CamsimError(f"verify must be one of {VERIFY_MODES}, got {verify!r}")
    if output not in FORMATS:
        raise CamsimError(f"format must be one of {', '.join(FORMATS)}, got {output!r}")
    if output == "zarr" and exr_compression is not None:
        raise CamsimError("--exr-compression is for the file layout: a Zarr store holds arrays (--format zarr)")
    if scheduler is not None and workers is not None:
        raise CamsimError("give either --workers (local processes) or --scheduler (a Dask cluster), not both")
    if workers is not None and not (isinstance(workers, int) and workers >= 1):
        raise CamsimError(f"workers must be an integer ≥ 1, got {workers!r}")
    if not (isinstance(threads, int) and threads >= 1):
        raise CamsimError(f"threads must be an integer ≥ 1, got {threads!r}")
    if exr_compression is not None:
        check_exr_compression(exr_compression)
    if srgb is not None:
        check_srgb(srgb)


def check_output_of(spec, output: str, srgb: str | None = None) -> None:
    """Refuse an output format a spec's frames cannot be written in (``spec``: a :class:`DatasetSpec` or its
    plan): a ``[raws]`` spec's frames are raw scenes' files, not a Zarr store's arrays (yet); bursts
    (``burst_frames``) have sRGB outputs of scenes, not of ``[raws]`` crops (yet)."""
    if output != "files" and spec.axes.get("raw_file") == "raws":
        raise CamsimError(f"{spec.name}: a [raws] dataset is written as files (a raw scene's DNG, EXR and sidecar "
                          "per frame): --format zarr is not made for it yet")
    if _has_bursts(spec) and srgb not in (None, "none"):
        if spec.axes.get("raw_file") == "raws":
            raise CamsimError(f"{spec.name}: bursts of [raws] crops have no sRGB outputs yet: drop --srgb (or the "
                              "spec's srgb)")


def _has_bursts(spec) -> bool:
    """Whether a spec's items are bursts: any of a :class:`DatasetSpec`'s frames, or (a plan, whose frames are not
    made yet) ``burst_frames`` set or inherited from a scene's ``[sequence]``."""
    if isinstance(spec.frames, tuple):
        return any(frame.burst is not None for frame in spec.frames)
    return "burst_frames" in spec.axes


def _check_format(out_dir: Path, output: str) -> None:
    """Refuse to write one format into a folder that holds a dataset of the other."""
    if output == "files" and (out_dir / zarr_store.STORE_NAME).exists():
        raise CamsimError(f"{out_dir} holds a Zarr dataset ({zarr_store.STORE_NAME}): add --format zarr, or choose "
                          "another --out")
    if output == "zarr" and any((out_dir / FRAMES_DIR).glob("*")):
        raise CamsimError(f"{out_dir} holds a dataset of files ({FRAMES_DIR}/): drop --format zarr, or choose "
                          "another --out")


def _kept_compressions(records: dict, compression: str) -> str:
    """``; N complete frames have EXR compression zip, kept`` where complete frames differ from ``compression``
    (a record without the key is of an earlier camsim, whose EXRs are ZIP-compressed)."""
    other = {}
    for record in records.values():
        name = record.get("exr_compression", "zip")
        if name != compression:
            other[name] = other.get(name, 0) + 1
    return "".join(f"; {n} complete frames have {name}, kept" for name, n in sorted(other.items()))
