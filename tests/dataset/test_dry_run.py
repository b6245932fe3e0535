"""``camsim dataset --dry-run`` checks what the run checks before its first frame (issue 24, point 8): for a spec
or settings the run refuses, the dry run exits with the same status and the same message, and neither writes
anything. The run's checks are shared, not copied: the settings (camsim.dataset.runner.check_settings) and every
frame's, as drawing it would check it (camsim.render.pipeline.check_frame, from the spec's planning)."""

from __future__ import annotations

import pytest

from camsim.cli import main
from tests.support.helpers import flat_scene_toml, write_text_file

SCENE = flat_scene_toml('"agree"')

SPEC = """
scene = "scene.toml"
[frame]
width = 32
height = 24
"""

#: label: (what the spec adds, extra command-line options, what the message says)
CASES = {
    "the issue's F = uniform [0, 1e308]": ("[random]\ncount = 2\nintensity_factor = { uniform = [0, 1e308] }\n",
                                          [], "overflows float64"),
    "a late frame's F overflows": ("[grid]\nintensity_factors = [0.5, 1.0, 1e300]\n", [], "frame 2"),
    "exposure beyond float64 for the dark charge": (
        "[fixed]\ndark_current_e_per_s = 1e300\n[grid]\nexposure_s = [1.0, 1e300]\n", [], "dark"),
    "values beyond float32 without saturation": (
        "[fixed]\nsaturation = false\n[random]\ncount = 3\nintensity_factor = { log_uniform = [1, 1e40] }\n", [],
        "float32"),
    "auto exposure that cannot reach its target": (
        "[fixed]\nexposure = \"auto\"\nexposure_target_e = 1e300\n", [], "exposure"),
    "a later frame's bits below its pedestal": (
        "[fixed]\npedestal_dn = 100\n[grid]\nbits = [12, 6]\n", [], "pedestal_dn"),
    "an exposure longer than the schema's": ("[grid]\nexposure_s = [1.0, 1e10]\n", [],
                                             "exposure_s must be a positive number ≤ 1e+06 s"),
    "an unknown EXR compression": ("", ["--exr-compression", "bogus"], "bogus"),
    "an EXR compression for a Zarr store": ("", ["--exr-compression", "zip", "--format", "zarr"], "--exr-compression"),
    "workers and a scheduler": ("", ["--workers", "2", "--scheduler", "tcp://127.0.0.1:1"], "--scheduler"),
}


@pytest.mark.parametrize("added, options, message", CASES.values(), ids=CASES.keys())
def test_the_dry_run_refuses_what_the_run_refuses(tmp_path, monkeypatch, capsys, added, options, message):
    monkeypatch.chdir(tmp_path)
    write_text_file(tmp_path, "scene.toml", SCENE)
    write_text_file(tmp_path, "spec.toml", SPEC + added)
    results = []
    for argv in (["--dry-run"], ["-q", "--out", "out"] + ([] if "--scheduler" in options else ["--workers", "1"])):
        status = main(["dataset", "spec.toml", *argv, *options])
        err = capsys.readouterr().err.strip()
        results.append((status, err))
    (dry_status, dry_err), (run_status, run_err) = results
    assert dry_status == run_status == 2, results
    assert dry_err == run_err and len(dry_err.splitlines()) == 1 and message in dry_err, results
    assert not (tmp_path / "out").exists()  # refused before anything is written


def test_a_good_spec_passes_both(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    write_text_file(tmp_path, "scene.toml", SCENE)
    write_text_file(tmp_path, "spec.toml", SPEC + "[random]\ncount = 2\nintensity_factor = { uniform = [0.1, 1] }\n")
    assert main(["dataset", "spec.toml", "--dry-run"]) == 0
    assert main(["dataset", "spec.toml", "-q", "--workers", "1", "--out", "out"]) == 0
    assert len(list((tmp_path / "out" / "frames").glob("*.done"))) == 2
