"""The one way camsim opens a file it reads: a regular file, of bounded size, named by a path without a NUL byte.

Every reader (scene files, dataset specs, presets, sidecars, manifests, ``*_map`` files, images, cubes, raws)
goes through :func:`open_input` (it reads the file itself) or :func:`check_input` (a library opens it by its name:
OpenImageIO, OpenEXR, rawpy, ``np.load``). What a path from input may name is anything: a FIFO or a character
device (``/dev/zero``, a terminal) blocks a reader forever or never ends; a socket cannot be read; a directory is
not a file; a NUL byte makes the operating system's call raise ``ValueError``. All of these are refused here, on one
line, before a byte is read.

The path is judged by ``stat`` before it is opened (opening some devices acts on them), then opened with
``O_NONBLOCK`` and judged again by ``fstat`` of the open descriptor: opening a FIFO that way does not wait for a
writer, and what is judged is what would be read (a file swapped for a FIFO between the two is still refused).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from camsim.core.errors import CamsimError

#: What a path names, for the message, by the type bits of its ``st_mode``.
_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def size_text(n_bytes: float) -> str:
    """``n_bytes`` for a message: ``"64 MB"``, ``"1.5 GB"``, ``"512 bytes"`` (decimal units)."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n_bytes >= scale:
            return f"{n_bytes / scale:.3g} {unit}"
    return f"{int(n_bytes)} bytes"


def _checked_path(path, what: str) -> str:
    name = os.fspath(path)
    if isinstance(name, bytes):
        name = os.fsdecode(name)
    if "\x00" in name:
        raise CamsimError(f"{what} path {name!r} holds a NUL byte, which no file name can")
    return name


def _kind(mode: int) -> str:
    return next((text for test, text in _KINDS if test(mode)), "not a regular file")


def open_input(path, what: str, max_bytes: int | None = None):
    """``path`` opened for reading in binary (a file object; close it, or use it in ``with``), once it is known to
    be a regular file of at most ``max_bytes`` bytes.

    Parameters
    ----------
    path : str or os.PathLike
        The file, from input.
    what : str
        What the file is, for messages (``"sidecar"``, ``"scene file"``, ``"dark_shading_map"``).
    max_bytes : int, optional
        The largest file accepted (its size from ``fstat``, before any byte is read); none: no limit.

    Raises
    ------
    CamsimError
        A path with a NUL byte, one that does not exist or cannot be opened, one that names a directory, a FIFO, a
        device or a socket, or a file over ``max_bytes``: one line, naming ``what`` and the path.
    """
    name = _checked_path(path, what)
    try:  # judged before it is opened too: opening some devices acts on them (a terminal, a tape rewinds)
        mode = os.stat(name).st_mode
    except OSError:
        mode = stat.S_IFREG  # missing or unreadable: the open below says which
    if not stat.S_ISREG(mode):
        raise CamsimError(f"cannot read {what} {name}: it is {_kind(mode)}, not a regular file")
    try:
        fd = os.open(name, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise CamsimError(f"{what} not found: {name}") from None
    except OSError as exc:
        try:  # a socket cannot be opened at all (ENXIO): say what it is
            mode = os.stat(name).st_mode
        except OSError:
            mode = stat.S_IFREG
        reason = f"it is {_kind(mode)}, not a regular file" if not stat.S_ISREG(mode) else exc.strerror or exc
        raise CamsimError(f"cannot read {what} {name}: {reason}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise CamsimError(f"cannot read {what} {name}: it is {_kind(info.st_mode)}, not a regular file")
        if max_bytes is not None and info.st_size > max_bytes:
            raise CamsimError(f"{what} {name} is {size_text(info.st_size)}, over the limit of "
                              f"{size_text(max_bytes)} for a {what}")
        os.set_blocking(fd, True)  # a regular file's reads never wait; the flag only mattered for opening
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def check_input(path, what: str, max_bytes: int | None = None) -> Path:
    """Check that ``path`` names a regular file (of at most ``max_bytes``) that a library may now open by name;
    returns it as a :class:`~pathlib.Path`. Raises as :func:`open_input`."""
    open_input(path, what, max_bytes).close()
    return Path(_checked_path(path, what))


def read_input(path, what: str, max_bytes: int | None = None) -> bytes:
    """The bytes of ``path``, a regular file of at most ``max_bytes``. Raises as :func:`open_input`, and on a read
    error (:class:`CamsimError`, one line)."""
    with open_input(path, what, max_bytes) as handle:
        try:
            data = handle.read() if max_bytes is None else handle.read(max_bytes + 1)
        except OSError as exc:
            raise CamsimError(f"cannot read {what} {os.fspath(path)}: {exc.strerror or exc}") from None
    if max_bytes is not None and len(data) > max_bytes:  # it grew since it was opened
        raise CamsimError(f"{what} {os.fspath(path)} is over the limit of {size_text(max_bytes)} for a {what}")
    return data


__all__ = ["check_input", "open_input", "read_input", "size_text"]
