"""Sequences with camera motion (issue 29): temporal independence, the fixed pattern, geometry against our own phase
correlation, motion blur against the closed form of a panned edge, a static sequence against camsim render, and
one-line errors."""

import json

import numpy as np
import pytest

from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.render.pipeline import light_scene, scene_frame
from camsim.render.raw_frame import render_expectation_frame
from camsim.render.sequence import moving_expectation, render_sequence_frames
from camsim.scene.scene_file import load_scene
from camsim.scene.sequence import Motion, SequenceParams, parse_sequence
from camsim.sensor.params import SensorParams
from tests.support.helpers import patch_pixels, small_scene

FLAT = """
name = "flatseq"
[target]
kind = "flat"
reflectance = 0.5
[light]
illuminants = ["D65"]
intensity_factors = [0.05]
[frame]
width = {w}
height = {h}
[camera.scale]
kind = "anchor"
reference_electrons = 8000
[sensor]
preset = "emva-12bit"
exposure_s = 1.0
prnu_percent = 2
dsnu_e = 3
{sensor}
[sequence]
{sequence}
"""


def flat_scene(tmp_path, sequence, sensor="", w=96, h=64):
    path = tmp_path / "s.toml"
    path.write_text(FLAT.format(w=w, h=h, sensor=sensor, sequence=sequence))
    return load_scene(path)


def frames_of(scene):
    lit = light_scene(scene, "D65")
    from camsim.render.pipeline import frame_sensor

    sensor = frame_sensor(scene, lit, scene.intensity_factors[0])
    return list(render_sequence_frames(scene, lit, sensor, scene.intensity_factors[0], workers=1))


@pytest.mark.parametrize("cfa", ['cfa = "RGGB"', ""])
def test_temporal_independence_and_fixed_pattern(tmp_path, cfa):
    scene = flat_scene(tmp_path, "frames = 3\nframe_interval_s = 1.0\nshake_px = 0.3", sensor=cfa, w=128, h=96)
    out = frames_of(scene)
    assert out[0][0] == "ref" and [o[0] for o in out[1:]] == [0, 1, 2]
    frames = [o[1] for o in out[1:]]
    residuals = []
    for f in frames:
        clean = f.clean_dn()
        if f.sensor.cfa is not None:  # each site's own channel
            from camsim.sensor.cfa import mosaic_of

            clean = mosaic_of(clean, f.sensor.cfa)[None]
        residuals.append((f.noisy_dn - clean).ravel().astype(np.float64))
    n = residuals[0].size
    for a, b in zip(residuals, residuals[1:]):
        r = np.corrcoef(a, b)[0, 1]
        assert abs(r) < 3 / np.sqrt(n), r
    # the residuals are noise about the expectation: mean ~ 0 within 5 standard errors
    assert all(abs(res.mean()) < 5 * res.std() / np.sqrt(n) for res in residuals)
    for name in ("offset_e", "gain"):
        maps = [getattr(f.maps, name) for f in frames]
        assert maps[0] is not None and all(np.array_equal(maps[0], m) for m in maps[1:])


def _phase_shift(a, b, bins=3):
    """Our own phase correlation: the translation d with b(x) = a(x − d), from the slope of the cross-power
    spectrum's phase at the lowest frequencies (after the integer peak)."""
    fa, fb = np.fft.fft2(a), np.fft.fft2(b)
    cross = fb * np.conj(fa)
    cross /= np.maximum(np.abs(cross), 1e-30)
    corr = np.fft.ifft2(cross).real
    py, px = np.unravel_index(np.argmax(corr), corr.shape)
    h, w = a.shape
    py = py - h if py > h // 2 else py
    px = px - w if px > w // 2 else px
    ky, kx = np.fft.fftfreq(h), np.fft.fftfreq(w)
    residual = cross * np.exp(2j * np.pi * (ky[:, None] * py + kx[None, :] * px))
    sel_x = [(0, k) for k in range(1, bins + 1)]
    sel_y = [(k, 0) for k in range(1, bins + 1)]
    fx = np.mean([-np.angle(residual[i, j]) / (2 * np.pi * kx[j]) for i, j in sel_x])
    fy = np.mean([-np.angle(residual[i, j]) / (2 * np.pi * ky[i]) for i, j in sel_y])
    return px + fx, py + fy


