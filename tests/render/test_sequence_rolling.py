"""Rolling shutter and flicker in sequences (issue 29, points 2 and 3): the skew of a panned vertical edge per row
(atan(v · Δ)) on the clean layer and in the sidecar's per-row homographies; a flat field's row means under a
flickering light against the closed-form integral of L(t) = 1 + m cos(2π f t + φ) over each row's exposure (global
and rolling shutter; the clean layer tightly, the noisy layer within its standard error; the dark current not
modulated); motion and flicker together (an edge's centroid per row against the closed-form light-weighted mean
time); one-line errors through ``camsim render``.

Every reference here is computed independently of the code under test: the flicker integral in its difference form
sin(ωb + φ) − sin(ωa + φ) (the code uses the product form), ∫ t L(t) dt by parts, and an edge's position as the
area to its left (Σₓ (1 − profile), exactly linear in a bilinear image's shift)."""

import json
import math

import numpy as np
import pytest

from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.io.exr import read_exr
from camsim.render.pipeline import frame_sensor, light_scene
from camsim.render.sequence import moving_expectation, render_sequence_frames
from camsim.render.sidecar_schema import check_sidecar
from camsim.scene.scene_file import load_scene
from camsim.scene.sequence import Motion, SequenceParams, parse_sequence

F_HZ, DEPTH, PHASE_DEG = 100.0, 0.6, 30.0


def light_mean(a, b, f=F_HZ, m=DEPTH, phase_deg=PHASE_DEG):
    """(1/(b − a)) ∫ₐᵇ (1 + m cos(ωt + φ)) dt, the difference form."""
    w, p = 2 * np.pi * f, np.radians(phase_deg)
    a, b = np.asarray(a, float), np.asarray(b, float)
    return 1 + m * (np.sin(w * b + p) - np.sin(w * a + p)) / (w * (b - a))


def light_time_moment(a, b, f=F_HZ, m=DEPTH, phase_deg=PHASE_DEG):
    """∫ₐᵇ t (1 + m cos(ωt + φ)) dt, by parts: t²/2 + m (t sin(ωt + φ)/ω + cos(ωt + φ)/ω²)."""
    w, p = 2 * np.pi * f, np.radians(phase_deg)

    def primitive(t):
        return t ** 2 / 2 + m * (t * np.sin(w * t + p) / w + np.cos(w * t + p) / w ** 2)

    return primitive(np.asarray(b, float)) - primitive(np.asarray(a, float))


def edge_position(profile, low, high):
    """The area to the left of a rising edge, Σₓ (1 − (profile − low)/(high − low)), per row: px. For a bilinear
    image shifted by d it is A + d exactly (A the unshifted one's), so it is linear in any time average of d."""
    return np.sum(1 - (np.asarray(profile, np.float64) - low) / (high - low), axis=-1)


FLAT = """
name = "flick"
[target]
kind = "flat"
reflectance = 0.5
[light]
illuminants = ["D65"]
intensity_factors = [1]
[frame]
width = {w}
height = {h}
[camera.scale]
kind = "anchor"
reference_electrons = 6000
[sensor]
bits = 16
full_well_e = 1e6
read_noise_e = 3
exposure_s = 0.004
dark_current_e_per_s = 50000
[sequence]
{sequence}
"""


def render_frames(tmp_path, sequence, w=256, h=48):
    path = tmp_path / "s.toml"
    path.write_text(FLAT.format(w=w, h=h, sequence=sequence))
    scene = load_scene(path)
    lit = light_scene(scene, "D65")
    sensor = frame_sensor(scene, lit, 1.0)
    return sensor, list(render_sequence_frames(scene, lit, sensor, 1.0, workers=1))


def flat_sequence(rolling_row_s=0.0):
    return (f"frames = 4\nframe_interval_s = 0.0137\nflicker_hz = {F_HZ}\nflicker_depth = {DEPTH}\n"
            f"flicker_phase_deg = {PHASE_DEG}\nrolling_shutter_row_s = {rolling_row_s}")


