"""The one way camsim opens an input file (camsim.core.input_files): a path that names no regular file — a FIFO, a
character device, a directory, a socket, a name with a NUL byte — or a file over its limit is refused on one line
before a byte is read, by the helpers themselves and by the commands that read scene files and dataset specs."""

import os
import resource
import socket
import sys

import pytest

from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.core.input_files import check_input, open_input, read_input
from camsim.core.schema import MAX_TOML_BYTES
from tests.support import clock
from tests.support.fifo_watchdog import fifo_watchdog
from tests.support.helpers import ROOT
from tests.support.hostile_files import not_regular, one_error_line

#: The address space a subprocess that is handed ``/dev/zero`` may take: a reader that read it would fail at this,
#: not take the machine's memory. Unit: bytes.
ZERO_READER_AS = 3 * 2**30


@pytest.fixture
def unix_socket(tmp_path):
    """A listening UNIX socket at ``tmp_path/sock.toml``: a path that exists and cannot be opened (ENXIO)."""
    path = tmp_path / "sock.toml"
    server = socket.socket(socket.AF_UNIX)
    server.bind(str(path))
    yield path
    server.close()


def _refused(call, *phrases):
    with pytest.raises(CamsimError) as info:
        call()
    message = str(info.value)
    assert "\n" not in message, message
    for phrase in phrases:
        assert phrase in message, message
    return message


def test_a_regular_file_is_opened_and_read(tmp_path):
    path = tmp_path / "a.toml"
    path.write_bytes(b"x = 1\n")
    with open_input(path, "scene file", max_bytes=6) as handle:
        assert handle.read() == b"x = 1\n"
    assert read_input(str(path), "scene file", 6) == b"x = 1\n"
    assert check_input(path, "scene file") == path


def test_a_file_over_its_limit_is_refused_before_it_is_read(tmp_path):
    path = tmp_path / "big.toml"
    path.write_bytes(b"x" * 101)
    _refused(lambda: open_input(path, "scene file", max_bytes=100), f"scene file {path} is 101 bytes",
             "over the limit of 100 bytes for a scene file")
    _refused(lambda: read_input(path, "scene file", 100), "over the limit")


@pytest.mark.parametrize("name", ["a\x00b.toml", b"a\x00b.toml"])
def test_a_name_with_a_nul_byte_is_refused(tmp_path, name):
    path = os.path.join(os.fsencode(tmp_path) if isinstance(name, bytes) else str(tmp_path), name)
    for call in (open_input, check_input, read_input):
        _refused(lambda: call(path, "scene file"), "scene file path", "holds a NUL byte, which no file name can")


def test_a_missing_file_is_named(tmp_path):
    _refused(lambda: open_input(tmp_path / "none.toml", "scene file"), f"scene file not found: {tmp_path}/none.toml")


@pytest.mark.parametrize("kind, said", [("fifo", "a FIFO (named pipe)"), ("device", "a character device"),
                                        ("directory", "a directory")])
def test_what_is_not_a_regular_file_is_refused_without_a_read(tmp_path, kind, said):
    """A FIFO without a writer, /dev/zero, a directory: each refused at once, whichever helper is asked (a read of
    /dev/zero is bounded by ``max_bytes`` here, so that a regression reads a kilobyte, not forever)."""
    path = not_regular(tmp_path / "input.toml", kind)
    with fifo_watchdog(path, what=f"open_input of a {kind}"):
        for call in (lambda: open_input(path, "scene file"), lambda: check_input(path, "scene file"),
                     lambda: read_input(path, "scene file", 1000)):
            _refused(call, f"cannot read scene file {path}: it is {said}, not a regular file")


def test_a_socket_is_refused(unix_socket):
    _refused(lambda: open_input(unix_socket, "scene file"), "it is a socket, not a regular file")


# --- through the commands: a scene file, a dataset spec -------------------------------------------------------

@pytest.mark.parametrize("command", ["render", "dataset"])
@pytest.mark.parametrize("kind", ["fifo", "directory", "socket", "nul", "oversize"])
def test_a_scene_file_or_spec_that_is_no_regular_file_is_one_line(tmp_path, capsys, unix_socket, command, kind):
    what = "scene file" if command == "render" else "dataset spec"
    if kind == "socket":
        path, said = unix_socket, "it is a socket, not a regular file"
    elif kind == "nul":
        path, said = f"{tmp_path}/a\x00b.toml", "holds a NUL byte"
    elif kind == "oversize":  # sparse: no disk taken
        path = tmp_path / "big.toml"
        with open(path, "wb") as handle:
            handle.truncate(MAX_TOML_BYTES + 1)
        said = f"over the limit of {MAX_TOML_BYTES / 1e6:g} MB for a {what}"
    else:
        path = not_regular(tmp_path / "input.toml", kind)
        said = f"it is {'a FIFO (named pipe)' if kind == 'fifo' else 'a directory'}, not a regular file"
    out = tmp_path / "out"
    with fifo_watchdog(*([path] if kind == "fifo" else []), what=f"camsim {command} of a FIFO"):
        assert main([command, str(path), "--out", str(out), "-q"]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert said in line and (what in line or kind == "nul"), line  # a NUL byte in argv: the parser may say it first
    assert not out.exists()


@pytest.mark.parametrize("command", ["render", "dataset"])
def test_a_scene_file_or_spec_that_is_dev_zero_is_one_line_in_a_bounded_process(tmp_path, command):
    """/dev/zero never ends: a reader that read it would take memory without bound, so the command runs in a
    subprocess with a CPU-time budget and an address-space limit (a regression fails there, not the machine)."""
    path = not_regular(tmp_path / "zero.toml", "device")

    def bounded():
        resource.setrlimit(resource.RLIMIT_AS, (ZERO_READER_AS, ZERO_READER_AS))

    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = clock.run([sys.executable, "-m", "camsim", command, str(path), "--out", str(tmp_path / "out"), "-q"],
                     cpu_s=60, env=env, capture_output=True, text=True, preexec_fn=bounded)
    assert done.returncode == 2, done.stderr
    line = one_error_line(done.stderr)
    assert f"{path}: it is a character device, not a regular file" in line, line


def test_a_scene_named_in_a_spec_that_is_a_fifo_is_one_line(tmp_path, capsys):
    fifo = not_regular(tmp_path / "scene.toml", "fifo")
    spec = tmp_path / "spec.toml"
    spec.write_text('name = "s"\nscene = "scene.toml"\n')
    with fifo_watchdog(fifo, what="camsim dataset of a spec naming a FIFO"):
        assert main(["dataset", str(spec), "--out", str(tmp_path / "out"), "-q"]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert f"cannot read scene file {fifo}: it is a FIFO (named pipe)" in line, line


@pytest.mark.parametrize("value", ["a\\u0000b.toml", "a\\u0000b"])
def test_a_scene_named_in_a_spec_with_a_nul_byte_is_one_line(tmp_path, capsys, value):
    """A NUL byte in the spec's ``scene`` (a path, or what looks like a built-in scene's name)."""
    spec = tmp_path / "spec.toml"
    spec.write_text(f'name = "s"\nscene = "{value}"\n')
    assert main(["dataset", str(spec), "--out", str(tmp_path / "out"), "-q"]) == 2
    line = one_error_line(capsys.readouterr().err)
    assert "scene file path" in line and "holds a NUL byte" in line, line