def test_geometry_phase_correlation_matches_homography():
    h, w = 96, 128
    y, x = np.mgrid[0:h, 0:w]
    blob = 1000 * np.exp(-((x - 60.0) ** 2 + (y - 45.0) ** 2) / (2 * 7.0 ** 2))
    static = np.stack([blob] * 3).astype(np.float32)
    shift = (3.37, -2.18)
    homographies = (np.eye(3), np.array([[1, 0, shift[0]], [0, 1, shift[1]], [0, 0, 1.0]]))
    seq = SequenceParams(frames=2, frame_interval_s=0.1, homographies=tuple(tuple(map(tuple, m)) for m in homographies))
    motion = Motion.of(seq, w, h, seed=0)
    sensor = SensorParams(exposure_s=0.05, photon_noise=False, read_noise=False, quantisation=False,
                          dark_current_e_per_s=0.0)
    cleans = [render_expectation_frame(moving_expectation(static, motion, i, 0.05), sensor, rng=i).clean_dn[1]
              for i in range(2)]
    dx, dy = _phase_shift(cleans[0].astype(np.float64), cleans[1].astype(np.float64))
    h1 = motion.mid_homography(1, 0.05) @ np.linalg.inv(motion.mid_homography(0, 0.05))
    assert abs(dx - h1[0, 2]) < 0.05 and abs(dy - h1[1, 2]) < 0.05, (dx, dy, h1)


def test_pan_blurs_an_edge_into_the_closed_form_ramp():
    h, w, x0, level = 8, 64, 20, 1000.0
    static = np.zeros((3, h, w), dtype=np.float32)
    static[:, :, x0:] = level  # a sharp edge between columns x0 − 1 and x0
    v, exposure = 400.0, 0.02  # v · T = 8 px
    seq = SequenceParams(frames=1, frame_interval_s=exposure, pan_px_per_s=(v, 0.0), blur_subsamples=512)
    got = moving_expectation(static, Motion.of(seq, w, h, 0), 0, exposure)[1, 3]

    def antiderivative(x):  # ∫ of the bilinear interpolation of the step: a ramp from x0 − 1 to x0
        a = x0 - 1.0
        return level * np.where(x < a, 0.0, np.where(x < a + 1, (x - a) ** 2 / 2, 0.5 + (x - a - 1)))

    p = np.arange(w, dtype=np.float64)
    expected = (antiderivative(p) - antiderivative(p - v * exposure)) / (v * exposure)  # p sees p − v t, t ∈ [0, T]
    assert np.max(np.abs(got - expected)) < 1e-3 * level
    inside = (got > 0.001 * level) & (got < 0.999 * level)
    assert inside.sum() == pytest.approx(v * exposure + 1, abs=1)  # a ramp v · T wide (plus bilinear's 1 px)


def test_static_sequence_equals_camsim_render_in_law():
    from camsim.scene.sequence import SequenceParams as SP

    scene = small_scene(width=240, height=160).with_sensor(prnu_percent=1.0, dsnu_e=2.0, read_noise_e=3.0,
                                                           exposure_s=0.5)
    scene = scene.replace(sequence=SP(frames=1, frame_interval_s=0.5))
    lit = light_scene(scene, "D65")
    ref, seq_frame = [o[1] for o in render_sequence_frames(scene, lit, scene.sensor, 0.5, workers=1)]
    static, info = scene_frame(scene, "D65", 0.5, lit=lit, workers=1)
    assert np.allclose(ref.clean_dn(), static.clean_dn(), rtol=1e-5, atol=1e-3)
    for rect in info.patch_rects[:24]:
        a = patch_pixels(seq_frame.noisy_dn, rect).astype(np.float64)
        b = patch_pixels(static.noisy_dn, rect).astype(np.float64)
        for c in range(3):
            n = a.shape[1]
            se_mean = np.sqrt(a[c].var() / n + b[c].var() / n)
            assert abs(a[c].mean() - b[c].mean()) < 5 * se_mean
            se_var = np.sqrt(2 / (n - 1)) * np.sqrt(a[c].var() ** 2 + b[c].var() ** 2)
            assert abs(a[c].var() - b[c].var()) < 5 * se_var


