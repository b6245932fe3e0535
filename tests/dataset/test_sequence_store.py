"""A sequence as one Zarr store (``camsim render --format zarr``, issue 29 point 4): the store's arrays equal the
file layout's layers (EXR noisy and clean, DNG digital numbers, sidecars), readable with zarr and xarray; atomic
(a run that dies leaves no store, an earlier store stays whole); one-line refusals."""

import json
from pathlib import Path

import numpy as np
import pytest

from camsim.cli import main
from camsim.io.dng import read_dng
from camsim.io.exr import read_exr

pytest.importorskip("zarr")

SCENE = """
name = "seqz"
[target]
kind = "dead-leaves"
[light]
illuminants = ["D65"]
intensity_factors = [0.5]
[frame]
width = 48
height = 32
[sensor]
preset = "emva-12bit"
exposure_s = 0.01
{sensor}
[render]
seed = 4
[sequence]
frames = 3
frame_interval_s = 0.02
shake_px = 0.8
shake_deg = 0.2
"""

#: Sidecar keys that say where the frame was written, not what it is.
_WHERE = ("files", "zarr", "exr_compression")


@pytest.mark.parametrize("sensor", ['cfa = "RGGB"', ""])
def test_store_round_trip_equals_the_files_layers(tmp_path, sensor):
    import xarray as xr
    import zarr

    scene = tmp_path / "seq.toml"
    scene.write_text(SCENE.format(sensor=sensor))
    assert main(["render", str(scene), "--out", str(tmp_path / "files"), "-q"]) == 0
    assert main(["render", str(scene), "--out", str(tmp_path / "zarr"), "--format", "zarr", "-q"]) == 0
    path = tmp_path / "zarr" / "seqz_D65_F0.5.zarr"
    assert sorted(p.name for p in (tmp_path / "zarr").iterdir()) == [path.name]  # nothing else, no temporaries
    group = zarr.open_group(path, mode="r")
    assert group.attrs["camsim"]["complete"] and np.asarray(group["done"][...]).all()
    planes = 1 if sensor else 3
    assert group["noisy"].shape == (3, planes, 32, 48) and group["clean"].shape == (3, 3, 32, 48)
    assert group["noisy"].chunks == (1, planes, 32, 48) and group["homography"].shape == (3, 3, 3)
    files = tmp_path / "files"
    for i in range(3):
        stem = f"{files}/seqz_D65_F0.5_f00{i}"
        noisy, clean, _ = read_exr(f"{stem}.exr")
        assert np.array_equal(group["noisy"][i], noisy) and np.array_equal(group["clean"][i], clean)
        digital, _ = read_dng(f"{stem}.dng")
        assert np.array_equal(group["digital"][i], digital)
        on_disk = json.loads(Path(f"{stem}.json").read_text())
        stored = json.loads(str(group["sidecar"][i]))
        assert stored["zarr"] == {"store": path.name, "index": i}
        assert {k: v for k, v in stored.items() if k not in _WHERE} == \
            {k: v for k, v in on_disk.items() if k not in _WHERE}
        assert group["time_s"][i] == on_disk["time_s"]
        assert np.array_equal(group["homography"][i], np.array(on_disk["homography"]))
    reference = read_exr(files / "seqz_D65_F0.5_ref.exr")[1]
    assert np.array_equal(group["reference"][...], reference)
    ref_meta = json.loads((files / "seqz_D65_F0.5_ref.json").read_text())
    stored = json.loads(group.attrs["camsim"]["reference_sidecar"])
    assert {k: v for k, v in stored.items() if k not in _WHERE} == \
        {k: v for k, v in ref_meta.items() if k not in _WHERE}
    # xarray reads it: named dimensions, time_s a coordinate of the frames
    ds = xr.open_zarr(path, consolidated=True)
    assert ds["noisy"].dims == ("frame", "channel" if not sensor else "cfa", "y", "x")
    assert np.array_equal(ds["clean"].isel(frame=2).values, group["clean"][2])
    assert "time_s" in ds["noisy"].coords


def test_store_is_atomic_and_refusals_are_one_line(tmp_path, capsys, monkeypatch):
    import camsim.dataset.zarr_store as zarr_store

    scene = tmp_path / "seq.toml"
    scene.write_text(SCENE.format(sensor=""))
    out = tmp_path / "zarr"
    assert main(["render", str(scene), "--out", str(out), "--format", "zarr", "-q"]) == 0
    before = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    real, calls = zarr_store.write_frame_arrays, []

    def dying(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(zarr_store, "write_frame_arrays", dying)
    scene.write_text(SCENE.format(sensor="").replace("seed = 4", "seed = 5"))
    assert main(["render", str(scene), "--out", str(out), "--format", "zarr", "-q"]) != 0  # interrupted
    assert len(calls) == 2
    after = {p.relative_to(out): p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before  # the earlier store is whole and untouched; no temporary left
    monkeypatch.setattr(zarr_store, "write_frame_arrays", real)
    capsys.readouterr()
    plain = tmp_path / "plain.toml"
    plain.write_text(SCENE.format(sensor="").split("[sequence]")[0])
    for args, message in (([str(plain)], "the scene needs a [sequence] table"),
                          ([str(scene), "--preview"], "have no preview")):
        code = main(["render", *args, "--out", str(tmp_path / "x"), "--format", "zarr", "-q"])
        err = capsys.readouterr().err
        assert code == 2 and message in err and err.count("\n") == 1, err
    assert not (tmp_path / "x").exists()
