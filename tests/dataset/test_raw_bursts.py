"""Bursts of ``[raws]`` crops (issue 29, point 4, for real raws): ``burst_frames`` with ``ratio`` and shake makes each
item a raw scene's burst (camsim.render.raw_sequence's frames), written ID_fNNN.dng/.exr/.json and ID_ref.exr/.json,
read back by WrittenPairs(burst=True). Checked against our own closed forms on phone-style DNGs
(tests/support/phone_dng.py): the reference is the flipped crop of the file made dark by the ratio, each frame's
homography moves the reference onto its clean layer in the files' own (flipped) pixels (our own phase correlation), the
frames' noise about their clean layers is independent (pairwise correlation within 3/√N); ``thin`` with motion refused
on one line; resuming."""

import json
from pathlib import Path

import numpy as np
import pytest

from camsim.cli import main
from camsim.dataset.runner import run_dataset
from camsim.io.exr import read_exr
from camsim.pairs import WrittenPairs
from tests.dataset.test_bursts import check_resuming_after_a_death_in_the_second_burst
from tests.render.test_sequence import _phase_shift
from tests.support.phone_dng import write_phone_dng

T_SOURCE = 0.5  # the source files' exposure (s)
BLACK_SOURCE = 512.0
SIZE = (66, 50)  # the files' width, height: the crop, its flips' spare and a cell more (the blob inside)
CROP = (64, 48)

SPEC = """
name = "rawburst"
seed = {seed}
[raws]
folder = "raws"
crop = [{w}, {h}]
flips = true
{raws}
[fixed]
burst_frames = 3
frame_interval_s = 0.01
shake_px = 1.5
pan_x_px_per_s = 120.0
pan_y_px_per_s = -70.0
ratio = 100.0
prnu_percent = 0.0
dsnu_e = 0.0
dark_current = false
row_noise_e = 0.0
{fixed}
[random]
count = {count}
"""


def source_mosaic(seed: int = 1) -> np.ndarray:
    """A smooth blob (so that a shift shows, and bilinear interpolation is near exact) with a little noise of its
    own (a real file's), DN above black up to about 9000."""
    width, height = SIZE
    y, x = np.mgrid[0:height, 0:width]
    blob = 400 + 8000 * np.exp(-((x - 33.0) ** 2 + (y - 25.0) ** 2) / (2 * 6.0 ** 2))
    noise = np.random.default_rng(seed).normal(0, 15, blob.shape)
    return np.rint(BLACK_SOURCE + blob + noise).astype(np.uint16)


def make_spec(tmp_path: Path, *, seed=4, count=4, raws="", fixed="", crop=CROP) -> Path:
    (tmp_path / "raws").mkdir(exist_ok=True)
    write_phone_dng(tmp_path / "raws" / "a.dng", source_mosaic(), pattern="RGGB", black_per_site=[BLACK_SOURCE] * 4,
                    white=16383, iso=100, exposure_s=T_SOURCE, make="SONY", model="ILCE-7SM2",
                    unique_camera_model="Sony ILCE-7SM2")
    path = tmp_path / "spec.toml"
    path.write_text(SPEC.format(seed=seed, w=crop[0], h=crop[1], count=count, raws=raws, fixed=fixed))
    return path


def site_plane(planes: np.ndarray, pattern: str = "RGGB") -> np.ndarray:
    """Our own mosaic of planes (3, H, W): each site's own colour's plane."""
    index = {"R": 0, "G": 1, "B": 2}
    out = np.empty(planes.shape[1:], planes.dtype)
    for k, letter in enumerate(pattern):
        dy, dx = divmod(k, 2)
        out[dy::2, dx::2] = planes[index[letter], dy::2, dx::2]
    return out


def test_a_raws_burst_renders_its_frames_and_reference_as_the_closed_form(tmp_path):
    """Each item: ID_ref.exr/.json and 3 × ID_fNNN.dng/.exr/.json, the manifest's burst; the reference's clean
    mosaic is the window of the file as recorded, mirrored as recorded, made 100 times darker (the same gain K
    source and target: sony-a7s2 both): (DN − black_s) / ratio (the EXR's DN, before the ADC's pedestal), to
    float32."""
    spec = make_spec(tmp_path)
    out = tmp_path / "out"
    run_dataset(spec, out, workers=1, progress=False, echo=None)
    lines = [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines()]
    assert len(lines) == 4
    mosaic = source_mosaic().astype(np.float64)
    flips = set()
    pairs = WrittenPairs(out, burst=True)
    for i, line in enumerate(lines):
        assert line["burst"] == {"frames": ["f000", "f001", "f002"], "reference": "ref"}
        assert (line["burst_frames"], line["shake_px"], line["ratio"], line["exposure_s"]) == (3, 1.5, 100.0, 0.005)
        kinds = {"ref.exr", "ref.json", *(f"f00{n}.{k}" for n in range(3) for k in ("dng", "exr", "json"))}
        assert kinds <= set(line["files"])
        for kind in kinds:
            assert (out / line["files"][kind]["name"]).is_file()
        noisy, clean, meta = pairs[i]
        assert noisy.shape == (3, 1, CROP[1], CROP[0]) and clean.shape == (1, CROP[1], CROP[0])
        x, y, fh, fv = line["crop_x"], line["crop_y"], line["flip_horizontal"], line["flip_vertical"]
        window = mosaic[y:y + CROP[1], x:x + CROP[0]]
        window = window[::-1 if fv else 1, ::-1 if fh else 1]
        expected = (window - BLACK_SOURCE) / 100.0  # the EXR's layers: DN before the ADC's pedestal
        np.testing.assert_allclose(clean[0], expected, rtol=2e-6)
        flips.add((fh, fv))
        for n in range(3):
            frame = json.loads((out / "frames" / f"{line['id']}_f00{n}.json").read_text())
            assert frame["frame_index"] == n and frame["sequence"]["stem"] == line["id"]
            assert frame["raw_source"]["flip_horizontal"] == fh and frame["raw_source"]["crop_xywh"] == \
                [x, y, *CROP]
    assert len(flips) > 1  # mirrored and not: the flips come before the motion (next test)


