"""Temporal analysis of sequences (``camsim analyze`` → ``temporal.csv``, :mod:`camsim.analysis.temporal`).

Independent references, computed here from the sensor's parameters alone:

* the flat grey target's G signal: the scale anchor puts the perfect white's G at 8000 e⁻ at F = 1 and T = 1 s, so
  a reflectance of 0.5 at F = 0.5 gives S = 2000 e⁻; D = 230 e⁻/s · 1 s;
* temporal variance of a pixel over frames: k² (S + D + σ_read² + σ_row²) + 1/12 DN² (Poisson charge, Gaussian read
  and row noise, the quantiser's uniform error); for R and B, whose S needs the spectra, S + D is taken from the
  frames' own mean DN, (DN + ½) / k (Eq. 11's floor, no pedestal);
* spatial variance, its expectation over sensors: k² (σ_DSNU² + (S σ_PRNU)²) (an offset o and a gain g on the
  mean signal, independent per pixel); 0 without a fixed pattern.

Each is compared within a few of the analysis's own standard errors.
"""

import csv
import json
import shutil

import numpy as np
import pytest

from camsim.analysis.columns import guide_text
from camsim.analysis.temporal import find_sequences, stack_moments
from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.render.frame_files import load_frame, write_frame
from camsim.render.pipeline import scene_frame

K = 0.5  # DN/e⁻: G_Ve⁻ 0.0002 V/e⁻ × 2500 DN/V
READ_E, ROW_E, DSNU_E, PRNU = 4.0, 5.0, 10.0, 0.01
S_G, D_G = 2000.0, 230.0
N = 8

FLAT = """
name = "flat"
[spectral]
start_nm = 400
end_nm = 700
step_nm = 10
[target]
kind = "flat"
reflectance = 0.5
[light]
illuminants = ["D65"]
intensity_factors = [0.5]
luminance_cd_m2 = 100
[frame]
width = 64
height = 48
[sensor]
analog_gain_dn_per_v = 2500.0
bits = 12
read_noise_e = 4.0
row_noise_e = 5.0
"""


def _scene(tmp_path, **sensor):
    from camsim.scene.scene_file import load_scene

    path = tmp_path / "flat.toml"
    path.write_text(FLAT, encoding="utf-8")
    return load_scene(path).with_sensor(**sensor)


def _render(scene, out, seeds, stem="flat"):
    for seed in seeds:
        frame, info = scene_frame(scene, "D65", 0.5, seed=seed)
        write_frame(out, f"{stem}_s{seed}", frame, info)


def _analyze(folder, out) -> list[dict]:
    assert main(["analyze", str(folder), "--out", str(out), "--no-figures", "-q"]) == 0
    path = out / "temporal.csv"
    if not path.exists():
        return []
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def _row(rows, region, channel):
    return next(r for r in rows if r["region"] == region and r["channel"] == channel)


def _f(row, key):
    return float(row[key])


@pytest.fixture(scope="module")
def pattern_sequence(tmp_path_factory):
    """N frames of a flat grey field from one sensor with DSNU, PRNU, read, row and shot noise, analysed."""
    tmp = tmp_path_factory.mktemp("seq")
    scene = _scene(tmp, dsnu_e=DSNU_E, prnu_percent=100 * PRNU, sensor_seed=7)
    _render(scene, tmp / "frames", range(N))
    return tmp / "frames", _analyze(tmp / "frames", tmp / "analysis")


def test_temporal_and_spatial_variances_match_the_closed_forms(pattern_sequence):
    folder, rows = pattern_sequence
    assert {r["n_frames"] for r in rows} == {str(N)}
    temporal = K**2 * (S_G + D_G + READ_E**2 + ROW_E**2) + 1 / 12
    spatial = K**2 * (DSNU_E**2 + (S_G * PRNU) ** 2)
    for region in ("flat", "frame"):
        g = _row(rows, region, "G")
        assert abs(_f(g, "temporal_var_dn2") - temporal) < 4 * _f(g, "temporal_var_se_dn2"), g
        assert abs(_f(g, "spatial_var_dn2") - spatial) < 4 * _f(g, "spatial_var_se_dn2"), g
        assert _f(g, "spatial_model_dn2") == pytest.approx(spatial, rel=1e-9)
        assert _f(g, "temporal_model_dn2") == pytest.approx(temporal, rel=0.01)  # its S + D from the clean layer
        assert g["spatial_model_terms"] == "dsnu_e prnu_percent" and g["spatial_not_modelled"] == ""
        # the standard errors are of the size the estimators' theory gives (Gaussian-like noise)
        n = int(g["n_pixels"])
        assert _f(g, "temporal_var_se_dn2") == pytest.approx(temporal * np.sqrt(2 / (n * (N - 1))), rel=0.35)
    # R and B: S + D from the frames' own mean
    frames = [load_frame(p) for p in sorted(folder.glob("*.dng"))]
    for c, channel in ((0, "R"), (2, "B")):
        mean_e = np.mean([f.pixels_dn[c].astype(float) + 0.5 for f in frames]) / K
        row = _row(rows, "flat", channel)
        expected = K**2 * (mean_e + READ_E**2 + ROW_E**2) + 1 / 12
        assert abs(_f(row, "temporal_var_dn2") - expected) < 4 * _f(row, "temporal_var_se_dn2"), row
        signal = mean_e - float(frames[0].meta["dark_current_e_per_s"][c])
        spatial_c = K**2 * (DSNU_E**2 + (signal * PRNU) ** 2)
        assert abs(_f(row, "spatial_var_dn2") - spatial_c) < 4 * _f(row, "spatial_var_se_dn2"), row


