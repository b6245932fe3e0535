"""A ``cmd:`` denoiser runs in its own process group, and the whole group is killed on every exit path: after a
timeout, a failure or a normal exit, no child it started (a shell script's ``sleep``) is left running."""

import os
import sys
import textwrap

import numpy as np
import pytest

from camsim.core.errors import CamsimError
from camsim.denoise.denoisers import resolve_denoiser
from tests.support import clock

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="process groups are POSIX")


def _running(pid: int) -> bool:
    """Whether process ``pid`` exists and is not a zombie (an orphan that PID 1 has not reaped counts as gone)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except FileNotFoundError:
        return False
    except OSError:  # no /proc: ask the kernel
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True


#: How long the script's background child sleeps before it leaves its mark. A denoiser call that waited for it would
#: return only after the mark; an orphan would still be running long after the call. Unit: s.
SLEEP_S = 600
#: The file the background child writes when its sleep has ended: its absence after the call shows the call did not
#: wait for the child (no clock involved).
MARK = "the-background-child-ended"


def _script(tmp_path, tail: str):
    """A shell-script denoiser that starts a background child (``sleep SLEEP_S``, then it writes :data:`MARK`),
    writes the child's PID, then runs ``tail``."""
    pid_file = tmp_path / "sleep.pid"
    script = tmp_path / "hang.sh"
    script.write_text(textwrap.dedent(f"""\
        #!/bin/sh
        ( sleep {SLEEP_S}; touch '{tmp_path / MARK}' ) &
        echo $! > '{pid_file}'
        {tail}
        """))
    script.chmod(0o755)
    return script, pid_file


def _child_pid(pid_file) -> int:
    pid = int(pid_file.read_text())
    assert pid > 1
    return pid


def _gone(pid: int) -> bool:
    """Whether ``pid`` is gone, given the time a killed process needs to die however busy the machine
    (:data:`tests.support.clock.EXIT_BACKSTOP_S`; a SIGKILL is delivered asynchronously: the kill call returns
    before the process is dead). An orphan would run for the rest of its ``SLEEP_S``."""
    return clock.eventually(lambda: not _running(pid))


def test_timeout_kills_the_commands_children(tmp_path):
    """The denoiser's timeout is wall time by design; it is judged once the script had started its child before
    the timeout ran out (1 s, or longer where a busy machine had not got that far)."""
    for timeout_s in (1, 4, 16):
        script, pid_file = _script(tmp_path, "wait")
        pid_file.unlink(missing_ok=True)
        denoiser = resolve_denoiser(f"cmd:{script} {{input}} {{output}}", timeout_s=timeout_s)
        with pytest.raises(CamsimError, match=f"did not finish within {timeout_s} s"):
            denoiser(np.ones((8, 8, 3), np.float32))
        if pid_file.is_file() and pid_file.read_text().endswith("\n"):
            break
    else:
        pytest.skip("the machine is too busy to judge the timeout: the script had not started its child in 16 s")
    assert not (tmp_path / MARK).exists()  # it did not wait for the background child
    assert _gone(_child_pid(pid_file))


@pytest.mark.parametrize("tail, message", [("echo broken >&2; exit 3", "exit status 3.*broken"),
                                           ("exit 0", "wrote no")])
def test_failure_and_exit_kill_the_commands_children(tmp_path, tail, message):
    script, pid_file = _script(tmp_path, tail)
    denoiser = resolve_denoiser(f"cmd:{script} {{input}} {{output}}", timeout_s=SLEEP_S / 2)
    with pytest.raises(CamsimError, match=message):
        denoiser(np.ones((8, 8, 3), np.float32))
    assert not (tmp_path / MARK).exists()  # not waiting for the child to close its end of the pipes
    assert _gone(_child_pid(pid_file))


def test_an_interrupt_kills_the_commands_children(tmp_path):
    """Ctrl-C (here KeyboardInterrupt from a signal handler) while the command runs — sent once the command has
    started its child, however long that took: the group goes too."""
    import signal
    import threading

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    script, pid_file = _script(tmp_path, "wait")
    denoiser = resolve_denoiser(f"cmd:{script} {{input}} {{output}}", timeout_s=SLEEP_S / 2)

    def when_the_command_runs():
        if clock.eventually(lambda: pid_file.is_file() and pid_file.read_text().endswith("\n"), backstop=SLEEP_S):
            os.kill(os.getpid(), signal.SIGALRM)  # handled in the main thread, inside the denoiser call

    previous = signal.signal(signal.SIGALRM, interrupt)
    watcher = threading.Thread(target=when_the_command_runs, daemon=True)
    try:
        watcher.start()
        with pytest.raises(KeyboardInterrupt):
            denoiser(np.ones((8, 8, 3), np.float32))
    finally:
        watcher.join()
        signal.signal(signal.SIGALRM, previous)
    assert _gone(_child_pid(pid_file))


@pytest.mark.parametrize("planes", [3, 4])
def test_an_output_exr_over_the_pixel_limit_is_refused_from_its_header(tmp_path, capfd, planes):
    """The EXR a command writes is input too: one whose dataWindow declares 10¹⁰ pixels is refused from its header,
    on one line, before OpenEXR decodes (or allocates) a pixel; OpenEXR says nothing on the terminal."""
    from camsim.io.exr import write_exr
    from tests.support.hostile_files import with_exr_window

    small = tmp_path / "small.exr"
    write_exr(small, np.zeros((3, 8, 8), np.float32), None, None)
    big = tmp_path / "big.exr"
    big.write_bytes(with_exr_window(small.read_bytes(), 100000, 100000))
    denoiser = resolve_denoiser(f"cmd:sh -c 'cp \"$0\" \"$1\"' {big} {{output}} {{input}}")
    capfd.readouterr()
    with pytest.raises(CamsimError) as exc:
        denoiser.function(np.zeros((8, 8, planes), np.float32), None)
    message = str(exc.value)
    assert "\n" not in message and "100000 × 100000 pixels, over camsim's limit" in message, message
    assert capfd.readouterr() == ("", "")