@pytest.mark.parametrize("rolling_row_s", [0.0, 2e-4])
def test_flat_field_row_means_follow_the_flicker_integral(tmp_path, rolling_row_s):
    """Clean layer: (row mean − reference) / (k S̄) = F_r − 1, F_r the light's mean over row r's exposure (dark
    current unmodulated: were it modulated too, the left side would be (1 + D̄/S̄)(F_r − 1)); noisy layer: the row
    means within their standard errors of the clean ones."""
    sensor, out = render_frames(tmp_path, flat_sequence(rolling_row_s))
    (_, ref, _), frames = out[0], out[1:]
    k, T, h = sensor.dn_per_electron, sensor.exposure_s, ref.clean_dn().shape[1]
    signal = np.asarray(ref.expected.signal_e[0], np.float64)  # S̄ per channel of the flat field
    dark = 50000 * T
    assert dark > 0.05 * signal.min()  # the dark charge is large enough to show were it modulated
    ref_rows = ref.clean_dn().astype(np.float64).mean(axis=2)
    z = []
    for index, frame, extra in frames:
        starts = index * 0.0137 + np.arange(h) * rolling_row_s
        factor = light_mean(starts, starts + T)
        assert np.ptp(factor if rolling_row_s else [light_mean(i * 0.0137, i * 0.0137 + T) for i in range(4)]) > 0.2
        clean_rows = frame.clean_dn().astype(np.float64).mean(axis=2)
        got = (clean_rows - ref_rows) / (k * signal[:, None])
        assert np.max(np.abs(got - (factor - 1))) < 2e-5, np.max(np.abs(got - (factor - 1)))
        # ground truth: one factor per frame (global) or per row (rolling)
        if rolling_row_s:
            assert extra["rolling_shutter_row_s"] == rolling_row_s and "flicker_factor" not in extra
            assert np.allclose(extra["flicker_row_factor"], factor, rtol=1e-12)
        else:
            assert extra["flicker_factor"] == pytest.approx(factor[0], rel=1e-12)
            assert "flicker_row_factor" not in extra and "row_homographies" not in extra
        noisy = frame.noisy_dn.astype(np.float64)
        n = noisy.shape[2]
        z.append((noisy.mean(axis=2) - clean_rows) / np.sqrt(noisy.var(axis=2, ddof=1) / n))
    z = np.array(z)
    assert np.max(np.abs(z)) < 5 and abs(np.mean(z ** 2) - 1) < 0.25, (np.max(np.abs(z)), np.mean(z ** 2))


def test_no_flicker_at_a_whole_number_of_periods_and_mean_one():
    """T = 1/f: every row's share of the light is exactly 1, whatever its start; over a period the mean is 1."""
    seq = SequenceParams(frames=2, frame_interval_s=0.02, flicker_hz=100, flicker_depth=0.9, flicker_phase_deg=17,
                         rolling_shutter_row_s=1e-4)
    factor = Motion.of(seq, 8, 100, 0).light_factor(1, 0.01)
    assert factor.shape == (100,) and np.allclose(factor, 1, atol=1e-12)
    assert np.ptp(Motion.of(seq, 8, 100, 0).light_factor(1, 0.004)) > 0.5


def rolling_edge_scene(tmp_path, v, row_s, extra=""):
    path = tmp_path / "edge.toml"
    path.write_text(f"""
name = "edge"
[target]
kind = "slanted-edge"
angle_deg = 0
[light]
illuminants = ["D65"]
intensity_factors = [1]
[frame]
width = 96
height = 48
[camera.scale]
kind = "anchor"
reference_electrons = 5000
[sensor]
exposure_s = 0.05
full_well_e = 1e6
bits = 16
[sequence]
frames = 2
frame_interval_s = 0.1
pan_px_per_s = [{v}, 0]
rolling_shutter_row_s = {row_s}
{extra}
""")
    return path


