"""camsim dataset: the spec's frame list, serial / resumed / interrupted runs, and local-process and Dask back-ends
giving the same bytes as the serial run, frame by frame."""

import argparse
import hashlib
import json
import shutil
from pathlib import Path

import pytest

import camsim.dataset.runner as runner
from camsim.cli.commands.dataset import add_parser, run
from camsim.core.errors import CamsimError
from camsim.dataset import _pool, load_spec, read_manifest, run_dataset
from tests.support.helpers import ROOT, file_tree, write_text_file

SCENE = (ROOT / "scenes" / "macbeth_26.toml").as_posix()

# 2 illuminants x 2 layouts (three-chip, Bayer) x 2 random draws = 8 frames of 64 x 48
TINY = f"""
name = "tiny"
scene = "{SCENE}"
seed = 7

[frame]
width = 64
height = 48

[fixed]
preset = "emva-12bit"

[grid]
illuminants = ["D65", "A"]
cfa = ["none", "RGGB"]

[random]
count = 2
intensity_factor = {{ log_uniform = [0.001, 1.0] }}
read_noise_e = {{ uniform = [2, 6] }}
"""


def write_spec(folder: Path, text: str = TINY, name: str = "tiny.toml") -> Path:
    return write_text_file(folder, name, text)


tree = file_tree


def assert_same_frames(out: Path, reference: Path) -> None:
    got, want = tree(out), tree(reference)
    assert sorted(got) == sorted(want)
    for name in want:  # frame by frame, file by file
        assert got[name] == want[name], name


@pytest.fixture(scope="module")
def spec_path(tmp_path_factory):
    return write_spec(tmp_path_factory.mktemp("spec"))


@pytest.fixture(scope="module")
def serial(spec_path, tmp_path_factory):
    """The reference: a serial, in-process run."""
    out = tmp_path_factory.mktemp("serial") / "out"
    summary = run_dataset(spec_path, out, workers=1, progress=False, echo=None)
    return out, summary


# --- the spec ------------------------------------------------------------------------------------------------


def test_frame_list_is_deterministic_and_ordered(spec_path):
    a, b = load_spec(spec_path), load_spec(spec_path)
    assert len(a) == 8 and a.width == 64 and a.height == 48
    assert [f.record for f in a.frames] == [f.record for f in b.frames]
    ids = [f.id for f in a.frames]
    assert len(set(ids)) == 8 and all(i.startswith(f"{n:05d}-") for n, i in enumerate(ids))
    assert len({f.seed for f in a.frames}) == 8 and all(0 <= f.seed < 2**53 for f in a.frames)
    records = [f.record for f in a.frames]
    # grid order (the last key fastest), then the random draws
    assert [r["illuminant"] for r in records] == ["D65"] * 4 + ["A"] * 4
    assert [r["cfa"] for r in records] == [None, None, "RGGB", "RGGB"] * 2
    for r in records:
        assert 0.001 <= r["intensity_factor"] <= 1 and 2 <= r["read_noise_e"] <= 6
        assert r["preset"] == "emva-12bit" and r["bits"] == 12
    assert len({r["intensity_factor"] for r in records}) == 8  # independent draws per frame
    assert a.axes["illuminant"] == "grid" and a.axes["read_noise_e"] == "random" and a.axes["preset"] == "fixed"


def test_more_draws_extend_the_same_streams(tmp_path):
    random_only = TINY.replace('[grid]\nilluminants = ["D65", "A"]\ncfa = ["none", "RGGB"]\n', "").replace(
        'preset = "emva-12bit"', 'preset = "emva-12bit"\nilluminant = "D65"')
    short = load_spec(write_spec(tmp_path, random_only, "a.toml"))
    longer = load_spec(write_spec(tmp_path, random_only.replace("count = 2", "count = 5"), "b.toml"))
    assert (len(short), len(longer)) == (2, 5)
    assert [f.record for f in longer.frames[:2]] == [f.record for f in short.frames]


def test_scene_lists_are_axes_unless_the_spec_sets_them(tmp_path):
    spec = load_spec(write_spec(tmp_path, TINY.replace('illuminants = ["D65", "A"]\n', "")))
    # macbeth_26.toml: 26 illuminants x (the grid's 2 layouts) x 2 draws
    assert len(spec) == 26 * 2 * 2 and spec.axes["illuminant"] == "scene"
    assert spec.frames[0].record["illuminant"] == "A" and spec.frames[-1].record["illuminant"] == "HP5"


