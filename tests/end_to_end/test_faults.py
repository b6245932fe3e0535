"""Fault injection with real processes and real signals: ``camsim render`` is started as a subprocess and sent
SIGINT, SIGTERM or SIGKILL before its first frame commits, in the middle of writing a frame, and between frames.
Then: the exit status and the one message line, no child process left, no temporary file after the next run, a
manifest that lists exactly the committed frames, ``camsim analyze`` working on what is there, and a re-run that
completes to files byte-identical to an uninterrupted run. Also two renders started into one folder.

(``camsim dataset`` under signals: tests/dataset/test_processes.py; full disks and unwritable folders for every
sub-command: tests/io/test_output_folder.py.)
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from camsim.cli import main
from camsim.render.frame_manifest import MANIFEST_NAME
from tests.support import clock
from tests.support.helpers import ROOT

pytestmark = [pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals"), pytest.mark.slow]

FACTORS = ("1", "0.5")
RENDER = ["render", "macbeth_26", "--size", "640x480", "--illuminant", "D65", "--intensity", *FACTORS,
          "--workers", "1", "-q"]


def env() -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}


def start(argv, out: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "camsim", *argv, "--out", str(out)], env=env(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def tree(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(out.iterdir()) if p.is_file()}


def partials(out: Path) -> list[str]:
    return sorted(p.name for p in out.glob(".*.partial"))


def committed(out: Path) -> set[str]:
    return {p.name for p in out.glob("*.json") if p.name != MANIFEST_NAME}


def listed(out: Path) -> set[str]:
    frames = json.loads((out / MANIFEST_NAME).read_text(encoding="utf-8"))["frames"]  # replaced atomically
    return {f["files"]["json"] for f in frames}


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> dict[str, bytes]:
    out = tmp_path_factory.mktemp("reference")
    assert main([*RENDER, "--out", str(out)]) == 0
    return tree(out)


# when to send the signal: a predicate on the output folder
POINTS = {
    "before-first-commit": lambda out: out.is_dir() and not committed(out),
    "mid-frame": lambda out: any(name.startswith(".macbeth_26") for name in partials(out)),
    "between-frames": lambda out: (out / MANIFEST_NAME).exists() and len(listed(out)) == 1,
}


#: The CPU time a render may use before it reaches the point (its whole run takes about 3 s). Unit: s.
POINT_CPU_S = 60.0
#: The CPU time a render may go on using after it was told to stop. Unit: s.
STOP_CPU_S = 30.0


def wait_until(proc: subprocess.Popen, ready, out: Path) -> None:
    """Wait for ``ready(out)`` while ``proc`` renders: judged by its CPU time (:mod:`tests.support.clock`)."""
    clock.wait_for(lambda: ready(out), proc, cpu_s=POINT_CPU_S, what="the point")


def finish(proc: subprocess.Popen) -> str:
    """Wait for ``proc`` to exit after a signal (judged by its CPU time) and return its stderr."""
    clock.wait_exit(proc, cpu_s=STOP_CPU_S, what="the exit after the signal")
    return proc.stderr.read()


def interrupt(point: str, signum: int, out: Path, attempts: int = 3) -> tuple[subprocess.Popen, str]:
    """Start a render into ``out``, wait for ``point``, send ``signum``; returns the ended process and its stderr.

    On a loaded machine this process can be held back between seeing the point and sending the signal for longer
    than the rest of the render takes: the signal then lands after the run's work (exit 0, or the signal's default
    action during the interpreter's shutdown) with every frame committed. That attempt tested nothing; it is made
    again in a fresh folder, up to ``attempts`` times (a run that ignores the signal fails all of them)."""
    for _ in range(attempts):
        shutil.rmtree(out, ignore_errors=True)
        proc = start(RENDER, out)
        wait_until(proc, POINTS[point], out)
        proc.send_signal(signum)
        err = finish(proc)
        late = proc.returncode in (0, -signum) and len(committed(out)) == len(FACTORS) and not err.strip()
        if signum == signal.SIGKILL or not late:
            break
    return proc, err


EXPECTED = {signal.SIGINT: (130, "camsim: interrupted"), signal.SIGTERM: (143, "camsim: terminated (SIGTERM)"),
            signal.SIGKILL: (-signal.SIGKILL, None)}


@pytest.mark.parametrize("point", POINTS)
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL], ids=lambda s: s.name)
def test_render_interrupted(point, signum, tmp_path, reference, capsys):
    out = tmp_path / "out"
    proc, err = interrupt(point, signum, out)
    status, message = EXPECTED[signum]
    assert proc.returncode == status, err
    lines = err.strip().splitlines()
    if message is not None:
        assert len(lines) == 1 and lines[0].startswith(message), err  # one line, no traceback
        assert partials(out) == []  # the frame being written was removed, temporaries and all
    # what is left is whole: the manifest (if the run got that far) lists exactly the committed frames, and every
    # committed frame's files are those of an uninterrupted run
    if (out / MANIFEST_NAME).exists():
        if signum == signal.SIGKILL:  # killed between a commit and the manifest's update at most one is missing
            assert listed(out) <= committed(out) and len(committed(out) - listed(out)) <= 1
        else:
            assert listed(out) == committed(out)
    for name in committed(out):
        meta = json.loads((out / name).read_text())
        for file in filter(None, meta["files"].values()):
            assert (out / file).read_bytes() == reference[file], file
    if point == "between-frames":  # one committed frame, maybe the next one's files: analyze takes what is whole
        # (the figures of a committed frame: tests/analysis/test_analyze_robust.py)
        assert main(["analyze", str(out), "-q", "--no-figures", "--out", str(tmp_path / "analysis")]) == 0
        rows = (tmp_path / "analysis" / "analysis.csv").read_text().splitlines()
        assert len({row.split(",")[0] for row in rows[1:]}) == len(committed(out))
    # the next run cleans up and completes to the same bytes as an uninterrupted run
    capsys.readouterr()
    assert main([*RENDER, "--out", str(out)]) == 0
    assert partials(out) == []
    assert tree(out) == reference


def test_two_renders_into_one_folder(tmp_path):
    """Two renders started together into one folder: one is refused at once with one line, the other goes on (here
    until it is stopped) and leaves a consistent folder."""
    out = tmp_path / "out"
    long_render = [*RENDER, "--intensity", *(f"{2.0 ** -k:g}" for k in range(2, 40))]
    runs = [start(long_render, out), start(long_render, out)]
    clock.wait_for(lambda: any(run.poll() is not None for run in runs), runs[0], cpu_s=POINT_CPU_S,
                   what="one of the two runs refused", poll_s=0.01, exited_ok=True)
    refused, = [run for run in runs if run.poll() is not None]
    winner, = [run for run in runs if run is not refused]
    err = refused.stderr.read()
    assert refused.returncode == 2
    assert err.strip().splitlines() == [f"camsim: error: another camsim run is writing to {out}; wait for it to "
                                        "finish or choose another --out"]
    assert winner.poll() is None, "the first run ended before the second was refused: make it longer"
    winner.send_signal(signal.SIGTERM)
    finish(winner)
    assert winner.returncode == 143
    assert partials(out) == []
    assert not (out / MANIFEST_NAME).exists() or listed(out) == committed(out)


def test_ctrl_c_while_colour_science_imports():
    """colour-science imports OpenImageIO, whose nanobind extension aborts the process (SIGABRT) if Ctrl-C lands
    while it initialises; camsim holds the signal back during that import and acts on it right after."""
    code = (
        "import os, signal, sys, threading\n"
        "from camsim.light.spectra import import_colour\n"
        "threading.Timer(0.02, os.kill, (os.getpid(), signal.SIGINT)).start()\n"
        "try:\n"
        "    import_colour()\n"
        "    threading.Event().wait(60)\n"
        "except KeyboardInterrupt:\n"
        "    print('interrupted after the import:', 'OpenImageIO' in sys.modules)\n"
    )
    done = clock.run([sys.executable, "-c", code], cpu_s=60, env=env(), capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "interrupted after the import: True"
