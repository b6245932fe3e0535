"""Rendered frames on disk: exact through rawpy, OpenEXR and OpenImageIO; sidecar; manifest; determinism."""

import json

import numpy as np
import pytest
import rawpy

import camsim.render.frame as render_module
from camsim.core.seeding import frame_seed_sequence
from camsim.io.dng import read_dng
from camsim.io.exr import read_exr, read_exr_oiio
from camsim.render.run import render_scene
from camsim.sensor.noise_profile import frame_noise_profile
from tests.support.helpers import libraw_black_levels, render, small_scene

FACTORS = (1.0, 0.02)
SIDECAR_KEYS = {
    "scene", "illuminant", "intensity_factor", "seed", "photon_statistics", "method", "camera", "reflectances",
    "bits", "dn_per_electron", "black_level_dn", "full_well_e", "read_noise_e", "exposure_s", "wavelengths_nm",
    "patches", "files",
}


@pytest.fixture(scope="module")
def scene():
    return small_scene(width=240, height=160, intensity_factors=FACTORS, illuminants=("D65", "FL2"), seed=42)


@pytest.fixture(scope="module")
def rendered(scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("frames")
    manifest = render_scene(scene, out, progress=False)
    return out, manifest


def test_manifest_lists_every_frame(rendered, scene):
    out, manifest = rendered
    assert json.loads((out / "manifest.json").read_text()) == manifest
    assert [(f["illuminant"], f["intensity_factor"]) for f in manifest["frames"]] == [
        (i, f) for i in scene.illuminants for f in FACTORS
    ]
    for entry in manifest["frames"]:
        assert entry["seed"] == 42 and entry["photon_statistics"] == "pixel" and entry["method"] == "poisson"
        for name in entry["files"].values():
            assert (out / name).is_file()
    assert not list(out.glob("*.partial")) and not list(out.glob(".*"))


@pytest.mark.parametrize("illuminant", ["D65", "FL2"])
@pytest.mark.parametrize("factor", FACTORS)
def test_files_hold_exactly_the_simulated_frame(rendered, scene, illuminant, factor):
    out, manifest = rendered
    entry = next(f for f in manifest["frames"] if f["illuminant"] == illuminant and f["intensity_factor"] == factor)
    files = entry["files"]
    # the same frame, rendered again in memory from the same seed
    frame, radiance = render(scene, factor=factor, seed=frame_seed_sequence(42, illuminant, factor),
                             illuminant=illuminant)
    with rawpy.imread(str(out / files["dng"])) as raw:
        np.testing.assert_array_equal(raw.raw_image[..., :3], frame.digital_dn.transpose(1, 2, 0))
        assert raw.white_level == 255
        np.testing.assert_array_equal(raw.black_level_per_channel[:3], libraw_black_levels(out / files["dng"]))
        picture = raw.postprocess(use_camera_wb=True)
    np.testing.assert_allclose(libraw_black_levels(out / files["dng"]), frame.sensor.black_level_dn, atol=0.5 + 1e-6)
    assert picture.shape == (scene.height, scene.width, 3)
    dn, info = read_dng(out / files["dng"])
    np.testing.assert_allclose(info["black_level_exact"], frame.sensor.black_level_dn, atol=1e-6)
    assert info["noise_profile"] == frame_noise_profile(frame, "pixel").tolist()  # the DNG's, as the sidecar's
    noisy, clean, header = read_exr(out / files["exr"])
    noisy_oiio, clean_oiio, header_oiio = read_exr_oiio(out / files["exr"])
    for n, c in ((noisy, clean), (noisy_oiio, clean_oiio)):
        np.testing.assert_array_equal(n, frame.noisy_dn)
        np.testing.assert_array_equal(c, frame.clean_dn())
    sidecar = json.loads((out / files["json"]).read_text())
    for h in (header, header_oiio):
        assert json.loads(h["camsim:metadata"]) == sidecar
        assert h["camsim:illuminant"] == illuminant and float(h["camsim:intensity_factor"]) == factor
        assert float(h["camsim:dn_per_electron"]) == frame.sensor.dn_per_electron
    assert SIDECAR_KEYS <= set(sidecar)
    assert sidecar["noise_profile"] == info["noise_profile"]
    assert sidecar["files"] == files and sidecar["illuminant"] == illuminant
    assert sidecar["camera"] == "Nikon 5100 (NPL)" and sidecar["reflectances"] == "ColorChecker N Ohta"
    assert len(sidecar["patches"]) == 24 and sidecar["patches"][18]["name"] == "white 9.5 (.05 D)"
    for index, patch in enumerate(sidecar["patches"]):
        x, y, w, h = patch["rect_xywh"]
        assert np.all(radiance.labels[y : y + h, x : x + w] == index)
        np.testing.assert_allclose(patch["signal_e"], frame.expected.signal_e[index], rtol=1e-12)
        np.testing.assert_allclose(patch["dark_e"], frame.expected.dark_e, rtol=1e-12)


def _bytes(folder):
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_same_seed_gives_byte_identical_files_whatever_the_threads(scene, tmp_path, monkeypatch):
    one = scene.replace(illuminants=("D65",), intensity_factors=(0.1,))
    monkeypatch.setattr(render_module, "BLOCK_PIXELS", 4096)  # many row blocks
    render_scene(one, tmp_path / "a", workers=1, progress=False)
    render_scene(one, tmp_path / "b", workers=2, progress=False)
    render_scene(one, tmp_path / "c", workers=3, progress=False)
    a = _bytes(tmp_path / "a")
    assert a == _bytes(tmp_path / "b") == _bytes(tmp_path / "c")
    render_scene(one.replace(seed=43), tmp_path / "d", workers=2, progress=False)
    d = _bytes(tmp_path / "d")
    for name in a:
        if name.endswith((".dng", ".exr")):
            assert a[name] != d[name]
    dn_a, _ = read_dng(tmp_path / "a" / "test_D65_F0.1.dng")
    dn_d, _ = read_dng(tmp_path / "d" / "test_D65_F0.1.dng")
    assert np.mean(dn_a != dn_d) > 0.5  # different noise, not a shifted copy


def test_a_frame_does_not_depend_on_the_other_frames_of_the_run(scene, tmp_path):
    render_scene(scene.replace(illuminants=("FL2",), intensity_factors=(0.02,)), tmp_path / "alone", progress=False)
    render_scene(scene, tmp_path / "all", progress=False)
    name = "test_FL2_F0.02.exr"
    assert (tmp_path / "alone" / name).read_bytes() == (tmp_path / "all" / name).read_bytes()


def test_no_dng_without_quantisation(scene, tmp_path):
    sc = scene.replace(illuminants=("D65",), intensity_factors=(1.0,)).with_sensor(quantisation=False)
    manifest = render_scene(sc, tmp_path, progress=False)
    files = manifest["frames"][0]["files"]
    assert files["dng"] is None and not list(tmp_path.glob("*.dng"))
    sidecar = json.loads((tmp_path / files["json"]).read_text())
    assert sidecar["stages"]["quantisation"] is False
    assert sidecar["noise_profile"] is None  # no DNG, no NoiseProfile


def test_render_frame_accepts_a_generator_seed_or_seed_sequence(scene):
    from camsim.render.frame import render_frame
    from camsim.render.pipeline import lit_scene
    from camsim.scene.radiance import scene_radiance
    from camsim.sensor.camera import load_camera

    radiance = scene_radiance(scene, "D65")
    camera = load_camera(scene.camera, scene.grid)
    expected = lit_scene(radiance, camera, scene.scale, scene.grid).expected(scene.sensor, 0.1, "pixel")
    frames = [render_frame(radiance.labels, expected, scene.sensor, rng=r)
              for r in (7, np.random.SeedSequence(7), np.random.default_rng(7), np.random.default_rng(7))]
    np.testing.assert_array_equal(frames[0].noisy_dn, frames[1].noisy_dn)
    np.testing.assert_array_equal(frames[2].noisy_dn, frames[3].noisy_dn)


def test_sidecar_patch_xyz_is_the_lights_colour(rendered):
    out, manifest = rendered
    for entry in manifest["frames"]:
        sidecar = json.loads((out / entry["files"]["json"]).read_text())
        white = np.array(sidecar["patches"][18]["xyz_cd_m2"])
        # the ColorChecker white reflects ~ 88–90 % of a 100 cd/m² perfect white, scaled by F
        assert 85 * entry["intensity_factor"] < white[1] < 92 * entry["intensity_factor"]


# --- a frame folder with files that are not regular ---------------------------------------------------------

@pytest.fixture(scope="module")
def two_frames(tmp_path_factory):
    """A folder of two committed frames (DNG, EXR, JSON each) at F = 1 and 0.5."""
    from camsim.cli import main

    out = tmp_path_factory.mktemp("two") / "frames"
    assert main(["render", "macbeth_26", "--size", "96x64", "--illuminant", "D65", "--intensity", "1", "0.5", "-q",
                 "--workers", "1", "--out", str(out)]) == 0
    return out


@pytest.mark.parametrize("command", ["analyze", "develop", "denoise-eval"])
@pytest.mark.parametrize("suffix", [".dng", ".exr"])
def test_a_fifo_by_a_frame_files_name_in_a_folder_blocks_no_command(two_frames, tmp_path, capfd, command,
                                                                   suffix):
    """A FIFO named as a committed frame's DNG or EXR (its sidecar claims it) in a folder searched for frames: the
    search takes regular files only, so no reader opens it (one would wait for a writer forever); the other frame
    is read as usual."""
    import shutil

    from camsim.cli import main
    from tests.support.hostile_files import no_hang, not_regular

    folder = tmp_path / "frames"
    shutil.copytree(two_frames, folder)
    (victim,) = folder.glob(f"*F0.5{suffix}")
    not_regular(victim, "fifo")
    argv = {"analyze": ["analyze", str(folder), "--border", "0", "--out", str(tmp_path / "out")],
            "develop": ["develop", str(folder), "--out", str(tmp_path / "out")],
            "denoise-eval": ["denoise-eval", str(folder), "--denoiser", "identity", "--out", str(tmp_path / "out")]}
    capfd.readouterr()
    with no_hang(f"{command} of a folder with a FIFO {victim.name}", seconds=120):
        status = main([*argv[command], "-q"])
    _, err = capfd.readouterr()
    assert status == 0, err
    assert "Traceback" not in err


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_a_frame_named_that_is_no_regular_file_is_named_as_such(tmp_path, capfd, kind):
    from camsim.cli import main
    from tests.support.hostile_files import not_regular, one_error_line

    path = not_regular(tmp_path / "x.dng", kind)
    capfd.readouterr()
    assert main(["develop", str(path), "--out", str(tmp_path / "out"), "-q"]) == 2
    what = "a FIFO (named pipe)" if kind == "fifo" else "a character device"
    assert one_error_line(capfd.readouterr().err) == f"camsim: error: {path}: it is {what}, not a regular file"
