"""An EXR frame in an image viewer: its default picture (the unprefixed R, G, B) looks like the scene, while the
DN stay in the ``noisy`` and ``clean`` layers bit for bit — through OpenImageIO (what ``iv`` and ``oiiotool``
read) and OpenEXR, independently of camsim's readers."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import OpenEXR
import OpenImageIO as oiio
import pytest

from camsim.cli import main
from camsim.io.exr import read_exr, read_exr_oiio
from camsim.render.frame_files import exr_view, load_frame
from camsim.render.pipeline import scene_frame
from camsim.render.run import render_scene
from camsim.scene.scene_file import load_scene
from tests.support.helpers import small_scene

ROOT = Path(__file__).resolve().parents[2]
DEFAULT_SCENE = ROOT / "scenes" / "macbeth_26.toml"
BLACK, WHITE = "black 2 (1.5 D)", "white 9.5 (.05 D)"
#: IEC 61966-2-1: linear sRGB → CIE 1931 XYZ (D65 white), written out here rather than taken from camsim.
SRGB_TO_XYZ = np.array([[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]])


def viewer_pixels(path):
    """What a viewer reads: OpenImageIO's first subimage, channels R, G, B; shape (H, W, 3) float32."""
    inp = oiio.ImageInput.open(str(path))
    assert inp is not None, oiio.geterror()
    try:
        spec = inp.spec()
        assert spec.get_int_attribute("oiio:subimages", 1) == 1 and tuple(spec.channelnames[:3]) == ("R", "G", "B")
        pixels = np.asarray(inp.read_image(0, 0, 0, 3, "float"))
    finally:
        inp.close()
    return pixels.reshape(spec.height, spec.width, 3)


def all_channels_oiio(path):
    inp = oiio.ImageInput.open(str(path))
    try:
        spec = inp.spec()
        pixels = np.asarray(inp.read_image(0, 0, 0, spec.nchannels, "float")).reshape(spec.height, spec.width, -1)
        return {name: pixels[..., i] for i, name in enumerate(spec.channelnames)}
    finally:
        inp.close()


def all_channels_openexr(path):
    with OpenEXR.File(str(path), separate_channels=True) as f:
        header = {k: v for k, v in f.header().items() if isinstance(v, str)}
        return {name: ch.pixels.copy() for name, ch in f.channels().items()}, header


def patch_means(pixels, sidecar):
    means = {}
    for patch in sidecar["patches"]:
        x, y, w, h = patch["rect_xywh"]
        means[patch["name"]] = pixels[y + 2:y + h - 2, x + 2:x + w - 2].reshape(-1, 3).mean(axis=0)
    return means


def bits(a):
    return np.ascontiguousarray(a, dtype=np.float32).view(np.uint32)


@pytest.fixture(scope="module")
def default_frame(tmp_path_factory):
    """``camsim render scenes/macbeth_26.toml --illuminant D65 --intensity 1``."""
    out = tmp_path_factory.mktemp("default")
    assert main(["render", str(DEFAULT_SCENE), "--illuminant", "D65", "--intensity", "1", "--out", str(out),
                 "-q"]) == 0
    path = out / "macbeth_26_D65_F1.exr"
    return path, json.loads(path.with_suffix(".json").read_text())


def test_a_viewer_shows_the_default_frame_with_black_near_0_and_white_near_1(default_frame):
    path, sidecar = default_frame
    means = patch_means(viewer_pixels(path), sidecar)
    assert np.all((means[BLACK] > 0.0) & (means[BLACK] < 0.06)), means[BLACK]  # reflectance about 3 %
    assert np.all((means[WHITE] > 0.8) & (means[WHITE] <= 1.0)), means[WHITE]  # reflectance about 90 %
    for name in (WHITE, "neutral 8 (.23 D)", "neutral 5 (.70 D)"):  # grey is grey (white-balanced to D65)
        assert np.ptp(means[name]) < 0.02 * means[name].max(), (name, means[name])


