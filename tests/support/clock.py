"""Verdicts that do not depend on how busy the machine is.

A test that says "does not hang", "stops promptly" or "leaves no process behind" must give the same verdict on a
quiet laptop and on a runner whose cores are shared with a browser and a build. Wall-clock time cannot judge that: it
stretches with the load. So the judge is **CPU time** — the seconds the processes under test actually ran, which a
busy machine does not inflate — and wall-clock time is only a **backstop**: once it has run out,

* a process that is still making progress (its CPU time grows, or a thread of it is runnable) means the machine was
  too busy to decide: the test is **skipped**, with the figures in the reason;
* a process that made no progress (every thread asleep, no CPU time gained over :data:`STALL_PROBE_S`) is blocked
  on something that will not come: that is a hang, and the test **fails**.

The helpers:

* :func:`run` — :func:`subprocess.run` with a CPU-time limit (``RLIMIT_CPU``, enforced by the kernel) instead of a
  ``timeout``;
* :func:`wait_for` — poll a condition while a process works towards it: fails once the process has spent its CPU
  budget without reaching it (or has exited), skips or fails at the backstop as above;
* :func:`wait_gone` — wait for processes to exit, up to :data:`EXIT_BACKSTOP_S` of wall time (a process that is
  on its way out gets there; one still alive then is a survivor), and :func:`eventually` for anything else that
  settles on its own in milliseconds;
* :func:`judge_wall` — for the few properties that are wall time by design (a grace period of the code): a miss is a
  failure on a quiet machine and a skip on a busy one (:func:`busy_reason`).

CPU time of this process is :func:`time.process_time` (every thread of it); the tests use it directly.
"""

from __future__ import annotations

import os
import resource
import signal
import subprocess
import time

import psutil
import pytest

#: The wall-clock backstop is this many times the CPU-time budget: a process that gets a twentieth of a core is
#: still judged. Unit: 1.
BACKSTOP_FACTOR = 20
#: The shortest backstop, whatever the budget (a start-up on a busy machine alone takes seconds). Unit: s.
MIN_BACKSTOP_S = 60.0
#: How long processes that were told to stop (or whose parent is gone) get to exit. Unit: s.
EXIT_BACKSTOP_S = 60.0
#: At the backstop, how long a process is watched for any progress before it is called blocked. Unit: s.
STALL_PROBE_S = 2.0
#: The machine is busy when some task waited for a CPU this share of the last 10 s (Linux's pressure stall
#: information, ``/proc/pressure/cpu``), or, without it, when the 1-minute load average exceeds the cores. Unit: %.
BUSY_PRESSURE_PERCENT = 10.0


def backstop_s(cpu_s: float) -> float:
    """The wall-clock backstop of a CPU-time budget of ``cpu_s`` seconds. Unit: s."""
    return max(MIN_BACKSTOP_S, BACKSTOP_FACTOR * cpu_s)


def _tree(pid: int) -> list[psutil.Process]:
    try:
        root = psutil.Process(pid)
        return [root, *root.children(recursive=True)]
    except psutil.Error:
        return []


def tree_cpu_s(pid: int) -> float:
    """CPU time of process ``pid``, its living descendants and the children it has reaped (user + system). Unit: s."""
    total = 0.0
    for index, process in enumerate(_tree(pid)):
        try:
            times = process.cpu_times()
        except psutil.Error:
            continue
        total += times.user + times.system
        if index == 0:
            total += times.children_user + times.children_system
    return total


def _runnable(pid: int) -> bool:
    """Whether any thread of ``pid`` or of its descendants is running or waiting for a CPU (state ``R``)."""
    for process in _tree(pid):
        try:
            for thread in process.threads():
                with open(f"/proc/{process.pid}/task/{thread.id}/stat", encoding="ascii") as stat:
                    if stat.read().rsplit(")", 1)[1].split()[0] == "R":
                        return True
        except (psutil.Error, OSError):
            continue
    return False


def progressing(pid: int, probe_s: float = STALL_PROBE_S) -> bool:
    """Whether process ``pid`` (with its descendants) makes progress within ``probe_s`` seconds: gains CPU time or
    has a runnable thread. A process asleep on a read that never returns does neither."""
    before = tree_cpu_s(pid)
    deadline = time.monotonic() + probe_s
    while time.monotonic() < deadline:
        if _runnable(pid) or tree_cpu_s(pid) > before + 0.01:
            return True
        time.sleep(0.05)
    return False