def test_bayer_sites_of_one_colour(tmp_path):
    """A Bayer sequence: each channel is its own sites (G: half the pixels), with the same closed forms."""
    _render(_scene(tmp_path, cfa="RGGB", dsnu_e=DSNU_E, prnu_percent=100 * PRNU), tmp_path / "frames", range(N))
    rows = _analyze(tmp_path / "frames", tmp_path / "analysis")
    g = _row(rows, "frame", "G")
    assert int(g["n_pixels"]) == 64 * 48 // 2 and int(_row(rows, "frame", "R")["n_pixels"]) == 64 * 48 // 4
    temporal = K**2 * (S_G + D_G + READ_E**2 + ROW_E**2) + 1 / 12
    spatial = K**2 * (DSNU_E**2 + (S_G * PRNU) ** 2)
    assert abs(_f(g, "temporal_var_dn2") - temporal) < 4 * _f(g, "temporal_var_se_dn2"), g
    assert abs(_f(g, "spatial_var_dn2") - spatial) < 4 * _f(g, "spatial_var_se_dn2"), g
    assert abs(_f(g, "spatial_var_dn2") - _f(g, "spatial_clean_dn2")) < 3 * _f(g, "spatial_var_se_dn2"), g


def test_spatial_variance_is_this_sensors_clean_pattern(pattern_sequence):
    """Against the realised pattern (the clean layer's variance) the spatial estimate is closer still."""
    _, rows = pattern_sequence
    for row in rows:
        assert abs(_f(row, "spatial_var_dn2") - _f(row, "spatial_clean_dn2")) < 3 * _f(row, "spatial_var_se_dn2")


def test_without_a_fixed_pattern_the_spatial_variance_is_zero(tmp_path):
    _render(_scene(tmp_path), tmp_path / "frames", range(6))
    rows = _analyze(tmp_path / "frames", tmp_path / "analysis")
    assert len(rows) == 6  # (the flat patch, the frame) × 3 channels
    for row in rows:
        assert abs(_f(row, "spatial_var_dn2")) < 3 * _f(row, "spatial_var_se_dn2"), row
        assert _f(row, "spatial_model_dn2") == 0.0 and row["spatial_model_terms"] == ""
        # the mean image's variance is the temporal noise left in it: σ²_temp / N
        assert _f(row, "mean_image_var_dn2") == pytest.approx(_f(row, "temporal_var_dn2") / 6, rel=0.2)


def test_frames_of_two_sensors_are_not_grouped(tmp_path):
    folder = tmp_path / "frames"
    _render(_scene(tmp_path, sensor_seed=0, dsnu_e=5.0), folder, range(3), stem="a")
    _render(_scene(tmp_path, sensor_seed=1, dsnu_e=5.0), folder, range(2), stem="b")
    _render(_scene(tmp_path, sensor_seed=2, dsnu_e=5.0), folder, [9], stem="c")  # alone: no sequence
    rows = _analyze(folder, tmp_path / "analysis")
    sequences = {(r["sensor_seed"], r["n_frames"], r["first_frame"].rsplit("/", 1)[-1]) for r in rows}
    assert sequences == {("0", "3", "a_s0.dng"), ("1", "2", "b_s0.dng")}


def test_no_sequence_leaves_the_outputs_as_they_were(tmp_path):
    folder = tmp_path / "frames"
    _render(_scene(tmp_path), folder, [1])
    _render(_scene(tmp_path, read_noise_e=3.0), folder, [1], stem="other")  # another sensor: no sequence
    out = tmp_path / "analysis"
    assert _analyze(folder, out) == []
    assert not (out / "temporal.csv").exists()
    assert "temporal" not in json.loads((out / "analysis.json").read_text(encoding="utf-8"))
    assert (out / "README.txt").read_text(encoding="utf-8") == guide_text([])