@pytest.mark.parametrize("change, message", [
    (("seed = 7", "seed = 7\nbogus = 1"), "unknown top-level key"),
    (("[grid]", "[grid]\nread_nose_e = [1.0]"), "unknown key 'read_nose_e' in \\[grid\\]"),
    (("count = 2", "count = 2\nexposure_s = { normal = [1, 2] }"), "unknown distribution 'normal'"),
    (("count = 2", "count = 2\nbits = { uniform = [8, 12] }"), "use choice"),
    (("[grid]", "[grid]\nexposure_s = [\"a\"]"), "exposure_s must be a number"),
    (("[grid]", "[grid]\nmethod = [\"poisson\", \"magic\"]"), "method must be one of"),
    (("\"D65\", \"A\"", "\"D65\", \"Moonlight\""), "unknown illuminant 'Moonlight'"),
    (("[grid]", "[grid]\nexposure_s = [1.0, -2.0]"), "exposure_s must be a positive number"),
    (("[fixed]", "[fixed]\nread_noise_model = \"gaussian\"\n[x]"), "unknown top-level key"),
    (("[grid]", "[grid]\npreset = [\"ideal\"]"), "preset is set in both"),
    (("[grid]", "[grid]\nintensity_factor = [1.0]"), "intensity_factor is set in both"),
    (("width = 64", "width = 63"), "even frame size"),
    (("width = 64", "width = 64\ndepth = 3"), "unknown key\\(s\\) in \\[frame\\]"),
    (("[0.001, 1.0]", "[0.0, 1.0]"), "log_uniform needs positive bounds"),
    (("count = 2", "count = 0"), "count"),
    (("\"D65\", \"A\"", "\"D65\", \"D65\""), "twice"),
    ((f'scene = "{SCENE}"', 'scene = "no_such_scene.toml"'), "scene file not found"),
    (("[fixed]", "[fixed]\ncamera = \"Nonexistent 1\""), "unknown camera"),
])
def test_bad_specs_are_refused_before_rendering(tmp_path, change, message):
    old, new = change
    assert old in TINY
    path = write_spec(tmp_path, TINY.replace(old, new, 1))
    with pytest.raises(CamsimError, match=message):
        run_dataset(path, tmp_path / "out", workers=1, progress=False, echo=None)
    assert not (tmp_path / "out").exists()  # nothing rendered, not even the folder


# --- runs ----------------------------------------------------------------------------------------------------


def test_serial_run_writes_every_frame_and_the_manifest(serial, spec_path):
    out, summary = serial
    spec = load_spec(spec_path)
    assert summary["rendered"] == 8 and summary["skipped"] == 0 and summary["frames_per_second"] > 0
    manifest = read_manifest(out)
    assert [m["id"] for m in manifest] == [f.id for f in spec.frames]
    for entry, frame in zip(manifest, spec.frames):
        assert {k: v for k, v in entry.items() if k not in ("files", "exr_compression")} == frame.record
        assert entry["exr_compression"] == "none"
        for kind in ("dng", "exr", "json"):
            data = (out / entry["files"][kind]["name"]).read_bytes()
            assert len(data) == entry["files"][kind]["bytes"]
            assert hashlib.sha256(data).hexdigest() == entry["files"][kind]["sha256"]
        sidecar = json.loads((out / entry["files"]["json"]["name"]).read_text())
        assert sidecar["seed"] == frame.seed and sidecar["illuminant"] == entry["illuminant"]
        assert sidecar["intensity_factor"] == entry["intensity_factor"]
        assert sidecar["read_noise_e"] == entry["read_noise_e"] and sidecar["cfa_pattern"] == entry["cfa"]
        assert (sidecar["width_px"], sidecar["height_px"], sidecar["bits"]) == (64, 48, 12)
    assert not list(out.rglob("*.partial"))


def test_rerun_renders_nothing(serial, spec_path):
    out, _ = serial
    before = {p: p.stat().st_mtime_ns for p in (out / "frames").iterdir()}
    summary = run_dataset(spec_path, out, workers=2, progress=False, echo=None)
    assert summary["rendered"] == 0 and summary["skipped"] == 8
    assert {p: p.stat().st_mtime_ns for p in (out / "frames").iterdir()} == before


def flip_byte(path: Path, offset: int = -10) -> None:
    data = bytearray(path.read_bytes())
    data[offset] ^= 0x01
    path.write_bytes(bytes(data))


def test_damaged_frames_are_rendered_again_identically(serial, spec_path, tmp_path, monkeypatch):
    reference, _ = serial
    out = tmp_path / "out"
    shutil.copytree(reference, out)
    manifest = read_manifest(out)
    exr = out / manifest[2]["files"]["exr"]["name"]
    exr.write_bytes(exr.read_bytes()[:-100])  # truncated
    (out / manifest[5]["files"]["dng"]["name"]).unlink()  # missing
    flip_byte(out / manifest[6]["files"]["json"]["name"], 200)  # same size, other bytes: only the hash sees it
    (out / "frames" / ".00000-x.exr.999.partial").write_bytes(b"left by a killed run")
    calls = []
    real = runner.render_task

    def counting(frame, out_dir, threads=1, **options):
        calls.append(frame.index)
        return real(frame, out_dir, threads, **options)

    monkeypatch.setattr(runner, "render_task", counting)
    summary = run_dataset(spec_path, out, workers=1, progress=False, echo=None)
    assert sorted(calls) == [2, 5, 6] and summary["rendered"] == 3 and summary["skipped"] == 5
    assert_same_frames(out, reference)  # the same bytes again, and the stale temporary file is gone


