"""Dataset bursts (issue 29, point 4): ``camsim dataset`` items that are bursts with camera motion, read back as
burst pairs (N noisy frames → the clean reference) by :class:`camsim.pairs.WrittenPairs`; the frames' fixed pattern
identical and their temporal noise independent; each frame's homography against our own phase correlation; one-line
errors; resuming a half-written burst."""

import json

import numpy as np
import pytest

from camsim.cli import main
from camsim.dataset.runner import run_dataset
from camsim.dataset.spec import load_spec
from camsim.io.exr import read_exr
from camsim.pairs import WrittenPairs
from tests.render.test_sequence import _phase_shift

FLAT = """
name = "flatburst"
[target]
kind = "flat"
reflectance = 0.5
[light]
illuminants = ["D65"]
intensity_factors = [0.05]
[camera.scale]
kind = "anchor"
reference_electrons = 8000
[sensor]
preset = "emva-12bit"
exposure_s = 0.01
prnu_percent = 2
dsnu_e = 3
{sensor}
{sequence}
"""

#: A scene whose expectation changes when it moves (a flat field does not).
TEXTURED = FLAT.replace('kind = "flat"\nreflectance = 0.5', 'kind = "dead-leaves"')

SPEC = """
name = "bursts"
scene = "scene.toml"
seed = 5
{top}
[frame]
width = {w}
height = {h}
[fixed]
{fixed}
[grid]
{grid}
"""


def write_spec(tmp_path, fixed="burst_frames = 4\nframe_interval_s = 0.02", grid="", top="", sensor="",
               sequence="", w=64, h=48, scene=FLAT):
    (tmp_path / "scene.toml").write_text(scene.format(sensor=sensor, sequence=sequence))
    path = tmp_path / "spec.toml"
    path.write_text(SPEC.format(fixed=fixed, grid=grid, top=top, w=w, h=h))
    return path


def test_burst_dataset_written_and_read_back_as_pairs(tmp_path):
    """A static burst: every frame's clean layer is the reference's (the fixed pattern identical, and present), the
    temporal noise of consecutive frames uncorrelated within ±3/√n, and WrittenPairs gives the frames stacked with
    the reference and identity homographies."""
    spec = write_spec(tmp_path, fixed="burst_frames = 4\nframe_interval_s = 0.02", w=96, h=64)
    out = tmp_path / "out"
    run_dataset(spec, out, workers=1, progress=False, echo=None)
    lines = [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines()]
    assert len(lines) == 1
    line = lines[0]
    assert line["burst"] == {"frames": ["f000", "f001", "f002", "f003"], "reference": "ref"}
    assert line["burst_frames"] == 4 and line["shake_px"] == 0.0
    for kind in ("ref.exr", "ref.json", *(f"f00{i}.{k}" for i in range(4) for k in ("dng", "exr", "json"))):
        assert (out / line["files"][kind]["name"]).is_file(), kind
    _, reference, _ = read_exr(out / line["files"]["ref.exr"]["name"])
    # the fixed pattern is in the clean layers (PRNU 2 %, DSNU 3 e⁻ on a flat field): not a constant
    assert reference[1].std() > 0.005 * reference[1].mean()
    residuals = []
    for i in range(4):
        noisy, clean, _ = read_exr(out / line["files"][f"f00{i}.exr"]["name"])
        assert np.array_equal(clean, reference)  # no motion: each frame's expectation is the reference's
        sidecar = json.loads((out / line["files"][f"f00{i}.json"]["name"]).read_text())
        assert sidecar["frame_index"] == i and sidecar["time_s"] == pytest.approx(0.02 * i)
        assert sidecar["sequence"]["stem"] == line["id"]
        residuals.append((noisy - clean).ravel().astype(np.float64))
    n = residuals[0].size
    for a, b in zip(residuals, residuals[1:]):
        assert abs(np.corrcoef(a, b)[0, 1]) < 3 / np.sqrt(n)
    assert all(abs(r.mean()) < 5 * r.std() / np.sqrt(n) for r in residuals)

    pairs = WrittenPairs(out, burst=True)
    noisy, clean, meta = pairs[0]
    assert noisy.shape == (4, 3, 64, 96) and clean.shape == (3, 64, 96)
    assert np.array_equal(clean, reference)
    assert np.array_equal(noisy[2], read_exr(out / line["files"]["f002.exr"]["name"])[0])
    assert meta["homography"].shape == (4, 3, 3) and np.array_equal(meta["homography"], np.tile(np.eye(3), (4, 1, 1)))
    assert meta["frames"] == [f"{line['id']}_f00{i}" for i in range(4)]
    noisy, clean, meta = WrittenPairs(out, burst=True, domain="raw", crop=(32, 16), seed=1)[0]
    assert noisy.shape == (4, 3, 16, 32) and clean.shape == (3, 16, 32) and meta["crop"][2:] == (32, 16)
    with pytest.raises(Exception, match="burst=True"):
        WrittenPairs(out)


