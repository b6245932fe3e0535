"""Outputs the environment refuses, in process: a folder that cannot be made, a full disk raised from the writers, a
folder held by another run. Every sub-command gives one line ``camsim: error: …``, exit 2, no traceback, and leaves
nothing it had begun. Also the render folder's manifest as frames commit and across runs.

The same with real processes and real signals: tests/end_to_end/test_faults.py.
"""

from __future__ import annotations

import errno
import importlib
import json
import os
from pathlib import Path

import pytest

import camsim.io.atomic as atomic
from camsim.cli import main
from camsim.core.errors import OutputError
from camsim.io.atomic import atomic_path, undo_on_failure, write_text_atomic
from camsim.io.output_folder import FolderBusyError, output_folder
from camsim.render.frame_manifest import MANIFEST_NAME
from tests.support.helpers import ROOT, FullDiskExrFile, full_disk

SMALL = ["--size", "64x48", "--illuminant", "D65", "-q"]
SPEC = f"""
name = "safety"
scene = "{(ROOT / 'scenes' / 'macbeth_26.toml').as_posix()}"
seed = 1
[frame]
width = 64
height = 48
[fixed]
preset = "emva-12bit"
illuminant = "D65"
[grid]
intensity_factors = [1.0, 0.5]
"""


@pytest.fixture(scope="module")
def frames(tmp_path_factory) -> Path:
    """Two committed frames (F = 1 and 0.5) for the commands that read frames."""
    out = tmp_path_factory.mktemp("frames")
    assert main(["render", "macbeth_26", *SMALL, "--intensity", "1", "0.5", "--out", str(out)]) == 0
    return out


def command_argv(name: str, out: Path, frames: Path, tmp: Path) -> list[str]:
    """A quick run of sub-command ``name`` writing into ``out``."""
    if name == "render":
        return ["render", "macbeth_26", *SMALL, "--intensity", "1", "--out", str(out)]
    if name == "dataset":
        spec = tmp / "spec.toml"
        spec.write_text(SPEC, encoding="utf-8")
        return ["dataset", str(spec), "--workers", "1", "-q", "--out", str(out)]
    if name == "analyze":
        return ["analyze", str(frames), "-q", "--out", str(out)]
    if name == "denoise-eval":
        return ["denoise-eval", str(frames), "-d", "identity", "-q", "--out", str(out)]
    if name == "emva":
        return ["emva", "--size", "16", "-q", "--out", str(out)]
    if name == "experiment":
        return ["experiment", "scenario1", "--size", "24x22", "-q", "--out", str(out)]  # 22: a DNG's least
    if name == "optimise":
        return ["optimise", "macbeth_26", "--preset", "sony-a7s2", "-F", "0.1", "--no-verify", "-q", "--out", str(out)]
    if name == "calibrate":  # the frames are no darks and flats: only the folder check is reached (its own file
        dngs = sorted(str(p) for p in frames.glob("*.dng"))  # tests the rest, a full disk included)
        return ["calibrate", "--dark", *dngs, "--flat", *dngs, "-q", "--out", str(out)]
    raise AssertionError(name)


COMMANDS = ("render", "dataset", "analyze", "denoise-eval", "emva", "experiment", "optimise")


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    errors = [line for line in err if line.startswith("camsim: error:")]
    assert len(errors) == 1, err
    assert not any("Traceback" in line for line in err)
    return errors[0]


def files_in(folder: Path) -> list[str]:
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()) if folder.exists() else []


@pytest.mark.parametrize("name", COMMANDS + ("calibrate",))
def test_output_under_a_file_fails_before_any_work(name, frames, tmp_path, capsys, monkeypatch):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    # the work itself must not start: any frame drawn or measured fails the test
    import camsim.analysis.analyze
    import camsim.dataset.runner
    import camsim.emva
    import camsim.experiments.scenarios
    import camsim.render.pipeline
    import camsim.render.run


    def no_work(*args, **kwargs):
        raise AssertionError("work started before the output folder was checked")

    monkeypatch.setattr(camsim.render.pipeline, "make_frame", no_work)
    monkeypatch.setattr(camsim.experiments.runner, "make_frame", no_work)
    monkeypatch.setattr(camsim.analysis.analyze, "analyse", no_work)
    monkeypatch.setattr(camsim.emva, "run", no_work)
    monkeypatch.setattr(importlib.import_module("camsim.calibration"), "calibrate", no_work)
    monkeypatch.setattr(importlib.import_module("camsim.denoise.evaluate"), "evaluate", no_work)
    out = blocker / "out"
    assert main(command_argv(name, out, frames, tmp_path)) == 2
    line = one_error_line(capsys)
    assert f"cannot create folder {out}: {blocker} is a file" in line
    assert blocker.read_text() == "not a folder"