def test_each_frames_homography_moves_the_flipped_reference_onto_its_clean_layer(tmp_path):
    """Shake and pan: frame n's clean layer is the reference shifted by meta["homography"][n]'s translation, in the
    files' pixels, flipped items too (our own phase correlation on the green plane, within 0.05 px). Were the flip
    applied after the motion, a flipped axis would move the other way."""
    spec = make_spec(tmp_path)
    out = tmp_path / "out"
    run_dataset(spec, out, workers=1, progress=False, echo=None)
    pairs = WrittenPairs(out, burst=True)
    flipped = 0
    for i in range(len(pairs)):
        _, _, meta = pairs[i]
        line = meta["record"]
        reference = read_exr(out / "frames" / f"{line['id']}_ref.exr")[1][1].astype(np.float64)
        flipped += line["flip_horizontal"] or line["flip_vertical"]
        moved = 0.0
        for n in range(3):
            clean = read_exr(out / "frames" / f"{line['id']}_f00{n}.exr")[1][1].astype(np.float64)
            dx, dy = _phase_shift(reference, clean)
            tx, ty = meta["homography"][n][:2, 2]
            assert meta["homography"][n][:2, :2] == pytest.approx(np.eye(2), abs=1e-12)  # shake_deg 0: translations
            assert abs(dx - tx) < 0.05 and abs(dy - ty) < 0.05, (i, n, dx, dy, tx, ty)
            moved = max(moved, abs(tx), abs(ty))
        assert moved > 0.5
    assert flipped


def test_the_frames_noise_is_independent_about_their_clean_layers(tmp_path):
    """Each frame's noisy mosaic minus its own clean layer (at its sites): zero mean and pairwise uncorrelated
    between frames of a burst (|ρ| < 3/√N, N sites; the source's own noise is in the clean layers, common, and
    out of the residuals). Tried once with every frame drawn from the first frame's seed: ρ ≈ 1, fails."""
    spec = make_spec(tmp_path, count=1, fixed="burst_frames = 4")
    spec.write_text(spec.read_text().replace("burst_frames = 3\n", ""))
    out = tmp_path / "out"
    run_dataset(spec, out, workers=1, progress=False, echo=None)
    line = json.loads((out / "manifest.jsonl").read_text().splitlines()[0])
    residuals = []
    for n in range(4):
        noisy, clean, _ = read_exr(out / "frames" / f"{line['id']}_f00{n}.exr")
        r = (noisy[0].astype(np.float64) - site_plane(clean.astype(np.float64))).ravel()
        residuals.append(r)
        assert abs(r.mean()) < 3 * r.std() / np.sqrt(r.size)
        assert r.std() > 0.3  # noise there (≥ 40 e⁻ a site, K ≈ 0.1 DN/e⁻: ≥ 0.6 DN of shot noise)
    bound = 3 / np.sqrt(residuals[0].size)
    for a in range(4):
        for b in range(a + 1, 4):
            rho = np.corrcoef(residuals[a], residuals[b])[0, 1]
            assert abs(rho) < bound, (a, b, rho, bound)


def test_rolling_shutter_and_flicker_are_recorded_and_reach_the_frames(tmp_path):
    spec = make_spec(tmp_path, count=1, fixed="rolling_shutter_row_s = 0.00005\nflicker_hz = 100.0\n"
                                              "flicker_depth = 0.3")
    out = tmp_path / "out"
    run_dataset(spec, out, workers=1, progress=False, echo=None)
    line = json.loads((out / "manifest.jsonl").read_text().splitlines()[0])
    assert (line["rolling_shutter_row_s"], line["flicker_hz"], line["flicker_depth"]) == (0.00005, 100.0, 0.3)
    frame = json.loads((out / "frames" / f"{line['id']}_f001.json").read_text())
    assert frame["sequence"]["rolling_shutter_row_s"] == 0.00005 and frame["sequence"]["flicker_hz"] == 100.0


