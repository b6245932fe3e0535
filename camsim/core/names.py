"""Names that become part of a file or folder name: one rule, checked where the name is read.

A scene's ``name`` becomes its frames' file names (``NAME_D65_F1.dng``) and its default output folder
(``outputs/NAME``); a dataset spec's ``name`` its default output folder; ``camsim calibrate --name`` the name of
the preset it writes (and a camera preset file's ``name``, the same rule, so that what calibrate writes is read
back). Each is checked by :func:`safe_component` where it is read — the scene file, the spec, the preset file,
the command line — before any work, so that a bad one is one ``camsim: error:`` line and nothing is written.

The rule (:func:`safe_component`). A name is one file-name component that stays where it is put:

* a non-empty string of at most :data:`MAX_NAME_BYTES` bytes in UTF-8 (file systems count bytes: ext4, APFS,
  NTFS allow 255, and a frame's file name adds the illuminant, the light level, a suffix and, while it is
  written, ``.NAME.PID.partial``);
* no ``/`` and no ``\\`` (a path separator on POSIX or on Windows): a name never names a folder;
* no leading ``.``: not ``.`` or ``..`` (this folder, its parent), and no hidden file, which ``analyze`` and a
  search of a folder pass over, and which could take the form of camsim's temporaries (``.NAME.PID.partial``,
  removed as stale by the next run);
* printable characters only (:meth:`str.isprintable`): no newline, tab, NUL or other control character, no
  invisible format character (a right-to-left override shows a name reversed, a zero-width space hides in it), no
  line or paragraph separator, no space but the ASCII space, no unassigned code point or lone surrogate;
* no ASCII space first or last (invisible in a listing; Windows drops a trailing one);
* none of ``< > : " | ? *``, which Windows, exFAT and SMB shares refuse in a file name: a dataset is copied to
  other machines.

Allowed, because they are safe: inner ASCII spaces (a file name with a space is legal everywhere, and camsim
never hands a path to a shell), and letters, digits, marks and symbols of any script (a POSIX file name is bytes,
camsim writes UTF-8; macOS may store a decomposed form, which reads back as the same name).
"""

from __future__ import annotations

from camsim.core.errors import CamsimError

__all__ = ["MAX_NAME_BYTES", "MAX_STEM_BYTES", "FORBIDDEN_CHARACTERS", "safe_component", "name_problem"]

#: The longest name, in bytes of UTF-8 (128 ASCII characters).
MAX_NAME_BYTES = 128
#: The longest file stem camsim builds from names (a frame's, ``NAME_ILLUMINANT_FF``), in bytes of UTF-8: its
#: longest suffix (``.dng.xmp``) and a temporary's ``.STEM.SUFFIX.PID.partial`` stay within the 255 bytes of a file
#: name.
MAX_STEM_BYTES = 200
#: Characters refused anywhere in a name: the path separators and those Windows refuses in a file name.
FORBIDDEN_CHARACTERS = '/\\<>:"|?*'


def name_problem(value, max_bytes: int = MAX_NAME_BYTES) -> str | None:
    """Why ``value`` is not a safe file-name component (the module's rule), e.g. ``"it contains /"``; None if it
    is one."""
    if not isinstance(value, str):
        return "it is not a string"
    if not value:
        return "it is empty"
    try:
        size = len(value.encode("utf-8"))
    except UnicodeEncodeError:  # a lone surrogate (from JSON, or undecodable bytes on the command line)
        return "it holds an unpaired surrogate"
    if size > max_bytes:
        return f"it is {size} bytes long in UTF-8, more than {max_bytes}"
    if "/" in value or "\\" in value:
        return "it contains a path separator, / or \\ (a name is one file name, not a path)"
    bad = [ch for ch in FORBIDDEN_CHARACTERS if ch in value]
    if bad:
        return f"it contains {' '.join(bad)} (refused in file names on Windows, exFAT and SMB shares)"
    if value.startswith("."):
        return "it starts with '.' (., .. and hidden files are refused)"
    odd = next((ch for ch in value if not ch.isprintable()), None)
    if odd is not None:
        return f"it holds the unprintable character U+{ord(odd):04X} (control, format or separator characters " \
               "are refused)"
    if value != value.strip(" "):
        return "it starts or ends with a space"
    return None


def safe_component(value, what: str, max_bytes: int = MAX_NAME_BYTES) -> str:
    """``value``, checked to be a safe file-name component (the module's rule).

    Parameters
    ----------
    value : object
        The name as read (a scene file's ``name``, a command-line value …).
    what : str
        The name's label for the message, with its place, e.g. ``"scenes/x.toml: name"``.
    max_bytes : int
        The longest name in bytes of UTF-8 (default :data:`MAX_NAME_BYTES`).

    Returns
    -------
    str
        ``value`` unchanged.

    Raises
    ------
    CamsimError
        ``"<what> <value> is not a safe file name: <why>"``, one line (the value shown with Python's escapes, so a
        newline reads ``\\n``).
    """
    problem = name_problem(value, max_bytes)
    if problem is not None:
        shown = repr(value)
        shown = shown if len(shown) <= 80 else shown[:76] + "...'"
        raise CamsimError(f"{what} {shown} is not a safe file name: {problem}")
    return value
