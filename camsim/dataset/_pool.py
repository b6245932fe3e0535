"""How the local process pool starts its workers, and how they die with the command. Light to import: the command
line starts the fork server before it imports camsim's heavy modules, so that both imports run at the same time.

Where the platform has one, the workers are forked from a fork server that has imported camsim and
colour-science once (:mod:`camsim.dataset._preload`): they start warm, and no process that may hold threads is
forked — not only Python threads: OpenEXR's writer keeps a C++ thread pool, and a worker forked from a process
that had written an EXR would wait forever on it. Elsewhere (Windows) the workers are spawned. Either way they
receive plain picklable data.

No process outlives the command, whatever ends it (Ctrl-C, SIGTERM, SIGKILL, a crash): each worker has a thread
that waits on multiprocessing's sentinel of the main process and ends the worker (``os._exit``) the moment the
main process is gone (:func:`watch_parent`, on every platform); on Linux, moreover, the kernel kills the fork
server when the main process dies and each worker when its parent (the fork server) dies
(``prctl(PR_SET_PDEATHSIG, SIGKILL)``, :func:`bind_to_parent`). With the workers gone, multiprocessing's resource
tracker reads the end of its pipe and exits too. (A worker has no pipe to the main process that it would see close:
it holds both ends of its queue's pipe, which is why it needs the sentinel.)
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import threading

#: Start method of the local pool; None: ``forkserver`` where it exists, else ``spawn``.
POOL_START_METHOD: str | None = None
PRELOAD = ["camsim.dataset._preload"]
#: Exit status of a worker that ends because the main process is gone.
ORPHAN_EXIT_STATUS = 70
_PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


#: Also preloaded for a Zarr store's workers (zarr takes about 0.5 s to import).
PRELOAD_ZARR = ["zarr"]


def pool_context(zarr: bool = False):
    """The multiprocessing context of the local pool (its fork server preloads camsim; with ``zarr``, zarr too,
    if the fork server is not running yet)."""
    method = POOL_START_METHOD
    if method is None:
        method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
    context = multiprocessing.get_context(method)
    if method == "forkserver":
        context.set_forkserver_preload(PRELOAD + (PRELOAD_ZARR if zarr else []))
    return context


def start_fork_server(zarr: bool = False) -> None:
    """Start the fork server now (it imports camsim, and with ``zarr`` zarr, while the caller goes on); a no-op
    without one, or with one running (whose preloads stay what they were: a worker imports the rest itself).

    On Linux the fork server dies with the thread that starts it (:func:`bind_to_parent`): call this from the
    thread that runs the pool (the command line's main thread); multiprocessing starts a new one when needed.
    """
    context = pool_context(zarr)
    if context.get_start_method() == "forkserver":
        from multiprocessing import forkserver

        start_quiet_resource_tracker()
        forkserver.ensure_running()


def start_quiet_resource_tracker() -> None:
    """Start multiprocessing's resource tracker (if it is not running) with its standard error on the null device.

    The tracker unlinks the named semaphores of the pool's queues that a process killed outright (SIGKILL) could
    not release; it then prints a ``resource_tracker: There appear to be N leaked semaphore objects`` warning, two
    lines on camsim's standard error after the run is over, about a cleanup that it did. Every exit path that runs
    code releases them (the main process's at exit, a worker's when it exits on its own: :func:`_stop` in
    :mod:`camsim.dataset.backends`); this silences the report of the tracker's cleanup after a kill, not the
    cleanup. The tracker inherits descriptor 2 when it is spawned, so it is redirected for that moment only.
    """
    from multiprocessing import resource_tracker  # ensure_running: a no-op while the tracker runs

    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        resource_tracker.ensure_running()
        return
    try:
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, 2)
        finally:
            os.close(null)
        resource_tracker.ensure_running()
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def bind_to_parent() -> bool:
    """Have the kernel kill this process (SIGKILL) when its parent dies: Linux's ``prctl(PR_SET_PDEATHSIG)``.

    The parent is, strictly, the thread that started this process: the signal comes when that thread ends. The
    setting is not inherited by children (cleared on fork). Safe in a process that forks (no thread is started).

    Returns
    -------
    bool
        Whether the process is now bound (False off Linux, or where the call fails).
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
    except (OSError, AttributeError):  # no libc prctl: the watchdog still ends the workers
        return False


def watch_parent() -> bool:
    """End this process (``os._exit(ORPHAN_EXIT_STATUS)``) as soon as the process that started it is gone.

    A daemon thread waits on multiprocessing's sentinel of the parent process (for a worker of the fork server,
    a pipe whose other end the main process holds; a process handle on Windows): no polling, and no confusion
    with a later process of the same pid. Not for a process that forks (the fork server).

    Returns
    -------
    bool
        Whether a thread now watches (False in a process not started by multiprocessing).
    """
    parent = multiprocessing.parent_process()
    sentinel = None if parent is None else parent.sentinel
    if sentinel is None:
        return False
    threading.Thread(target=_exit_when_ready, args=(sentinel,), name="camsim-watch-parent", daemon=True).start()
    return True


def _exit_when_ready(sentinel) -> None:
    from multiprocessing.connection import wait

    wait([sentinel])  # readable (end of file) or signalled: the parent is gone
    os._exit(ORPHAN_EXIT_STATUS)


def worker_init() -> None:
    """Initializer of a pool worker: Ctrl-C is the main process's to handle (the whole terminal's process group
    gets it), and the worker dies with its parent (Linux) and with the main process (everywhere)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    bind_to_parent()
    watch_parent()