def test_bayer_burst_pairs_and_torch(tmp_path):
    """A Bayer burst: (N, 1, H, W) mosaics with the reference at each site's own channel; (N, 4, H/2, W/2) packed in
    raw; written_pairs and collate_pairs stack (B, N, P, H, W), (B, P, H, W), (B, N, 3, 3)."""
    torch = pytest.importorskip("torch")
    from camsim.pairs_torch import collate_pairs, written_pairs
    from camsim.sensor.cfa import mosaic_of

    spec = write_spec(tmp_path, fixed="burst_frames = 3\nframe_interval_s = 0.02\ncfa = \"RGGB\"\nshake_deg = 0.5",
                      grid="shake_px = [0.5, 1.0]", w=32, h=24, scene=TEXTURED)
    out = tmp_path / "out"
    run_dataset(spec, out, workers=1, progress=False, echo=None)
    pairs = WrittenPairs(out, burst=True)
    assert len(pairs) == 2
    noisy, clean, meta = pairs[1]
    line = meta["record"]
    _, reference, _ = read_exr(out / "frames" / f"{line['id']}_ref.exr")
    assert noisy.shape == (3, 1, 24, 32) and np.array_equal(clean[0], mosaic_of(reference, "RGGB"))
    own = read_exr(out / "frames" / f"{line['id']}_f000.exr")[1]
    assert not np.array_equal(clean[0], mosaic_of(own, "RGGB"))  # the reference, not a frame's own expectation
    assert not np.allclose(meta["homography"][1], np.eye(3))  # it shakes
    # a crop's homographies map the crop's pixels: reference crop pixel q is the full frame's q + (x, y), seen at
    # H (q + (x, y)) in the full frame, i.e. at that minus (x, y) in the crop
    _, _, cropped = WrittenPairs(out, burst=True, crop=(16, 12), seed=3)[1]
    x, y = cropped["crop"][:2]
    assert (x, y) != (0, 0)
    for n in range(3):
        for q in ((0.0, 0.0), (15.0, 11.0), (7.5, 3.0)):
            full = meta["homography"][n] @ np.array([q[0] + x, q[1] + y, 1.0])
            crop = cropped["homography"][n] @ np.array([q[0], q[1], 1.0])
            assert crop[:2] / crop[2] == pytest.approx(full[:2] / full[2] - np.array([x, y]), abs=1e-9)
    noisy, clean, _ = WrittenPairs(out, burst=True, domain="raw")[0]
    assert noisy.shape == (3, 4, 12, 16) and clean.shape == (4, 12, 16)
    batch = collate_pairs([written_pairs(out, burst=True)[i] for i in range(2)])
    assert tuple(batch["noisy"].shape) == (2, 3, 1, 24, 32) and tuple(batch["clean"].shape) == (2, 1, 24, 32)
    assert tuple(batch["homography"].shape) == (2, 3, 3, 3) and batch["homography"].dtype == torch.float64


BLOB_SCENE = """
name = "blob"
[image]
path = "blob.png"
kind = "reflectance"
colourspace = "sRGB"
[light]
illuminants = ["D65"]
intensity_factors = [1.0]
[sensor]
preset = "ideal"
exposure_s = 0.002
photon_noise = false
"""


@pytest.mark.slow
def test_each_frames_homography_moves_the_reference_onto_it(tmp_path):
    """A pure pan: the clean layer of frame n is the reference shifted by the translation of meta["homography"][n]
    (our own phase correlation, within 0.05 px), the full frame and a crop alike."""
    from camsim.isp import write_png

    h, w = 64, 96
    y, x = np.mgrid[0:h, 0:w]
    blob = 0.15 + 0.7 * np.exp(-((x - 44.0) ** 2 + (y - 30.0) ** 2) / (2 * 6.0 ** 2))
    write_png(tmp_path / "blob.png", np.stack([blob] * 3), bits=16)
    (tmp_path / "scene.toml").write_text(BLOB_SCENE)
    (tmp_path / "spec.toml").write_text(SPEC.replace("[frame]\nwidth = {w}\nheight = {h}\n", "").format(
        top="", grid="", fixed="burst_frames = 3\nframe_interval_s = 0.01\npan_x_px_per_s = 140.0\n"
                                         "pan_y_px_per_s = -75.0"))
    out = tmp_path / "out"
    run_dataset(tmp_path / "spec.toml", out, workers=1, progress=False, echo=None)
    pairs = WrittenPairs(out, burst=True)
    _, reference, meta = pairs[0]
    line = meta["record"]
    for n in range(3):
        clean = read_exr(out / "frames" / f"{line['id']}_f00{n}.exr")[1]
        dx, dy = _phase_shift(reference[1].astype(np.float64), clean[1].astype(np.float64))
        t = meta["time_s"][n] + 0.001  # the exposure's middle
        assert meta["homography"][n][:2, 2] == pytest.approx([140.0 * t, -75.0 * t], abs=1e-9)
        assert abs(dx - meta["homography"][n][0, 2]) < 0.05 and abs(dy - meta["homography"][n][1, 2]) < 0.05
    _, _, cropped = WrittenPairs(out, burst=True, crop=(40, 30), seed=2)[0]
    assert np.allclose(cropped["homography"], meta["homography"])  # a translation is the same in crop pixels


