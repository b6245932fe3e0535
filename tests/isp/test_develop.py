"""The camera ISP (camsim.isp): colour against the ColorChecker's true colours, LibRaw's development of the same
DNG, each stage against its formula, packing, the record and the writers."""

import json
import shutil

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import camsim.isp as isp
from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.render.frame_files import load_frame
from camsim.sensor.cfa import CFA_PATTERNS
from tests.support.profiles import examples

BORDER = 8  # pixels left out along each edge of a patch
WHITE = 18  # "white 9.5 (.05 D)" in ColorChecker order
CHART_MARGIN = 0.3
"""ΔE00 allowed above the camera's colorimetric error for noise, quantisation and demosaicing (measured on
2026-11-25: at most 0.004 above it, see the test)."""


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    """macbeth_26 at F = 1 under D65: a Bayer sony-a7s2 frame (14-bit RGGB) and a three-chip paper-table1 one."""
    out = tmp_path_factory.mktemp("isp")
    for name, extra in (("bayer", ["--preset", "sony-a7s2"]), ("chip3", [])):
        assert main(["render", "macbeth_26", *extra, "-F", "1", "--illuminant", "D65", "--seed", "3",
                     "--out", str(out / name), "-q"]) == 0
    files = {name: out / name / "macbeth_26_D65_F1.dng" for name in ("bayer", "chip3")}
    return files | {"bayer-exr": files["bayer"].with_suffix(".exr")}


def _colour():
    import colour

    return colour


def _lab_of_linear_srgb(rgb):
    colour = _colour()
    srgb = colour.RGB_COLOURSPACES["sRGB"]
    return colour.XYZ_to_Lab(colour.RGB_to_XYZ(rgb, srgb, apply_cctf_decoding=False), srgb.whitepoint)


def _patch_means(image, meta, count=24):
    means = []
    for patch in meta["patches"][:count]:
        x, y, w, h = patch["rect_xywh"]
        means.append(image[:, y + BORDER:y + h - BORDER, x + BORDER:x + w - BORDER].mean(axis=(1, 2)))
    return np.array(means, dtype=np.float64)


def _white_gain(meta):
    """The gain that puts the perfect white under the frame's light (the sidecar's white_signal_e) at 1."""
    green = meta["white_signal_e"][1] * meta["dn_per_electron"] / (meta["white_level_dn"] - meta["black_level_dn"][1])
    return 1.0 / green


def _chart_truth(meta):
    """CIELAB (D65 white) of the 24 patches under D65, the perfect white Y = 1: colour-science from the chart's
    reflectance spectra, independently of camsim."""
    colour = _colour()
    chart = colour.SDS_COLOURCHECKERS[meta["reflectances"]]
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    d65 = colour.SDS_ILLUMINANTS["D65"]
    xyz = np.array([colour.sd_to_XYZ(chart[p["name"]], cmfs, d65) for p in meta["patches"][:24]]) / 100.0
    white = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    return colour.XYZ_to_Lab(xyz, white)


def _expected_camera(meta):
    """The noise-free camera values of the 24 patches under D65, white-balanced and normalised so that the
    perfect white is (1, 1, 1): Σ_λ Qe(λ) ρ(λ) E(λ) λ (photons per unit energy ∝ λ) on the sidecar's grid."""
    colour = _colour()
    wl = np.asarray(meta["wavelengths_nm"])
    qe = np.asarray(meta["qe_e_m2_sr_per_photon"])
    shape = colour.SpectralShape(wl[0], wl[-1], wl[1] - wl[0])
    chart = colour.SDS_COLOURCHECKERS[meta["reflectances"]]
    refl = np.array([chart[p["name"]].copy().align(shape).values for p in meta["patches"][:24]])
    light = colour.SDS_ILLUMINANTS["D65"].copy().align(shape).values
    camera = (refl * light * wl) @ qe.T
    white = (light * wl) @ qe.T
    return camera / white


