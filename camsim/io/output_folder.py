"""An output folder, made ready before any work: created, checked writable, locked, swept of stale temporaries.

Every sub-command that writes calls :func:`output_folder` before its work starts, so that a folder it cannot
create or write is reported in one line at once (not after minutes of rendering), and so that two camsim runs
never write into one folder at the same time: the folder itself is held with an exclusive advisory lock
(``flock`` on the folder; POSIX, local file systems), the same lock for every sub-command. The lock goes with the
process, however it ends, and leaves no file behind.

While a run holds its folder, it writes nowhere else (:func:`camsim.io.atomic.confined_to`): a file or folder
whose path leads outside (``..``, an absolute path, a symbolic link out) is refused before it is created, whatever
name it was built from.

Holding the lock, the run removes the temporary files (``.NAME.PID.partial``, :mod:`camsim.io.atomic`) that a
process killed outright (SIGKILL, power loss) left in the folder: no live camsim process can own them.
"""

from __future__ import annotations

import contextlib
import os
import re
from collections.abc import Iterator
from pathlib import Path

from camsim.core.errors import CamsimError, OutputError, describe_os_error
from camsim.io.atomic import PARTIAL_SUFFIX, check_confined, confined_to, record_created

__all__ = ["output_folder", "make_folder", "check_writable", "remove_stale_partials", "FolderBusyError"]

_PARTIAL = re.compile(r"^\..+\.\d+" + re.escape(PARTIAL_SUFFIX) + "$")


class FolderBusyError(CamsimError):
    """Another camsim run holds the folder's lock."""


def make_folder(path: str | os.PathLike[str]) -> list[Path]:
    """Create ``path`` and its missing parents; returns the folders created, outermost first (they also count as
    outputs of an open :func:`camsim.io.atomic.undo_on_failure` block).

    Raises
    ------
    OutputError
        A file is in the way, or the file system refuses (permission, read-only, no space), or ``path`` lies
        outside the output folder the run holds (:func:`camsim.io.atomic.confined_to`).
    """
    path = Path(path)
    missing = []
    for folder in (path, *path.parents):
        if folder.is_dir():
            break
        missing.append(folder)
    if missing:
        check_confined(path)
    created = []
    for folder in reversed(missing):
        try:
            folder.mkdir()
        except FileExistsError:
            if not folder.is_dir():
                raise OutputError(f"cannot create folder {path}: {folder} is a file") from None
            continue  # made meanwhile by another process: not ours
        except NotADirectoryError:
            raise OutputError(f"cannot create folder {path}: {folder.parent} is a file") from None
        except OSError as exc:
            raise OutputError(f"cannot create folder {path}: {describe_os_error(exc)}") from None
        record_created(folder)
        created.append(folder)
    return created


def check_writable(folder: str | os.PathLike[str]) -> None:
    """Create and remove a small file in ``folder``, so that a folder that cannot be written is known now.

    Raises
    ------
    OutputError
        The folder cannot be written.
    """
    probe = Path(folder) / f".camsim-probe.{os.getpid()}{PARTIAL_SUFFIX}"
    try:
        fd = os.open(probe, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        try:
            os.write(fd, b"camsim")
        finally:
            os.close(fd)
    except OSError as exc:
        raise OutputError(f"cannot write into {folder}: {describe_os_error(exc)}") from None
    finally:  # whatever happened, Ctrl-C included
        with contextlib.suppress(OSError):
            probe.unlink(missing_ok=True)


def remove_stale_partials(folder: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporary files (``.NAME.PID.partial``) in ``folder`` (not its subfolders); returns them.

    Call it only while holding the folder's lock: then no live camsim process is writing them.
    """
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    for entry in entries:
        if _PARTIAL.match(entry.name) and entry.is_file(follow_symlinks=False):
            with contextlib.suppress(OSError):
                os.unlink(entry.path)
                removed.append(Path(entry.path))
    return removed


@contextlib.contextmanager
def _locked(folder: Path) -> Iterator[None]:
    """Hold an exclusive ``flock`` on the folder itself (no lock file to leave behind); released when the block
    ends or the process dies, however it dies."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - no advisory locks on this platform: best effort
        yield
        return
    try:
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError as exc:
        raise OutputError(f"cannot open folder {folder}: {describe_os_error(exc)}") from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise FolderBusyError(f"another camsim run is writing to {folder}; wait for it to finish or choose "
                                  "another --out") from None
        except OSError:  # a file system without flock (some network mounts): no lock, as before locks existed
            pass
        yield
    finally:
        os.close(fd)


def _remove_if_empty(created: list[Path]) -> None:
    """Remove the folders this run created, innermost first, where nothing is in them."""
    for folder in reversed(created):
        with contextlib.suppress(OSError):
            folder.rmdir()


@contextlib.contextmanager
def output_folder(path: str | os.PathLike[str], *, subfolders: tuple[str, ...] = ()) -> Iterator[Path]:
    """Make ``path`` ready for a run's outputs and hold it for the ``with`` block.

    Creates the folder (and ``subfolders`` in it), checks that a file can be written there, takes the folder's
    lock and removes stale temporaries in the folder and the subfolders. In the block, camsim's writes outside the
    folder are refused (:func:`camsim.io.atomic.confined_to`). If the block fails
    (any exception, Ctrl-C included) and the folders it created hold nothing, they are removed again.

    Parameters
    ----------
    path : str or os.PathLike
        The output folder.
    subfolders : tuple of str
        Folders inside ``path`` the run writes into (swept of stale temporaries too).

    Yields
    ------
    pathlib.Path
        ``path``.

    Raises
    ------
    OutputError
        The folder cannot be created or written.
    FolderBusyError
        Another camsim run holds the folder.
    """
    path = Path(path)
    created = make_folder(path)
    try:
        check_writable(path)
        for name in subfolders:
            created += make_folder(path / name)
        with _locked(path), confined_to(path):
            for folder in (path, *(path / name for name in subfolders)):
                remove_stale_partials(folder)
            yield path
    except BaseException:
        _remove_if_empty(created)
        raise

