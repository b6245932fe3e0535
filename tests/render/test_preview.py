"""The sRGB preview (camsim.render.preview, render_scene(..., preview=True)):
colours, white balance, exposure, files."""

import dataclasses
import json

import imageio.v3 as iio
import numpy as np
import pytest

from camsim.core.errors import CamsimError
from camsim.core.seeding import frame_seed_sequence
from camsim.io.exr import read_exr
from camsim.render.preview import preview_srgb, write_preview_png
from camsim.render.run import render_scene
from camsim.scene.scene_file import load_scene
from tests.support.helpers import ROOT, render

SEED = 11
WHITE, GREYS, BLUE, GREEN, RED = 18, range(18, 24), 12, 13, 14


@pytest.fixture(scope="module")
def scene():
    """The default scene, small: D65 and A at F = 1 and 0.01."""
    return load_scene(ROOT / "scenes" / "macbeth_26.toml").replace(
        width=240, height=160, illuminants=("D65", "A"), intensity_factors=(1.0, 0.01), seed=SEED)


@pytest.fixture(scope="module")
def rendered(scene, tmp_path_factory):
    out = tmp_path_factory.mktemp("preview")
    return out, render_scene(scene, out, progress=False, preview=True)


def entry(manifest, illuminant, factor):
    return next(f for f in manifest["frames"] if f["illuminant"] == illuminant and f["intensity_factor"] == factor)


def picture(rendered, illuminant, factor):
    out, manifest = rendered
    files = entry(manifest, illuminant, factor)["files"]
    return iio.imread(out / files["png"]), json.loads((out / files["json"]).read_text())


def patch_means(image, sidecar, border=4):
    """Mean sRGB (R, G, B) of each patch's interior, shape (patches, 3)."""
    means = []
    for patch in sidecar["patches"]:
        x, y, w, h = patch["rect_xywh"]
        means.append(image[y + border:y + h - border, x + border:x + w - border].reshape(-1, 3).mean(axis=0))
    return np.array(means)


def assert_neutral_bright_white(means, spread=15):
    white = means[WHITE]
    assert np.all(white > 200), white
    assert np.ptp(white) < spread, white


def test_d65_colours(rendered):
    image, sidecar = picture(rendered, "D65", 1.0)
    assert image.shape == (160, 240, 3) and image.dtype == np.uint8
    means = patch_means(image, sidecar)
    assert_neutral_bright_white(means)
    greys = means[list(GREYS)]
    assert np.all(np.ptp(greys, axis=1) < 15), greys
    assert np.all(np.diff(greys.mean(axis=1)) < -20), greys  # white → black, clearly ordered
    r, g, b = means[RED]
    assert r > g + 50 and r > b + 50
    r, g, b = means[BLUE]
    assert b > r + 50 and b > g + 50
    r, g, b = means[GREEN]
    assert g > r + 30 and g > b + 30


def test_illuminant_a_is_white_balanced(rendered):
    image, sidecar = picture(rendered, "A", 1.0)
    means = patch_means(image, sidecar)
    assert_neutral_bright_white(means)
    assert np.all(np.ptp(means[[19, 20, 21]], axis=1) < 15)
    assert means[RED, 0] > means[RED, 1:].max() and means[BLUE, 2] > means[BLUE, :2].max()


def test_low_light_is_darker_by_f_and_auto_exposure_brings_it_back(rendered, scene):
    bright, sidecar = picture(rendered, "D65", 1.0)
    dark, dark_sidecar = picture(rendered, "D65", 0.01)
    white_bright, white_dark = patch_means(bright, sidecar)[WHITE], patch_means(dark, dark_sidecar)[WHITE]
    # default exposure: F = 0.01 puts the white at Y ≈ 0.009, sRGB ≈ 0.1
    assert np.all((white_dark > 12) & (white_dark < 40)), white_dark
    frame, _ = render(scene, factor=0.01, seed=frame_seed_sequence(SEED, "D65", 0.01))
    auto = preview_srgb(frame, dark_sidecar, exposure="auto")
    white_auto = patch_means(auto, dark_sidecar)[WHITE]
    # exposed like F = 1 (a little below it on average: ±1 DN steps are clipped at white and encoded non-linearly)
    assert np.all((white_auto > 180) & (white_auto <= white_bright)), (white_auto, white_bright)
    # the noise is amplified with the signal: a grey patch is much noisier than at F = 1
    x, y, w, h = sidecar["patches"][21]["rect_xywh"]
    assert auto[y + 4:y + h - 4, x + 4:x + w - 4].std() > 3 * bright[y + 4:y + h - 4, x + 4:x + w - 4].std()
    # a gain is a multiple of the scene exposure
    np.testing.assert_array_equal(preview_srgb(frame, dark_sidecar, exposure=100.0), auto)
    with pytest.raises(CamsimError, match="exposure"):
        preview_srgb(frame, dark_sidecar, exposure="bright")
    with pytest.raises(CamsimError, match="exposure"):
        preview_srgb(frame, dark_sidecar, exposure=-1.0)