def test_every_temporal_column_is_explained(pattern_sequence):
    folder, rows = pattern_sequence
    text = guide_text([], temporal=True)
    for column in rows[0]:
        assert f"  {column}: " in text


def test_a_copied_frame_is_left_out_with_one_line(tmp_path, capsys):
    folder = tmp_path / "frames"
    _render(_scene(tmp_path), folder, range(3))
    for suffix in (".dng", ".exr", ".json", ".dng.xmp"):
        shutil.copy(folder / f"flat_s2{suffix}", folder / f"flat_s2copy{suffix}")
    sidecar = folder / "flat_s2copy.json"
    meta = json.loads(sidecar.read_text(encoding="utf-8"))
    meta["files"] = {k: v.replace("flat_s2", "flat_s2copy") for k, v in meta["files"].items()}
    sidecar.write_text(json.dumps(meta), encoding="utf-8")
    capsys.readouterr()
    rows = _analyze(folder, tmp_path / "analysis")
    assert {r["n_frames"] for r in rows} == {"3"}
    warnings = [line for line in capsys.readouterr().err.splitlines() if "same scene, sensor and seed" in line]
    assert len(warnings) == 1 and warnings[0].startswith("camsim: warning: ")


def test_sequence_frames_by_frame_index_and_motion(tmp_path):
    """The other kind of sequence: frames of one ``sequence`` stem told apart by ``frame_index``; one that moves
    (a homography other than the identity) is left out with one line."""
    folder = tmp_path / "frames"
    _render(_scene(tmp_path), folder, range(3))
    metas = []
    for i, path in enumerate(sorted(folder.glob("*.json"))):
        meta = json.loads(path.read_text(encoding="utf-8"))
        meta.update(seed=0, sequence={"stem": "flat"}, frame_index=i, homography=np.eye(3).tolist())
        path.write_text(json.dumps(meta), encoding="utf-8")
        metas.append(meta)
    found = find_sequences(sorted(folder.glob("*.dng")))
    assert len(found) == 1 and [m["frame_index"] for m in found[0].metas] == [0, 1, 2]
    meta = metas[2] | {"homography": [[1, 0, 0.5], [0, 1, 0], [0, 0, 1]]}
    (folder / "flat_s2.json").write_text(json.dumps(meta), encoding="utf-8")
    lines = []
    assert find_sequences(sorted(folder.glob("*.dng")), warn=lines.append) == []
    assert len(lines) == 1 and "moves" in lines[0] and "\n" not in lines[0]
    # a rolling shutter's row homographies move too; a flickering light is no steady one (a factor of 1 is)
    rows = metas[2]["height_px"]
    for extra, says in [({"row_homographies": [np.eye(3).tolist()] * (rows - 1) + [[[1, 0, 0.5], [0, 1, 0],
                                                                                    [0, 0, 1]]]}, "moves"),
                        ({"flicker_factor": 1.02}, "flicker"),
                        ({"flicker_row_factor": [1.0] * (rows - 1) + [0.97]}, "flicker")]:
        (folder / "flat_s2.json").write_text(json.dumps(metas[2] | extra), encoding="utf-8")
        lines = []
        assert find_sequences(sorted(folder.glob("*.dng")), warn=lines.append) == []
        assert len(lines) == 1 and says in lines[0] and "\n" not in lines[0], lines
    (folder / "flat_s2.json").write_text(json.dumps(metas[2] | {"flicker_factor": 1.0,
                                                                "row_homographies": [np.eye(3).tolist()] * rows}))
    assert len(find_sequences(sorted(folder.glob("*.dng")))) == 1


def test_stack_errors_are_one_line():
    with pytest.raises(CamsimError) as one:
        stack_moments([np.zeros((1, 4, 4))])
    with pytest.raises(CamsimError) as shapes:
        stack_moments([np.zeros((1, 4, 4)), np.zeros((1, 4, 5))])
    for exc in (one, shapes):
        assert "\n" not in str(exc.value)


def test_stack_moments_are_exact():
    rng = np.random.default_rng(3)
    frames = rng.integers(0, 4096, size=(5, 3, 6, 7)).astype(np.uint16)
    stack = stack_moments(iter(frames))
    np.testing.assert_allclose(stack.mean_dn, frames.mean(axis=0), rtol=0, atol=1e-9)
    np.testing.assert_allclose(stack.var_dn2, frames.astype(float).var(axis=0, ddof=1), rtol=1e-12)
