"""Python-level signal handlers for the length of a block: installed, then the previous ones put back."""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator

__all__ = ["handlers_installed"]


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
