"""The checks a scene's frames pass before anything is drawn (:func:`camsim.render.pipeline.check_frames`)."""

import numpy as np

from camsim.cli import main


def _lens_scene(tmp_path, reference_electrons, factor=1.0):
    path = tmp_path / "lens.toml"
    path.write_text('name = "lens"\n[target]\nkind = "slanted-edge"\n[light]\nilluminants = ["D65"]\n'
                    f'intensity_factors = [{factor!r}]\n[frame]\nwidth = 48\nheight = 32\n[optics]\nf_number = 4.0\n'
                    f'[camera.scale]\nkind = "anchor"\nreference_electrons = {reference_electrons!r}\n')
    return path


def test_a_mean_beyond_the_lens_float32_blur_is_refused_on_one_line(tmp_path, capsys):
    """The largest [camera.scale] (1e30 e⁻) at F = 1e10 through a lens: the float32 blur would make the mean infinite
    and its neighbours NaN (numpy then refused the Poisson means: a traceback); refused with the reason before
    anything is written, while without the lens the same charge is drawn at the saturation cap."""
    out = tmp_path / "out"
    assert main(["render", str(_lens_scene(tmp_path, 1e30, 1e10)), "--out", str(out), "-q", "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "beyond 1e+36, the largest a frame's per-pixel float32 expectation" in err, err
    assert not out.exists()


def test_a_mean_beyond_a_sequences_float32_warp_is_refused_on_one_line(tmp_path, capsys):
    """The same through a motion: a sequence warps the per-pixel expectation as float32 (dead leaves, shaking)."""
    path = tmp_path / "seq.toml"
    path.write_text('name = "seq"\n[target]\nkind = "dead-leaves"\n[light]\nilluminants = ["D65"]\n'
                    'intensity_factors = [1e10]\n[frame]\nwidth = 24\nheight = 22\n[sensor]\nexposure_s = 0.01\n'
                    '[sequence]\nframes = 3\nframe_interval_s = 0.05\nshake_px = 0.5\n'
                    '[camera.scale]\nkind = "anchor"\nreference_electrons = 1e30\n')
    out = tmp_path / "out"
    assert main(["render", str(path), "--out", str(out), "-q", "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "per-pixel float32 expectation (through a lens or a motion)" in err, err
    assert not out.exists()


def test_a_bright_lens_frame_within_the_bound_saturates(tmp_path, capsys):
    from camsim.io.exr import read_exr

    out = tmp_path / "out"
    assert main(["render", str(_lens_scene(tmp_path, 1e30)), "--out", str(out), "-q", "--workers", "1"]) == 0
    noisy, clean, _ = read_exr(out / "lens_D65_F1.exr")
    assert np.all(np.isfinite(noisy)) and np.all(np.isfinite(clean))
