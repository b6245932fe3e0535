"""Exception types.

:class:`CamsimError` marks a *user* error (bad input, unknown name, malformed file). The CLI prints its message
on one line and exits with status 2, with no traceback; any other exception is a bug and keeps its traceback.
:class:`OutputError` is the environment's refusal of a write (a full disk, a read-only folder, a file in the way),
reported the same way.
"""

from __future__ import annotations

import os
import shutil


class CamsimError(ValueError):
    """A problem with the user's input, reported as one clear message."""


class OutputError(CamsimError):
    """A file or folder could not be written (no space, no permission, a file in the way): one clear message."""


def describe_os_error(exc: BaseException) -> str:
    """The reason an :class:`OSError` gives, without Python's ``[Errno N]`` prefix and without the path (the caller
    names the path), e.g. ``No space left on device``; other exceptions as ``str(exc)``."""
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    if isinstance(exc, OSError) and exc.errno:
        return os.strerror(exc.errno)
    return str(exc) or type(exc).__name__


def output_error(path, exc: BaseException) -> OutputError:
    """An :class:`OutputError` saying that ``path`` could not be written, and why (from ``exc``).

    A writer's error without an error number (e.g. a short write: ``N requested and M written``) gets the free
    space of the file system, the usual cause.
    """
    reason = describe_os_error(exc)
    if not (isinstance(exc, OSError) and exc.errno):
        try:
            free = shutil.disk_usage(os.path.dirname(os.path.abspath(path))).free
            reason += f" ({free / 1e6:.1f} MB free on that file system)"
        except OSError:
            pass
    return OutputError(f"cannot write {path}: {reason}")
