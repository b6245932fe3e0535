"""Hostile stand-ins for the files camsim reads back (frames, raws, manifests), made small.

* :func:`with_tiff_size` and :func:`with_exr_window`: a real DNG or EXR whose header declares another size, its
  pixel data unchanged (a header that claims 10¹⁰ pixels costs a few bytes to write and must cost nothing to
  refuse: no gigabytes are allocated here or by a reader that checks the header first);
* :func:`not_regular`: a FIFO, a character device or a directory by a file's name;
* :func:`no_hang`: a block that fails clearly, instead of hanging the suite, when a reader waits on a FIFO from
  Python (an ``open`` interrupted by the alarm raises out of it);
* :func:`one_error_line`: the check of camsim's rule, one ``camsim: error:`` line on stderr and nothing else.

A reader that blocks inside a C library (OpenEXR, LibRaw opening a FIFO) is judged in a subprocess instead
(:func:`tests.support.clock.run`): the alarm's handler runs only once the C call returns.
"""

from __future__ import annotations

import contextlib
import os
import signal
import struct
from pathlib import Path

import pytest

from tests.support.fuzz import apply_dng_ops, exr_attributes, tiff_entries

#: TIFF tags of an image's size.
IMAGE_WIDTH, IMAGE_LENGTH, COMPRESSION = 256, 257, 259
#: How long a read of a non-regular file may take before it counts as a hang (it takes microseconds). Unit: s.
HANG_S = 20
#: Sizes a header declares: over the pixel limit by one row, 9 × 10⁸ and 10¹⁰ pixels. Unit: pixels.
HUGE_SIZES = ((20001, 10000), (30000, 30000), (100000, 100000))


def with_tiff_size(data: bytes, width: int, height: int, extra: dict | None = None) -> bytes:
    """``data`` (a little-endian TIFF/DNG) with every IFD's ImageWidth and ImageLength (IFD0's and its SubIFDs')
    set to ``width`` × ``height`` pixels, and the tags of ``extra`` (code → value, e.g. ``{COMPRESSION: 8}``)."""
    values = {IMAGE_WIDTH: width, IMAGE_LENGTH: height, **(extra or {})}
    ops = []
    for entry in tiff_entries(data):
        if entry[1] in (IMAGE_WIDTH, IMAGE_LENGTH):  # LONG, which TIFF allows for both: a SHORT holds 65535 at most
            ops.append(("tag", entry, "type", 4))
        if entry[1] in values:
            ops.append(("tag", entry, "value", values[entry[1]]))
    assert {op[1][1] for op in ops} >= {IMAGE_WIDTH, IMAGE_LENGTH}, "no size tags found"
    return apply_dng_ops(data, ops)


def with_exr_window(data: bytes, width: int, height: int) -> bytes:
    """``data`` (a single-part EXR) whose dataWindow declares ``width`` × ``height`` pixels from (0, 0)."""
    at, size = exr_attributes(data)["dataWindow"]
    assert size == 16
    buf = bytearray(data)
    struct.pack_into("<4i", buf, at, 0, 0, width - 1, height - 1)
    return bytes(buf)


def not_regular(path: Path, kind: str) -> Path:
    """Put a ``kind`` ("fifo", "device": a link to /dev/zero, "directory") at ``path``; returns ``path``."""
    path = Path(path)
    with contextlib.suppress(FileNotFoundError):
        path.unlink()
    {"fifo": lambda: os.mkfifo(path), "device": lambda: path.symlink_to("/dev/zero"),
     "directory": path.mkdir}[kind]()
    return path


@contextlib.contextmanager
def no_hang(what: str, seconds: int = HANG_S):
    """Fail (not hang) when the block takes ``seconds`` of wall time: a reader blocked on a FIFO from Python is
    interrupted by SIGALRM and fails the test, naming ``what``."""
    def alarm(signum, frame):
        pytest.fail(f"{what}: still blocked after {seconds} s (waiting on a FIFO?)")

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def one_error_line(err: str) -> str:
    """The one ``camsim: error:`` line ``err`` (a command's whole stderr) must be; fails otherwise."""
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("camsim: error: "), err
    return lines[0]