def test_png_is_the_preview_and_listed_in_the_sidecar(rendered, scene):
    out, manifest = rendered
    for illuminant in scene.illuminants:
        for factor in scene.intensity_factors:
            files = entry(manifest, illuminant, factor)["files"]
            sidecar = json.loads((out / files["json"]).read_text())
            assert sidecar["files"] == files and files["png"] == files["json"][:-4] + "png"
            frame, _ = render(scene, factor=factor, seed=frame_seed_sequence(SEED, illuminant, factor),
                              illuminant=illuminant)
            np.testing.assert_array_equal(iio.imread(out / files["png"]), preview_srgb(frame, sidecar))
    assert not list(out.glob(".*"))  # no temporary left


def test_png_only_with_preview_and_other_files_unchanged(rendered, scene, tmp_path):
    out, manifest = rendered
    plain = render_scene(scene, tmp_path, progress=False)
    assert not list(tmp_path.glob("*.png"))
    for frame, with_png in zip(plain["frames"], manifest["frames"]):
        files = frame["files"]
        assert list(files) == ["dng", "exr", "json", "xmp"]  # xmp: darktable's sidecar of the three-chip DNG
        assert with_png["files"] == files | {"png": files["json"][:-4] + "png"}
        assert (tmp_path / files["dng"]).read_bytes() == (out / files["dng"]).read_bytes()
        # the EXR holds the same pixels; its header carries the sidecar, whose files now list the PNG
        plain_exr, with_exr = read_exr(tmp_path / files["exr"]), read_exr(out / files["exr"])
        for a, b in zip(plain_exr[:2], with_exr[:2]):
            np.testing.assert_array_equal(a, b)
        a = json.loads((tmp_path / files["json"]).read_text())
        b = json.loads((out / files["json"]).read_text())
        assert json.loads(with_exr[2]["camsim:metadata"]) == b
        assert b.pop("files") == with_png["files"] and a.pop("files") == files and a == b


def test_png_bytes_are_deterministic(rendered, scene, tmp_path):
    out, manifest = rendered
    one = scene.replace(illuminants=("A",), intensity_factors=(0.01,))
    again = render_scene(one, tmp_path, progress=False, preview=True)
    name = again["frames"][0]["files"]["png"]
    assert name == entry(manifest, "A", 0.01)["files"]["png"]
    assert (tmp_path / name).read_bytes() == (out / name).read_bytes()


def test_bayer_frame(scene, tmp_path):
    bayer = scene.replace(illuminants=("D65",), intensity_factors=(1.0,)).with_sensor(cfa="GRBG")
    manifest = render_scene(bayer, tmp_path, progress=False, preview=True)
    files = manifest["frames"][0]["files"]
    image, sidecar = iio.imread(tmp_path / files["png"]), json.loads((tmp_path / files["json"]).read_text())
    assert image.shape == (160, 240, 3)
    means = patch_means(image, sidecar)
    assert_neutral_bright_white(means)
    assert means[RED, 0] > means[RED, 1:].max() + 50 and means[BLUE, 2] > means[BLUE, :2].max() + 50