def test_rolling_pan_skews_a_vertical_edge_and_the_sidecar_says_so(tmp_path):
    """camsim render: the clean layer's edge per row moves by v · Δ per row (skew atan(v · Δ)), and each row's
    edge is the reference's plus the x translation of that row's homography in the sidecar."""
    v, row_s, T = 100.0, 1e-3, 0.05
    path = rolling_edge_scene(tmp_path, v, row_s)
    assert main(["render", str(path), "--out", str(tmp_path / "out"), "-q"]) == 0
    out = tmp_path / "out"
    _, ref, _ = read_exr(out / "edge_D65_F1_ref.exr")
    g = ref[1].astype(np.float64)
    low, high = g[:, :10].mean(), g[:, -10:].mean()
    base = edge_position(g, low, high)  # the reference's edge, every row alike
    assert np.ptp(base) < 1e-6
    for i in range(2):
        meta = json.loads((out / f"edge_D65_F1_f{i:03d}.json").read_text())
        check_sidecar(meta, "f")
        _, clean, _ = read_exr(out / f"edge_D65_F1_f{i:03d}.exr")
        x = edge_position(clean[1], low, high)
        rows = np.arange(48)
        slope, intercept = np.polyfit(rows, x, 1)
        assert math.degrees(math.atan(slope)) == pytest.approx(math.degrees(math.atan(v * row_s)), abs=1e-4)
        assert intercept - base[0] == pytest.approx(v * (i * 0.1 + T / 2), abs=1e-3)  # row 0 at its exposure middle
        assert np.max(np.abs(x - (intercept + slope * rows))) < 1e-3  # straight
        shifts = np.array(meta["row_homographies"])[:, 0, 2]
        assert len(meta["row_homographies"]) == 48 == meta["height_px"]
        assert np.max(np.abs((x - base) - shifts)) < 1e-3
        assert meta["rolling_shutter_row_s"] == row_s and meta["time_s"] == pytest.approx(i * 0.1)
        assert np.allclose(meta["homography"], meta["row_homographies"][0])
        assert meta["sequence"]["rolling_shutter_row_s"] == row_s


def test_global_shutter_does_not_skew():
    h, w, x0, level, v = 32, 64, 20, 1000.0, 150.0
    static = np.zeros((3, h, w), np.float32)
    static[:, :, x0:] = level
    seq = SequenceParams(frames=1, frame_interval_s=0.04, pan_px_per_s=(v, 0.0))
    x = edge_position(moving_expectation(static, Motion.of(seq, w, h, 0), 0, 0.04)[1], 0, level)
    assert np.ptp(x) < 1e-4 and x[0] - x0 == pytest.approx(v * 0.02, abs=1e-3)


@pytest.mark.parametrize("rolling_row_s, subsamples", [(0.0, None), (2e-4, None), (2e-4, 64)])
def test_motion_and_flicker_together(rolling_row_s, subsamples):
    """A pan under a flickering light: a flat field's rows keep their share of the light exactly (the warp's
    weights), and an edge sits at x0 + v · (light-weighted mean time of the row's exposure), ∫ t L / ∫ L (closed
    form), visibly off the exposure's middle."""
    h, w, x0, level, v, T = 40, 96, 20, 800.0, 2000.0, 0.005  # v T = 10 px; T = half a period of 100 Hz
    seq = SequenceParams(frames=2, frame_interval_s=0.02, pan_px_per_s=(v, 0.0), flicker_hz=F_HZ,
                         flicker_depth=DEPTH, flicker_phase_deg=PHASE_DEG, rolling_shutter_row_s=rolling_row_s,
                         blur_subsamples=subsamples)
    motion = Motion.of(seq, w, h, 0)
    if subsamples is None:  # ≤ 0.25 px a step, ≥ 8 per period of the light
        assert motion.subsample_count(1, T) == 40
    starts = 0.02 + np.arange(h) * rolling_row_s
    flat = np.full((3, h, w), level, np.float32)
    rows = moving_expectation(flat, motion, 1, T)[1].astype(np.float64).mean(axis=1)
    assert np.max(np.abs(rows / level - light_mean(starts, starts + T))) < 1e-5
    edge = np.zeros((3, h, w), np.float32)
    edge[:, :, x0:] = level
    out = moving_expectation(edge, motion, 1, T)[1].astype(np.float64)
    bright = level * light_mean(starts, starts + T)
    x = edge_position(out, 0, bright[:, None])
    mean_time = light_time_moment(starts, starts + T) / (T * light_mean(starts, starts + T))
    assert np.max(np.abs(x - x0 - v * mean_time)) < 5e-3, np.max(np.abs(x - x0 - v * mean_time))
    assert np.max(np.abs(v * mean_time - v * (starts + T / 2))) > 1  # the light moves the edge visibly


