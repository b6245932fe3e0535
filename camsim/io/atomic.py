"""Atomic file writes: a file appears under its final name complete or not at all.

Every writer in :mod:`camsim.io` writes into a temporary file next to the target and renames it onto the target
with :func:`os.replace` only after the write has finished. A crash, an exception or Ctrl-C in the middle of a write
therefore never leaves a truncated file under the final name (an older complete file, if any, stays in place).
A write the environment refuses (no space, no permission) raises :class:`camsim.core.errors.OutputError`, one line.

Inside :func:`confined_to` (every sub-command's output folder holds its writes so:
:func:`camsim.io.output_folder.output_folder`), a write whose target lies outside the folder is refused before
anything is created: the last line of defence behind the checks of every name that becomes part of a path
(:mod:`camsim.core.names`).

:func:`undo_on_failure` groups writes into one unit: if the block fails, the files it completed are removed too,
so that a set of files that belong together (a frame's DNG and EXR, a report and its tables) appears whole or
not at all.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from pathlib import Path
from typing import Any

from camsim.core.errors import CamsimError, OutputError, output_error

__all__ = ["atomic_path", "write_json_atomic", "write_text_atomic", "undo_on_failure", "record_created",
           "fsync_path", "confined_to", "check_confined", "PARTIAL_SUFFIX"]

#: The suffix of a temporary file (``.NAME.PID.partial``) while it is being written.
PARTIAL_SUFFIX = ".partial"

# The files completed inside the innermost undo_on_failure block of this thread/task (None: no block).
_completed: ContextVar[list[Path] | None] = ContextVar("camsim_completed_writes", default=None)


# The folder the writes of this thread/task must stay inside, resolved (None: no confinement).
_confinement: ContextVar[Path | None] = ContextVar("camsim_write_confinement", default=None)


@contextlib.contextmanager
def confined_to(folder: str | os.PathLike[str]) -> Iterator[Path]:
    """Refuse, in the block, every write (:func:`atomic_path`, and the folders
    :func:`camsim.io.output_folder.make_folder` creates) whose target lies outside ``folder``.

    Yields
    ------
    pathlib.Path
        ``folder``, resolved (symbolic links followed).
    """
    root = Path(folder).resolve()
    token = _confinement.set(root)
    try:
        yield root
    finally:
        _confinement.reset(token)


def check_confined(path: str | os.PathLike[str]) -> None:
    """Refuse ``path`` as a write's target if it lies outside the folder of the innermost :func:`confined_to`
    block (nothing to check outside one).

    The target's folder is resolved (symbolic links and ``..`` followed); its last component is taken as it is,
    since a write replaces that entry and never follows it.

    Raises
    ------
    OutputError
        ``path`` lies outside the folder.
    """
    root = _confinement.get()
    if root is None:
        return
    target = Path(path)
    resolved = Path(os.path.normpath(target.parent.resolve() / target.name))
    if resolved != root and root not in resolved.parents:
        raise OutputError(f"refusing to write {target}: it lies outside the output folder {root}")


def _temp_name(path: Path) -> Path:
    # Hidden, in the same directory (so os.replace is a same-filesystem rename), and deterministic. The process
    # id keeps two processes that write the same target from clobbering each other's half-written temporary.
    return path.with_name(f".{path.name}.{os.getpid()}{PARTIAL_SUFFIX}")


def fsync_path(path: str | os.PathLike[str], *, directory: bool = False) -> None:
    """Flush a file (or, with ``directory``, a folder's entries) to disk; a folder that cannot be opened or synced
    is passed over (durability is best effort there)."""
    flags = os.O_RDONLY | (getattr(os, "O_DIRECTORY", 0) if directory else 0)
    try:
        fd = os.open(path, flags)
    except OSError:
        if directory:  # some platforms/filesystems cannot open directories; durability is best effort there
            return
        raise
    try:
        os.fsync(fd)
    except OSError:
        if not directory:
            raise
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str], *, renamed: Callable[[], None] | None = None) -> Iterator[Path]:
    """Yield a temporary path to write to; move it onto ``path`` when the ``with`` block succeeds.

    Parameters
    ----------
    path : str or os.PathLike
        Final destination. Its directory must exist.
    renamed : callable, optional
        Called with no argument right after the rename, before the directory is synced: what must follow the
        file's appearance at once (a manifest line; a kill in between is then microseconds' chance).

    Yields
    ------
    pathlib.Path
        ``<dir>/.<name>.<pid>.partial``, in the same directory as ``path``. The body of the ``with`` block must
        create this file (any stale file of that name is removed first).

    Raises
    ------
    CamsimError
        If the directory of ``path`` does not exist.
    OutputError
        If ``path`` lies outside the folder of a :func:`confined_to` block.

    Notes
    -----
    On normal exit the temporary file is flushed to disk (``fsync``) and atomically renamed onto ``path`` with
    :func:`os.replace`, replacing any existing file. On any exception (including ``KeyboardInterrupt``) the
    temporary file is deleted and the exception re-raised, so neither a partial final file nor a temporary file
    is left behind; an :class:`OSError` (no space, no permission, an I/O error) is re-raised as
    :class:`camsim.core.errors.OutputError` naming ``path``.
    """
    final = Path(path)
    check_confined(final)
    if not final.parent.is_dir():
        raise CamsimError(f"cannot write {final}: directory {final.parent} does not exist")
    tmp = _temp_name(final)
    try:
        tmp.unlink(missing_ok=True)
        yield tmp
        fsync_path(tmp)
        os.replace(tmp, final)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise output_error(final, exc) from None
        raise
    if renamed is not None:
        renamed()
    record_created(final)
    fsync_path(final.parent, directory=True)


def record_created(path: Path) -> None:
    """Count ``path`` (a file just completed, or a folder just made) among the innermost
    :func:`undo_on_failure` block's outputs, if a block is open."""
    completed = _completed.get()
    if completed is not None:
        completed.append(Path(path))