@pytest.mark.parametrize("kind, matrix", [("bayer", "camera"), ("chip3", "camera"), ("bayer", "paper"),
                                          ("bayer-exr", "camera")])
def test_colorchecker_within_the_cameras_colorimetric_error(frames, kind, matrix):
    """The developed chart's mean ΔE00 against its true sRGB colours is within the camera's colorimetric error —
    the same matrix on the patches' noise-free camera values — plus CHART_MARGIN.

    Measured on 2026-11-25 (seed 3, F = 1, D65, the camera "Nikon 5100 (NPL)" of both presets). The ``"camera"``
    matrix (fitted on 190 training reflectances, not the chart): bound 0.947 (largest 3.02), the developed a7s2
    Bayer frame (Malvar 2004) 0.950, the three-chip paper-table1 frame 0.944. The ``"paper"`` matrix (Eq. 15):
    bound 1.39 (largest 4.47), the Bayer frame 1.39. ``bayer-exr`` is the Bayer frame's EXR: its float values
    before quantisation, less the level before the ADC.
    """
    loaded = load_frame(frames[kind])
    meta, facts = loaded.meta, isp.facts_of(loaded)
    truth = _chart_truth(meta)
    stages = isp.develop_stages(loaded.pixels_dn, facts,
                                isp.IspSettings(gain=_white_gain(meta), tone="linear", matrix=matrix))
    developed = _patch_means(stages["gained"], meta)
    matrix = isp.srgb_matrix(facts, "as-shot", matrix)
    expected = _expected_camera(meta) @ matrix.T
    colour = _colour()
    bound = colour.delta_E(_lab_of_linear_srgb(expected), truth, method="CIE 2000")
    found = colour.delta_E(_lab_of_linear_srgb(developed), truth, method="CIE 2000")
    assert bound.mean() < 2.0, bound.mean()  # a sound matrix: the chart within a few ΔE00
    assert found.mean() <= bound.mean() + CHART_MARGIN, (found.mean(), bound.mean())
    white = isp.develop(loaded.pixels_dn, facts, isp.IspSettings(gain="white")).record["stages"]["gain"]["value"]
    assert white == pytest.approx(_white_gain(meta), rel=1e-9)  # gain "white" is the gain used here


def test_libraw_develops_the_same_dng_alike(frames, tmp_path):
    """LibRaw's development (rawpy: camera white balance, sRGB output, gamma (2.4, 12.92), no auto-bright, 16 bits,
    its own AHD demosaic) against camsim's on the Bayer chart's 24 patches.

    Measured on 2026-11-25: from the DNG's own tags (ColorMatrix1, AsShotNeutral, as LibRaw) or with
    ``matrix="dng"``, mean ΔE00 0.09 (largest 0.69): the white balance and matrix agree, the rest is the demosaicing
    and LibRaw's integer steps; with the spectral ``"camera"`` matrix (fitted on other reflectances than
    ColorMatrix1's ColorChecker), 0.18 (largest 0.77).
    """
    import rawpy

    path = frames["bayer"]
    loaded = load_frame(path)
    meta = loaded.meta
    gain = _white_gain(meta)
    with rawpy.imread(str(path)) as raw:
        out = raw.postprocess(use_camera_wb=True, output_color=rawpy.ColorSpace.sRGB, gamma=(2.4, 12.92),
                              no_auto_bright=True, output_bps=16, bright=float(gain), user_flip=0)
    colour = _colour()
    libraw = np.moveaxis(colour.models.eotf_sRGB(out.astype(np.float64) / 65535.0), -1, 0)
    libraw_lab = _lab_of_linear_srgb(_patch_means(libraw, meta))
    alone = tmp_path / "alone.dng"  # the DNG without its sidecar: developed from its tags
    shutil.copy(path, alone)
    from camsim.isp.files import read_frame_to_develop

    tags, sidecar = read_frame_to_develop(alone).facts, isp.facts_of(loaded)
    for facts, matrix, limit in ((tags, "camera", 0.3), (sidecar, "dng", 0.3), (sidecar, "camera", 0.5)):
        settings_ = isp.IspSettings(gain=gain, tone="linear", matrix=matrix)
        image = isp.develop_stages(loaded.pixels_dn, facts, settings_)["gained"]
        difference = colour.delta_E(_lab_of_linear_srgb(_patch_means(image, meta)), libraw_lab, method="CIE 2000")
        assert difference.mean() <= limit, (matrix, facts.record()["colour_source"], difference.mean())