@pytest.mark.parametrize("T, v, m, phase_deg", [(0.005, 2000.0, 0.6, 30.0), (0.0075, 200.0, 0.9, 120.0),
                                                 (0.004, 500.0, 0.9, 90.0), (0.013, 150.0, 1.0, 0.0),
                                                 (0.005, 50.0, 0.9, 0.0), (0.005, 100.0, 0.9, 0.0),
                                                 (0.005, 40.0, 0.7, 0.0)])
def test_automatic_subsamples_bound_the_flicker_displacement(T, v, m, phase_deg):
    """Under a pan and a flickering light, the automatic sub-sampling keeps an edge within
    MAX_FLICKER_DISPLACEMENT_PX of the closed-form light-weighted mean position, x0 + v ∫ t L / ∫ L (the last three
    move little in an exposure: the motion's 0.25 px a step alone would take 1 or 2 sub-samples, 0.02 to 0.05 px
    off)."""
    from camsim.scene.sequence import MAX_FLICKER_DISPLACEMENT_PX

    h, w, x0, level = 4, 80, 20, 1000.0
    seq = SequenceParams(frames=1, frame_interval_s=0.03, pan_px_per_s=(v, 0.0), flicker_hz=F_HZ, flicker_depth=m,
                         flicker_phase_deg=phase_deg)
    edge = np.zeros((3, h, w), np.float32)
    edge[:, :, x0:] = level
    out = moving_expectation(edge, Motion.of(seq, w, h, 0), 0, T)[1].astype(np.float64)
    factor = light_mean(0, T, F_HZ, m, phase_deg)
    x = edge_position(out, 0, level * factor)
    mean_time = light_time_moment(0, T, F_HZ, m, phase_deg) / (T * factor)
    assert np.max(np.abs(x - x0 - v * mean_time)) <= MAX_FLICKER_DISPLACEMENT_PX
    assert abs(mean_time - T / 2) * v > 2 * MAX_FLICKER_DISPLACEMENT_PX  # (the light moves the edge off the middle)


def test_motion_and_flicker_profile_against_quadrature():
    """The whole blurred profile of an edge under a pan and a flickering light against our own fine quadrature of
    (1/T) ∫ L(t) R(x − v t) dt, R the bilinear step (the automatic sub-sampling)."""
    h, w, x0, level, v, T = 4, 64, 20, 1000.0, 1600.0, 0.005
    seq = SequenceParams(frames=1, frame_interval_s=0.01, pan_px_per_s=(v, 0.0), flicker_hz=F_HZ,
                         flicker_depth=DEPTH, flicker_phase_deg=PHASE_DEG)
    static = np.zeros((3, h, w), np.float32)
    static[:, :, x0:] = level
    got = moving_expectation(static, Motion.of(seq, w, h, 0), 0, T)[1, 2].astype(np.float64)
    t = (np.arange(20000) + 0.5) * (T / 20000)
    light = 1 + DEPTH * np.cos(2 * np.pi * F_HZ * t + np.radians(PHASE_DEG))
    x = np.arange(w, dtype=np.float64)[:, None]
    ramp = level * np.clip(x - v * t[None, :] - (x0 - 1), 0, 1)
    expected = (ramp * light[None, :]).mean(axis=1)
    assert np.max(np.abs(got - expected)) < 0.01 * level, np.max(np.abs(got - expected))


def test_row_homographies_vectorised():
    """A pan's per-row homographies are the translations v · (tᵢ + r · Δ + T/2) (closed form); thousands of rows ×
    sub-samples cost milliseconds (one vectorised call, no loop per row); the rolling shutter's extra knot of the
    shake leaves the walk's first steps as the global shutter's."""
    import time

    v = (30.0, -20.0)
    seq = SequenceParams(frames=3, frame_interval_s=0.04, pan_px_per_s=v, rolling_shutter_row_s=1e-5)
    rows = Motion.of(seq, 4000, 3000, 5).row_homographies(2, 0.01)
    t = 2 * 0.04 + np.arange(3000) * 1e-5 + 0.005
    expected = np.zeros((3000, 3, 3))
    expected[:, 0, 0] = expected[:, 1, 1] = expected[:, 2, 2] = 1
    expected[:, 0, 2], expected[:, 1, 2] = v[0] * t, v[1] * t
    assert np.allclose(rows, expected, rtol=0, atol=1e-9)
    shaky = SequenceParams(frames=3, frame_interval_s=0.04, shake_px=2, shake_deg=0.5, pan_px_per_s=v,
                           rolling_shutter_row_s=1e-5, blur_subsamples=32)
    motion = Motion.of(shaky, 4000, 3000, 5)
    start = time.process_time()  # CPU time (measured: 0.05 s; a loop per row would take seconds)
    times, weights = motion.exposure_samples(2, 0.01)
    inverses = np.linalg.inv(motion.homographies(times, 2))
    assert time.process_time() - start < 1.0 and inverses.shape == (32 * 3000, 3, 3)
    poses = Motion.of(SequenceParams(frames=3, frame_interval_s=0.04, shake_px=2, shake_deg=0.5), 4000, 3000, 5).poses
    assert np.array_equal(motion.poses[:4], poses) and len(motion.poses) == 5