@pytest.mark.parametrize("name", COMMANDS)
def test_full_disk_gives_one_line_and_leaves_nothing(name, frames, tmp_path, capsys, monkeypatch):
    out = tmp_path / "out"
    argv = command_argv(name, out, frames, tmp_path)
    full_disk(monkeypatch)
    assert main(argv) == 2
    line = one_error_line(capsys)
    assert "No space left on device" in line and str(out) in line
    assert not out.exists() or files_in(out) == []


def test_full_disk_at_the_sidecar_leaves_no_dng_without_it(tmp_path, capsys, monkeypatch):
    """The commit record fails last: the frame's DNG and EXR, already written, are removed again."""
    out = tmp_path / "out"
    assert main(["render", "macbeth_26", *SMALL, "--intensity", "1", "--out", str(out)]) == 0
    earlier = {name: (out / name).read_bytes() for name in files_in(out)}
    full_disk(monkeypatch, only_suffix="json")
    assert main(["render", "macbeth_26", *SMALL, "--intensity", "0.5", "--out", str(out)]) == 2
    assert "No space left on device" in one_error_line(capsys)
    assert {name: (out / name).read_bytes() for name in files_in(out)} == earlier  # the F = 1 frame is intact


def test_exr_writer_failure_is_one_line(tmp_path, capsys, monkeypatch):
    """OpenEXR reports a failed write as RuntimeError; it reaches the user as the reason, one line."""
    import camsim.io.exr as exr_mod

    monkeypatch.setattr(exr_mod.OpenEXR, "File", FullDiskExrFile)
    out = tmp_path / "out"
    assert main(["render", "macbeth_26", *SMALL, "--intensity", "1", "--out", str(out)]) == 2
    line = one_error_line(capsys)
    assert line == f"camsim: error: cannot write {out / 'macbeth_26_D65_F1.exr'}: No space left on device"
    assert files_in(out) == []


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder(tmp_path, capsys):
    out = tmp_path / "ro"
    out.mkdir()
    out.chmod(0o555)
    try:
        assert main(["render", "macbeth_26", *SMALL, "--intensity", "1", "--out", str(out)]) == 2
        assert "Permission denied" in one_error_line(capsys)
    finally:
        out.chmod(0o755)


def test_permission_denied_is_one_line(tmp_path, capsys, monkeypatch):
    """Any OSError a writer meets (here EACCES at the rename) is one line naming the file."""
    def refuse(src, dst):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES))

    monkeypatch.setattr(atomic.os, "replace", refuse)
    out = tmp_path / "out"
    assert main(["render", "macbeth_26", *SMALL, "--intensity", "1", "--out", str(out)]) == 2
    assert "Permission denied" in one_error_line(capsys)
    monkeypatch.undo()
    assert files_in(out) == []


def test_a_held_folder_is_refused(tmp_path, capsys):
    out = tmp_path / "out"
    with output_folder(out):
        assert main(["render", "macbeth_26", *SMALL, "--intensity", "1", "--out", str(out)]) == 2
        assert "another camsim run is writing to" in one_error_line(capsys)
        with pytest.raises(FolderBusyError):
            with output_folder(out):
                pass
    assert main(["render", "macbeth_26", *SMALL, "--intensity", "1", "--out", str(out)]) == 0


def test_undo_on_failure_removes_the_units_files(tmp_path):
    keep = tmp_path / "keep.txt"
    write_text_atomic(keep, "earlier")
    with pytest.raises(KeyboardInterrupt):
        with undo_on_failure() as done:
            write_text_atomic(tmp_path / "a.txt", "a")
            with undo_on_failure():
                write_text_atomic(tmp_path / "b.txt", "b")
            assert done == [tmp_path / "a.txt", tmp_path / "b.txt"]  # the inner unit joined the outer
            raise KeyboardInterrupt
    assert files_in(tmp_path) == ["keep.txt"]


