"""The ``camsim`` command line. ``main(argv)`` does the work and returns an exit status; importing does nothing.

Each sub-command is a module of :mod:`camsim.cli.commands` with ``add_parser(subparsers)`` and ``run(args)``;
:data:`COMMANDS` names them. User errors (bad names, malformed files, bad values) and the environment's (a folder
that cannot be written, a full disk, no memory) print one line, ``camsim: error: ...``, and exit with 2. Ctrl-C
(SIGINT) exits with 130 and SIGTERM (``kill``, ``timeout``, batch schedulers) with 143, both after the files being
written are removed: what a run leaves is complete.

Layer 10, the commands: this package (with :mod:`camsim.cli.types`, the argparse value types the sub-commands
share) may import every layer below it, the applications included; only ``camsim.__main__`` imports it.
``tests/test_layers.py`` checks the layers.
"""

from __future__ import annotations

import argparse
import re
import signal
import sys
import warnings

from camsim import __version__
from camsim.cli.commands import analyze, calibrate, dataset, denoise_eval, develop, emva, experiment, optimise, render
from camsim.cli.commands import list as list_command
from camsim.core.errors import CamsimError, describe_os_error
from camsim.core.signals import handlers_installed

#: The sub-commands, by name, in the order ``camsim --help`` lists them.
COMMANDS = {
    "render": render,
    "analyze": analyze,
    "experiment": experiment,
    "emva": emva,
    "calibrate": calibrate,
    "optimise": optimise,
    "dataset": dataset,
    "denoise-eval": denoise_eval,
    "develop": develop,
    "list": list_command,
}


#: The modules whose warnings ``-q`` silences: colour-science's and colour-demosaicing's (e.g. "Interpolating ...
#: cmfs to 1nm interval" from a spectral recovery); camsim's own warnings (``camsim: warning: ...``) stay.
QUIET_MODULES = r"colour(_demosaicing)?(\.|$)"


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


class Terminated(BaseException):
    """Raised in the main thread when the process receives SIGTERM, so that it unwinds like Ctrl-C."""


#: The stop signals (SIGINT, SIGTERM) the current run of :func:`main` has received, in order.
_stops: list[int] = []


def _raise_interrupted(signum, frame):
    _stops.append(signum)
    raise KeyboardInterrupt


def _raise_terminated(signum, frame):
    _stops.append(signum)
    raise Terminated


def _stop_signal(exc: BaseException) -> int | None:
    """The stop signal that ended the run, if one did: the exception it raised, or any exception once it was
    received — a C library can turn the KeyboardInterrupt raised inside a call it makes into another error on its
    way out (numpy's ``tofile``, which tifffile writes with, reports a ``TypeError``)."""
    if isinstance(exc, KeyboardInterrupt):
        return signal.SIGINT
    if isinstance(exc, Terminated):
        return signal.SIGTERM
    return _stops[0] if _stops and isinstance(exc, Exception) else None


def _os_error_text(exc: OSError) -> str:
    where = f"{exc.filename}: " if exc.filename else ""
    return f"{where}{describe_os_error(exc)}"


#: Exit status after Ctrl-C (128 + SIGINT) and SIGTERM (128 + SIGTERM), as shells report them.
EXIT_INTERRUPTED, EXIT_TERMINATED = 128 + signal.SIGINT, 128 + signal.SIGTERM
_STOPPED = "what was complete is kept, nothing half-written is left"


#: Control characters (C0, DEL, C1) other than the line breaks and tabs that become spaces: written escaped
#: (``\x00``, ``\r``, ``\x1b``), as a name from input may hold them and a terminal would act on them.
_CONTROLS = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f]")


def _one_line(message) -> str:
    """An error message on one line: line breaks (a value's repr across lines, a library's text) and tabs become
    spaces; any other control character (a carriage return, a NUL, an escape sequence from a hostile file name) is
    written escaped, so the message is one line that a terminal only shows."""
    text = re.sub(r"[ \t]*(\r\n|\n)[ \t]*|\t", " ", str(message)).strip()
    return _CONTROLS.sub(lambda match: match.group().encode("unicode_escape").decode("ascii"), text)


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 2 error, 130 interrupted, 143 terminated)."""
    parser = build_parser()
    given = sys.argv[1:] if argv is None else argv
    nul = next((arg for arg in given if isinstance(arg, str) and "\x00" in arg), None)
    if nul is not None:  # no process's argv can hold one (exec refuses it); a caller of main() can
        print(f"camsim: error: {_one_line(f'argument {nul!r} holds a NUL byte, which no argument or file name can')}",
              file=sys.stderr)
        return 2
    try:
        args = parser.parse_args(argv)
    except _UsageError as exc:
        print(f"camsim: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    if args.command is None:
        parser.print_help()
        return 2
    _stops.clear()
    try:
        with handlers_installed({signal.SIGINT: _raise_interrupted, signal.SIGTERM: _raise_terminated}), \
                warnings.catch_warnings():
            if getattr(args, "quiet", False):  # -q: no library chatter either
                warnings.filterwarnings("ignore", module=QUIET_MODULES)
            return COMMANDS[args.command].run(args)
    except BaseException as exc:
        stop = _stop_signal(exc)
        if stop == signal.SIGINT:
            print(f"camsim: interrupted; {_STOPPED}", file=sys.stderr)
            return EXIT_INTERRUPTED
        if stop == signal.SIGTERM:
            print(f"camsim: terminated (SIGTERM); {_STOPPED}", file=sys.stderr)
            return EXIT_TERMINATED
        if isinstance(exc, CamsimError):
            print(f"camsim: error: {_one_line(exc)}", file=sys.stderr)
            return 2
        if isinstance(exc, OSError):  # the environment's: a file or folder that cannot be read or written
            print(f"camsim: error: {_one_line(_os_error_text(exc))}", file=sys.stderr)
            return 2
        if isinstance(exc, RuntimeError) and str(exc).startswith("Symlink loop from "):
            # pathlib's resolve() (before Python 3.13) raises this where the system's calls give ELOOP
            print(f"camsim: error: {_one_line(exc)} (a symbolic link that leads back to itself)", file=sys.stderr)
            return 2
        if isinstance(exc, MemoryError):
            print("camsim: error: out of memory (try a smaller --size, or fewer --workers)", file=sys.stderr)
            return 2
        raise
    finally:
        _stops.clear()


def main_entry() -> None:
    """Console-script entry point."""
    sys.exit(main())