@pytest.mark.parametrize("table, message", [
    ({"frames": 0}, "frames must be"),
    ({"frames": 10 ** 6}, "at most"),
    ({"frames": 2, "frame_interval_s": -1}, "frame_interval_s"),
    ({"frames": 2, "shake_px": "a"}, "shake_px"),
    ({"frames": 2, "pan_px_per_s": [1]}, "pan_px_per_s"),
    ({"frames": 2, "homographies": [[[1, 0, 0], [0, 1, 0], [0, 0, 1]]]}, "one 3x3 matrix per frame"),
    ({"frames": 1, "homographies": [[[1, 0], [0, 1]]]}, "3x3"),
    ({"frames": 1, "homographies": [[[0, 0, 0], [0, 0, 0], [0, 0, 0]]]}, "invertible"),
    ({"frames": 1, "wobble": 1}, "unknown key"),
    ({}, "frames is required"),
])
def test_bad_tables(table, message):
    with pytest.raises(CamsimError, match=message):
        parse_sequence(table)


def test_cli_files_and_one_line_errors(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(FLAT.format(w=64, h=64, sensor='cfa = "RGGB"',
                                sequence="frames = 3\nframe_interval_s = 1.0\npan_px_per_s = [0.5, 0]"))
    assert main(["render", str(path), "--out", str(tmp_path / "out"), "-q"]) == 0
    names = sorted(p.name for p in (tmp_path / "out").iterdir())
    stem = "flatseq_D65_F0.05"
    for i in range(3):
        assert {f"{stem}_f{i:03d}.dng", f"{stem}_f{i:03d}.exr", f"{stem}_f{i:03d}.json"} <= set(names)
    assert {f"{stem}_ref.exr", f"{stem}_ref.json"} <= set(names) and f"{stem}_ref.dng" not in names
    meta = json.loads((tmp_path / "out" / f"{stem}_f002.json").read_text())
    assert meta["frame_index"] == 2 and meta["time_s"] == 2.0 and meta["exposure_s"] == 1.0
    assert np.allclose(meta["homography"], [[1, 0, 0.5 * 2.5], [0, 1, 0], [0, 0, 1]])  # the exposure's middle
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    entries = {e["files"]["json"]: e for e in manifest["frames"]}
    assert [entries[f"{stem}_f{i:03d}.json"]["frame_index"] for i in range(3)] == [0, 1, 2]
    assert entries[f"{stem}_ref.json"]["sequence_reference"] is True
    capsys.readouterr()
    path.write_text(FLAT.format(w=64, h=64, sensor="", sequence="frames = 2\nhomographies = [[[1, 0], [0, 1]]]"))
    assert main(["render", str(path), "--out", str(tmp_path / "bad"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error: ") and err.count("\n") == 1, err
    path.write_text(FLAT.format(w=64, h=64, sensor="", sequence="frames = 2\nframe_interval_s = 0.5"))
    assert main(["render", str(path), "--out", str(tmp_path / "bad2"), "-q"]) == 2  # T = 1 s > the interval
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "longer than frame_interval_s" in err, err
    assert not (tmp_path / "bad2").exists()  # refused before the folder is made


@pytest.mark.parametrize("cfa", [None, "GRBG"])
def test_per_pixel_draw_variance_matches_the_closed_form(cfa):
    """A flat expectation S̄ per channel: each plane's (or site's) variance is k²(S̄ + D̄ + σ_read²) + σ_row² k²
    and its mean k(S̄ + D̄) plus the frame's black-level error of its channel (quantisation off: no 1/12)."""
    h, w = 128, 160
    levels = np.array([200.0, 800.0, 450.0])
    sensor = SensorParams(exposure_s=2.0, read_noise_e=4.0, row_noise_e=1.5, dark_current_e_per_s=(5.0, 20.0, 60.0),
                          black_level_error_dn=30.0, quantisation=False, saturation=False, cfa=cfa)
    planes = np.broadcast_to(levels[:, None, None], (3, h, w)).astype(np.float32)
    from camsim.sensor.cfa import cfa_sites, mosaic_of

    source = planes if cfa is None else mosaic_of(planes, cfa)[None]
    draw = render_expectation_frame(source, sensor, rng=7, workers=2)
    k = sensor.dn_per_electron
    views = [(c, draw.noisy_dn[c]) for c in range(3)] if cfa is None else \
        [(c, draw.noisy_dn[0, dy::2, dx::2]) for dy, dx, c in cfa_sites(cfa)]
    for c, values in views:
        dark = float(sensor.dark_mean_e[c])
        var = k ** 2 * (levels[c] + dark + sensor.read_noise_e ** 2 + sensor.row_noise_e ** 2)
        n, rows = values.size, values.shape[0]
        row_var = k ** 2 * sensor.row_noise_e ** 2  # shared along a row: the mean's error has it once per row
        error = draw.black_level_error_dn[c]  # the frame's one draw per channel, added to its pixels
        assert abs(error) > 1  # (σ = 30 DN: the seed's draws are far from 0, so a wrong channel shows)
        assert abs(values.mean() - error - k * (levels[c] + dark)) < 5 * np.sqrt((var - row_var) / n + row_var / rows)
        assert values.var() == pytest.approx(var, rel=5 * (np.sqrt(2 / n) + np.sqrt(2 / rows) * row_var / var))


def test_bayer_clean_layer_is_exact_at_the_sites():
    from camsim.render.raw_frame import expectation_clean_dn
    from camsim.sensor.cfa import mosaic_of

    rng = np.random.default_rng(3)
    planes = (rng.random((3, 32, 48)) * 9000).astype(np.float32)
    sensor = SensorParams(exposure_s=1.0, cfa="RGGB", prnu_percent=1.0, dsnu_e=2.0, full_well_e=8000.0)
    draw = render_expectation_frame(mosaic_of(planes, "RGGB")[None], sensor, rng=1)
    clean = expectation_clean_dn(planes, sensor, draw.maps)
    assert np.allclose(mosaic_of(clean, "RGGB"), draw.clean_dn[0], rtol=1e-6, atol=1e-4)
    assert clean.max() <= sensor.dn_per_electron * sensor.full_well_e * (1 + 1e-6)  # the full well bounds E


def test_sequence_files_read_back(tmp_path):
    from camsim.render.frame_files import load_frame

    path = tmp_path / "s.toml"
    path.write_text(FLAT.format(w=64, h=48, sensor="", sequence="frames = 2\nframe_interval_s = 1.0\nshake_px = 1"))
    assert main(["render", str(path), "--out", str(tmp_path / "out"), "-q"]) == 0
    for name in ("flatseq_D65_F0.05_f001.exr", "flatseq_D65_F0.05_ref.exr", "flatseq_D65_F0.05_f000.dng"):
        frame = load_frame(tmp_path / "out" / name)
        assert frame is not None


@pytest.mark.parametrize("extra", ["shake_px = 1e300", "pan_px_per_s = [1e300, 0]", "pan_px_per_s = [1e6, 0]"])
def test_motion_beyond_any_frame_is_one_line(tmp_path, extra):
    """A pan or shake that moves the scene beyond 10⁷ px (float32 sampling coordinates lose the pixel there; numpy
    warned of overflows before) is refused on one line, exit 2, nothing written."""
    from camsim.cli import main

    scene = tmp_path / "s.toml"
    scene.write_text('name = "far"\n[target]\nkind = "flat"\n[light]\nilluminants = ["D65"]\n[frame]\nwidth = 32\n'
                     f'height = 24\n[sequence]\nframes = 6\nframe_interval_s = 2.0\n{extra}\n', encoding="utf-8")
    assert main(["render", str(scene), "--out", str(tmp_path / "out"), "-q"]) == 2
    assert not (tmp_path / "out").exists()