@contextlib.contextmanager
def undo_on_failure() -> Iterator[list[Path]]:
    """Group the atomic writes of the block into one unit: if the block raises (anything, Ctrl-C included), the
    files it completed are removed before the exception goes on, and the folders it made
    (:func:`camsim.io.output_folder.make_folder`) if they are empty then.

    Yields
    ------
    list of pathlib.Path
        The files completed so far in the block, in order. A block nested in another hands its files to the outer
        one when it succeeds.

    Notes
    -----
    A file completed in the block replaced any older file of its name, so after a failure neither is there: the
    unit is gone, not rolled back.
    """
    outer = _completed.get()
    completed: list[Path] = []
    token = _completed.set(completed)
    try:
        yield completed
    except BaseException:
        for path in reversed(completed):  # files before the folders that hold them
            with contextlib.suppress(OSError):
                if path.is_dir():
                    path.rmdir()  # only if the block left it empty
                else:
                    path.unlink(missing_ok=True)
        raise
    finally:
        _completed.reset(token)
    if outer is not None:
        outer.extend(completed)


def write_text_atomic(path: str | os.PathLike[str], text: str, *, renamed: Callable[[], None] | None = None) -> None:
    """Write ``text`` to ``path`` as UTF-8, atomically (see :func:`atomic_path`).

    Parameters
    ----------
    path : str or os.PathLike
        Destination file.
    text : str
        Content, written verbatim (no newline translation, on any platform).
    renamed : callable, optional
        Called right after the rename (:func:`atomic_path`).
    """
    data = text.encode("utf-8")  # encode first: an unencodable string (lone surrogate) creates no file at all
    with atomic_path(path, renamed=renamed) as tmp:
        tmp.write_bytes(data)


def write_json_atomic(path: str | os.PathLike[str], obj: Any, *, renamed: Callable[[], None] | None = None) -> None:
    """Write ``obj`` as pretty-printed JSON (UTF-8, trailing newline) to ``path``, atomically.

    Parameters
    ----------
    path : str or os.PathLike
        Destination file.
    obj : Any
        JSON-serialisable object. Serialised with ``indent=2, allow_nan=False, ensure_ascii=False``.
    renamed : callable, optional
        Called right after the rename (:func:`atomic_path`).

    Raises
    ------
    ValueError
        If ``obj`` contains NaN or infinity (not valid JSON). Raised before any file is created.
    TypeError
        If ``obj`` contains a value :mod:`json` cannot serialise. Raised before any file is created.
    """
    text = json.dumps(obj, indent=2, allow_nan=False, ensure_ascii=False) + "\n"
    write_text_atomic(path, text, renamed=renamed)
