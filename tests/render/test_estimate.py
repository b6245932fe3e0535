"""The up-front estimate of ``camsim render``: the frames it counts are the frames written, the bytes an upper bound
within a few per cent of the files' sizes (uncompressed EXR, the default), and a render past the limits is refused
on one line before anything is written unless ``--yes``."""

import pytest

import camsim.render.estimate as estimate_module
from camsim.cli import main
from camsim.render.estimate import CONFIRM_FRAMES, estimate_render, frame_bytes
from camsim.scene.scene_file import load_scene
from tests.support.fuzz import to_toml

SMALL = ["--size", "60x40", "--illuminant", "D65", "A", "-F", "1", "0.5", "-q"]


def _scene_file(tmp_path, factors, **tables):
    doc = {"name": "many", "chart": {"reflectances": "ColorChecker N Ohta", "columns": 6, "rows": 4},
           "light": {"illuminants": ["D65", "A"], "intensity_factors": factors},
           "frame": {"width": 60, "height": 40}, **tables}
    path = tmp_path / "many.toml"
    path.write_text(to_toml(doc), encoding="utf-8")
    return path


def _written_bytes(folder):
    return sum(f.stat().st_size for f in folder.iterdir() if f.name != "manifest.json")


@pytest.mark.parametrize("options", [[], ["--cfa", "RGGB", "--sensor", "bits=12"], ["--preview"],
                                     ["--preset", "ideal"]], ids=["three-chip", "bayer-12bit", "preview", "float"])
def test_the_estimate_bounds_the_files_written(tmp_path, options, capsys):
    """The frames counted are the frames written; the bytes bound the files; the DNG's and EXR's pixels are exact
    (their files hold them and at most the overhead's headers more)."""
    from camsim.cli import build_parser
    from camsim.cli.commands.render import apply_overrides

    out = tmp_path / "out"
    argv = ["render", "macbeth_26", *SMALL, *options, "--out", str(out)]
    assert main(argv) == 0
    args = build_parser().parse_args(argv)
    scene = apply_overrides(load_scene(args.scene), args)
    estimate = estimate_render(scene, preview=args.preview)
    frames = [f for f in out.glob("*.json") if f.name != "manifest.json"]
    assert estimate.frames == len(frames) == 4
    assert _written_bytes(out) <= estimate.max_bytes
    sensor = scene.sensor
    pixels = frame_bytes(60, 40, planes=1 if sensor.cfa else 3, bits=sensor.bits, quantised=sensor.quantisation,
                         preview=False) - estimate_module.FRAME_OVERHEAD_BYTES
    raw_files = sum(f.stat().st_size for f in out.iterdir() if f.suffix in (".dng", ".exr"))
    assert estimate.frames * pixels <= raw_files <= estimate.frames * (pixels + estimate_module.FRAME_OVERHEAD_BYTES)
    assert any(f.suffix == ".dng" for f in out.iterdir()) == sensor.quantisation


def test_the_pixels_part_is_the_layouts():
    assert frame_bytes(600, 400, planes=3, bits=8, quantised=True, preview=False) == \
        600 * 400 * (3 + 4 * 9) + estimate_module.FRAME_OVERHEAD_BYTES
    assert frame_bytes(600, 400, planes=1, bits=14, quantised=True, preview=False) == \
        600 * 400 * (2 + 4 * 7) + estimate_module.FRAME_OVERHEAD_BYTES


def test_a_sequence_counts_its_frames_and_references(tmp_path):
    scene = load_scene(_scene_file(tmp_path, [1.0, 0.5, 0.25],
                                   sequence={"frames": 5, "frame_interval_s": 2.0}))
    assert estimate_render(scene).frames == 2 * 3 * (5 + 1)


def test_a_typo_in_a_list_is_refused_before_anything_is_written(tmp_path, capsys):
    factors = [float(i) for i in range(1, CONFIRM_FRAMES // 2 + 2)]  # 2 illuminants: just over the limit
    out = tmp_path / "out"
    assert main(["render", str(_scene_file(tmp_path, factors)), "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith(
        f"camsim: error: this render writes {2 * len(factors)} frames of 60x40, up to ") and "--yes" in err[0], err
    assert f"over {CONFIRM_FRAMES} frames" in err[0]
    assert not out.exists()


def test_yes_renders_past_the_limit_and_the_estimate_is_said(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(estimate_module, "CONFIRM_FRAMES", 3)
    scene = str(_scene_file(tmp_path, [1.0, 0.5]))
    assert main(["render", scene, "--out", str(tmp_path / "a"), "-q"]) == 2
    assert "over 3 frames" in capsys.readouterr().err
    assert main(["render", scene, "--out", str(tmp_path / "b"), "--yes"]) == 0
    err = capsys.readouterr().err
    assert "camsim render: 4 frames of 60x40, up to " in err and f"to {tmp_path / 'b'}/" in err
    assert len(list((tmp_path / "b").glob("many_*.json"))) == 4


def test_a_render_larger_than_the_free_space_is_refused(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(estimate_module, "_free_bytes", lambda out_dir: 1000)
    out = tmp_path / "out"
    assert main(["render", str(_scene_file(tmp_path, [1.0])), "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "more than the 1 kB free there" in err[0], err
    assert not out.exists()
