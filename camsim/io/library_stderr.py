"""What a C library writes on the process's standard error (file descriptor 2), captured instead of printed.

libpng (through OpenImageIO) prints ``libpng error: IDAT: Read error: hit end of file in png reader`` and
``libpng warning: ...`` lines straight to descriptor 2, around Python's ``sys.stderr``; camsim's rule is one line
per error. :func:`library_stderr` redirects descriptor 2 to a temporary file for the duration of a library call,
so that the caller can put the library's reason into its own one-line message (or drop a warning).
"""

from __future__ import annotations

import os
import sys
import tempfile
from contextlib import contextmanager

__all__ = ["CapturedStderr", "library_stderr"]

#: The most bytes of a library's output kept (its last ones).
KEEP_BYTES = 4000


class CapturedStderr:
    """What was written on descriptor 2 inside :func:`library_stderr`; ``text`` is set when the block ends."""

    def __init__(self):
        self.text = ""

    def reason(self) -> str:
        """The captured lines without the library's ``libpng error:``-style prefixes, joined by ``; ``."""
        lines = []
        for line in self.text.splitlines():
            line = line.strip()
            for prefix in ("libpng error:", "libpng warning:", "libtiff error:", "Error:", "ERROR:"):
                if line.startswith(prefix):
                    line = line[len(prefix):].strip()
            if line and line not in lines:
                lines.append(line)
        return "; ".join(lines)


@contextmanager
def library_stderr(*, stdout: bool = False):
    """Redirect file descriptor 2 (and 1 with ``stdout``) to a temporary file while the block runs; yields a
    :class:`CapturedStderr` holding what was written on either.

    Use it around a C library's call only (Python's own messages would be captured too). ``stdout`` is for a
    library that prints on descriptor 1 (the OpenEXR bindings' "Warning: Exception raised reading pixel data …").
    Where a descriptor cannot be duplicated (closed), the block runs without capture.
    """
    captured = CapturedStderr()
    fds = (1, 2) if stdout else (2,)
    try:
        sys.stdout.flush()
        sys.stderr.flush()
        saved = [os.dup(fd) for fd in fds]
    except (OSError, ValueError, AttributeError):
        yield captured
        return
    with tempfile.TemporaryFile() as sink:
        for fd in fds:
            os.dup2(sink.fileno(), fd)
        try:
            yield captured
        finally:
            for stream in (sys.stdout, sys.stderr):  # what a library printed through Python's streams, too
                try:
                    stream.flush()
                except (OSError, ValueError, AttributeError):
                    pass
            for fd, old in zip(fds, saved):
                os.dup2(old, fd)
                os.close(old)
            size = sink.seek(0, os.SEEK_END)
            sink.seek(max(0, size - KEEP_BYTES))
            captured.text = sink.read().decode("utf-8", errors="replace")
