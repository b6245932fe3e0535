"""Python-level signal handlers for the length of a block: installed, then the previous ones put back; and stop
signals deferred to the points where a block can act on them safely."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator

__all__ = ["Deferred", "handlers_installed", "signals_deferred"]


@contextlib.contextmanager
def handlers_installed(handlers: dict[int, Callable]) -> Iterator[bool]:
    """Install ``handlers`` (signal number → handler) for the block, and put the previous handlers back after it.

    Python runs signal handlers in the main thread only, and only the main thread may install them: called from
    another thread, this installs nothing.

    Yields
    ------
    bool
        Whether the handlers were installed.
    """
    if threading.current_thread() is not threading.main_thread():
        yield False
        return
    previous = {sig: signal.signal(sig, handler) for sig, handler in handlers.items()}
    try:
        yield True
    finally:
        for sig, handler in previous.items():  # None: a handler not set from Python, i.e. the default
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)


class Deferred:
    """The stop signals noted inside a :func:`signals_deferred` block, and the handlers in force before it."""

    def __init__(self, previous: dict):
        self.previous = previous
        self.received: list[int] = []

    def note(self, signum, frame) -> None:
        self.received.append(signum)

    def act(self, *, inside: bool = True) -> None:
        """Act on the first signal noted, now, as the handlers in force before the block would have: a handler
        that raises (Ctrl-C's KeyboardInterrupt, the command line's ``Terminated``) raises here. Call it where an
        exception leaves nothing half-done; the others noted are dropped (the first stops the work). ``inside``:
        called in the block (its noting handlers installed), not after it."""
        if not self.received:
            return
        signum = self.received[0]
        self.received.clear()
        handler = self.previous.get(signum)
        if callable(handler):
            handler(signum, None)
            return
        if not inside:  # the previous disposition is back: the default action, or ignored
            signal.raise_signal(signum)
            return
        signal.signal(signum, signal.SIG_DFL if handler is None else handler)
        try:
            signal.raise_signal(signum)
        finally:
            signal.signal(signum, self.note)


@contextlib.contextmanager
def signals_deferred(signals=(signal.SIGINT, signal.SIGTERM)) -> Iterator[Deferred]:
    """SIGINT and SIGTERM are noted, not acted on, in the block; :meth:`Deferred.act` acts on them where the block
    says it is safe.

    A Python signal handler runs between any two bytecodes, so the exception it raises can land inside code that
    holds a lock without the ``with`` that would release it: in :func:`concurrent.futures.wait`, between the
    acquisitions of the futures' locks, the pool's management thread then waits for a lock that is never released
    and the process never exits. Code that waits on a pool defers the signals and acts on them between two waits.

    Where the block ends without an exception, a signal noted but not acted on is acted on as the block ends; where
    it ends with one (the work is stopping already), the signals noted meanwhile are dropped. Outside the main
    thread nothing is installed and signals act as they would.

    Yields
    ------
    Deferred
    """
    if threading.current_thread() is not threading.main_thread():
        deferred = Deferred({})
        yield deferred
        return
    previous = {sig: signal.getsignal(sig) for sig in signals}
    deferred = Deferred(previous)
    for sig in signals:
        signal.signal(sig, deferred.note)
    failed = False
    try:
        yield deferred
    except BaseException:
        failed = True
        raise
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        if not failed:
            deferred.act(inside=False)
