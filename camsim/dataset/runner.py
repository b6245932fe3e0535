"""Rendering a dataset: every frame of a spec, in parallel, resumable, with a JSON Lines manifest.

Layout of ``OUT``::

    OUT/frames/<id>.dng, <id>.exr, <id>.json   the frame's files (camsim's writers: temporary name, then rename)
    OUT/frames/<id>.done                       the frame's record, written (atomically) after all its files
    OUT/manifest.jsonl                         one line per complete frame, in frame order

A frame is complete when its ``.done`` record exists, describes the same frame (every parameter and the seed)
and every file it lists exists with the recorded size and SHA-256. The manifest is rebuilt from the records when
a run starts and when it ends (also on Ctrl-C or an error), always by atomic rename, so it never holds a half
line; a run killed outright leaves the records, and the next run rebuilds the manifest from them. A re-run skips
complete frames and renders the others; a frame's files do not depend on the back-end, the number of processes
or threads, or the order the frames are rendered in.

Back-ends: ``workers == 1`` renders in this process; ``workers > 1`` in a pool of that many processes (forked
from a fork server that has imported camsim, or spawned: see :mod:`camsim.dataset._pool`), which write into
``OUT`` themselves; ``scheduler=ADDRESS`` submits one task per frame to a ``dask.distributed`` cluster, whose workers
render into a private temporary folder and send the bytes back, so the cluster needs camsim importable but no
file system shared with this machine.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import multiprocessing
import signal
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from functools import lru_cache
from pathlib import Path

from tqdm import tqdm

from camsim.camera import load_camera
from camsim.dataset._pool import pool_context, start_fork_server
from camsim.dataset.spec import DatasetSpec, FrameSpec, load_spec
from camsim.errors import CamsimError
from camsim.frame_files import write_frame
from camsim.io.atomic import atomic_path, write_json_atomic, write_text_atomic
from camsim.pipeline import light_scene, scene_frame
from camsim.render import default_workers
from camsim.scene import load_scene

FRAMES_DIR = "frames"
MANIFEST_NAME = "manifest.jsonl"
DONE_SUFFIX = ".done"
LOCK_NAME = ".camsim-dataset.lock"
VERIFY_MODES = ("sha256", "size")
_HASH_CHUNK = 1 << 22


# --- one frame: runs in a worker process (or in this one) ----------------------------------------------------


@lru_cache(maxsize=16)
def _scene(path: str):
    return load_scene(path)


@lru_cache(maxsize=16)
def _camera(name: str, grid, basis: str, base_dir):
    return load_camera(name, grid, basis, base_dir)


@lru_cache(maxsize=64)
def _lit(path: str, width: int, height: int, illuminant: str, camera: str):
    scene = _scene(path).replace(width=width, height=height, camera=camera)
    return light_scene(scene, illuminant, _camera(camera, scene.grid, scene.sensitivity_basis, scene.base_dir))


def render_files(frame: FrameSpec, directory: Path, threads: int = 1) -> dict:
    """Render one frame and write ``<id>.dng`` (if quantised), ``<id>.exr`` and ``<id>.json`` into ``directory``.

    :func:`camsim.pipeline.scene_frame`, as for ``camsim render``, with the frame's own seed. Returns the file
    names by kind (``dng`` None without quantisation).
    """
    base = _scene(frame.scene_path)
    scene = base.replace(width=frame.width, height=frame.height, illuminants=(frame.illuminant,),
                         intensity_factors=(frame.intensity_factor,), **frame.scene_changes)
    if frame.sensor_overrides:
        scene = scene.with_sensor(**frame.sensor_overrides)
    camera = _camera(scene.camera, scene.grid, scene.sensitivity_basis, scene.base_dir)
    lit = _lit(frame.scene_path, frame.width, frame.height, frame.illuminant, scene.camera)
    rendered, info = scene_frame(scene, frame.illuminant, frame.intensity_factor, seed=frame.seed, lit=lit,
                                 camera=camera, workers=threads)
    return write_frame(Path(directory), frame.id, rendered, info)


def _sha256_file(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        while chunk := handle.read(_HASH_CHUNK):
            digest.update(chunk)
    return digest.hexdigest()


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
                  "sha256": _sha256_file(folder / name)}
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


def _ignore_sigint() -> None:  # pool workers: Ctrl-C is the main process's to handle
    signal.signal(signal.SIGINT, signal.SIG_IGN)


# --- records, verification, manifest -------------------------------------------------------------------------


def done_path(out_dir: Path, frame_id: str) -> Path:
    return Path(out_dir) / FRAMES_DIR / f"{frame_id}{DONE_SUFFIX}"


def verified_record(out_dir: Path, frame: FrameSpec, verify: str = "sha256") -> dict | None:
    """The frame's record if the frame is complete and verified, else None.

    Complete and verified: the ``.done`` record describes this very frame (every parameter and the seed), and
    every file it lists exists with the recorded size and (``verify="sha256"``) SHA-256.
    """
    try:
        record = json.loads(done_path(out_dir, frame.id).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or {k: v for k, v in record.items() if k != "files"} != frame.record:
        return None
    files = record.get("files")
    if not isinstance(files, dict) or not files.get("exr") or not files.get("json"):
        return None
    for entry in files.values():
        if entry is None:
            continue
        try:
            path = Path(out_dir) / entry["name"]
            if path.stat().st_size != entry["bytes"]:
                return None
            if verify == "sha256" and _sha256_file(path) != entry["sha256"]:
                return None
        except (OSError, KeyError, TypeError):
            return None
    return record


def write_manifest(out_dir: Path, records: dict) -> Path:
    """(Re)write ``OUT/manifest.jsonl`` atomically: one JSON object per complete frame, in frame order."""
    lines = [json.dumps(records[index], ensure_ascii=False, allow_nan=False) + "\n" for index in sorted(records)]
    path = Path(out_dir) / MANIFEST_NAME
    write_text_atomic(path, "".join(lines))
    return path


def read_manifest(out_dir: Path) -> list[dict]:
    """The manifest's records, in frame order."""
    text = (Path(out_dir) / MANIFEST_NAME).read_text(encoding="utf-8")
    return [json.loads(line) for line in text.splitlines() if line.strip()]


