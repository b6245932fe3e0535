"""The sub-commands of ``camsim``, one module each (``render``, ``analyze``, ``experiment``, ``emva``, ``calibrate``,
``dataset``, ``denoise_eval``, ``develop``, ``list``), all alike:

* ``add_parser(subparsers)`` adds the sub-command and its options to an ``ArgumentParser.add_subparsers()``
  object and returns its parser;
* ``run(args) -> int`` carries it out and returns the exit status; user errors raise
  :class:`camsim.core.errors.CamsimError`, which :func:`camsim.cli.main` prints on one line (exit 2).

Importing a command module does no work: the modules that do the work are imported inside ``run``.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

DEFAULT_OUT = Path("outputs")
"""Where a command writes when no ``--out`` is given, relative to the working directory."""


def camera_argument(name_or_csv: str | None) -> str | None:
    """A ``--camera`` value as a scene takes it: a CSV file named on the command line is relative to the working
    directory, so its path is made absolute; a colour-science camera name (or None) is returned as it is."""
    if name_or_csv is not None and name_or_csv.lower().endswith(".csv"):
        return str(Path(name_or_csv).resolve())
    return name_or_csv


def preset_argument(name_or_toml: str) -> str:
    """A ``--preset`` value as a scene takes it: a camera preset file (``.toml``) named on the command line is
    relative to the working directory, so its path is made absolute; a preset name is returned as it is."""
    if name_or_toml.lower().endswith(".toml"):
        return str(Path(name_or_toml).resolve())
    return name_or_toml


@contextlib.contextmanager
def writing_to(out: Path) -> Iterator[Path]:
    """Hold the command's output folder for its work: made ready before the work starts (created, checked writable,
    locked; :func:`camsim.io.output_folder.output_folder`), and the files written in the block are one unit — if the
    block fails or is interrupted, those it had completed are removed (:func:`camsim.io.atomic.undo_on_failure`)."""
    from camsim.io.atomic import undo_on_failure
    from camsim.io.output_folder import output_folder

    with output_folder(out) as folder, undo_on_failure():
        yield folder


def exr_compression_argument(parser, spec_key: bool = False) -> None:
    """Add ``--exr-compression NAME`` to ``parser``, checked when the command runs (the installed OpenEXR decides
    which names exist). With ``spec_key``, it defaults to None: the spec's ``exr_compression``, else camsim's."""
    from camsim.io.exr_compression import DEFAULT_EXR_COMPRESSION, LOSSLESS_EXR_COMPRESSIONS

    default = f"the spec's exr_compression, else {DEFAULT_EXR_COMPRESSION}" if spec_key else DEFAULT_EXR_COMPRESSION
    parser.add_argument("--exr-compression", metavar="NAME", default=None if spec_key else DEFAULT_EXR_COMPRESSION,
                        help="compression of the EXR files, one of OpenEXR's lossless ones: "
                             f"{', '.join(LOSSLESS_EXR_COMPRESSIONS)} (zstd and htj2k* need OpenEXR >= 3.5 / 3.4 "
                             f"to read them). Default: {default} (noisy float32 barely compresses: docs, "
                             "reference 'File formats'). The lossy ones (pxr24, b44, b44a, dwaa, dwab, lj2k) are "
                             "refused")
