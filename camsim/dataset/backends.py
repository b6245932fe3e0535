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
import signal
from concurrent.futures import ProcessPoolExecutor, as_completed

from camsim.dataset._pool import pool_context
from camsim.dataset.task import exr_threads
from camsim.errors import CamsimError

__all__ = ["run_serial", "run_pool", "run_dask"]


def _ignore_sigint() -> None:  # pool workers: Ctrl-C is the main process's to handle
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def run_serial(task, todo, out_dir, threads, on_done) -> None:
    """Run ``task`` on every frame of ``todo`` in this process, one after the other."""
    previous = exr_threads(threads)
    try:
        for frame in todo:
            on_done(frame, task(frame, str(out_dir), threads))
    finally:  # this process's OpenEXR setting is the caller's
        if previous:
            exr_threads(previous)


def run_pool(task, todo, out_dir, workers, threads, on_done) -> None:
    """Run ``task`` on every frame of ``todo`` in a pool of ``workers`` local processes; they write into ``out_dir``.

    On an error or Ctrl-C, the frames not started are cancelled and those being rendered are still recorded.
    """
    context = pool_context()
    recorded = set()
    with ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_ignore_sigint) as pool:
        futures = {pool.submit(task, frame, str(out_dir), threads): frame for frame in todo}
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


def run_dask(task, todo, address, threads, on_done) -> None:
    """Submit ``task`` for every frame of ``todo`` to the ``dask.distributed`` scheduler at ``address``; the
    workers send the files' bytes back."""
    try:
        from distributed import Client, as_completed as dask_completed
    except ImportError:
        raise CamsimError("--scheduler needs dask.distributed: pip install 'dask[distributed]'") from None
    try:
        client = Client(address, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise CamsimError(f"cannot connect to the Dask scheduler at {address}: {exc}") from None
    with client:
        futures = [client.submit(task, frame, None, threads, pure=False) for frame in todo]
        frames = {future.key: frame for future, frame in zip(futures, todo)}
        try:
            for future in dask_completed(futures, loop=client.loop):
                on_done(frames[future.key], future.result())
                future.release()
        except BaseException:
            client.cancel(futures)
            raise
