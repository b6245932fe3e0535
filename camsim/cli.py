"""The ``camsim`` command line. ``main(argv)`` does the work and returns an exit status; importing does nothing.

Each sub-command is a module of :mod:`camsim.commands` with ``add_parser(subparsers)`` and ``run(args)``;
:data:`COMMANDS` names them. User errors (bad names, malformed files, bad values) print one line,
``camsim: error: ...``, and exit with 2.
"""

from __future__ import annotations

import argparse
import sys

from camsim import __version__
from camsim.commands import analyze, dataset, denoise_eval, emva, experiment, render
from camsim.commands import list as list_command
from camsim.errors import CamsimError

#: The sub-commands, by name, in the order ``camsim --help`` lists them.
COMMANDS = {
    "render": render,
    "analyze": analyze,
    "experiment": experiment,
    "emva": emva,
    "dataset": dataset,
    "denoise-eval": denoise_eval,
    "list": list_command,
}


class _UsageError(Exception):
    """A command-line usage error, reported on one line like any other user error."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse would print the usage block and exit; camsim prints one line
        raise _UsageError(f"{message} (see '{self.prog} --help')")


def build_parser() -> argparse.ArgumentParser:
    """The ``camsim`` parser, with every sub-command of :data:`COMMANDS`."""
    parser = _Parser(
        prog="camsim",
        description=(
            "Physically grounded camera simulator: spectral scenes through the image-sensor model of "
            "'Image Sensor Modeling: Color Measurement at Low Light Levels' (2014) into 8-bit DNG raw, "
            "float EXR and JSON sidecar files."
        ),
        epilog="Run 'camsim render --help' for the rendering options.",
    )
    parser.add_argument("--version", action="version", version=f"camsim {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for command in COMMANDS.values():
        command.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 2 user error, 130 interrupted)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except _UsageError as exc:
        print(f"camsim: error: {exc}", file=sys.stderr)
        return 2
    if args.command is None:
        parser.print_help()
        return 2
    try:
        return COMMANDS[args.command].run(args)
    except CamsimError as exc:
        print(f"camsim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("camsim: interrupted; completed frames are kept, no partial file is left", file=sys.stderr)
        return 130


def main_entry() -> None:
    """Console-script entry point."""
    sys.exit(main())
