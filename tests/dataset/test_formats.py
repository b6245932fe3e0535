"""camsim dataset's outputs: the EXR compression of the file layout (chosen, recorded, kept on resume), and the
Zarr store (--format zarr): the file layout's frames bit for bit, read back through xarray and Dask, the same
bytes from any back-end, resumed after an interruption or damage, and refused for specs it cannot hold."""

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

import camsim.dataset.runner as runner
from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.dataset import _pool, load_spec, read_manifest, run_dataset
from camsim.dataset.zarr_store import RECORDS_DIR, STORE_NAME
from camsim.io.dng import read_dng
from camsim.io.exr import read_exr
from tests.support.helpers import ROOT, file_tree, write_text_file

try:
    import zarr
except ImportError:  # a dependency of camsim; the EXR tests run without it
    zarr = None
needs_zarr = pytest.mark.skipif(zarr is None, reason="zarr is not installed")

SCENE = (ROOT / "scenes" / "macbeth_26.toml").as_posix()

# 2 illuminants x 2 random draws x 2 repeats = 8 frames of 64 x 48, three-chip, 12 bits
SPEC = f"""
name = "formats"
scene = "{SCENE}"
seed = 11
repeats = 2

[frame]
width = 64
height = 48

[fixed]
preset = "emva-12bit"

[grid]
illuminants = ["D65", "A"]

[random]
count = 2
intensity_factor = {{ log_uniform = [0.001, 1.0] }}
read_noise_e = {{ uniform = [2, 6] }}
"""


def write_spec(folder: Path, text: str = SPEC, name: str = "formats.toml") -> Path:
    return write_text_file(folder, name, text)


tree = file_tree


def bits(a):
    return np.ascontiguousarray(a).view(np.uint32)


@pytest.fixture(scope="module")
def spec_path(tmp_path_factory):
    return write_spec(tmp_path_factory.mktemp("spec"))


@pytest.fixture(scope="module")
def files(spec_path, tmp_path_factory):
    """The file layout, serially."""
    out = tmp_path_factory.mktemp("files") / "out"
    run_dataset(spec_path, out, workers=1, progress=False, echo=None)
    return out


@pytest.fixture(scope="module")
def store(spec_path, tmp_path_factory):
    """The Zarr store, serially: (OUT, summary)."""
    out = tmp_path_factory.mktemp("zarr") / "out"
    summary = run_dataset(spec_path, out, workers=1, progress=False, echo=None, output="zarr")
    return out, summary


# --- the file layout's EXR compression -------------------------------------------------------------------------


def test_exr_compression_is_chosen_recorded_and_kept_on_resume(spec_path, files, tmp_path):
    import OpenEXR

    out = tmp_path / "out"
    summary = run_dataset(spec_path, out, workers=1, progress=False, echo=None, exr_compression="zip")
    assert summary["exr_compression"] == "zip" and summary["format"] == "files"
    manifest, reference = read_manifest(out), read_manifest(files)
    for entry, ref in zip(manifest, reference):
        assert entry["exr_compression"] == "zip" and ref["exr_compression"] == "none"
        exr = out / entry["files"]["exr"]["name"]
        with OpenEXR.File(str(exr), header_only=True) as f:
            assert f.header()["compression"] == OpenEXR.ZIP_COMPRESSION
        assert json.loads((out / entry["files"]["json"]["name"]).read_text())["exr_compression"] == "zip"
        for a, b in zip(read_exr(exr), read_exr(files / ref["files"]["exr"]["name"])):  # the same pixels
            if isinstance(a, np.ndarray):
                np.testing.assert_array_equal(bits(a), bits(b))
        assert (out / entry["files"]["dng"]["name"]).read_bytes() == \
            (files / ref["files"]["dng"]["name"]).read_bytes()
    # a re-run with another compression keeps the complete frames (the same pixels) and says so
    lines = []
    (out / manifest[3]["files"]["exr"]["name"]).unlink()
    summary = run_dataset(spec_path, out, workers=1, progress=False, echo=lines.append)
    assert summary["rendered"] == 1 and summary["exr_compression"] == "none"
    assert "7 complete frames have zip, kept" in lines[0] and "EXR compression none" in lines[0]
    assert [m["exr_compression"] for m in read_manifest(out)] == ["zip"] * 3 + ["none"] + ["zip"] * 4