def test_atomic_write_os_error_becomes_output_error(tmp_path):
    with pytest.raises(OutputError, match=r"cannot write .*x\.bin: No space left on device"):
        with atomic_path(tmp_path / "x.bin") as tmp:
            tmp.write_bytes(b"half")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert files_in(tmp_path) == []


def test_stale_partials_are_removed_by_the_next_run(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    stale = [out / ".macbeth_26_D65_F1.exr.4242.partial", out / ".manifest.json.77.partial"]
    for path in stale:
        path.write_bytes(b"left by a killed run")
    other = out / ".notes.partial"  # not camsim's pattern (no process id): left alone
    other.write_text("mine")
    assert main(["render", "macbeth_26", *SMALL, "--intensity", "1", "--out", str(out)]) == 0
    assert not any(path.exists() for path in stale)
    assert other.read_text() == "mine"


def sidecars(out: Path) -> set[str]:
    return {p.name for p in out.glob("*.json") if p.name != MANIFEST_NAME}


def manifest_sidecars(out: Path) -> list[str]:
    return [f["files"]["json"] for f in json.loads((out / MANIFEST_NAME).read_text())["frames"]]


def test_manifest_adds_to_earlier_runs_and_replaces_in_place(tmp_path):
    out = tmp_path / "out"
    render = ["render", "macbeth_26", *SMALL, "--out", str(out)]
    assert main([*render, "--intensity", "1", "0.5"]) == 0
    assert main([*render, "--intensity", "0.25"]) == 0
    assert manifest_sidecars(out) == ["macbeth_26_D65_F1.json", "macbeth_26_D65_F0.5.json",
                                      "macbeth_26_D65_F0.25.json"]
    before = (out / "macbeth_26_D65_F0.5.dng").read_bytes()
    assert main([*render, "--intensity", "0.5", "--seed", "9"]) == 0  # re-rendered: replaced where it was
    entries = json.loads((out / MANIFEST_NAME).read_text())["frames"]
    assert [e["files"]["json"] for e in entries] == manifest_sidecars(out)
    assert len(entries) == 3 and entries[1]["seed"] == 9
    assert (out / "macbeth_26_D65_F0.5.dng").read_bytes() != before


def test_manifest_is_rebuilt_from_the_committed_frames(tmp_path):
    """A manifest lost (or never written: a run killed between a commit and the manifest) is rebuilt from the
    sidecars; a frame whose sidecar is gone (never committed) is not listed."""
    out = tmp_path / "out"
    render = ["render", "macbeth_26", *SMALL, "--out", str(out)]
    assert main([*render, "--intensity", "1", "0.5"]) == 0
    (out / MANIFEST_NAME).unlink()
    (out / "macbeth_26_D65_F0.5.json").unlink()
    assert main([*render, "--intensity", "0.125"]) == 0
    assert set(manifest_sidecars(out)) == sidecars(out) == {"macbeth_26_D65_F1.json", "macbeth_26_D65_F0.125.json"}
    entry = json.loads((out / MANIFEST_NAME).read_text())["frames"][0]
    assert entry["scene"] == "macbeth_26" and entry["intensity_factor"] == 1.0
    assert entry["files"] == {"dng": "macbeth_26_D65_F1.dng", "exr": "macbeth_26_D65_F1.exr",
                              "json": "macbeth_26_D65_F1.json", "xmp": "macbeth_26_D65_F1.dng.xmp"}


def test_interrupt_mid_frame_leaves_only_committed_frames(tmp_path, capsys, monkeypatch):
    """Ctrl-C while the second frame's EXR is written: the first frame and a manifest listing it stay; nothing of
    the second frame is left (its DNG, written already, is removed)."""
    import camsim.render.frame_files as frame_files

    real = frame_files.write_exr
    calls = []

    def interrupted(path, *args, **kwargs):
        calls.append(path)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(path, *args, **kwargs)

    monkeypatch.setattr(frame_files, "write_exr", interrupted)
    out = tmp_path / "out"
    assert main(["render", "macbeth_26", *SMALL, "--intensity", "1", "0.5", "--out", str(out)]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert files_in(out) == ["macbeth_26_D65_F1.dng", "macbeth_26_D65_F1.dng.xmp", "macbeth_26_D65_F1.exr",
                             "macbeth_26_D65_F1.json", MANIFEST_NAME]  # .dng.xmp: darktable's black level
    assert manifest_sidecars(out) == ["macbeth_26_D65_F1.json"]


def test_readers_skip_uncommitted_frames_with_one_warning(frames, tmp_path, capsys):
    """A frame whose sidecar is missing (never committed) is left out by analyze and denoise-eval, each with one
    warning line; the committed frame is measured."""
    import shutil

    folder = tmp_path / "frames"
    shutil.copytree(frames, folder)
    (folder / "macbeth_26_D65_F0.5.json").unlink()
    (folder / ".macbeth_26_D65_F1.exr.999.partial").write_bytes(b"half")  # hidden temporaries: passed over
    assert main(["analyze", str(folder), "-q", "--no-figures", "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("camsim: warning: ignored 2 uncommitted frame file(s)"), err
    assert err[0].endswith(": macbeth_26_D65_F0.5.dng, macbeth_26_D65_F0.5.exr")
    assert main(["denoise-eval", str(folder), "-d", "identity", "-q", "--out", str(tmp_path / "d")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert [line for line in err if line.startswith("camsim: warning:")] == [
        "camsim: warning: ignored 1 uncommitted frame file(s) (no sidecar claims them): macbeth_26_D65_F0.5.exr"]


def test_a_failed_run_removes_the_empty_folders_it_made(tmp_path):
    kept = tmp_path / "kept"
    kept.mkdir()
    with pytest.raises(KeyboardInterrupt):
        with output_folder(kept / "a" / "b", subfolders=("frames",)):
            assert (kept / "a" / "b" / "frames").is_dir()
            raise KeyboardInterrupt
    assert kept.is_dir() and list(kept.iterdir()) == []  # a, b and frames were made by the run: gone again
    (kept / "mine").mkdir()
    with pytest.raises(KeyboardInterrupt):
        with output_folder(kept / "mine"):
            raise KeyboardInterrupt
    assert (kept / "mine").is_dir()  # there before the run: left alone


def test_a_frame_committed_but_not_yet_recorded_is_listed(tmp_path, monkeypatch):
    """A signal between a frame's commit (its sidecar renamed into place) and the manifest's update: the run's
    unwinding still lists the frame, so the manifest equals the committed frames."""
    from camsim.render.frame_manifest import FrameManifest

    def interrupted(self, info, files):
        raise KeyboardInterrupt

    monkeypatch.setattr(FrameManifest, "commit", interrupted)
    out = tmp_path / "out"
    assert main(["render", "macbeth_26", *SMALL, "--intensity", "1", "0.5", "--out", str(out)]) == 130
    assert sidecars(out) == {"macbeth_26_D65_F1.json"}
    assert manifest_sidecars(out) == ["macbeth_26_D65_F1.json"]


@pytest.mark.parametrize("frames_before", [0, 1])
def test_a_signal_inside_the_manifests_write_is_undone(frames_before, tmp_path, monkeypatch):
    """A signal inside the manifest's own write (the frame's entry made, the manifest not yet renamed into place;
    the race that made tests/end_to_end/test_faults.py's two-renders test fail now and then): the run's unwinding writes
    it again, so the manifest equals the committed frames."""
    import camsim.render.frame_manifest as frame_manifest

    real = frame_manifest.write_json_atomic
    calls = []

    def interrupted(path, data):
        calls.append(path)
        if len(calls) == frames_before + 1:  # this frame's update of the manifest: interrupted before the rename
            raise KeyboardInterrupt
        return real(path, data)

    monkeypatch.setattr(frame_manifest, "write_json_atomic", interrupted)
    out = tmp_path / "out"
    assert main(["render", "macbeth_26", *SMALL, "--intensity", "1", "0.5", "--out", str(out)]) == 130
    committed = sidecars(out)
    assert len(committed) == frames_before + 1
    assert sorted(manifest_sidecars(out)) == sorted(committed)
