"""Burst pairs with a rolling shutter and a flickering light (camsim.pairs with burst_frames, rolling_shutter_row_s,
flicker_hz, flicker_depth, flicker_phase_deg): the laws of a scene's [sequence] (issue 29), checked against theory
written here. A panned vertical edge (a PNG written in tmp_path) is skewed row by row: each row's edge, found by the
test's own area method, at x₀ + v · t_row with t_row the row's exposure middle (within 0.05 px); a flat image's row
means follow the closed-form integral of L(t) = 1 + m cos(2π f t + φ) over each row's exposure (the signal only, not
the dark current; within 1e-4 relative; the noisy rows within 5 standard errors); the same seed gives the same bits,
the frames' noise is independent; bad settings are refused on one line before any work."""

import math

import imageio.v3 as iio
import numpy as np
import pytest

from camsim.core.errors import CamsimError
from camsim.pairs import PairSource

CROP = (64, 48)


def _source(images, **settings) -> PairSource:
    """A burst source of the built-in ``macbeth_26`` scene (T = 1 s unless the sensor says otherwise) on ``images``,
    IMX174 (three planes, no fixed pattern, no row noise), no flips."""
    from camsim.scene.scene_file import load_scene

    scene = load_scene("macbeth_26")
    sensor = settings.pop("sensor", {})
    if sensor:
        scene = scene.with_sensor(**sensor)
    base = {"crop": CROP, "batch_size": 2, "cameras": ("sony-imx174",), "intensity": (0.05, 0.2), "seed": 5,
            "burst_frames": 2, "flips": False}
    return PairSource.from_scene(scene, images, **(base | settings))


def _edge_png(tmp_path, width: int, height: int, column: int):
    """A PNG of sRGB code 40 left of ``column`` (columns 0 … column − 1), 220 from it on."""
    codes = np.full((height, width, 3), 40, dtype=np.uint8)
    codes[:, column:] = 220
    path = tmp_path / "edge.png"
    iio.imwrite(path, codes)
    return path


def _flat_png(tmp_path, width: int, height: int):
    path = tmp_path / "flat.png"
    iio.imwrite(path, np.full((height, width, 3), (180, 150, 120), dtype=np.uint8))
    return path


def _edge_positions(rows: np.ndarray) -> np.ndarray:
    """Each row's edge (rising left to right) by the area method: with g = (f − lo)/(hi − lo) (lo, hi the row's
    plateaus at its ends), the edge e of a step is where Σₓ g(x) = (W − ½) − e. Exact for a bilinearly sampled step
    (a ramp one pixel wide) averaged over any shifts: the sum over integers of a ramp of width 1 equals its integral
    (its derivative's spectrum, sinc(k), vanishes at every integer k ≠ 0), and each shifted ramp's centre enters
    linearly with its weight."""
    rows = np.asarray(rows, dtype=np.float64)
    lo, hi = rows[:, :3].mean(axis=1, keepdims=True), rows[:, -3:].mean(axis=1, keepdims=True)
    g = (rows - lo) / (hi - lo)
    return rows.shape[1] - 0.5 - g.sum(axis=1)


def _light_share(start, exposure, hz, depth, phase_deg):
    """(1/T) ∫ₐ^{a+T} (1 + m cos(ω t + φ)) dt = 1 + m (sin(ω(a + T) + φ) − sin(ω a + φ)) / (ω T), in closed form."""
    omega, phi = 2 * math.pi * hz, math.radians(phase_deg)
    start = np.asarray(start, dtype=np.float64)
    return 1 + depth * (np.sin(omega * (start + exposure) + phi) - np.sin(omega * start + phi)) / (omega * exposure)