def test_exr_compression_from_the_spec_and_the_command_line(spec_path, tmp_path, capsys):
    spec = write_spec(tmp_path, SPEC.replace("repeats = 2", 'repeats = 2\nexr_compression = "piz"'))
    assert load_spec(spec).exr_compression == "piz"
    out = tmp_path / "out"
    assert main(["dataset", str(spec), "--out", str(out), "--workers", "1", "-q"]) == 0
    assert {m["exr_compression"] for m in read_manifest(out)} == {"piz"}
    assert "EXR compression piz" in capsys.readouterr().out
    lossy = write_spec(tmp_path, SPEC.replace("repeats = 2", 'repeats = 2\nexr_compression = "pxr24"'), "l.toml")
    for argv in (["dataset", str(lossy), "--out", str(tmp_path / "a")],
                 ["dataset", str(spec_path), "--out", str(tmp_path / "b"), "--exr-compression", "dwaa"],
                 ["dataset", str(spec_path), "--out", str(tmp_path / "c"), "--format", "zarr",
                  "--exr-compression", "zip"]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("camsim: error: "), err
        assert "refused" in err[0] or "for the file layout" in err[0]
    assert not any((tmp_path / name).exists() for name in "abc")


# --- the Zarr store --------------------------------------------------------------------------------------------


@needs_zarr
def test_store_equals_the_file_layout_bit_for_bit(store, files, spec_path):
    out, summary = store
    assert summary["format"] == "zarr" and summary["rendered"] == 8 and summary["store"] == str(out / STORE_NAME)
    group = zarr.open_group(out / STORE_NAME, mode="r")
    spec = load_spec(spec_path)
    assert group["noisy"].shape == (8, 3, 48, 64) and group["noisy"].dtype == np.float32
    assert group["clean"].shape == (8, 3, 48, 64) and group["digital"].dtype == np.uint16
    assert group["noisy"].chunks == (1, 3, 48, 64)
    assert group["done"][:].all()
    manifest = read_manifest(out)
    for entry, ref, frame in zip(manifest, read_manifest(files), spec.frames):
        i = frame.index
        assert {k: v for k, v in entry.items() if k != "arrays"} == frame.record
        noisy, clean, header = read_exr(files / ref["files"]["exr"]["name"])
        np.testing.assert_array_equal(bits(group["noisy"][i]), bits(noisy))
        np.testing.assert_array_equal(bits(group["clean"][i]), bits(clean))
        digital, _ = read_dng(files / ref["files"]["dng"]["name"])
        assert np.array_equal(group["digital"][i], digital)
        sidecar = json.loads(str(group["sidecar"][i]))
        file_sidecar = json.loads((files / ref["files"]["json"]["name"]).read_text())
        assert sidecar.pop("zarr") == {"store": STORE_NAME, "index": i} and sidecar.pop("files") is None
        file_sidecar.pop("files"), file_sidecar.pop("exr_compression")
        assert sidecar == file_sidecar
        assert json.loads(str(group["records"][i])) == frame.record
        for layer in ("noisy", "clean", "digital"):
            data = np.ascontiguousarray(group[layer][i])
            assert entry["arrays"][layer]["sha256"] == hashlib.sha256(data.tobytes()).hexdigest()
            assert (out / STORE_NAME / entry["arrays"][layer]["chunk"]).stat().st_size == \
                entry["arrays"][layer]["bytes"]
    assert not list(out.rglob("*.partial"))


@needs_zarr
def test_store_reads_through_xarray_and_dask(store, spec_path):
    xarray = pytest.importorskip("xarray")
    dask_array = pytest.importorskip("dask.array")
    out, _ = store
    spec = load_spec(spec_path)
    ds = xarray.open_zarr(out / STORE_NAME)
    assert dict(ds.sizes) == {"frame": 8, "channel": 3, "y": 48, "x": 64}
    assert ds.noisy.dims == ("frame", "channel", "y", "x") and list(ds.channel.values) == ["R", "G", "B"]
    # the parameters are coordinates of the frame dimension
    assert list(ds.id.values) == [f.id for f in spec.frames]
    assert list(ds.illuminant.values) == [f.record["illuminant"] for f in spec.frames]
    np.testing.assert_array_equal(ds.intensity_factor.values, [f.record["intensity_factor"] for f in spec.frames])
    np.testing.assert_array_equal(ds.seed.values, [f.seed for f in spec.frames])
    assert ds.dark_current_e_per_s.dims == ("frame", "channel")
    under_a = ds.noisy.isel(frame=np.flatnonzero(ds.illuminant.values == "A"))  # selection by parameter
    assert under_a.sizes["frame"] == 4
    group = zarr.open_group(out / STORE_NAME, mode="r")
    stack = dask_array.from_zarr(str(out / STORE_NAME), component="noisy")
    assert stack.chunksize == (1, 3, 48, 64)
    np.testing.assert_array_equal(bits(stack[5].compute()), bits(group["noisy"][5]))
    np.testing.assert_array_equal(bits((ds.noisy - ds.clean)[2].values),
                                  bits(group["noisy"][2] - group["clean"][2]))


@needs_zarr
@pytest.mark.slow
@pytest.mark.parametrize("start_method", [None, "spawn"])  # None: the preloaded fork server (POSIX)
def test_store_bytes_do_not_depend_on_the_back_end(store, spec_path, tmp_path, monkeypatch, start_method):
    reference, _ = store
    monkeypatch.setattr(_pool, "POOL_START_METHOD", start_method)
    summary = run_dataset(spec_path, tmp_path / "out", workers=2, progress=False, echo=None, output="zarr")
    assert summary["rendered"] == 8 and summary["backend"] == "2 processes"
    got, want = tree(tmp_path / "out"), tree(reference)
    assert sorted(got) == sorted(want)
    for name in want:  # every chunk, metadata file and record: same seed, same bytes
        assert got[name] == want[name], name


@needs_zarr
@pytest.mark.slow
def test_store_through_a_dask_cluster(store, spec_path, tmp_path):
    distributed = pytest.importorskip("distributed")
    reference, _ = store
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        summary = run_dataset(spec_path, tmp_path / "out", scheduler=cluster.scheduler_address, progress=False,
                              echo=None, output="zarr")
    assert summary["rendered"] == 8
    assert tree(tmp_path / "out") == tree(reference)


@needs_zarr
def test_an_interrupted_store_resumes_to_the_same_bytes(store, spec_path, tmp_path, monkeypatch):
    reference, _ = store
    out = tmp_path / "out"
    real = runner.zarr_task
    done = []

    def crashing(frame, out_dir, threads=1, **options):
        if len(done) == 3:
            raise KeyboardInterrupt  # Ctrl-C in the middle of the run
        done.append(frame.index)
        return real(frame, out_dir, threads, **options)

    monkeypatch.setattr(runner, "zarr_task", crashing)
    with pytest.raises(KeyboardInterrupt):
        run_dataset(spec_path, out, workers=1, progress=False, echo=None, output="zarr")
    assert [m["index"] for m in read_manifest(out)] == [0, 1, 2]
    group = zarr.open_group(out / STORE_NAME, mode="r")
    assert list(group["done"][:]) == [True] * 3 + [False] * 5
    assert np.isnan(group["noisy"][5]).all() and str(group["sidecar"][5]) == ""  # not rendered: the fill values
    # a chunk half-written by a killed worker (zarr's temporary name) is swept
    (out / STORE_NAME / "noisy" / "c.4.0.0.0.0123abcd.partial").write_bytes(b"half a chunk")
    monkeypatch.setattr(runner, "zarr_task", real)
    lines = []
    summary = run_dataset(spec_path, out, workers=1, progress=False, echo=lines.append, output="zarr")
    assert summary["rendered"] == 5 and summary["skipped"] == 3
    assert "3 complete and verified, 5 to render" in lines[0]
    assert tree(out) == tree(reference)


@needs_zarr
def test_damaged_chunks_are_rendered_again(store, spec_path, tmp_path, monkeypatch):
    reference, _ = store
    out = tmp_path / "out"
    shutil.copytree(reference, out)
    manifest = read_manifest(out)
    (out / STORE_NAME / manifest[1]["arrays"]["clean"]["chunk"]).unlink()  # missing
    chunk = out / STORE_NAME / manifest[6]["arrays"]["noisy"]["chunk"]
    data = bytearray(chunk.read_bytes())
    data[-5] ^= 0x01  # the same size, another value: only the hash sees it
    chunk.write_bytes(bytes(data))
    (out / RECORDS_DIR / f"{manifest[7]['id']}.done").unlink()  # never recorded
    calls = []
    real = runner.zarr_task

    def counting(frame, out_dir, threads=1, **options):
        calls.append(frame.index)
        return real(frame, out_dir, threads, **options)

    monkeypatch.setattr(runner, "zarr_task", counting)
    assert run_dataset(spec_path, out, workers=1, progress=False, echo=None, output="zarr",
                       verify="size")["rendered"] == 2  # the flipped bit passes a size check
    assert sorted(calls) == [1, 7]
    calls.clear()
    assert run_dataset(spec_path, out, workers=1, progress=False, echo=None, output="zarr")["rendered"] == 1
    assert calls == [6]
    assert tree(out) == tree(reference)


@needs_zarr
def test_a_longer_spec_extends_the_store(store, spec_path, tmp_path):
    reference, _ = store
    out = tmp_path / "out"
    shutil.copytree(reference, out)
    longer = write_spec(tmp_path, SPEC.replace("repeats = 2", "repeats = 3"), "formats.toml")
    summary = run_dataset(longer, out, workers=1, progress=False, echo=None, output="zarr")
    group = zarr.open_group(out / STORE_NAME, mode="r")
    assert group["noisy"].shape[0] == 12 and group["done"][:].all()
    kept = {f.index for f in load_spec(longer).frames if f.id in {m["id"] for m in read_manifest(reference)}}
    assert summary["rendered"] == 12 - len(kept)


@needs_zarr
def test_cfa_frames_go_to_a_mosaic_plane(tmp_path):
    spec = write_spec(tmp_path, SPEC.replace('preset = "emva-12bit"', 'preset = "emva-12bit"\ncfa = "RGGB"')
                      .replace("repeats = 2", "repeats = 1"))
    run_dataset(spec, tmp_path / "files", workers=1, progress=False, echo=None)
    run_dataset(spec, tmp_path / "zarr", workers=1, progress=False, echo=None, output="zarr")
    group = zarr.open_group(tmp_path / "zarr" / STORE_NAME, mode="r")
    assert group["noisy"].shape == (4, 1, 48, 64) and group["clean"].shape == (4, 3, 48, 64)
    assert group["noisy"].metadata.dimension_names == ("frame", "cfa", "y", "x")
    for ref in read_manifest(tmp_path / "files"):
        noisy, clean, _ = read_exr(tmp_path / "files" / ref["files"]["exr"]["name"])
        np.testing.assert_array_equal(bits(group["noisy"][ref["index"]]), bits(noisy))
        np.testing.assert_array_equal(bits(group["clean"][ref["index"]]), bits(clean))
        digital, _ = read_dng(tmp_path / "files" / ref["files"]["dng"]["name"])
        assert np.array_equal(group["digital"][ref["index"]], digital)


def _cube_scene(folder: Path) -> Path:
    np.save(folder / "cube.npy", np.random.default_rng(0).uniform(0.05, 0.9, size=(30, 40, 101)))
    path = folder / "cube.toml"
    path.write_text('name = "cube"\n[cube]\npath = "cube.npy"\n[light]\nilluminants = ["D65"]\n')
    return path


@needs_zarr
@pytest.mark.parametrize("case", ["sizes", "cfa"])
def test_specs_a_store_cannot_hold_are_refused(tmp_path, capsys, case):
    if case == "sizes":  # a chart at the default 256 x 192 and a cube of its own 40 x 30
        text = f'name = "mixed"\nscene = ["{SCENE}", "{_cube_scene(tmp_path).as_posix()}"]\n' \
               '[fixed]\nilluminant = "D65"\nintensity_factor = 1.0\n'
        message = "needs frames of one size.*256x192"
    else:
        text = SPEC.replace("[grid]", '[grid]\ncfa = ["none", "RGGB"]')
        message = "mixes three-chip frames and colour filter array"
    spec = write_spec(tmp_path, text, "bad.toml")
    with pytest.raises(CamsimError, match=message):
        run_dataset(spec, tmp_path / "out", workers=1, progress=False, echo=None, output="zarr")
    assert not (tmp_path / "out" / STORE_NAME).exists()
    assert main(["dataset", str(spec), "--out", str(tmp_path / "cli"), "--format", "zarr"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("camsim: error: --format zarr needs")


@needs_zarr
def test_one_folder_holds_one_format(store, files, spec_path, tmp_path):
    with pytest.raises(CamsimError, match="holds a Zarr dataset"):
        run_dataset(spec_path, store[0], workers=1, progress=False, echo=None)
    with pytest.raises(CamsimError, match="holds a dataset of files"):
        run_dataset(spec_path, files, workers=1, progress=False, echo=None, output="zarr")
    other = tmp_path / "other"
    (other / STORE_NAME).mkdir(parents=True)
    (other / STORE_NAME / "notes.txt").write_text("mine")
    with pytest.raises(CamsimError, match="not a Zarr store"):
        run_dataset(spec_path, other, workers=1, progress=False, echo=None, output="zarr")
    assert (other / STORE_NAME / "notes.txt").read_text() == "mine"
