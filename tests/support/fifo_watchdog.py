"""A watchdog for a test that hands camsim a FIFO: if the code under test opens the FIFO to read and waits on it, the
watchdog proves it and lets it go, so that the test fails with the reason instead of hanging the suite.

The proof is the FIFO's own: opening a FIFO for writing with ``O_NONBLOCK`` succeeds only while some process holds
it open for reading (``ENXIO`` otherwise). camsim's :func:`camsim.core.input_files.open_input` opens a FIFO with
``O_NONBLOCK`` and closes it at once, so a reader that is still there after :data:`PATIENCE_S` is one that waits. The
watchdog then opens and closes the writing end, which ends the reader's wait (an ``open`` returns, a ``read`` sees
the end of the file), wherever it waits: in Python or inside a C library. It is a process of its own, not a thread:
a library that blocks holding the GIL (OpenImageIO's ``ImageInput.open``) would stop a thread too, and an alarm's
handler would not run until the call returned. No verdict rests on wall time: a busy machine only makes the
watchdog look later.
"""

from __future__ import annotations

import contextlib
import subprocess
import sys

import pytest

#: How long the watchdog waits before it looks for a reader on the FIFO; the refusal takes milliseconds. Unit: s.
PATIENCE_S = 5.0
#: How often it looks again, and opens the writing end again for a reader that opens the FIFO anew. Unit: s.
POLL_S = 0.05

#: The watchdog process: after the patience, release every reader of the FIFOs (argv) and say which it found.
_WATCH = """
import errno, os, sys, time
patience, poll, fifos = float(sys.argv[1]), float(sys.argv[2]), sys.argv[3:]
time.sleep(patience)
while True:
    for fifo in fifos:
        try:
            fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
        except OSError as exc:
            if exc.errno in (errno.ENXIO, errno.ENOENT):
                continue  # no reader holds it: nothing waits on it
            raise
        print(fifo, flush=True)
        os.close(fd)  # the reader's open returns, or its read sees the end of the file
    time.sleep(poll)
"""


@contextlib.contextmanager
def fifo_watchdog(*fifos, what: str = "the command"):
    """Run the block; fail it, naming ``what``, where it waited reading one of ``fifos`` (each released, so that the
    block returns)."""
    if not fifos:
        yield
        return
    watcher = subprocess.Popen([sys.executable, "-c", _WATCH, str(PATIENCE_S), str(POLL_S), *map(str, fifos)],
                               stdout=subprocess.PIPE, text=True)
    try:
        yield
    finally:
        watcher.kill()
        caught = watcher.communicate()[0].split()
    if caught:
        pytest.fail(f"{what} waited reading the FIFO {caught[0]} (opened it without O_NONBLOCK, or read it)")


__all__ = ["PATIENCE_S", "fifo_watchdog"]