def _facts(pattern="RGGB", black=(60.0, 64.0, 70.0), white=1023.0, neutral=(0.5, 1.0, 0.8)):
    """Facts of a made-up camera: Gaussian QE bumps at 600, 540, 460 nm on a 400–700 nm grid."""
    wl = np.arange(400.0, 701.0, 10.0)
    qe = np.stack([np.exp(-0.5 * ((wl - c) / 40.0) ** 2) for c in (600.0, 540.0, 460.0)])
    return isp.IspFacts(cfa_pattern=pattern, black_dn=np.array(black), white_dn=white,
                        as_shot_neutral=np.array(neutral), intensity_factor=0.25, illuminant="D65",
                        wavelengths_nm=wl, qe=qe)


@pytest.mark.parametrize("pattern", [None, *CFA_PATTERNS])
def test_normalise_puts_each_channels_black_at_0_and_the_white_level_at_1(pattern):
    facts = _facts(pattern)
    black, white = facts.black_dn, facts.white_dn
    if pattern is None:
        raw = np.stack([np.full((4, 6), black[c]) for c in range(3)])
        assert np.allclose(isp.normalise(raw, facts), 0.0, atol=1e-6)
        assert np.allclose(isp.normalise(np.full((3, 4, 6), white), facts), 1.0, atol=1e-6)
        return
    raw = np.empty((4, 6))
    for i, letter in enumerate(pattern):
        raw[i // 2::2, i % 2::2] = black["RGB".index(letter)]
    assert isp.normalise(raw, facts).dtype == np.float32
    assert np.allclose(isp.normalise(raw, facts), 0.0, atol=1e-6)
    assert np.allclose(isp.normalise(np.full((4, 6), white), facts), 1.0, atol=1e-6)
    halfway = (raw + white) / 2
    assert np.allclose(isp.normalise(halfway, facts), 0.5, atol=1e-6)


@pytest.mark.parametrize("white_balance", ["as-shot", "A", "FL2"])
def test_the_matrix_maps_the_white_balanced_perfect_white_to_srgb_white(white_balance):
    """Under the white-balance illuminant the perfect white, white-balanced, is (1, 1, 1) and the matrix maps it to
    sRGB white (1, 1, 1), i.e. to D65's chromaticity (colour-science's sRGB → XYZ)."""
    facts = _facts()
    gains = isp.white_balance_gains(facts, white_balance)
    neutral = facts.as_shot_neutral if white_balance == "as-shot" else isp.stages.illuminant_neutral(facts,
                                                                                                     white_balance)
    assert gains[1] == 1.0
    assert np.allclose(neutral * gains, neutral[1], rtol=1e-12)
    matrix = isp.srgb_matrix(facts, white_balance)
    out = matrix @ (neutral * gains / neutral[1])
    assert np.allclose(out, 1.0, atol=1e-12), out
    colour = _colour()
    xy = colour.XYZ_to_xy(colour.RGB_to_XYZ(out, colour.RGB_COLOURSPACES["sRGB"], apply_cctf_decoding=False))
    assert np.allclose(xy, [0.3127, 0.3290], atol=1e-4)


def test_the_named_illuminants_neutral_is_the_cameras_response_to_its_white():
    """white balance "A": the gains make the camera's response to illuminant A (computed here from the QE)
    neutral."""
    colour = _colour()
    facts = _facts()
    wl = facts.wavelengths_nm
    light = colour.SDS_ILLUMINANTS["A"].copy().align(colour.SpectralShape(wl[0], wl[-1], wl[1] - wl[0])).values
    response = (light * wl) @ facts.qe.T
    balanced = response * isp.white_balance_gains(facts, "A")
    assert np.allclose(balanced / balanced[1], 1.0, rtol=1e-9)


@pytest.mark.parametrize("shape", [(16, 20), (2, 4), (4, 6), (5, 7), (3, 3)])
def test_demosaicing_a_constant_mosaic_gives_a_constant_image(shape):
    """Everywhere, the edges included (colour-demosaicing's own border handling alone gives bilinear 1.5× the value
    along the edges and 2.25× in a corner)."""
    mosaic = np.full(shape, 0.375, dtype=np.float32)
    for method in isp.DEMOSAIC_METHODS:
        for pattern in CFA_PATTERNS:
            rgb = isp.demosaic(mosaic, pattern, method)
            assert rgb.shape == (3, *shape) and rgb.dtype == np.float32
            assert np.allclose(rgb, 0.375, atol=1e-6), (method, pattern)


def test_demosaicing_keeps_each_sites_own_value():
    """Bilinear and Malvar interpolate only the missing colours: a site's own channel is its mosaic value."""
    rng = np.random.default_rng(1)
    mosaic = rng.random((12, 14)).astype(np.float32)
    for method in ("bilinear", "malvar2004"):
        for pattern in CFA_PATTERNS:
            rgb = isp.demosaic(mosaic, pattern, method)
            for i, letter in enumerate(pattern):
                c = "RGB".index(letter)
                assert np.allclose(rgb[c, i // 2::2, i % 2::2], mosaic[i // 2::2, i % 2::2], atol=1e-6)


def test_tone_curves_follow_their_formulas():
    x = np.linspace(-0.1, 1.3, 1401).reshape(1, 1, -1).repeat(3, axis=0)
    v = np.clip(x.astype(np.float64), 0.0, 1.0)
    srgb = np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)  # IEC 61966-2-1
    assert np.allclose(isp.tone_curve(x, "srgb"), srgb, atol=2e-6)
    p = np.maximum(x.astype(np.float64), 0.0)
    aces = np.clip(p * (2.51 * p + 0.03) / (p * (2.43 * p + 0.59) + 0.14), 0.0, 1.0)  # Narkowicz 2015
    filmic = np.where(aces <= 0.0031308, 12.92 * aces, 1.055 * aces ** (1 / 2.4) - 0.055)
    assert np.allclose(isp.tone_curve(x, "filmic"), filmic, atol=2e-6)
    assert np.array_equal(isp.tone_curve(x, "linear"), np.clip(x, 0, 1).astype(np.float32))
    colour = _colour()
    assert np.allclose(isp.tone_curve(x, "srgb"), colour.models.eotf_inverse_sRGB(v), atol=2e-6)
    with pytest.raises(CamsimError, match="unknown tone curve"):
        isp.tone_curve(x, "reinhard")


@settings(max_examples=examples(40), deadline=None)
@given(pattern=st.sampled_from(CFA_PATTERNS), h=st.integers(1, 6), w=st.integers(1, 6), seed=st.integers(0, 2**32 - 1))
def test_pack_and_unpack_are_exact_inverses(pattern, h, w, seed):
    mosaic = np.random.default_rng(seed).random((2 * h, 2 * w)).astype(np.float32)
    planes = isp.pack_rggb(mosaic, pattern)
    assert planes.shape == (4, h, w)
    assert np.array_equal(isp.unpack_rggb(planes, pattern), mosaic)
    assert np.array_equal(isp.pack_rggb(isp.unpack_rggb(planes, pattern), pattern), planes)


@pytest.mark.parametrize("pattern", CFA_PATTERNS)
def test_packed_planes_are_r_g1_g2_b(pattern):
    """Plane 0 holds the red sites, 3 the blue ones, 1 the green on red's row, 2 the green on blue's row."""
    letters = np.empty((4, 4), dtype="<U1")
    rows = np.empty((4, 4), dtype=int)
    for i, letter in enumerate(pattern):
        letters[i // 2::2, i % 2::2] = letter
    rows[:] = np.arange(4)[:, None]
    red_row = pattern.index("R") // 2
    planes = isp.pack_rggb(letters, pattern)
    assert (planes[0] == "R").all() and (planes[3] == "B").all()
    assert (planes[1] == "G").all() and (planes[2] == "G").all()
    assert (isp.pack_rggb(rows, pattern)[1] % 2 == red_row).all()
    assert (isp.pack_rggb(rows, pattern)[2] % 2 == 1 - red_row).all()


def test_packing_refuses_odd_sizes():
    with pytest.raises(CamsimError, match="even"):
        isp.pack_rggb(np.zeros((5, 6)), "RGGB")


def test_each_stage_is_switchable_and_recorded():
    facts = _facts(None)
    rng = np.random.default_rng(2)
    raw = facts.black_dn[:, None, None] + rng.random((3, 8, 10)) * 500
    base = isp.develop_stages(raw, facts)
    assert list(base) == list(isp.STAGE_NAMES)
    assert np.allclose(base["toned"], isp.develop(raw, facts).image)

    no_black = isp.develop_stages(raw, facts, isp.IspSettings(black=False))
    assert np.allclose(no_black["normalised"], raw / facts.white_dn, rtol=1e-6)
    none_wb = isp.develop(raw, facts, isp.IspSettings(white_balance="none"))
    assert none_wb.record["stages"]["white_balance"]["gains"] == [1.0, 1.0, 1.0]
    no_matrix = isp.develop_stages(raw, facts, isp.IspSettings(matrix="none"))
    assert np.array_equal(no_matrix["srgb_linear"], no_matrix["demosaiced"])
    assert isp.develop(raw, facts, isp.IspSettings(matrix="none")).record["stages"]["matrix"]["matrix"] is None
    with pytest.raises(CamsimError, match="ColorMatrix1"):  # these facts have none
        isp.develop(raw, facts, isp.IspSettings(matrix="dng"))
    with pytest.raises(CamsimError, match="white_signal_e"):  # nor the perfect white's signal
        isp.develop(raw, facts, isp.IspSettings(gain="white"))
    gained = isp.develop_stages(raw, facts, isp.IspSettings(gain=2.5, tone="linear"))
    assert np.allclose(gained["gained"], 2.5 * gained["srgb_linear"], rtol=1e-6)
    assert np.array_equal(gained["toned"], np.clip(gained["gained"], 0, 1))
    auto = isp.develop(raw, facts, isp.IspSettings(gain="auto"))
    assert auto.record["stages"]["gain"]["value"] == pytest.approx(1 / facts.intensity_factor)
    for settings_ in (isp.IspSettings(demosaic="bilinear", tone="filmic", white_balance="A"),
                      isp.IspSettings(black=False, matrix="none", gain=3.0)):
        record = isp.develop(raw, facts, settings_).record
        assert record["settings"] == settings_.record()
        json.dumps(record, allow_nan=False)
    with pytest.raises(CamsimError, match="demosaicing"):
        isp.IspSettings(demosaic="ahd")
    with pytest.raises(CamsimError, match="gain"):
        isp.IspSettings(gain=0.0)


def test_a_bayer_frames_stages_have_the_mosaics_shape_until_demosaiced():
    facts = _facts("GRBG")
    raw = np.full((8, 10), 300.0)
    stages = isp.develop_stages(raw, facts, isp.IspSettings(demosaic="bilinear"))
    assert stages["white_balanced"].shape == (8, 10)
    assert stages["demosaiced"].shape == (3, 8, 10)
    assert isp.develop(raw, facts).record["stages"]["demosaic"]["method"] == "malvar2004"
    assert isp.develop(np.full((3, 8, 10), 300.0), _facts(None)).record["stages"]["demosaic"] is None


def test_a_pair_is_developed_with_the_same_gains_and_matrix(frames):
    loaded = load_frame(frames["bayer"])
    facts = isp.facts_of(loaded)
    clean = loaded.pixels_dn.astype(np.float32) + 1.0
    noisy, target = isp.develop_pair(loaded.pixels_dn, clean, facts, isp.IspSettings(gain="auto"))
    assert noisy.record == target.record
    assert np.array_equal(target.image, isp.develop(clean, facts, isp.IspSettings(gain="auto")).image)
    with pytest.raises(CamsimError, match="shape"):
        isp.develop_pair(loaded.pixels_dn, clean[:, :-2], facts)


def test_the_in_memory_frame_develops_as_its_files_do(frames):
    """facts_from_info on the Frame and FrameInfo that the render wrote give the same picture as the files."""
    from camsim.render.pipeline import scene_frame
    from camsim.scene.scene_file import load_scene

    loaded = load_frame(frames["bayer"])
    scene = load_scene("macbeth_26").replace(preset_name="sony-a7s2", seed=3)
    frame, info = scene_frame(scene, "D65", 1.0)
    assert np.array_equal(frame.digital_dn, loaded.pixels_dn)  # the same frame as the command's
    settings_ = isp.IspSettings(gain="white")
    from_memory = isp.develop(frame.digital_dn, isp.facts_from_info(frame, info), settings_)
    from_files = isp.develop(loaded.pixels_dn, isp.facts_of(loaded), settings_)
    assert np.allclose(from_memory.image, from_files.image, atol=1e-6)
    assert from_memory.record["stages"]["gain"]["value"] == pytest.approx(from_files.record["stages"]["gain"]["value"])
    unquantised = isp.facts_from_info(frame, info, quantised=False)
    assert np.array_equal(unquantised.black_dn, np.asarray(loaded.meta["dark_level_dn"]))


def _read_png16(path):
    """A 16-bit PNG's pixels (H, W, 3) through OpenImageIO (Pillow reads 16-bit RGB PNGs as 8 bits)."""
    import OpenImageIO as oiio

    reader = oiio.ImageInput.open(str(path))
    try:
        spec = reader.spec()
        assert spec.format == "uint16" and spec.nchannels == 3
        return reader.read_image(0, 0, 0, 3, "uint16")
    finally:
        reader.close()


def test_png_and_jpeg_hold_the_image_and_the_record(tmp_path):
    import imageio.v3 as iio
    from PIL import Image

    rng = np.random.default_rng(4)
    image = rng.random((3, 7, 9)).astype(np.float32)
    record = {"a": [1, 2.5], "stage": "développé"}
    isp.write_png(tmp_path / "x.png", image, 16, record)
    back = _read_png16(tmp_path / "x.png")
    assert back.dtype == np.uint16 and back.shape == (7, 9, 3)
    assert np.array_equal(back, np.floor(np.moveaxis(image, 0, -1) * 65535 + 0.5).astype(np.uint16))
    assert isp.read_png_record(tmp_path / "x.png") == record
    assert json.loads(Image.open(tmp_path / "x.png").text["camsim:develop"]) == record
    isp.write_png(tmp_path / "y.png", image, 8)
    assert np.array_equal(iio.imread(tmp_path / "y.png"),
                          np.floor(np.moveaxis(image, 0, -1) * 255 + 0.5).astype(np.uint8))
    isp.write_jpeg(tmp_path / "x.jpg", image, 95, record)
    with Image.open(tmp_path / "x.jpg") as jpeg:
        assert jpeg.size == (9, 7)
        assert json.loads(jpeg.info["comment"].decode("ascii").split(" ", 1)[1]) == record
    with pytest.raises(CamsimError, match="quality"):
        isp.write_jpeg(tmp_path / "z.jpg", image, 0)
    assert not (tmp_path / "z.jpg").exists()


def test_jpeg_quality_is_the_quality_asked_for(frames, tmp_path):
    """A developed chart as JPEG: at quality 95 within a few codes of the 8-bit PNG's values, at quality 20 much
    further, and smaller (measured 2026-11-25: mean absolute error 2.7 and 5.3 codes on this noisy 8-bit frame)."""
    import imageio.v3 as iio

    loaded = load_frame(frames["chip3"])
    image = isp.develop(loaded.pixels_dn, isp.facts_of(loaded), isp.IspSettings(gain="white")).image
    exact = np.floor(np.moveaxis(image, 0, -1) * 255 + 0.5)
    errors, sizes = {}, {}
    for quality in (95, 20):
        path = tmp_path / f"q{quality}.jpg"
        isp.write_jpeg(path, image, quality)
        errors[quality] = np.abs(iio.imread(path).astype(np.float64) - exact).mean()
        sizes[quality] = path.stat().st_size
    assert errors[95] < 4.0 and errors[20] > 1.5 * errors[95], errors
    assert sizes[20] < sizes[95] / 2, sizes


@pytest.mark.parametrize("kind", ["bayer", "chip3"])
def test_a_frames_dng_and_exr_normalise_alike(frames, kind):
    """The DNG holds the EXR's float values quantised (floor(dn + ½) + P with the A7S2's pedestal P = 512, floor(dn)
    for paper-table1): normalised, each pixel of one is within a quantisation step of the other."""
    dng = load_frame(frames[kind])
    exr = load_frame(frames[kind].with_suffix(".exr"))
    from_dng = isp.normalise(dng.pixels_dn, isp.facts_of(dng))
    from_exr = isp.normalise(exr.pixels_dn, isp.facts_of(exr))
    step = 1.0 / (dng.meta["white_level_dn"] - max(dng.meta["black_level_dn"]))
    numbers = dng.pixels_dn[0] if kind == "bayer" else dng.pixels_dn
    unclipped = (numbers > 0) & (numbers < dng.meta["white_level_dn"])  # the ADC's clip at 0 or the white: not compared
    difference = np.abs(from_dng - from_exr)[unclipped]
    assert difference.max() <= step, difference.max() / step


def test_encoding_clips_and_takes_nan_as_black():
    from camsim.isp.writers import encode_image

    image = np.array([np.nan, np.inf, -np.inf, -0.2, 0.5, 1.7], dtype=np.float32).reshape(1, 1, 6).repeat(3, axis=0)
    assert encode_image(image, 8)[0, :, 0].tolist() == [0, 255, 0, 0, 128, 255]
    assert encode_image(image, 16)[0, :, 1].tolist() == [0, 65535, 0, 0, 32768, 65535]


@pytest.mark.parametrize("kind", ["fifo", "device", "directory"])
def test_a_png_record_of_a_path_that_is_no_regular_file_is_refused_not_waited_on(tmp_path, kind):
    from tests.support.hostile_files import no_hang, not_regular

    path = not_regular(tmp_path / "x.png", kind)
    with no_hang(f"read_png_record of a {kind}"), pytest.raises(CamsimError, match="not a regular file"):
        isp.read_png_record(path)


def test_a_png_record_is_found_past_the_pixels_and_bounded(tmp_path, monkeypatch):
    """The chunks are walked (a record after the pixels is found, the pixels skipped over); a tEXt chunk over
    the limit is refused from its length, before it is read."""
    import struct
    import zlib

    from camsim.isp import writers

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    ihdr = struct.pack(">IIBBBBB", 2, 1, 8, 2, 0, 0, 0)
    text = b"camsim:develop\0" + json.dumps({"a": 1}).encode()
    body = chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(bytes(7) * 2)) + chunk(b"tEXt", b"other\0x")
    (tmp_path / "x.png").write_bytes(b"\x89PNG\r\n\x1a\n" + body + chunk(b"tEXt", text) + chunk(b"IEND", b""))
    assert isp.read_png_record(tmp_path / "x.png") == {"a": 1}
    monkeypatch.setattr(writers, "MAX_RECORD_TEXT_BYTES", 10)
    with pytest.raises(CamsimError, match="over the limit of 10"):
        isp.read_png_record(tmp_path / "x.png")