@pytest.mark.parametrize("table, message", [
    ({"frames": 2, "flicker_depth": 1.5}, "flicker_depth must be at most 1"),
    ({"frames": 2, "flicker_depth": -0.1}, "flicker_depth"),
    ({"frames": 2, "flicker_hz": -100}, "flicker_hz"),
    ({"frames": 2, "flicker_hz": 1e9}, "flicker_hz must be at most"),
    ({"frames": 2, "flicker_hz": "mains"}, "flicker_hz"),
    ({"frames": 2, "rolling_shutter_row_s": -1e-5}, "rolling_shutter_row_s"),
    ({"frames": 2, "flicker_phase_deg": float("nan")}, "flicker_phase_deg"),
])
def test_bad_values(table, message):
    with pytest.raises(CamsimError, match=message):
        parse_sequence(table)


@pytest.mark.parametrize("extra, message", [
    ("flicker_depth = 2", "flicker_depth must be at most 1"),
    ("flicker_hz = -1", "flicker_hz"),
    ("rolling_shutter_row_s = -1", "rolling_shutter_row_s"),
    ("rolling_shutter_row_s = 0.003", "readout, 48 rows"),  # 48 × 3 ms = 0.144 s > the interval 0.1 s
])
def test_bad_values_one_line_through_the_cli(tmp_path, capsys, extra, message):
    path = rolling_edge_scene(tmp_path, 10.0, 0.0, extra)
    text = path.read_text().replace("rolling_shutter_row_s = 0.0\n", "")
    path.write_text(text)
    assert main(["render", str(path), "--out", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error: ") and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "out").exists()


def test_sidecar_schema_refuses_bad_per_row_keys(tmp_path):
    path = rolling_edge_scene(tmp_path, 10.0, 1e-3, "flicker_hz = 120\nflicker_depth = 0.2")
    assert main(["render", str(path), "--out", str(tmp_path / "out"), "-q"]) == 0
    meta = json.loads((tmp_path / "out" / "edge_D65_F1_f001.json").read_text())
    check_sidecar(meta, "f")
    assert len(meta["flicker_row_factor"]) == 48 and meta["sequence"]["flicker_hz"] == 120
    for key, value, says in [("row_homographies", meta["row_homographies"][:-1], "one entry per row"),
                             ("flicker_row_factor", meta["flicker_row_factor"] + [1.0], "one entry per row"),
                             ("row_homographies", [[[1, 0], [0, 1]]] * 48, "3 × 3"),
                             ("flicker_row_factor", [-1.0] * 48, "≥ 0"),
                             ("rolling_shutter_row_s", -1, "rolling_shutter_row_s")]:
        with pytest.raises(CamsimError, match=says):
            check_sidecar({**meta, key: value}, "f")


def test_timing_rule_allows_overlap_across_rows():
    """A row is exposed once per frame (T ≤ the interval) and the frame's readout fits in the interval (H · Δ ≤ the
    interval); a frame's last rows may still expose when the next frame's row 0 starts (T + (H − 1) Δ > the
    interval is allowed)."""
    from camsim.scene.sequence import check_timing

    seq = SequenceParams(frames=3, frame_interval_s=0.04, rolling_shutter_row_s=1e-4)
    check_timing(seq, 0.04, 400)  # T = the interval, readout 400 × 0.1 ms = the interval: the limits themselves
    with pytest.raises(CamsimError, match="readout, 401 rows"):
        check_timing(seq, 0.01, 401)
    with pytest.raises(CamsimError, match="longer than frame_interval_s"):
        check_timing(seq, 0.041, 10)