def test_the_viewers_colours_are_the_patches_colours(default_frame):
    """The viewer's linear sRGB of each patch, through the IEC 61966-2-1 matrix, against the patch's XYZ in the
    sidecar (the spectra through the CIE 1931 observer), relative to the perfect white at F = 1."""
    import colour

    path, sidecar = default_frame
    means = patch_means(viewer_pixels(path), sidecar)
    white = colour.xy_to_XYZ(colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"])
    shown = np.array([SRGB_TO_XYZ @ means[p["name"]] for p in sidecar["patches"]])
    truth = np.array([p["xyz_cd_m2"] for p in sidecar["patches"]]) / sidecar["luminance_cd_m2"]
    delta_e = colour.delta_E(colour.XYZ_to_Lab(shown, white), colour.XYZ_to_Lab(truth, white), method="CIE 2000")
    assert np.mean(delta_e) < 2.0 and np.max(delta_e) < 6.0, delta_e


def test_the_dn_are_recovered_bit_for_bit_and_the_readers_agree(default_frame):
    path, sidecar = default_frame
    scene = load_scene(DEFAULT_SCENE)
    frame, _ = scene_frame(scene, "D65", 1.0)  # the same frame, rendered again in memory
    exr_channels, header = all_channels_openexr(path)
    oiio_channels = all_channels_oiio(path)
    assert sorted(exr_channels) == sorted(oiio_channels) == sorted(
        ["R", "G", "B", "noisy.R", "noisy.G", "noisy.B", "clean.R", "clean.G", "clean.B"])
    for name, plane in exr_channels.items():  # OpenEXR and OpenImageIO: the same bits in every channel
        np.testing.assert_array_equal(bits(oiio_channels[name]), bits(plane), err_msg=name)
    for i, c in enumerate("RGB"):  # the DN, in the layers
        np.testing.assert_array_equal(bits(exr_channels[f"noisy.{c}"]), bits(frame.noisy_dn[i]))
        np.testing.assert_array_equal(bits(exr_channels[f"clean.{c}"]), bits(frame.clean_dn()[i]))
    for reader in (read_exr, read_exr_oiio):
        noisy, clean, _ = reader(path)
        np.testing.assert_array_equal(bits(noisy), bits(frame.noisy_dn))
        np.testing.assert_array_equal(bits(clean), bits(frame.clean_dn()))
    np.testing.assert_array_equal(bits(load_frame(path).pixels_dn), bits(frame.noisy_dn))
    # the picture is what the header says: camsim:view_matrix @ (noisy - camsim:dark_level_dn)
    matrix = np.array(json.loads(header["camsim:view_matrix"]))
    dark = np.array(json.loads(header["camsim:dark_level_dn"]))
    assert header["camsim:view"].startswith("linear sRGB") and int(header["camsim:white_level_dn"]) == 255
    noisy = np.stack([exr_channels[f"noisy.{c}"] for c in "RGB"]).astype(np.float64) - dark[:, None, None]
    expected = np.einsum("ij,jyx->iyx", matrix, noisy)
    view = np.stack([exr_channels[c] for c in "RGB"])
    np.testing.assert_allclose(view, expected, rtol=1e-5, atol=1e-6)


def test_a_bayer_frame_shows_the_scene_and_keeps_its_mosaic(tmp_path):
    scene = small_scene(width=240, height=160, intensity_factors=(1.0,), seed=7).with_sensor(cfa="RGGB")
    render_scene(scene, tmp_path, progress=False)
    path = tmp_path / "test_D65_F1.exr"
    sidecar = json.loads(path.with_suffix(".json").read_text())
    means = patch_means(viewer_pixels(path), sidecar)
    assert np.all((means[BLACK] > 0.0) & (means[BLACK] < 0.06)) and np.all((means[WHITE] > 0.8) &
                                                                            (means[WHITE] <= 1.0)), means
    exr_channels, _ = all_channels_openexr(path)
    assert sorted(exr_channels) == sorted(["R", "G", "B", "noisy.CFA", "clean.R", "clean.G", "clean.B"])
    frame, _ = scene_frame(scene, "D65", 1.0)
    np.testing.assert_array_equal(bits(exr_channels["noisy.CFA"]), bits(frame.noisy_dn[0]))
    for reader in (read_exr, read_exr_oiio):
        np.testing.assert_array_equal(bits(reader(path)[0]), bits(frame.noisy_dn))


def test_without_patches_to_fit_on_the_view_takes_eq_15s_matrix_and_still_shows_white_near_1():
    scene = small_scene(width=240, height=160, intensity_factors=(1.0,))
    frame, info = scene_frame(scene, "D65", 1.0)
    view, header = exr_view(frame, dataclasses.replace(info, patch_xyz=None))  # as a cube or an image scene
    assert "Eq. 15" in header["camsim:view"] and "fitted" not in header["camsim:view"]
    sidecar = {"patches": [{"name": n, "rect_xywh": r} for n, r in zip(info.patch_names, info.patch_rects)]}
    means = patch_means(np.moveaxis(view, 0, -1), sidecar)
    assert np.all((means[WHITE] > 0.8) & (means[WHITE] <= 1.0)) and np.all(np.abs(means[BLACK]) < 0.06), means


def test_without_a_white_balance_the_view_is_the_camera_rgb_between_dark_and_white_level():
    """The last resort of :func:`exr_view`: where no camera → sRGB matrix can be made (here: a scene white of 0),
    the camera's R, G, B with the dark level at 0 and the white level at 1."""
    scene = small_scene(width=120, height=80, intensity_factors=(1.0,))
    frame, info = scene_frame(scene, "D65", 1.0)
    view, header = exr_view(frame, dataclasses.replace(info, as_shot_neutral=np.zeros(3)))
    black = np.array(json.loads(header["camsim:view_black_dn"]))
    np.testing.assert_allclose(black, frame.sensor.dark_level_dn, rtol=1e-12)
    assert header["camsim:view"].startswith("camera R, G, B")
    expected = (frame.noisy_dn - black[:, None, None]) / (frame.sensor.max_dn - black[:, None, None])
    np.testing.assert_allclose(view, expected, rtol=1e-6, atol=1e-7)


def test_frames_written_before_the_view_still_read(default_frame, tmp_path):
    """A frame in the earlier layout (the noisy DN in R, G, B, no noisy layer), written with OpenEXR directly."""
    path, _ = default_frame
    channels, header = all_channels_openexr(path)
    old = {c: channels[f"noisy.{c}"] for c in "RGB"} | {f"clean.{c}": channels[f"clean.{c}"] for c in "RGB"}
    old_header = {k: v for k, v in header.items() if not k.startswith("camsim:view") and k != "camsim:white_level_dn"}
    old_path = tmp_path / path.name
    with OpenEXR.File({"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage} | old_header,
                      old) as f:
        f.write(str(old_path))
    for reader in (read_exr, read_exr_oiio):
        noisy, clean, _ = reader(old_path)
        for i, c in enumerate("RGB"):
            np.testing.assert_array_equal(bits(noisy[i]), bits(channels[f"noisy.{c}"]))
            np.testing.assert_array_equal(bits(clean[i]), bits(channels[f"clean.{c}"]))
    np.testing.assert_array_equal(bits(load_frame(old_path).pixels_dn), bits(load_frame(path).pixels_dn))
