"""camsim dataset as a user runs it, with real processes and real signals: a run killed outright (SIGKILL), asked
to stop (SIGTERM) or interrupted (SIGINT, Ctrl-C) while its workers render leaves no process behind (fork server,
workers, resource tracker), and a re-run completes the dataset with the bytes of an uninterrupted run. An
interrupted Dask run leaves its cluster idle and usable."""

import hashlib
import operator
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from camsim.dataset import load_spec, read_manifest, run_dataset
from camsim.dataset.backends import GRACE_S, run_dask
from camsim.dataset.manifest import FRAMES_DIR
from camsim.dataset.task import render_task
from tests.support import clock

psutil = pytest.importorskip("psutil")  # dask.distributed's dependency, so camsim's too

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="POSIX signals"),
]

ROOT = Path(__file__).resolve().parents[2]
SCENE = (ROOT / "scenes" / "macbeth_26.toml").as_posix()

# 12 frames of 320 x 240: a few tenths of a second each, so that a run is caught while its workers render
SPEC = f"""
name = "signals"
scene = "{SCENE}"
seed = 5

[frame]
width = 320
height = 240

[fixed]
preset = "emva-12bit"

[grid]
illuminants = ["D65", "A"]

[random]
count = 6
intensity_factor = {{ log_uniform = [0.001, 1.0] }}
"""
#: The CPU time a run may use before its workers render (fork server, two workers importing camsim). Unit: s.
START_CPU_S = 60.0
#: The CPU time a run may go on using after the signal: the frames in flight get GRACE_S seconds. Unit: s.
STOP_CPU_S = 30.0
#: What the command exits with, by signal: killed; SIGTERM handled as Ctrl-C is (128 + 15); Ctrl-C.
EXIT_STATUS = {signal.SIGKILL: -signal.SIGKILL, signal.SIGTERM: 143, signal.SIGINT: 130}


def digests(out: Path) -> dict:
    """SHA-256 of every file under ``out/frames``, by name."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted((out / FRAMES_DIR).iterdir())}


def alive(process) -> bool:
    try:
        return process.status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def describe(process) -> str:
    try:
        return f"{process.pid} {' '.join(process.cmdline())[:120]}"
    except psutil.Error:
        return str(process.pid)


@pytest.fixture(scope="module")
def spec_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("spec") / "signals.toml"
    path.write_text(SPEC, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def reference(spec_path, tmp_path_factory):
    """An uninterrupted run (in this process; the bytes do not depend on the back-end)."""
    out = tmp_path_factory.mktemp("reference") / "out"
    run_dataset(spec_path, out, workers=1, progress=False, echo=None)
    return out


def start_and_signal(spec_path: Path, out: Path, sig: signal.Signals) -> dict:
    """Start ``python -m camsim dataset`` on two workers, send ``sig`` to its main process once the workers render
    and a frame is recorded, and see which of its descendants are still alive once they had every chance to exit
    (:func:`tests.support.clock.wait_gone`: a process on its way out gets there; the verdict is not a wall-clock
    limit)."""
    command = [sys.executable, "-m", "camsim", "dataset", str(spec_path), "--out", str(out), "--workers", "2", "-q"]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    stderr = out.parent / f"{out.name}.stderr"
    with open(stderr, "w") as err:  # not a pipe: a surviving process would hold it open
        process = subprocess.Popen(command, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=err)
    family, done = [], []
    main = psutil.Process(process.pid)

    def rendering() -> bool:  # the fork server, the resource tracker and both workers, and a frame done
        nonlocal family, done
        family = main.children(recursive=True)
        done = list((out / FRAMES_DIR).glob("*.done")) if (out / FRAMES_DIR).is_dir() else []
        return len(family) >= 4 and bool(done)

    try:
        clock.wait_for(rendering, process, cpu_s=START_CPU_S, what="the run rendering its first frame", poll_s=0.02)
        sent = time.monotonic()
        process.send_signal(sig)
        status = clock.wait_exit(process, cpu_s=STOP_CPU_S, what=f"the run's exit after {sig.name}")
        exited_after = time.monotonic() - sent
        survivors = [describe(p) for p in clock.wait_gone(family)]
    finally:
        if process.poll() is None:  # whatever happened, leave nothing running
            process.kill()
        for p in family:
            if alive(p):
                p.kill()
    return {"signal": sig, "status": status, "exited_after": exited_after, "survivors": survivors,
            "done_before": len(done), "out": out, "stderr": stderr.read_text()}


@pytest.fixture(scope="module", params=[signal.SIGKILL, signal.SIGTERM, signal.SIGINT], ids=lambda s: s.name)
def signalled(request, spec_path, tmp_path_factory):
    out = tmp_path_factory.mktemp(request.param.name) / "out"
    return start_and_signal(spec_path, out, request.param)


def test_no_process_outlives_the_command(signalled):
    assert signalled["survivors"] == [], (f"alive {clock.EXIT_BACKSTOP_S:g} s after the run's exit "
                                          f"({signalled['signal'].name})")


def test_exit_status(signalled):
    assert signalled["status"] == EXIT_STATUS[signalled["signal"]], signalled["stderr"]


def test_an_interrupted_run_stops_promptly_and_keeps_its_frames(signalled, spec_path):
    """Ctrl-C and SIGTERM: the pool is shut down within the grace period (not after the queued frames): the run
    exits within the grace period (a wall-clock design, judged on a quiet machine only:
    :func:`tests.support.clock.judge_wall`) with fewer frames than the spec's; every frame finished is in the
    manifest, and no temporary file is left."""
    if signalled["signal"] == signal.SIGKILL:
        pytest.skip("SIGKILL runs no shutdown: the next run removes the temporaries (test_a_rerun_...)")
    out = signalled["out"]
    assert ("interrupted" if signalled["signal"] == signal.SIGINT else "terminated (SIGTERM)") in signalled["stderr"]
    manifest = read_manifest(out)
    assert len(manifest) >= signalled["done_before"]
    clock.judge_wall(signalled["exited_after"], GRACE_S + 5, f"the exit within the grace period after "
                     f"{signalled['signal'].name}")
    assert len(manifest) == len(list((out / FRAMES_DIR).glob("*.done"))) < len(load_spec(spec_path))
    assert not list((out / FRAMES_DIR).glob(".*.partial"))


def test_at_most_one_line_on_stderr(signalled):
    """The command's one line (none after SIGKILL), and nothing from multiprocessing: the resource tracker, which
    unlinks the semaphores of a killed run's pool, reports that on the null device."""
    lines = signalled["stderr"].splitlines()
    assert "resource_tracker" not in signalled["stderr"], signalled["stderr"]
    assert len(lines) == (0 if signalled["signal"] == signal.SIGKILL else 1), signalled["stderr"]