@pytest.mark.parametrize("fixed, args, message", [
    ("burst_frames = 0", (), "burst_frames must be ≥ 1"),
    ("burst_frames = 3\nshake_px = -1.0", (), "shake_px must be ≥ 0"),
    ("shake_px = 1.0", (), "shake_px set a burst's motion, but burst_frames is not set"),
    ("burst_frames = 3\nframe_interval_s = 0.001", (), "longer than frame_interval_s"),
    ("burst_frames = 3\nstatistics = \"paper\"", (), "statistics = 'pixel'"),
    ("burst_frames = 3\nrolling_shutter_row_s = 0.001", (), "the rolling shutter's readout, 48 rows"),
    ("burst_frames = 3\nflicker_depth = 1.5", (), "flicker_depth must be"),
])
def test_bad_burst_parameters_are_one_line_exit_2(tmp_path, capsys, fixed, args, message):
    spec = write_spec(tmp_path, fixed=fixed)
    for dry in ((), ("--dry-run",)):
        code = main(["dataset", str(spec), "--out", str(tmp_path / "out"), "--workers", "1", "-q", *args, *dry])
        err = capsys.readouterr().err
        assert code == 2 and message in err and err.count("\n") == 1 and err.startswith("camsim: error:"), err
    assert not (tmp_path / "out" / "frames").exists() or not any((tmp_path / "out" / "frames").iterdir())


def test_raws_crops_make_bursts_and_thin_with_shake_is_refused_on_one_line(tmp_path, capsys):
    """A [raws] spec with burst_frames plans bursts (tests/dataset/test_raw_bursts.py renders them); photon_law
    'thin' with shake cannot move (a moved site has no count to thin): exit 2, one line, at --dry-run."""
    from tests.support.phone_dng import write_phone_dng

    (tmp_path / "raws").mkdir()
    mosaic = np.full((48, 64), 600, dtype=np.uint16)
    write_phone_dng(tmp_path / "raws" / "a.dng", mosaic, pattern="RGGB", black_per_site=[64] * 4, white=1023,
                    iso=100, exposure_s=0.01)
    text = ('name = "r"\n[raws]\nfolder = "raws"\ncrop = [32, 32]\npreset = "sony-a7s2"\n{law}'
            '[fixed]\nburst_frames = 4\nframe_interval_s = 0.02\nshake_px = 1.0\n')
    (tmp_path / "spec.toml").write_text(text.format(law=""))
    frame, = load_spec(tmp_path / "spec.toml").frames
    assert frame.burst.frames == 4 and frame.burst.shake_px == 1.0 and frame.record["burst_frames"] == 4
    assert main(["dataset", str(tmp_path / "spec.toml"), "--dry-run"]) == 0
    assert "1 bursts of 32x32" in capsys.readouterr().out
    code = main(["dataset", str(tmp_path / "spec.toml"), "--dry-run", "--srgb", "png"])
    err = capsys.readouterr().err
    assert code == 2 and "bursts of [raws] crops have no sRGB outputs yet" in err and err.count("\n") == 1, err
    (tmp_path / "spec.toml").write_text(text.format(law='photon_law = "thin"\n'))
    code = main(["dataset", str(tmp_path / "spec.toml"), "--dry-run"])
    err = capsys.readouterr().err
    assert code == 2 and "photon_law = 'thin' cannot move" in err and err.count("\n") == 1, err


