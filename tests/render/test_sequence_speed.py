"""What makes a sequence frame cheaper changes none of its values: the compiled warp against the numpy one through
render_sequence_frames, and a draw without its clean layer (a CFA sequence's, which makes its own) against one
with it."""

from pathlib import Path

import numpy as np
import pytest

from camsim.render import warp
from camsim.render.pipeline import frame_sensor, light_scene
from camsim.render.raw_frame import render_expectation_frame
from camsim.render.sequence import render_sequence_frames
from camsim.scene.scene_file import load_scene
from camsim.scene.sequence import SequenceParams
from camsim.sensor.params import SensorParams

ROOT = Path(__file__).resolve().parents[2]

pytest.importorskip("numba")


def _frames(scene):
    lit = light_scene(scene, scene.illuminants[0])
    sensor = frame_sensor(scene, lit, scene.intensity_factors[0])
    return list(render_sequence_frames(scene, lit, sensor, scene.intensity_factors[0], workers=2))


@pytest.mark.parametrize("cfa", ["RGGB", None])
def test_sequence_frames_are_the_same_on_both_warp_paths(cfa, monkeypatch):
    """A textured scene (dead leaves) with shake, pan and a perspective homography per frame, Bayer and three-chip:
    every frame's noisy, digital and clean arrays bit for bit with the compiled warp and with the numpy one (numba
    made unavailable); the frames move (they differ from the reference)."""
    homographies = (((1, 0.01, 0), (0, 1, 0), (1e-4, 0, 1)), ((1, 0, 0.3), (0, 1, 0), (0, 0, 1)),
                    ((1, 0, 0), (0, 1, 0), (0, 0, 1)))
    scene = load_scene(ROOT / "camsim" / "scenes" / "dead_leaves.toml")
    scene = scene.replace(width=48, height=40, intensity_factors=(1.0,)).with_sensor(
        cfa=cfa, exposure_s=0.02, prnu_percent=1.0)
    scene = scene.replace(sequence=SequenceParams(frames=3, frame_interval_s=0.04, shake_px=1.5, shake_deg=0.4,
                                                  pan_px_per_s=(20.0, -7.0), homographies=homographies))
    assert warp.warp_path() == warp.COMPILED_PATH
    compiled = _frames(scene)
    monkeypatch.setattr(warp._KERNELS, "state", {"kernels": None, "why": "no numba (test)"})
    reference = _frames(scene)
    assert len(compiled) == len(reference) == 4
    assert not np.allclose(compiled[0][1].clean_dn(), compiled[1][1].clean_dn(), rtol=1e-2)
    for (i, a, _), (j, b, _) in zip(compiled, reference):
        assert i == j
        assert np.array_equal(a.noisy_dn, b.noisy_dn) and np.array_equal(a.clean_dn(), b.clean_dn())
        assert (a.digital_dn is None and b.digital_dn is None) or np.array_equal(a.digital_dn, b.digital_dn)


@pytest.mark.parametrize("cfa", ["GBRG", None])
def test_a_draw_without_its_clean_layer_draws_the_same(cfa):
    """render_expectation_frame(clean=False): the same noisy and digital frames from the same seed, no clean layer."""
    sensor = SensorParams(cfa=cfa, read_noise_e=2.0, prnu_percent=2.0, dsnu_e=1.0, row_noise_e=0.5,
                          stuck_pixel_fraction=0.01)
    planes = 1 if cfa else 3
    signal = np.random.default_rng(0).uniform(0, 500, (planes, 24, 32)).astype(np.float32)
    full = render_expectation_frame(signal, sensor, rng=7, workers=2)
    bare = render_expectation_frame(signal, sensor, rng=7, workers=2, clean=False)
    assert bare.clean_dn is None and full.clean_dn is not None
    assert np.array_equal(full.noisy_dn, bare.noisy_dn)
    assert np.array_equal(full.digital_dn, bare.digital_dn)