def test_thin_with_motion_is_refused_on_one_line_and_a_static_thin_burst_renders(tmp_path, capsys):
    spec = make_spec(tmp_path, count=1, raws='photon_law = "thin"')
    for dry in (("--dry-run",), ()):
        code = main(["dataset", str(spec), "--out", str(tmp_path / "out"), "--workers", "1", "-q", *dry])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and err.startswith("camsim: error:"), err
        assert "photon_law = 'thin' cannot move" in err and "a burst without motion" in err, err
    assert not (tmp_path / "out" / "frames").exists() or not any((tmp_path / "out" / "frames").iterdir())
    text = spec.read_text()
    for key in ("shake_px = 1.5\n", "pan_x_px_per_s = 120.0\n", "pan_y_px_per_s = -70.0\n"):
        text = text.replace(key, "")
    spec.write_text(text)
    assert main(["dataset", str(spec), "--out", str(tmp_path / "out"), "--workers", "1", "-q"]) == 0
    spec.write_text(text.replace("[fixed]\n", "[fixed]\nflicker_hz = 100.0\nflicker_depth = 0.5\n"))
    code = main(["dataset", str(spec), "--dry-run"])
    err = capsys.readouterr().err
    assert code == 2 and "cannot follow a flickering light" in err and err.count("\n") == 1, err


def test_a_raws_burst_timing_and_zarr_are_refused_on_one_line(tmp_path, capsys):
    spec = make_spec(tmp_path, count=1, fixed="frame_interval_s = 0.001")
    spec.write_text(spec.read_text().replace("frame_interval_s = 0.01\n", ""))
    code = main(["dataset", str(spec), "--dry-run"])
    err = capsys.readouterr().err
    assert code == 2 and "longer than frame_interval_s" in err and err.count("\n") == 1, err
    spec = make_spec(tmp_path, count=1)
    code = main(["dataset", str(spec), "--out", str(tmp_path / "z"), "--format", "zarr", "-q"])
    err = capsys.readouterr().err
    assert code == 2 and "--format zarr" in err and err.count("\n") == 1, err


def test_resuming_a_half_written_raws_burst_dataset(tmp_path, monkeypatch):
    """A run that dies inside the second burst (its reference and first frame written) leaves the first complete; a
    re-run renders the second only, byte for byte an uninterrupted run's; a damaged frame file is rendered again."""
    import camsim.render.raw_render as raw_render

    check_resuming_after_a_death_in_the_second_burst(make_spec(tmp_path, count=2), tmp_path, monkeypatch, raw_render,
                                                     "write_raw_frame")


def test_the_common_source_noise_is_warned_of_on_one_line(tmp_path, capsys):
    """At ratio 2 (f = 0.5) the source's own photon noise is f / (1 + f) = 1/3 of a frame's shot-noise variance,
    common to every frame: one warning line; at ratio 100 (f = 0.01, 0.99 %) none."""
    spec = make_spec(tmp_path, count=1)
    assert main(["dataset", str(spec), "--out", str(tmp_path / "quiet"), "--workers", "1", "-q"]) == 0
    assert capsys.readouterr().err == ""
    spec.write_text(spec.read_text().replace("ratio = 100.0", "ratio = 2.0").replace("frame_interval_s = 0.01",
                                                                                     "frame_interval_s = 0.3"))
    assert main(["dataset", str(spec), "--out", str(tmp_path / "out"), "--workers", "1", "-q"]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("camsim: warning: bursts of [raws] crops"), err
    assert "at f = 0.5, about 33.3 %" in err, err


def test_saturated_sites_make_moving_masks_listed_and_verified(tmp_path):
    """A saturated patch in the file: every frame and the reference have ID_<frame>_mask.png, listed in the record
    (``f000.mask`` …) and verified on a re-run (nothing rendered again)."""
    spec = make_spec(tmp_path, count=1)
    mosaic = source_mosaic()
    mosaic[20:30, 25:40] = 16383
    write_phone_dng(tmp_path / "raws" / "a.dng", mosaic, pattern="RGGB", black_per_site=[BLACK_SOURCE] * 4,
                    white=16383, iso=100, exposure_s=T_SOURCE, make="SONY", model="ILCE-7SM2",
                    unique_camera_model="Sony ILCE-7SM2")
    out = tmp_path / "out"
    run_dataset(spec, out, workers=1, progress=False, echo=None)
    line = json.loads((out / "manifest.jsonl").read_text().splitlines()[0])
    for suffix in ("ref", "f000", "f001", "f002"):
        assert (out / line["files"][f"{suffix}.mask"]["name"]).is_file()
        meta = json.loads((out / "frames" / f"{line['id']}_{suffix}.json").read_text())
        assert meta["raw_source"]["masked_px"] > 0
    summary = run_dataset(spec, out, workers=1, progress=False, echo=None)
    assert (summary["skipped"], summary["rendered"]) == (1, 0)