def test_a_scene_files_sequence_makes_bursts_and_none_turns_it_off(tmp_path):
    seq = "[sequence]\nframes = 3\nframe_interval_s = 0.05\nshake_px = 0.5"
    spec = load_spec(write_spec(tmp_path, fixed="", sequence=seq))
    frame, = spec.frames
    assert frame.burst.frames == 3 and frame.burst.shake_px == 0.5 and frame.record["burst_frames"] == 3
    spec = load_spec(write_spec(tmp_path, fixed="burst_frames = 5\nshake_deg = 0.1", sequence=seq))
    frame, = spec.frames
    assert (frame.burst.frames, frame.burst.shake_px, frame.burst.shake_deg, frame.burst.frame_interval_s) == \
        (5, 0.5, 0.1, 0.05)
    spec = load_spec(write_spec(tmp_path, fixed='burst_frames = "none"', sequence=seq))
    frame, = spec.frames
    assert frame.burst is None and "burst_frames" not in frame.record
    # a single-frame spec's records (and ids) carry no burst key
    spec = load_spec(write_spec(tmp_path, fixed=""))
    assert spec.frames[0].burst is None and not any(k.startswith("burst") for k in spec.frames[0].record)


def test_random_burst_parameters_draw_per_item(tmp_path):
    spec = write_spec(tmp_path, fixed="burst_frames = 2\nframe_interval_s = 0.05")
    spec.write_text(spec.read_text() + "[random]\ncount = 3\nshake_px = { uniform = [0.0, 2.0] }\n")
    frames = load_spec(spec).frames
    values = [f.burst.shake_px for f in frames]
    assert len(set(values)) == 3 and all(0 <= v <= 2 for v in values)
    assert [f.record["shake_px"] for f in frames] == values and all(f.burst.frames == 2 for f in frames)


def _hashes(folder):
    import hashlib

    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted((folder / "frames").iterdir())}


def check_resuming_after_a_death_in_the_second_burst(spec, tmp_path, monkeypatch, owner, writer: str,
                                                    damage: str = "f001.exr") -> None:
    """Render ``spec`` (two bursts) whole; then again with ``owner.writer`` (the function that writes a frame's
    files) raising KeyboardInterrupt on its 6th call, inside the second burst after its reference: the first burst
    complete, the second without its record, the manifest listing the first only; a re-run renders the second
    only and the files equal the whole run's byte for byte; a damaged frame file of the first burst is rendered
    again, the same bytes (``damage``: which, ``<id>_<damage>``)."""
    whole = tmp_path / "whole"
    run_dataset(spec, whole, workers=1, progress=False, echo=None)
    expected = _hashes(whole)

    real = getattr(owner, writer)
    calls = []

    def dying(*args, **kwargs):
        calls.append(args[1])
        if len(calls) == 6:
            raise KeyboardInterrupt
        return real(*args, **kwargs)

    monkeypatch.setattr(owner, writer, dying)
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt):
        run_dataset(spec, out, workers=1, progress=False, echo=None)
    monkeypatch.setattr(owner, writer, real)
    first, second = load_spec(spec).frames
    assert (out / "frames" / f"{first.id}.done").is_file() and not (out / "frames" / f"{second.id}.done").exists()
    assert (out / "frames" / f"{second.id}_ref.exr").is_file()  # half-written: its reference is there
    assert [json.loads(line)["id"] for line in (out / "manifest.jsonl").read_text().splitlines()] == [first.id]
    summary = run_dataset(spec, out, workers=1, progress=False, echo=None)
    assert (summary["skipped"], summary["rendered"]) == (1, 1)
    assert _hashes(out) == expected
    damaged = out / "frames" / f"{first.id}_{damage}"
    data = damaged.read_bytes()
    damaged.write_bytes(data[:-1] + bytes([data[-1] ^ 0xFF]))
    summary = run_dataset(spec, out, workers=1, progress=False, echo=None)
    assert (summary["skipped"], summary["rendered"]) == (1, 1)
    assert _hashes(out) == expected


def test_resuming_a_half_written_burst_dataset(tmp_path, monkeypatch):
    """A run that dies inside the second burst leaves the first complete and the second without its record; a
    re-run renders the second only, and the files equal an uninterrupted run's byte for byte. A damaged frame
    file of a complete burst is rendered again."""
    import camsim.dataset.frame_render as frame_render

    spec = write_spec(tmp_path, fixed="burst_frames = 3\nframe_interval_s = 0.02", grid="shake_px = [0.0, 0.7]",
                      w=32, h=24)
    check_resuming_after_a_death_in_the_second_burst(spec, tmp_path, monkeypatch, frame_render, "write_frame")