@pytest.mark.parametrize("frame_interval_s", [2.0, 4.0])
def test_a_rolling_shutter_skews_a_panned_edge_row_by_row(tmp_path, frame_interval_s):
    """A pan of v = 3 px/s, Δ = 40 ms a row (the 48 rows' readout 1.92 s, T = 1 s): in each frame's clean layer
    (every channel) row r's edge is at x₀ + v · (tᵢ + r · Δ + T/2), x₀ the reference crop's edge (the photograph's
    step between its columns 47 and 48, i.e. 47.5 − crop_x), within 0.05 px; so the frame is skewed by v · Δ = 0.12 px
    a row. The batch's row homographies are the pan at those times, and the global-shutter frame is not skewed."""
    v, delta = 3.0, 0.04
    png = _edge_png(tmp_path, 110, 48, 48)
    settings = dict(pan_px_per_s=(v, 0.0), frame_interval_s=frame_interval_s)
    batch = _source(png, rolling_shutter_row_s=delta, **settings).batch(0)
    still = _source(png, **settings).batch(0)
    width, height = CROP
    rows = np.arange(height)
    assert batch.row_homographies.shape == (2, 2, height, 3, 3) and batch.row_homographies.dtype == np.float32
    assert batch.flicker_factor is None and still.row_homographies is None
    for i, p in enumerate(batch.params):
        burst, exposure = p["burst"], p["exposure_s"]
        assert exposure == 1.0 and burst["rolling_shutter_row_s"] == delta and burst["flicker_depth"] == 0.0
        x0 = 47.5 - p["crop_x"]
        for j in range(2):
            t_row = j * frame_interval_s + rows * delta + exposure / 2
            expected = x0 + v * t_row
            assert 6 < expected.min() and expected.max() < width - 6  # both plateaus inside the crop
            for c in range(3):
                found = _edge_positions(batch.frames_clean[i, j, c])
                assert np.max(np.abs(found - expected)) < 0.05, (j, c, np.max(np.abs(found - expected)))
            np.testing.assert_allclose(batch.row_homographies[i, j, :, 0, 2], v * t_row, rtol=1e-6)
            np.testing.assert_allclose(batch.row_homographies[i, j, :, :2, :2], np.broadcast_to(np.eye(2), (48, 2, 2)))
            assert batch.homographies[i, j, 0, 2] == pytest.approx(v * t_row[0])  # row 0's exposure middle
        # the global shutter: every row's edge at the frame's middle
        p0 = still.params[i]
        found = _edge_positions(still.frames_clean[i, 1, 1])
        assert np.max(np.abs(found - (47.5 - p0["crop_x"] + v * (frame_interval_s + 0.5)))) < 0.05


def test_flicker_row_means_follow_the_light_integrated_over_each_rows_exposure(tmp_path):
    """A flat image, T = 2 ms, a rolling shutter of Δ = 0.1 ms, 100 Hz flicker of depth 0.8 and phase 30° and a dark
    current of 4000 e⁻/s (8 e⁻ a frame, not modulated): each row of each frame's clean layer is k · (S̄ · Lᵣ + D̄),
    Lᵣ = (1/T) ∫ L over the row's exposure in closed form, S̄ from the reference (k · (S̄ + D̄)) and D̄ the record's
    dark charge: within 1e-4 relative; the noisy rows' means within 5 standard errors of it (and their z-scores'
    mean, over all rows and frames, within 5 of its standard errors of 0). A global shutter's rows
    share the frame's Lᵢ, and the batch's flicker_factor is Lᵣ."""
    hz, depth, phase = 100.0, 0.8, 30.0
    png = _flat_png(tmp_path, 80, 60)
    sensor = {"exposure_s": 0.002, "dark_current_e_per_s": 4000.0}
    light = dict(flicker_hz=hz, flicker_depth=depth, flicker_phase_deg=phase, frame_interval_s=0.0113,
                 intensity=(400.0, 800.0), burst_frames=4, sensor=sensor)
    width, height = CROP
    for delta in (1e-4, 0.0):
        batch = _source(png, rolling_shutter_row_s=delta, **light).batch(1)
        assert batch.flicker_factor.shape == (2, 4, height) and (batch.row_homographies is None) == (delta == 0)
        z = []
        for i, p in enumerate(batch.params):
            k, dark = p["dn_per_electron"], np.array(p["dark_e"])[:, None]
            assert p["exposure_s"] == 0.002 and dark.min() > 7.9
            reference = batch.clean[i].astype(np.float64).mean(axis=2)  # (3, H): k (S̄ + D̄) per row
            signal = reference / k - dark
            for j in range(4):
                starts = j * 0.0113 + np.arange(height) * delta
                share = _light_share(starts, 0.002, hz, depth, phase)
                assert np.ptp(share) > (0.3 if delta else -1)  # the bands are there (a rolling shutter)
                np.testing.assert_allclose(batch.flicker_factor[i, j], share, rtol=1e-9)
                model = k * (signal * share + dark)  # (3, H)
                rows = batch.frames_clean[i, j].astype(np.float64).mean(axis=2)
                np.testing.assert_allclose(rows, model, rtol=1e-4)
                residual = batch.noisy[i, j].astype(np.float64) - model[:, :, None]  # (3, H, W)
                residual = residual.transpose(1, 0, 2).reshape(height, -1)  # a row's every channel and column
                error = residual.std(axis=1, ddof=1) / np.sqrt(residual.shape[1])
                assert np.all(np.abs(residual.mean(axis=1)) < 5 * error), np.max(np.abs(residual.mean(axis=1)) / error)
                z.append(residual.mean(axis=1) / error)
        z = np.concatenate(z)  # every row of every frame: independent, each of mean 0 and variance ≈ 1
        assert abs(z.mean()) < 5 / np.sqrt(z.size), z.mean()