def test_size_only_verification_misses_same_size_damage(serial, spec_path, tmp_path):
    reference, _ = serial
    out = tmp_path / "out"
    shutil.copytree(reference, out)
    flip_byte(out / read_manifest(out)[1]["files"]["exr"]["name"])
    assert run_dataset(spec_path, out, workers=1, verify="size", progress=False, echo=None)["rendered"] == 0
    assert run_dataset(spec_path, out, workers=1, verify="sha256", progress=False, echo=None)["rendered"] == 1
    assert_same_frames(out, reference)


def test_a_darktable_sidecar_rewritten_by_darktable_is_no_damage(serial, spec_path, tmp_path):
    """darktable rewrites a three-chip DNG's .dng.xmp when it opens it: the frame is not rendered again, while
    damage to the frame's own files still is found."""
    reference, _ = serial
    out = tmp_path / "out"
    shutil.copytree(reference, out)
    records = read_manifest(out)
    three_chip = [r for r in records if r["cfa"] is None]
    assert three_chip and all(r["files"]["xmp"] for r in three_chip)
    (out / three_chip[0]["files"]["xmp"]["name"]).write_text("<x:xmpmeta>edited in darktable</x:xmpmeta>\n")
    assert run_dataset(spec_path, out, workers=1, verify="sha256", progress=False, echo=None)["rendered"] == 0
    flip_byte(out / three_chip[0]["files"]["dng"]["name"])
    assert run_dataset(spec_path, out, workers=1, verify="sha256", progress=False, echo=None)["rendered"] == 1


def test_an_interrupted_run_keeps_its_completed_frames(serial, spec_path, tmp_path, monkeypatch):
    reference, _ = serial
    out = tmp_path / "out"
    real = runner.render_task
    done = []

    def crashing(frame, out_dir, threads=1, **options):
        if len(done) == 3:
            raise RuntimeError("simulated crash")
        done.append(frame.index)
        return real(frame, out_dir, threads, **options)

    monkeypatch.setattr(runner, "render_task", crashing)
    with pytest.raises(RuntimeError, match="simulated crash"):
        run_dataset(spec_path, out, workers=1, progress=False, echo=None)
    assert [m["index"] for m in read_manifest(out)] == [0, 1, 2]  # every complete frame, no half line
    assert len(list((out / "frames").glob("*.done"))) == 3
    monkeypatch.setattr(runner, "render_task", real)
    summary = run_dataset(spec_path, out, workers=1, progress=False, echo=None)
    assert summary["rendered"] == 5 and summary["skipped"] == 3
    assert_same_frames(out, reference)


@pytest.mark.slow
@pytest.mark.parametrize("start_method", [None, "spawn"])  # None: the preloaded fork server (POSIX)
def test_local_processes_give_the_serial_bytes(serial, spec_path, tmp_path, monkeypatch, start_method):
    reference, _ = serial
    monkeypatch.setattr(_pool, "POOL_START_METHOD", start_method)
    summary = run_dataset(spec_path, tmp_path / "out", workers=2, progress=False, echo=None)
    assert summary["rendered"] == 8 and summary["backend"] == "2 processes"
    assert_same_frames(tmp_path / "out", reference)


@pytest.mark.slow
def test_dask_local_cluster_gives_the_serial_bytes(serial, spec_path, tmp_path):
    distributed = pytest.importorskip("distributed")
    reference, _ = serial
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        summary = run_dataset(spec_path, tmp_path / "out", scheduler=cluster.scheduler_address,
                              progress=False, echo=None)
    assert summary["rendered"] == 8 and summary["backend"].startswith("dask ")
    assert_same_frames(tmp_path / "out", reference)


# --- the command line ----------------------------------------------------------------------------------------


def parse(argv):
    parser = argparse.ArgumentParser(prog="camsim")
    add_parser(parser.add_subparsers(dest="command"))
    return parser.parse_args(argv)


def test_cli_functions(serial, spec_path, tmp_path, capsys):
    reference, _ = serial
    assert run(parse(["dataset", str(spec_path), "--out", str(tmp_path / "cli"), "--workers", "1", "-q"])) == 0
    assert_same_frames(tmp_path / "cli", reference)
    out = capsys.readouterr().out
    assert "rendered 8 frames" in out and "frames/s" in out
    assert run(parse(["dataset", str(spec_path), "--dry-run"])) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("dataset tiny: 8 frames of 64x48") and len(lines) == 9
    assert json.loads(lines[1])["id"] == read_manifest(reference)[0]["id"]
    with pytest.raises(CamsimError, match="not both"):
        run(parse(["dataset", str(spec_path), "--out", str(tmp_path / "x"), "--workers", "2",
                   "--scheduler", "tcp://127.0.0.1:1"]))


def test_example_spec_is_valid():
    spec = load_spec(ROOT / "scenes" / "denoise_small.toml")
    assert len(spec) == 96 and (spec.width, spec.height) == (256, 192)