def test_burst_store_equals_the_files(tmp_path):
    """--format zarr: a store of bursts holds the file layout's bursts bit for bit (each frame's noisy, clean and
    digital layers, the reference, the homographies, start times and sidecars); xarray reads its (frame,
    burst_frame, …) arrays; WrittenPairs gives the same burst pairs from both; bursts of two lengths are refused."""
    import xarray as xr
    import zarr

    from camsim.io.dng import read_dng

    spec = write_spec(tmp_path, fixed="burst_frames = 3\nframe_interval_s = 0.02\ncfa = \"RGGB\"",
                      grid="shake_px = [0.0, 1.2]", w=32, h=24, scene=TEXTURED)
    run_dataset(spec, tmp_path / "files", workers=1, progress=False, echo=None)
    run_dataset(spec, tmp_path / "zarr", workers=1, progress=False, echo=None, output="zarr")
    group = zarr.open_group(tmp_path / "zarr" / "dataset.zarr", mode="r")
    assert group["noisy"].shape == (2, 3, 1, 24, 32) and group["noisy"].chunks == (1, 3, 1, 24, 32)
    assert group["reference"].shape == (2, 3, 24, 32) and group["homography"].shape == (2, 3, 3, 3)
    frames = tmp_path / "files" / "frames"
    for item in load_spec(spec).frames:
        i = item.index
        stored = json.loads(str(group["sidecar"][i]))
        reference = read_exr(frames / f"{item.id}_ref.exr")[1]
        assert np.array_equal(group["reference"][i], reference)
        if i == 1:  # it shakes: its frames' expectations are not the reference's
            assert not np.array_equal(group["clean"][i, 0], reference)
        for n in range(3):
            noisy, clean, _ = read_exr(frames / f"{item.id}_f00{n}.exr")
            assert np.array_equal(group["noisy"][i, n], noisy) and np.array_equal(group["clean"][i, n], clean)
            assert np.array_equal(group["digital"][i, n], read_dng(frames / f"{item.id}_f00{n}.dng")[0])
            meta = json.loads((frames / f"{item.id}_f00{n}.json").read_text())
            assert np.array_equal(group["homography"][i, n], np.array(meta["homography"]))
            assert group["time_s"][i, n] == meta["time_s"]
            assert stored["frames"][n]["zarr"] == {"store": "dataset.zarr", "index": i, "burst_frame": n}
            drop = ("files", "zarr", "exr_compression")
            assert {k: v for k, v in stored["frames"][n].items() if k not in drop} == \
                {k: v for k, v in meta.items() if k not in drop}
        for a, b in zip(WrittenPairs(tmp_path / "files", burst=True, domain="raw", crop=(16, 12), seed=4)[i],
                        WrittenPairs(tmp_path / "zarr", burst=True, domain="raw", crop=(16, 12), seed=4)[i]):
            if isinstance(a, dict):
                assert np.array_equal(a["homography"], b["homography"]) and a["frames"] == b["frames"]
            else:
                assert np.array_equal(a, b)
    ds = xr.open_zarr(tmp_path / "zarr" / "dataset.zarr")
    assert (ds["noisy"].dims == ("frame", "burst_frame", "cfa", "y", "x")
            and ds["shake_px"].values.tolist() == [0.0, 1.2])
    summary = run_dataset(spec, tmp_path / "zarr", workers=1, progress=False, echo=None, output="zarr")
    assert summary["skipped"] == 2  # resumed: complete and verified
    mixed = write_spec(tmp_path, fixed="frame_interval_s = 0.02", grid="burst_frames = [2, 3]", w=32, h=24)
    with pytest.raises(Exception, match="needs one burst length"):
        run_dataset(mixed, tmp_path / "mixed", workers=1, progress=False, echo=None, output="zarr")


