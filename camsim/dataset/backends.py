"""Where a dataset's frames are rendered: each back-end runs a task (:func:`camsim.dataset.task.render_task`) on
every frame to do and hands each result to ``on_done`` as it arrives.

``run_serial`` renders in this process; ``run_pool`` in a pool of local processes (forked from a fork server that
has imported camsim, or spawned: see :mod:`camsim.dataset._pool`), which write into ``OUT`` themselves;
``run_dask`` submits one task per frame to a ``dask.distributed`` cluster, whose workers render into a private
temporary folder and send the bytes back, so the cluster needs camsim importable but no file system shared with
this machine. A frame's files do not depend on the back-end.
"""

from __future__ import annotations

import contextlib
import itertools
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path

from camsim.core.errors import CamsimError
from camsim.core.signals import signals_deferred
from camsim.dataset._pool import pool_context, worker_init
from camsim.dataset.manifest import FRAMES_DIR
from camsim.io.exr import restore_exr_threads, set_exr_threads

__all__ = ["run_serial", "run_pool", "run_dask"]


#: On an interruption or an error, how long the frames being rendered get to finish (and be recorded) before their
#: workers are terminated. Unit: s.
GRACE_S = 2.0
#: After an interruption or an error, how long an idle worker gets to exit on its own (so that its finalizers run:
#: numcodecs' Blosc makes a multiprocessing lock, a named semaphore, in each worker that writes Zarr chunks, and a
#: terminated worker leaves it to the resource tracker, which prints a "leaked semaphore" warning). Unit: s.
EXIT_S = 1.0
#: Frames submitted to the pool ahead of the results, per worker: enough to keep every worker busy, few enough
#: that a spec of 10⁵ frames does not become 10⁵ queued tasks (and that an interruption has little to cancel).
AHEAD_PER_WORKER = 2
#: How long the pool's loop waits for a result before it looks at the signals noted meanwhile. Unit: s.
POLL_S = 0.1


def run_serial(task, todo, out_dir, threads, on_done) -> None:
    """Run ``task`` on every frame of ``todo`` in this process, one after the other."""
    previous = set_exr_threads(threads)
    try:
        for frame in todo:
            on_done(frame, task(frame, str(out_dir), threads))
    finally:  # this process's OpenEXR setting is the caller's
        restore_exr_threads(previous)


def run_pool(task, todo, out_dir, workers, threads, on_done) -> None:
    """Run ``task`` on every frame of ``todo`` in a pool of ``workers`` local processes; they write into ``out_dir``.

    Frames are submitted a few per worker ahead of the results. On an error, Ctrl-C (KeyboardInterrupt) or any
    exception raised in this thread (a SIGTERM handler's), the frames not started are cancelled, those being
    rendered get :data:`GRACE_S` seconds to finish, every finished frame is handed to ``on_done``, the workers
    still rendering are terminated and their temporary files removed (a frame's files that were already renamed
    into place but not recorded are rendered again by the next run, to the same bytes), and the exception
    propagates: the pool is gone within about ``GRACE_S`` seconds, whatever the frame size.
    """
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=pool_context(), initializer=worker_init)
    pending = {}  # future -> frame, until its result is handed to on_done
    # Ctrl-C and SIGTERM act between two waits, never inside one: raised inside concurrent.futures.wait, their
    # exception can leave a future's lock held, and the pool's management thread, then the process, never ends
    with signals_deferred() as deferred:
        try:
            frames = iter(todo)
            _submit(pool, pending, frames, workers * AHEAD_PER_WORKER, task, out_dir, threads)
            while pending:
                done, _ = wait(pending, timeout=POLL_S, return_when=FIRST_COMPLETED)
                deferred.act()
                for future in done:
                    on_done(pending[future], future.result())
                    del pending[future]
                _submit(pool, pending, frames, workers * AHEAD_PER_WORKER, task, out_dir, threads)
            pool.shutdown(wait=True)
        except BaseException:  # a second Ctrl-C meanwhile is noted and dropped: the clean-up is not cut short
            try:
                _keep_finished(pending, on_done)
            finally:
                _remove_partials(Path(out_dir), _stop(pool))
            raise


def _submit(pool, pending: dict, frames, ahead: int, task, out_dir, threads) -> None:
    """Submit frames until ``ahead`` are pending."""
    for frame in itertools.islice(frames, max(0, ahead - len(pending))):
        pending[pool.submit(task, frame, str(out_dir), threads)] = frame


def _keep_finished(pending: dict, on_done) -> None:
    """After an interruption: cancel the frames not started, give those being rendered :data:`GRACE_S` seconds,
    and hand every finished one to ``on_done`` (a frame that failed is left out)."""
    for future in pending:
        future.cancel()
    wait([f for f in pending if not f.cancelled()], timeout=GRACE_S)
    for future, frame in pending.items():
        if future.done() and not future.cancelled() and future.exception() is None:
            with contextlib.suppress(Exception):
                on_done(frame, future.result())


def _stop(pool: ProcessPoolExecutor) -> list[int]:
    """Shut the pool down now: idle workers get :data:`EXIT_S` seconds to exit on their own (cleanly: their
    semaphores are released), those still rendering are terminated; waits for them briefly and returns their
    process ids."""
    processes = list((getattr(pool, "_processes", None) or {}).values())  # the executor has no public handle
    pool.shutdown(wait=False, cancel_futures=True)  # sends each worker its exit sentinel
    deadline = time.monotonic() + EXIT_S
    for process in processes:
        with contextlib.suppress(Exception):
            process.join(timeout=max(0.0, deadline - time.monotonic()))
    for process in processes:
        with contextlib.suppress(Exception):
            if process.is_alive():
                process.terminate()
    for process in processes:
        with contextlib.suppress(Exception):
            process.join(timeout=GRACE_S)
            if process.is_alive():
                process.kill()
                process.join(timeout=GRACE_S)
    return [process.pid for process in processes]


def _remove_partials(out_dir: Path, pids: list[int]) -> None:
    """Remove the temporary files that the (terminated) workers ``pids`` left in ``out_dir/frames``: camsim's
    writers name them ``.<name>.<pid>.partial`` (:mod:`camsim.io.atomic`)."""
    for pid in pids:
        for path in (out_dir / FRAMES_DIR).glob(f".*.{pid}.partial"):
            path.unlink(missing_ok=True)


def run_dask(task, todo, address, threads, on_done) -> None:
    """Submit ``task`` for every frame of ``todo`` to the ``dask.distributed`` scheduler at ``address``; the
    workers send the files' bytes back.

    On an error, Ctrl-C or any exception raised in this thread, every frame not yet handed to ``on_done`` is
    cancelled on the cluster and the client is closed, so that the cluster is left idle and usable.
    """
    try:
        from distributed import Client
        from distributed import as_completed as dask_completed
    except ImportError:
        raise CamsimError("--scheduler needs dask.distributed: pip install 'dask[distributed]'") from None
    try:
        client = Client(address, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise CamsimError(f"cannot connect to the Dask scheduler at {address}: {exc}") from None
    futures = {}  # key -> (future, frame), until the frame is handed to on_done
    try:
        for frame in todo:
            future = client.submit(task, frame, None, threads, pure=False)
            futures[future.key] = (future, frame)
        for future in dask_completed([f for f, _ in futures.values()], loop=client.loop):
            on_done(futures[future.key][1], future.result())
            del futures[future.key]
            future.release()
    except BaseException:
        with contextlib.suppress(Exception):
            client.cancel([f for f, _ in futures.values()])
        raise
    finally:
        with contextlib.suppress(Exception):
            client.close()