@pytest.mark.parametrize("cfa", [None, "BGGR"])
def test_row_blocks_do_not_change_the_picture(scene, monkeypatch, cfa):
    from colour_demosaicing import demosaicing_CFA_Bayer_bilinear

    import camsim.render.preview as preview_module

    one = scene if cfa is None else scene.with_sensor(cfa=cfa)
    frame, _ = render(one, one.sensor, factor=0.1, seed=5)
    info = {"intensity_factor": 0.1, "luminance_cd_m2": 100.0, "wavelengths_nm": one.grid.wavelengths_nm.tolist(),
            "as_shot_neutral": [0.5, 1.0, 0.8], "patches": []}  # the paper's matrix: no patches needed
    whole = preview_srgb(frame, info)  # 160 rows: one block
    for block in (240 * 6, 240 * 5, 240 * 3):  # 6, 4 and 2 rows a block
        monkeypatch.setattr(preview_module, "BLOCK_PIXELS", block)
        np.testing.assert_array_equal(preview_srgb(frame, info), whole)
    if cfa is not None:  # a block's demosaicing is the whole frame's (away from the frame's left and right
        # edges, where colour-demosaicing's mirrored kernels do not sum to one and the black level is better
        # subtracted first, as the preview does)
        expected = np.asarray(demosaicing_CFA_Bayer_bilinear(frame.digital_dn[0].astype(np.float64), cfa))
        got = preview_module._camera_dn(frame, 40, 60)
        black = frame.sensor.black_level_dn
        np.testing.assert_allclose(got[:, 1:-1], expected[40:60, 1:-1] - black, atol=1e-9)


def test_unquantised_frame(scene, rendered, tmp_path):
    float_scene = scene.replace(illuminants=("D65",), intensity_factors=(1.0,)).with_sensor(quantisation=False)
    manifest = render_scene(float_scene, tmp_path, progress=False, preview=True)
    files = manifest["frames"][0]["files"]
    assert files["dng"] is None
    image, sidecar = iio.imread(tmp_path / files["png"]), json.loads((tmp_path / files["json"]).read_text())
    quantised, _ = picture(rendered, "D65", 1.0)
    # the same frame before and after Eq. 11: ½ DN of bias is removed, so the pictures agree closely
    np.testing.assert_allclose(patch_means(image, sidecar), patch_means(quantised, sidecar), atol=2.0)


def test_paper_matrix_and_frames_without_patches(rendered, scene):
    _, sidecar = picture(rendered, "D65", 1.0)
    frame, _ = render(scene, factor=1.0, seed=frame_seed_sequence(SEED, "D65", 1.0))
    paper = patch_means(preview_srgb(frame, sidecar, matrix="paper"), sidecar)
    assert_neutral_bright_white(paper)
    assert np.all(np.diff(paper[list(GREYS)].mean(axis=1)) < -20)
    # without patch XYZ (a cube scene) the preview falls back to the paper's matrix
    bare = dict(sidecar, patches=[dict(p, xyz_cd_m2=None) for p in sidecar["patches"]])
    np.testing.assert_array_equal(preview_srgb(frame, bare), preview_srgb(frame, sidecar, matrix="paper"))
    with pytest.raises(CamsimError, match="matrix"):
        preview_srgb(frame, sidecar, matrix="identity")


def test_frame_info_and_sidecar_give_the_same_picture(rendered, scene):
    from camsim.render.frame_files import FrameInfo

    _, sidecar = picture(rendered, "A", 1.0)
    frame, _ = render(scene, factor=1.0, seed=frame_seed_sequence(SEED, "A", 1.0), illuminant="A")
    info = FrameInfo(
        scene=sidecar["scene"], illuminant="A", intensity_factor=1.0, seed=SEED, photon_statistics="pixel",
        method="poisson", camera=sidecar["camera"], sensitivity_basis="energy", reflectances="",
        wavelengths_nm=np.array(sidecar["wavelengths_nm"]), luminance_cd_m2=sidecar["luminance_cd_m2"],
        normalisation="chart", scale={}, patch_names=[], patch_rects=[],
        color_matrix1=np.array(sidecar["color_matrix1_xyz_to_camera"]),
        as_shot_neutral=np.array(sidecar["as_shot_neutral"]),
        patch_xyz=np.array([p["xyz_cd_m2"] for p in sidecar["patches"]]),
    )
    np.testing.assert_array_equal(preview_srgb(frame, info), preview_srgb(frame, sidecar))
    np.testing.assert_array_equal(preview_srgb(frame, dataclasses.replace(info, patch_xyz=None)),
                                  preview_srgb(frame, sidecar, matrix="paper"))


def test_write_preview_png_refuses_other_arrays(tmp_path):
    with pytest.raises(ValueError, match="uint8"):
        write_preview_png(tmp_path / "x.png", np.zeros((4, 4, 3), dtype=np.float32))
    assert not list(tmp_path.iterdir())