def test_a_bursts_rolling_shutter_and_flicker_reach_its_frames(tmp_path):
    """The spec's rolling_shutter_row_s and flicker keys (and a scene file's) reach each burst frame: on a flat field
    (no motion) each row's clean layer is the reference's times F_r = 1 + m/(ωT) (sin(ω(t_r + T)) − sin(ω t_r)),
    t_r = tᵢ + r Δ (this test's closed form), the sidecar lists the same factors, and the records carry the keys."""
    delta, f_hz, m, interval, exposure = 2e-4, 130.0, 0.5, 0.02, 0.01  # T: 1.3 periods
    spec = write_spec(tmp_path, fixed=f"burst_frames = 2\nframe_interval_s = {interval}\nrolling_shutter_row_s = "
                      f"{delta}\nflicker_depth = {m}", sequence=f"[sequence]\nframes = 2\nflicker_hz = {f_hz}")
    out = tmp_path / "out"
    run_dataset(spec, out, workers=1, progress=False, echo=None)
    line, = [json.loads(t) for t in (out / "manifest.jsonl").read_text().splitlines()]
    assert (line["rolling_shutter_row_s"], line["flicker_hz"], line["flicker_depth"]) == (delta, f_hz, m)
    _, reference, _ = read_exr(out / line["files"]["ref.exr"]["name"])
    omega = 2 * np.pi * f_hz
    for i in range(2):
        t = i * interval + np.arange(48) * delta
        factor = 1 + m / (omega * exposure) * (np.sin(omega * (t + exposure)) - np.sin(omega * t))
        sidecar = json.loads((out / line["files"][f"f00{i}.json"]["name"]).read_text())
        assert np.allclose(sidecar["flicker_row_factor"], factor, rtol=1e-9)
        _, clean, _ = read_exr(out / line["files"][f"f00{i}.exr"]["name"])
        # the dark charge is not modulated: clean − ref = (F_r − 1) · K g S̄, the flat field's signal alone (one value
        # for every row, but for the PRNU's 2 % averaged over a row's 64 pixels)
        signal = (clean - reference).mean(axis=(0, 2))[np.abs(factor - 1) > 0.005] / (factor - 1)[np.abs(factor - 1)
                                                                                                  > 0.005]
        assert np.ptp(factor) > 0.05 and signal.size > 20
        assert np.allclose(signal, signal.mean(), rtol=0.01) and signal.mean() > 0


# --- sRGB outputs of bursts: one development per burst, its reference's ---------------------------------------------

#: A flat field at moderate light (F = 0.8: 4× the shot-noise SNR of F = 0.05 at the same developed brightness, so
#: that the sRGB curve's bias on a noisy mean, about ½ |f''/f'| σ² ≈ 1 standard error here, stays well inside 5).
BRIGHT = FLAT.replace("reference_electrons = 8000", "reference_electrons = 300000").replace("[0.05]", "[0.8]")


def _srgb_to_linear(code: np.ndarray) -> np.ndarray:
    """The inverse of the IEC 61966-2-1 curve (this test's own), on values in [0, 1]."""
    code = code.astype(np.float64)
    return np.where(code <= 0.04045, code / 12.92, ((code + 0.055) / 1.055) ** 2.4)


def _burst_pngs(out, line) -> tuple[dict, dict]:
    """Every sRGB PNG of a burst by kind (``f000.srgb_noisy`` …, ``ref.srgb_clean``): values in [0, 1], and the ISP
    record each carries."""
    from camsim.isp import read_png_record
    from camsim.pairs import _read_png_planes

    images, records = {}, {}
    for kind, entry in line["files"].items():
        if ".srgb_" in kind:
            path = out / entry["name"]
            bits = line["srgb"]["bits"]
            images[kind] = _read_png_planes(path).astype(np.float64) / (2 ** bits - 1)
            records[kind] = read_png_record(path)
    return images, records


def test_a_static_bursts_srgb_frames_are_developed_as_its_reference(tmp_path):
    """A static burst (no motion, no flicker) with --srgb png16: files ID_fNNN_srgb_noisy.png, ID_fNNN_srgb_clean.png
    and ID_ref_srgb_clean.png listed in the manifest; every PNG carries the same ISP record (one development: the
    same white balance, matrix, gain 1/F and tone curve), the line's srgb record; each frame's noisy sRGB mean per
    channel over a flat region equals the reference's clean sRGB within 5 standard errors; each frame's own clean
    sRGB is the reference's (no motion: the same expectation); WrittenPairs reads the burst in the srgb domain."""
    spec = write_spec(tmp_path, fixed="burst_frames = 4\nframe_interval_s = 0.02", top='srgb = "png16"', w=96, h=64,
                      scene=BRIGHT)
    out = tmp_path / "out"
    run_dataset(spec, out, workers=1, progress=False, echo=None)
    line, = [json.loads(t) for t in (out / "manifest.jsonl").read_text().splitlines()]
    kinds = {f"f00{i}.srgb_{layer}" for i in range(4) for layer in ("noisy", "clean")} | {"ref.srgb_clean"}
    assert {k for k in line["files"] if ".srgb_" in k} == kinds
    for kind in kinds:
        suffix, _, layer = kind.partition(".")
        assert line["files"][kind]["name"] == f"frames/{line['id']}_{suffix}_{layer}.png"
        assert (out / line["files"][kind]["name"]).is_file()
    assert line["srgb"]["output"] == "png16" and line["srgb"]["bits"] == 16
    assert line["srgb"]["layers"] == {"frames": ["srgb_noisy", "srgb_clean"], "reference": ["srgb_clean"]}
    images, records = _burst_pngs(out, line)
    for kind, record in records.items():  # one development, recorded in every PNG and in the line
        assert record["isp"] == line["srgb"]["isp"] and record["layer"] == kind.partition(".")[2], kind
    isp = line["srgb"]["isp"]
    assert isp["stages"]["gain"]["value"] == pytest.approx(1 / 0.8) and isp["facts"]["intensity_factor"] == 0.8
    reference = images["ref.srgb_clean"]
    assert 0.2 < reference.mean() < 0.7 and reference.min() > 0.05 and reference.max() < 0.95  # no clipping
    region = (slice(None), slice(8, -8), slice(8, -8))  # away from the borders
    for i in range(4):
        assert np.allclose(images[f"f00{i}.srgb_clean"], reference, atol=2 / 65535)  # no motion, one development
        difference = (images[f"f00{i}.srgb_noisy"] - reference)[region].reshape(3, -1)
        standard_error = difference.std(axis=1) / np.sqrt(difference.shape[1])
        assert np.all(np.abs(difference.mean(axis=1)) < 5 * standard_error), (i, difference.mean(axis=1),
                                                                             standard_error)
        assert np.all(difference.std(axis=1) > 0.005)  # noisy indeed
    noisy, clean, meta = WrittenPairs(out, burst=True, domain="srgb")[0]
    assert noisy.shape == (4, 3, 64, 96) and clean.shape == (3, 64, 96) and meta["isp"] == isp
    assert np.array_equal(clean, reference.astype(np.float32)) and meta["domain"] == "srgb"
    assert np.array_equal(noisy[3], images["f003.srgb_noisy"].astype(np.float32))
    noisy, clean, meta = WrittenPairs(out, burst=True, domain="srgb", crop=(32, 16), seed=1)[0]
    x, y, _, _ = meta["crop"]
    assert noisy.shape == (4, 3, 16, 32) and np.array_equal(clean, reference[:, y:y + 16, x:x + 32].astype(np.float32))