def busy_reason() -> str | None:
    """Why the machine counts as busy now (a sentence with the figures), or None where it is quiet."""
    try:
        with open("/proc/pressure/cpu", encoding="ascii") as handle:
            some = dict(item.split("=") for item in handle.readline().split()[1:])
        pressure = float(some["avg10"])
        if pressure >= BUSY_PRESSURE_PERCENT:
            return f"tasks waited for a CPU {pressure:.0f} % of the last 10 s"
        return None
    except (OSError, KeyError, ValueError):
        load, cores = os.getloadavg()[0], os.cpu_count() or 1
        return f"load average {load:.1f} on {cores} cores" if load > cores else None


def _at_backstop(pid: int, what: str, cpu_s: float, wall_s: float) -> None:
    """Fail (blocked) or skip (busy) for a process still running at its backstop."""
    if progressing(pid):
        pytest.skip(f"the machine is too busy to judge {what}: {cpu_s:.1f} s of CPU time in {wall_s:.0f} s of "
                    f"wall time, still working")
    pytest.fail(f"{what}: blocked — no progress for {STALL_PROBE_S:g} s after {wall_s:.0f} s of wall time "
                f"({cpu_s:.1f} s of CPU time)")


def limit_cpu(pid: int, cpu_s: float) -> None:
    """Give process ``pid`` (and what it starts from now on) ``cpu_s`` seconds of CPU time: the kernel sends SIGXCPU
    then, and SIGKILL a second later. A process that has already exited is left alone."""
    soft = max(1, int(-(-cpu_s // 1)))
    try:
        resource.prlimit(pid, resource.RLIMIT_CPU, (soft, soft + 1))
    except (ProcessLookupError, PermissionError):
        pass


def over_cpu_limit(returncode: int | None) -> bool:
    """Whether a process ended because it used up its CPU-time limit (:func:`limit_cpu`): SIGXCPU (a shell
    reports it as 128 + the signal)."""
    return returncode in (-signal.SIGXCPU, 128 + signal.SIGXCPU)


def run(args, *, cpu_s: float, input=None, check: bool = False, wait_descendants: bool = False,
        **kwargs) -> subprocess.CompletedProcess:
    """:func:`subprocess.run` judged by CPU time: the command (each of its processes) may use ``cpu_s`` seconds of
    CPU time; more fails the test. Its wall-clock backstop (:func:`backstop_s`) skips the test if the command was
    still working, and fails it if the command was blocked. ``kwargs`` are :class:`subprocess.Popen`'s.

    With ``wait_descendants``, the processes the command started (seen while it ran: a fork server, workers,
    multiprocessing's resource tracker, which reports after the command's exit) are waited for too
    (:func:`wait_gone`), so that whatever they write to a file the caller gave as stdout or stderr is there when
    this returns; one still alive then fails the test. Output must then go to files, not pipes (a pipe would be
    read before they write)."""
    if input is not None:
        kwargs["stdin"] = subprocess.PIPE
    if kwargs.pop("capture_output", False):
        kwargs["stdout"] = kwargs["stderr"] = subprocess.PIPE
    name = os.path.basename(str(args[0] if isinstance(args, (list, tuple)) else args).split()[0])
    start = time.monotonic()
    seen: dict[int, psutil.Process] = {}
    with subprocess.Popen(args, **kwargs) as process:
        limit_cpu(process.pid, cpu_s)
        try:
            if wait_descendants:
                stdout = stderr = None
                assert input is None and kwargs.get("stdout") != subprocess.PIPE != kwargs.get("stderr")
                while process.poll() is None:
                    seen.update((p.pid, p) for p in _tree(process.pid)[1:])
                    if time.monotonic() - start > backstop_s(cpu_s):
                        raise subprocess.TimeoutExpired(args, backstop_s(cpu_s))
                    time.sleep(0.01)
            else:
                stdout, stderr = process.communicate(input, timeout=backstop_s(cpu_s))
        except subprocess.TimeoutExpired:
            try:
                _at_backstop(process.pid, f"`{name} …`", tree_cpu_s(process.pid), time.monotonic() - start)
            finally:
                kill_tree(process.pid)
                process.communicate()
        if over_cpu_limit(process.returncode):
            pytest.fail(f"`{name} …` used more than {cpu_s:g} s of CPU time (killed, exit {process.returncode})")
    survivors = wait_gone(seen.values())
    if survivors:
        pytest.fail(f"`{name} …`: {len(survivors)} of its processes still alive {EXIT_BACKSTOP_S:g} s after it "
                    f"exited: {[p.pid for p in survivors]}")
    done = subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)
    if check:
        done.check_returncode()
    return done


def wait_for(ready, process: subprocess.Popen | int, *, cpu_s: float, what: str, poll_s: float = 0.001,
             exited_ok: bool = False) -> None:
    """Wait until ``ready()`` is true while ``process`` (a Popen or a process id) works towards it.

    Fails once the process (with its descendants) has used ``cpu_s`` seconds of CPU time and ``ready()`` is still
    false, or when it exits first (unless ``exited_ok``); at the wall-clock backstop, skips (still working) or fails
    (blocked). ``what`` names the condition in the messages."""
    pid = process if isinstance(process, int) else process.pid
    start = time.monotonic()
    next_check = start
    while not ready():
        now = time.monotonic()
        if now >= next_check:  # CPU time costs a /proc walk: a few times a second
            next_check = now + 0.2
            exited = (process.poll() is not None) if not isinstance(process, int) else not psutil.pid_exists(pid)
            if exited:
                if ready() or exited_ok:
                    return
                pytest.fail(f"{what}: the process ended first"
                            + (f" (exit {process.returncode})" if not isinstance(process, int) else ""))
            used = tree_cpu_s(pid)
            if used > cpu_s:
                if ready():
                    return
                pytest.fail(f"{what}: not reached after {used:.1f} s of CPU time (budget {cpu_s:g} s)")
            if now - start > backstop_s(cpu_s):
                if ready():
                    return
                _at_backstop(pid, what, used, now - start)
        time.sleep(poll_s)


def wait_exit(process: subprocess.Popen, *, cpu_s: float, what: str) -> int:
    """Wait for ``process`` to exit (after it was told to stop) and return its status; judged as :func:`wait_for`:
    a process that goes on working for ``cpu_s`` seconds of CPU time has not stopped."""
    wait_for(lambda: process.poll() is not None, process, cpu_s=cpu_s, what=what, poll_s=0.01, exited_ok=True)
    return process.wait()


def _alive(process: psutil.Process) -> bool:
    try:
        return process.status() not in (psutil.STATUS_ZOMBIE, psutil.STATUS_DEAD)
    except psutil.Error:
        return False


def wait_gone(processes, backstop: float = EXIT_BACKSTOP_S) -> list[psutil.Process]:
    """Wait until none of ``processes`` (psutil Processes or ids) is alive (a zombie counts as gone), up to
    ``backstop`` seconds of wall time; returns those still alive then. A process on its way out exits within
    that, however busy the machine; one still alive after it is not on its way out."""
    tracked = [p if isinstance(p, psutil.Process) else _process(p) for p in processes]
    tracked = [p for p in tracked if p is not None]
    deadline = time.monotonic() + backstop
    while True:
        alive = [p for p in tracked if _alive(p)]
        if not alive or time.monotonic() > deadline:
            return alive
        time.sleep(0.05)


def eventually(predicate, backstop: float = EXIT_BACKSTOP_S) -> bool:
    """Wait until ``predicate()`` is true — something that settles on its own in milliseconds (a cancelled task
    forgotten, a killed process reaped) — up to ``backstop`` seconds of wall time; returns its last value."""
    deadline = time.monotonic() + backstop
    while not predicate():
        if time.monotonic() > deadline:
            return bool(predicate())
        time.sleep(0.02)
    return True


def _process(pid: int) -> psutil.Process | None:
    try:
        return psutil.Process(pid)
    except psutil.Error:
        return None


def kill_tree(pid: int) -> None:
    """SIGKILL process ``pid`` and every descendant (whatever happened, a test leaves nothing running)."""
    for process in reversed(_tree(pid)):
        try:
            process.kill()
        except psutil.Error:
            pass


def judge_wall(seconds: float, limit_s: float, what: str) -> None:
    """For a property that is wall time by design (a grace period in the code): ``seconds`` within ``limit_s``
    passes; beyond it the test fails on a quiet machine and is skipped, with the reason, on a busy one."""
    if seconds <= limit_s:
        return
    reason = busy_reason()
    if reason is not None:
        pytest.skip(f"the machine is too busy to judge {what} ({seconds:.1f} s against {limit_s:g} s): {reason}")
    pytest.fail(f"{what}: {seconds:.1f} s, more than {limit_s:g} s on a quiet machine")
