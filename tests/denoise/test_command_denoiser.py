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
    script, pid_file = _script(tmp_path, "wait")
    denoiser = resolve_denoiser(f"cmd:{script} {{input}} {{output}}", timeout_s=1.0)
    with pytest.raises(CamsimError, match="did not finish within 1 s"):
        denoiser(np.ones((8, 8, 3), np.float32))
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
    """Ctrl-C (here KeyboardInterrupt from a timer's signal handler) while the command runs: the group goes too."""
    import signal

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    script, pid_file = _script(tmp_path, "wait")
    denoiser = resolve_denoiser(f"cmd:{script} {{input}} {{output}}", timeout_s=SLEEP_S / 2)
    previous = signal.signal(signal.SIGALRM, interrupt)
    try:
        signal.setitimer(signal.ITIMER_REAL, 1.0)
        with pytest.raises(KeyboardInterrupt):
            denoiser(np.ones((8, 8, 3), np.float32))
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    assert _gone(_child_pid(pid_file))