def test_a_flickering_bursts_srgb_frames_differ_as_their_light(tmp_path):
    """A burst under a flickering light (global shutter: frame i's light is F_i = 1 + m/(ωT) (sin(ω(tᵢ + T)) −
    sin(ω tᵢ)) of the steady light, this test's closed form), developed once, the reference's way: every PNG's ISP
    record is the same, and the frames' clean sRGB, back to linear (this test's inverse of the sRGB curve), differ
    from the reference's as their light does: mean(linᵢ − lin_ref) / mean(linⱼ − lin_ref) = (Fᵢ − 1) / (Fⱼ − 1) (the
    unmodulated dark charge cancels in the differences; white balance, matrix and gain are linear)."""
    f_hz, m, interval, exposure = 55.0, 0.5, 0.013, 0.01  # F_i: 0.955, 1.285, 0.920, 0.750
    spec = write_spec(tmp_path, fixed=f"burst_frames = 4\nframe_interval_s = {interval}\nflicker_hz = {f_hz}\n"
                      f"flicker_depth = {m}", top='srgb = "png16"', w=64, h=48, scene=BRIGHT)
    out = tmp_path / "out"
    run_dataset(spec, out, workers=1, progress=False, echo=None)
    line, = [json.loads(t) for t in (out / "manifest.jsonl").read_text().splitlines()]
    images, records = _burst_pngs(out, line)
    assert len(records) == 9 and all(r["isp"] == line["srgb"]["isp"] for r in records.values())
    omega = 2 * np.pi * f_hz
    t = np.arange(4) * interval
    factor = 1 + m / (omega * exposure) * (np.sin(omega * (t + exposure)) - np.sin(omega * t))
    assert np.all(np.abs(factor - 1) > 0.04)
    assert max(images[f"f00{i}.srgb_clean"].max() for i in range(4)) < 0.99  # no clipping
    reference = _srgb_to_linear(images["ref.srgb_clean"])
    change = np.array([(_srgb_to_linear(images[f"f00{i}.srgb_clean"]) - reference).mean(axis=(1, 2))
                       for i in range(4)])  # (frame, channel)
    last = int(np.argmax(np.abs(factor - 1)))
    for i in range(4):
        assert np.allclose(change[i] / change[last], (factor[i] - 1) / (factor[last] - 1), rtol=2e-3), i
    assert np.all(np.abs(change) > 0.005)  # the frames do differ


