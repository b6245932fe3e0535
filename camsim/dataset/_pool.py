"""How the local process pool starts its workers. Light to import: the command line starts the fork server
before it imports camsim's heavy modules, so that both imports run at the same time.

Where the platform has one, the workers are forked from a fork server that has imported camsim and
colour-science once (:mod:`camsim.dataset._preload`): they start warm, and no process that may hold threads is
forked — not only Python threads: OpenEXR's writer keeps a C++ thread pool, and a worker forked from a process
that had written an EXR would wait forever on it. Elsewhere (Windows) the workers are spawned. Either way they
receive plain picklable data.
"""

from __future__ import annotations

import multiprocessing

#: Start method of the local pool; None: ``forkserver`` where it exists, else ``spawn``.
POOL_START_METHOD: str | None = None
PRELOAD = ["camsim.dataset._preload"]


def pool_context():
    """The multiprocessing context of the local pool (its fork server preloads camsim)."""
    method = POOL_START_METHOD
    if method is None:
        method = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
    context = multiprocessing.get_context(method)
    if method == "forkserver":
        context.set_forkserver_preload(PRELOAD)
    return context


def start_fork_server() -> None:
    """Start the fork server now (it imports camsim while the caller goes on); a no-op without one."""
    context = pool_context()
    if context.get_start_method() == "forkserver":
        from multiprocessing import forkserver

        forkserver.ensure_running()