def test_the_manifest_lists_exactly_the_committed_frames(signalled):
    """Whatever stopped the run — SIGKILL included, which runs no ``finally`` — ``manifest.jsonl`` lists each
    committed frame (a ``.done`` record) once, and no other: each is appended as it is committed."""
    out = signalled["out"]
    committed = {p.name[: -len(".done")] for p in (out / FRAMES_DIR).glob("*.done")}
    listed = [m["id"] for m in read_manifest(out)]
    assert len(committed) >= signalled["done_before"] >= 1
    assert sorted(listed) == sorted(committed), signalled["stderr"]


def test_a_rerun_completes_the_dataset_identically(signalled, spec_path, reference):
    out = signalled["out"]
    summary = run_dataset(spec_path, out, workers=1, progress=False, echo=None)
    assert summary["skipped"] >= signalled["done_before"] and summary["rendered"] > 0
    assert [m["id"] for m in read_manifest(out)] == [f.id for f in load_spec(spec_path).frames]
    assert digests(out) == digests(reference)
    assert not list(out.rglob(".*.partial"))  # a killed run's temporaries are gone after the next run


def test_an_interrupted_dask_run_leaves_the_cluster_usable(spec_path):
    distributed = pytest.importorskip("distributed")
    frames = load_spec(spec_path).frames
    recorded = []

    def on_done(frame, result):
        recorded.append(frame.index)
        raise KeyboardInterrupt  # Ctrl-C after the first frame

    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        with pytest.raises(KeyboardInterrupt):
            run_dask(render_task, frames, cluster.scheduler_address, 1, on_done)
        assert len(recorded) == 1
        assert clock.eventually(lambda: not cluster.scheduler.tasks), (  # cancelled, forgotten
            f"the scheduler still holds {len(cluster.scheduler.tasks)} task(s) {clock.EXIT_BACKSTOP_S:g} s later")
        with distributed.Client(cluster.scheduler_address, set_as_default=False) as client:
            assert client.submit(operator.add, 1, 2).result(timeout=clock.EXIT_BACKSTOP_S) == 3
            assert len(client.scheduler_info()["workers"]) == 1