def test_resuming_a_half_written_srgb_burst_dataset(tmp_path, monkeypatch):
    """As test_resuming_a_half_written_burst_dataset with --srgb: the resumed run's files, the PNGs among them,
    equal an uninterrupted run's byte for byte; a damaged PNG of a complete burst is rendered again."""
    import camsim.dataset.frame_render as frame_render

    spec = write_spec(tmp_path, fixed="burst_frames = 3\nframe_interval_s = 0.02", grid="shake_px = [0.0, 0.7]",
                      top='srgb = "png"', w=32, h=24)
    check_resuming_after_a_death_in_the_second_burst(spec, tmp_path, monkeypatch, frame_render, "write_frame",
                                                     damage="f001_srgb_noisy.png")
    assert sum(1 for p in (tmp_path / "out" / "frames").glob("*_srgb_*.png")) == 2 * 7


def test_a_burst_dataset_gains_its_srgb_outputs_when_run_again_with_srgb(tmp_path):
    """A burst dataset written without --srgb gets its sRGB PNGs when run again with it: the bursts are rendered
    again, their EXRs the same bytes."""
    spec = write_spec(tmp_path, fixed="burst_frames = 2\nframe_interval_s = 0.02", w=32, h=24)
    out = tmp_path / "out"
    run_dataset(spec, out, workers=1, progress=False, echo=None)
    before = _hashes(out)
    summary = run_dataset(spec, out, workers=1, progress=False, echo=None, srgb="png")
    assert summary["rendered"] == 1
    after = _hashes(out)
    assert {k: v for k, v in after.items() if k in before and not k.endswith(".done")} == \
        {k: v for k, v in before.items() if not k.endswith(".done")}
    assert sorted(k for k in after if k not in before) == sorted(
        f"{load_spec(spec).frames[0].id}_{name}.png" for name in
        ("f000_srgb_noisy", "f000_srgb_clean", "f001_srgb_noisy", "f001_srgb_clean", "ref_srgb_clean"))
    assert run_dataset(spec, out, workers=1, progress=False, echo=None, srgb="png")["skipped"] == 1


def test_a_burst_store_with_srgb_holds_the_files_pngs(tmp_path):
    """--format zarr --srgb png with Bayer bursts: the store's srgb_noisy and srgb_clean (frame, burst_frame, channel,
    y, x) hold each frame's PNG codes of the file layout, srgb_reference the reference's, and the records the same
    srgb record; WrittenPairs reads the same srgb bursts from both; a re-run skips the complete bursts."""
    import zarr

    from camsim.isp import read_png_record
    from camsim.pairs import _read_png_planes

    spec = write_spec(tmp_path, fixed="burst_frames = 3\nframe_interval_s = 0.02\ncfa = \"RGGB\"",
                      grid="shake_px = [0.0, 1.2]", top='srgb = "png"', w=32, h=24, scene=TEXTURED)
    run_dataset(spec, tmp_path / "files", workers=1, progress=False, echo=None)
    run_dataset(spec, tmp_path / "zarr", workers=1, progress=False, echo=None, output="zarr")
    group = zarr.open_group(tmp_path / "zarr" / "dataset.zarr", mode="r")
    assert group["srgb_noisy"].shape == (2, 3, 3, 24, 32) and group["srgb_reference"].shape == (2, 3, 24, 32)
    assert group["srgb_reference"].dtype == np.uint8
    files = [json.loads(t) for t in (tmp_path / "files" / "manifest.jsonl").read_text().splitlines()]
    stored = [json.loads(t) for t in (tmp_path / "zarr" / "manifest.jsonl").read_text().splitlines()]
    for i, (line, record) in enumerate(zip(files, stored)):
        assert record["srgb"] == line["srgb"]
        for n in range(3):
            for layer in ("srgb_noisy", "srgb_clean"):
                path = tmp_path / "files" / line["files"][f"f00{n}.{layer}"]["name"]
                assert np.array_equal(group[layer][i, n], _read_png_planes(path))
                assert read_png_record(path)["isp"] == record["srgb"]["isp"]
        reference = _read_png_planes(tmp_path / "files" / line["files"]["ref.srgb_clean"]["name"])
        assert np.array_equal(group["srgb_reference"][i], reference)
        if i == 1:  # the shaken burst: its frames' clean layers are not the reference's
            assert not np.array_equal(group["srgb_clean"][i, 2], reference)
        for a, b in zip(WrittenPairs(tmp_path / "files", burst=True, domain="srgb", crop=(16, 12), seed=4)[i],
                        WrittenPairs(tmp_path / "zarr", burst=True, domain="srgb", crop=(16, 12), seed=4)[i]):
            if isinstance(a, dict):
                assert a["crop"] == b["crop"] and a["isp"] == b["isp"] and np.array_equal(a["homography"],
                                                                                           b["homography"])
            else:
                assert np.array_equal(a, b) and a.dtype == np.float32
    summary = run_dataset(spec, tmp_path / "zarr", workers=1, progress=False, echo=None, output="zarr")
    assert summary["skipped"] == 2