def test_a_rolling_flickering_burst_is_its_seeds_and_its_frames_noise_independent(tmp_path):
    """Shake, pan, rolling shutter and flicker together: the same seed gives the same bits (two sources); the noise
    of consecutive frames (noisy − the frame's own expectation) uncorrelated within ±3/√n."""
    png = _flat_png(tmp_path, 96, 80)
    settings = dict(burst_frames=4, batch_size=3, shake_px=0.6, shake_deg=0.2, pan_px_per_s=(300.0, -100.0),
                    frame_interval_s=0.01, rolling_shutter_row_s=1e-4, flicker_hz=120.0, flicker_depth=0.5,
                    flicker_phase_deg=-40.0, intensity=(1.0, 3.0), sensor={"exposure_s": 0.004})
    a = _source(png, **settings).batch(2)
    b = _source(png, **settings).batch(2)
    for name in ("noisy", "clean", "digital", "frames_clean", "homographies", "row_homographies", "flicker_factor"):
        assert getattr(a, name) is not None and np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.params == b.params
    residual = a.noisy.astype(np.float64) - a.frames_clean
    n = residual[:, 0].size
    correlations = [np.corrcoef(residual[:, j].ravel(), residual[:, j + 1].ravel())[0, 1] for j in range(3)]
    assert np.all(np.abs(correlations) < 3 / np.sqrt(n)), correlations
    assert not np.array_equal(a.frames_clean[:, 0], a.frames_clean[:, 1])


@pytest.mark.parametrize("settings, match", [
    ({"rolling_shutter_row_s": 0.03}, "readout, 48 rows × rolling_shutter_row_s 0.03 s = 1.44 s, is longer than "
                                      "frame_interval_s 1 s"),
    ({"rolling_shutter_row_s": 0.01, "frame_interval_s": 1.2}, None),
    ({"rolling_shutter_row_s": 0.03, "frame_interval_s": 1.2}, "is longer than frame_interval_s 1.2 s"),
    ({"rolling_shutter_row_s": -1e-4}, "burst pairs: rolling_shutter_row_s must be ≥ 0"),
    ({"rolling_shutter_row_s": float("inf")}, "burst pairs: rolling_shutter_row_s must be a finite number"),
    ({"flicker_depth": 1.5, "flicker_hz": 100.0}, "burst pairs: flicker_depth must be at most 1"),
    ({"flicker_depth": -0.1, "flicker_hz": 100.0}, "burst pairs: flicker_depth must be ≥ 0"),
    ({"flicker_hz": float("nan"), "flicker_depth": 0.5}, "burst pairs: flicker_hz must be a finite number"),
    ({"flicker_hz": -100.0, "flicker_depth": 0.5}, "burst pairs: flicker_hz must be ≥ 0"),
    ({"flicker_phase_deg": float("inf")}, "burst pairs: flicker_phase_deg must be a finite number"),
    ({"flicker_hz": "100"}, "burst pairs: flicker_hz must be a number"),
    ({"burst_frames": None, "flicker_hz": 100.0, "flicker_depth": 0.5},
     "flicker_hz, flicker_depth set without burst_frames"),
    ({"burst_frames": None, "rolling_shutter_row_s": 1e-5}, "rolling_shutter_row_s set without burst_frames"),
])
def test_bad_shutter_and_light_settings_are_refused_on_one_line(tmp_path, monkeypatch, settings, match):
    """Refused when the source is made (the macbeth_26 scene's fixed exposure of 1 s, a 48-row crop), before any
    photograph is lit; a readout that fits its interval is taken."""
    from tests.support.helpers import ROOT

    lit = []
    monkeypatch.setattr(PairSource, "_lit", lambda self, *args: lit.append(args))
    images = ROOT / "scenes" / "images"
    if match is None:
        assert _source(images, **settings).rolling_shutter_row_s == settings["rolling_shutter_row_s"]
        return
    with pytest.raises(CamsimError, match=match) as info:
        _source(images, **settings)
    assert "\n" not in str(info.value) and not lit


def test_the_torch_batch_hands_over_the_rows_ground_truth(tmp_path):
    """camsim.pairs_torch.batch_tensors: ``row_homographies`` and ``flicker_factor`` as tensors sharing the batch's
    memory with both on, None with neither."""
    torch = pytest.importorskip("torch")
    from camsim.pairs_torch import batch_tensors

    png = _flat_png(tmp_path, 80, 60)
    on = batch_tensors(_source(png, rolling_shutter_row_s=0.01, flicker_hz=50.0, flicker_depth=0.3).batch(0))
    assert tuple(on["row_homographies"].shape) == (2, 2, 48, 3, 3) and on["row_homographies"].dtype == torch.float32
    assert tuple(on["flicker_factor"].shape) == (2, 2, 48) and on["flicker_factor"].dtype == torch.float64
    off = batch_tensors(_source(png, pan_px_per_s=(1.0, 0.0)).batch(0))
    assert off["row_homographies"] is None and off["flicker_factor"] is None and off["homographies"] is not None