def _store(out_dir: Path, frame: FrameSpec, result: dict) -> dict:
    """Write a rendered frame's bytes (if sent back) and then its record; returns the record."""
    for kind, data in result.get("blobs", {}).items():
        with atomic_path(Path(out_dir) / result["files"][kind]["name"]) as tmp:
            tmp.write_bytes(data)
    record = {**frame.record, "files": result["files"]}
    write_json_atomic(done_path(out_dir, frame.id), record)
    return record


@contextlib.contextmanager
def _exclusive(out_dir: Path):
    """Hold an exclusive lock on ``OUT`` for the run (POSIX): two runs into one folder would trip each other."""
    try:
        import fcntl
    except ImportError:  # no advisory locks on this platform: best effort
        yield
        return
    with open(out_dir / LOCK_NAME, "a") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            raise CamsimError(f"another camsim dataset run is writing to {out_dir}") from None
        yield


# --- back-ends -----------------------------------------------------------------------------------------------


def _run_serial(todo, out_dir, threads, on_done) -> None:
    previous = exr_threads(threads)
    try:
        for frame in todo:
            on_done(frame, render_task(frame, str(out_dir), threads))
    finally:  # this process's OpenEXR setting is the caller's
        if previous:
            exr_threads(previous)


def _run_pool(todo, out_dir, workers, threads, on_done) -> None:
    context = pool_context()
    recorded = set()
    with ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_ignore_sigint) as pool:
        futures = {pool.submit(render_task, frame, str(out_dir), threads): frame for frame in todo}
        try:
            for future in as_completed(futures):
                on_done(futures[future], future.result())
                recorded.add(future)
        except BaseException:
            for future in futures:
                future.cancel()
            for future, frame in futures.items():  # frames already being rendered finish: keep them
                if future not in recorded and not future.cancelled():
                    with contextlib.suppress(Exception):
                        on_done(frame, future.result())
            raise


def _run_dask(todo, address, threads, on_done) -> None:
    try:
        from distributed import Client, as_completed as dask_completed
    except ImportError:
        raise CamsimError("--scheduler needs dask.distributed: pip install 'dask[distributed]'") from None
    try:
        client = Client(address, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise CamsimError(f"cannot connect to the Dask scheduler at {address}: {exc}") from None
    with client:
        futures = [client.submit(render_task, frame, None, threads, pure=False) for frame in todo]
        frames = {future.key: frame for future, frame in zip(futures, todo)}
        try:
            for future in dask_completed(futures, loop=client.loop):
                on_done(frames[future.key], future.result())
                future.release()
        except BaseException:
            client.cancel(futures)
            raise


# --- the run -------------------------------------------------------------------------------------------------


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
    out_dir = Path(out_dir)
    frames_dir = out_dir / FRAMES_DIR
    frames_dir.mkdir(parents=True, exist_ok=True)
    with _exclusive(out_dir):
        for stale in frames_dir.glob(".*.partial"):  # left by a run killed outright (we hold the lock)
            stale.unlink(missing_ok=True)
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
            records[frame.index] = _store(out_dir, frame, result)
            if not bars:
                bars.append(tqdm(total=len(todo), desc=f"dataset {spec.name}", unit="frame", disable=not progress))
            bars[0].update()

        start = time.perf_counter()
        try:
            if not todo:
                pass
            elif scheduler is not None:
                _run_dask(todo, scheduler, threads, on_done)
            elif workers == 1:
                _run_serial(todo, out_dir, threads, on_done)
            else:
                _run_pool(todo, out_dir, workers, threads, on_done)
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


__all__ = ["run_dataset", "render_task", "render_files", "verified_record", "write_manifest", "read_manifest",
           "FRAMES_DIR", "MANIFEST_NAME", "DONE_SUFFIX", "VERIFY_MODES"]
