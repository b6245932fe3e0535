"""Image scenes ([image]): a picture's colours as spectra, factored on Mallett 2019's basis, through the renderer.

Independent references: a chart whose reflectance CSV holds the same recovered spectrum (the dense K × N path);
colour-science's own ColorChecker XYZ under D65; the exact law of each pixel's digital number (tests.support.theory);
sRGB's transfer function written out here; luminance and chromaticity from colour-science's CIE 1931 CMFs
(683 lm/W); the camera's anchor (MODEL.md §3: the perfect white at 100 cd/m² under D65 gives 8000 e⁻).
"""

import json
import warnings
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from camsim.cli import main
from camsim.light.rates import FactoredSpectra
from camsim.render.pipeline import light_scene, make_frame
from camsim.scene.chart import ChartGeometry
from camsim.scene.sources import ChartSource, ImageSource
from camsim.sensor.camera import load_camera
from camsim.sensor.params import PRESETS, SensorParams
from tests.support.helpers import small_scene
from tests.support.theory import digital_pmf, pmf_moments

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    import colour

TABLE1 = PRESETS["paper-table1"]
IDEAL = PRESETS["ideal"]


def _srgb_decode(code: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1: 8-bit code → linear sRGB."""
    v = np.asarray(code, dtype=np.float64) / 255.0
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def _mallett_on_grid(grid) -> np.ndarray:
    """colour-science's Mallett 2019 basis, interpolated here with numpy onto the grid, shape (3, N)."""
    data = colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019
    return np.stack([np.interp(grid.wavelengths_nm, data.wavelengths, data.values[:, j]) for j in range(3)])


def _image_scene(path: Path, **changes):
    return small_scene(source=ImageSource(path=path), **changes)


def _flat_image_and_its_chart(tmp_path: Path, shape: tuple):
    """Write ``tmp_path/flat.png``, one 8-bit sRGB colour (200, 120, 60) over ``shape`` (H, W), and return the
    one-patch chart scene whose CSV reflectance is that colour's Mallett spectrum (built here: sRGB decoded and
    the basis interpolated with numpy) — the dense K × N route to the same spectrum."""
    code = np.array([200, 120, 60], dtype=np.uint8)
    iio.imwrite(tmp_path / "flat.png", np.broadcast_to(code, (*shape, 3)).copy())
    grid = small_scene().grid
    spectrum = _srgb_decode(code) @ _mallett_on_grid(grid)
    csv = tmp_path / "patch.csv"
    rows = ["wavelength_nm,painted"] + [f"{w:g},{r:.17g}" for w, r in zip(grid.wavelengths_nm, spectrum)]
    csv.write_text("\n".join(rows) + "\n")
    return small_scene(source=ChartSource(reflectances=str(csv), geometry=ChartGeometry(columns=1, rows=1)))


def _write_exr(path: Path, values: np.ndarray) -> None:
    """A float32 RGB OpenEXR file of ``values`` (H, W, 3), linear."""
    import OpenImageIO as oiio

    height, width = values.shape[:2]
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(width, height, 3, oiio.FLOAT))
    out.write_image(np.ascontiguousarray(values, dtype=np.float32))
    out.close()


def _cie1931(grid) -> np.ndarray:
    """colour-science's CIE 1931 2° x̄ ȳ z̄, interpolated here with numpy onto the grid, shape (3, N)."""
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return np.stack([np.interp(grid.wavelengths_nm, cmfs.wavelengths, cmfs.values[:, j]) for j in range(3)])


def test_a_radiance_image_has_its_stated_luminance_whatever_the_illuminant(tmp_path):
    """kind = "radiance": linear (1, 1, 1) is D65 light at the [image]'s luminance_cd_m2 (Y = 683 Σ L ȳ δ with
    colour-science's CMFs, within 0.5 %; chromaticity D65's), 0.5 is half of it, the spectra stay factored, and
    neither the scene's illuminant nor its [light] luminance changes the electrons. At 100 cd/m² the white gives
    the anchor's 8000 e⁻ in the strongest channel (MODEL.md §3), as the perfect white under D65 does."""
    values = np.ones((20, 30, 3))
    values[:, 15:] = 0.5
    _write_exr(tmp_path / "glow.exr", values)
    grid = small_scene().grid
    source = ImageSource(path=tmp_path / "glow.exr", kind="radiance", luminance_cd_m2=250.0)
    spectra = source.spectra(grid, 0, 0)
    assert spectra.kind == "radiance" and isinstance(spectra.spectra, FactoredSpectra)
    white, grey = spectra.spectra[int(spectra.labels[0, 0])], spectra.spectra[int(spectra.labels[0, 20])]
    xyz = 683.0 * grid.step_nm * (_cie1931(grid) @ np.stack([white, grey]).T).T
    assert abs(xyz[0, 1] / 250.0 - 1) < 0.005, xyz[0, 1]
    assert abs(xyz[1, 1] / 125.0 - 1) < 0.005, xyz[1, 1]
    np.testing.assert_allclose(xyz[0, :2] / xyz[0].sum(), [0.3127, 0.3290], atol=1e-3)  # D65's xy
    scene = small_scene(source=source)
    camera = load_camera(scene.camera, grid)
    under = {light: light_scene(scene, light, camera).expected(IDEAL, 1.0, "pixel").signal_e for light in
             ("D65", "A", "FL2")}
    dimmer_light = light_scene(scene.replace(luminance_cd_m2=20.0), "A", camera).expected(IDEAL, 1.0, "pixel")
    for signal in (under["A"], under["FL2"], dimmer_light.signal_e):
        np.testing.assert_allclose(signal, under["D65"], rtol=1e-12)
    at_100 = small_scene(source=ImageSource(path=tmp_path / "glow.exr", kind="radiance", luminance_cd_m2=100.0))
    lit = light_scene(at_100, "A", camera)
    signal = lit.expected(IDEAL, 1.0, "pixel").signal_e
    assert abs(signal[lit.labels[0, 0]].max() / 8000.0 - 1) < 0.005, signal[lit.labels[0, 0]]
    np.testing.assert_allclose(signal[lit.labels[0, 20]], signal[lit.labels[0, 0]] / 2, rtol=1e-6)


def test_resampling_averages_in_linear_light(tmp_path):
    """size = [w, h]: a 2 × 2 checker of two 8-bit sRGB colours shrunk to 1 × 1 (and an 8 × 8 one to 4 × 4) is
    their linear-light mean (sRGB decoded here), and its electrons are the mean of the two colours' electrons."""
    a, b = np.array([200, 30, 90], dtype=np.uint8), np.array([20, 240, 160], dtype=np.uint8)
    mean = (_srgb_decode(a) + _srgb_decode(b)) / 2
    grid = small_scene().grid
    camera = load_camera(small_scene().camera, grid)

    def electrons(source):
        lit = light_scene(small_scene(source=source), "D65", camera)
        return lit.expected(IDEAL, 1.0, "pixel").signal_e[lit.labels]

    for n, size in ((2, (1, 1)), (8, (4, 4))):
        checker = np.where((np.indices((n, n)).sum(0) % 2 == 0)[..., None], a, b)
        iio.imwrite(tmp_path / f"checker{n}.png", checker)
        source = ImageSource(path=tmp_path / f"checker{n}.png", size=size)
        assert source.own_size() == size
        spectra = source.spectra(grid, 0, 0)
        assert spectra.labels.shape == size[::-1]
        np.testing.assert_allclose(spectra.spectra.coefficients[spectra.labels], np.broadcast_to(mean, (*size, 3)),
                                   rtol=1e-9)
    for colour_code, name in ((a, "a"), (b, "b")):
        iio.imwrite(tmp_path / f"{name}.png", np.broadcast_to(colour_code, (2, 2, 3)).copy())
    pair = electrons(ImageSource(path=tmp_path / "a.png"))[0, 0] + electrons(ImageSource(path=tmp_path / "b.png"))[0, 0]
    np.testing.assert_allclose(electrons(ImageSource(path=tmp_path / "checker2.png", size=(1, 1)))[0, 0], pair / 2,
                               rtol=1e-9)
    # crop first, then resample; size equal to the crop keeps the file's codes
    crop = ImageSource(path=tmp_path / "checker8.png", crop=(2, 2, 4, 4), size=(3, 5))
    assert crop.own_size() == (3, 5) and crop.spectra(grid, 0, 0).labels.shape == (5, 3)
    same = ImageSource(path=tmp_path / "checker8.png", size=(8, 8)).spectra(grid, 0, 0)
    assert same.spectra.shape[0] == 2


def test_a_flat_image_region_equals_a_chart_patch_of_its_recovered_spectrum(tmp_path):
    """One colour painted flat and the chart patch whose CSV reflectance is that colour's Mallett spectrum give the
    same expected electrons (the factored 3 × 3 route against the dense K × N one), under D65 and A."""
    chart = _flat_image_and_its_chart(tmp_path, (30, 40))
    grid = chart.grid
    image = _image_scene(tmp_path / "flat.png")
    camera = load_camera(chart.camera, grid)
    for illuminant in ("D65", "A"):
        from_image = light_scene(image, illuminant, camera).expected(TABLE1, 0.3, "pixel")
        from_chart = light_scene(chart, illuminant, camera).expected(TABLE1, 0.3, "pixel")
        assert from_image.signal_e.shape == (1, 3)
        np.testing.assert_allclose(from_image.signal_e[0], from_chart.signal_e[0], rtol=1e-4)
        # paper statistics: the variance T² F Σ g Qe² is linear in the spectrum too
        paper_image = light_scene(image, illuminant, camera).expected(TABLE1, 0.3, "paper")
        paper_chart = light_scene(chart, illuminant, camera).expected(TABLE1, 0.3, "paper")
        np.testing.assert_allclose(paper_image.signal_var_e2[0], paper_chart.signal_var_e2[0], rtol=1e-4)


def test_a_colorchecker_painted_in_srgb_comes_back_within_a_stated_delta_e(tmp_path):
    """The 24 ColorChecker colours under D65, painted as 8-bit sRGB, rendered as an image scene, taken to XYZ with
    the camera → XYZ matrix fitted on the real chart: mean ΔE00 ≤ 1.6, max ≤ 3.5 against the chart's own XYZ (the
    matrix alone, on the real chart, gives 0.98 / 2.75; measured 1.23 / 3.08 for the image)."""
    from camsim.colour.colorimetry import camera_to_xyz_matrix

    checker = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    d65 = colour.SDS_ILLUMINANTS["D65"]
    xyz = np.array([colour.sd_to_XYZ(sd, illuminant=d65) for sd in checker.values()]) / 100
    codes = np.clip(np.round(colour.XYZ_to_sRGB(xyz) * 255), 0, 255).astype(np.uint8)
    iio.imwrite(tmp_path / "checker.png", np.repeat(np.repeat(codes.reshape(4, 6, 3), 8, 0), 8, 1))
    image, chart = _image_scene(tmp_path / "checker.png"), small_scene()
    camera = load_camera(chart.camera, chart.grid)
    lit_image, lit_chart = light_scene(image, "D65", camera), light_scene(chart, "D65", camera)
    from_chart = lit_chart.expected(IDEAL, 1.0, "pixel").signal_e[:24]
    from_image = lit_image.expected(IDEAL, 1.0, "pixel").signal_e[lit_image.labels[4::8, 4::8].ravel()]
    matrix = camera_to_xyz_matrix(lit_chart.qe, chart.grid.wavelengths_nm, 1.0, method="least-squares",
                                  training=(from_chart, xyz))
    delta_e = colour.delta_E(colour.XYZ_to_Lab(from_image @ matrix.T), colour.XYZ_to_Lab(xyz), method="CIE 2000")
    assert delta_e.mean() <= 1.6 and delta_e.max() <= 3.5, (delta_e.mean(), delta_e.max())


def test_per_pixel_digital_numbers_on_a_gradient_follow_the_exact_law(tmp_path):
    """A grey ramp (one colour per column): each column's DN mean and variance against the exact law of
    Poisson charge (signal + dark), full well, read noise, gain, floor and clip (tests.support.theory.digital_pmf)."""
    ramp = np.linspace(0, 255, 64).round().astype(np.uint8)
    iio.imwrite(tmp_path / "ramp.png", np.broadcast_to(ramp[None, :, None], (600, 64, 3)).copy())
    scene = _image_scene(tmp_path / "ramp.png")
    lit = light_scene(scene, "D65", load_camera(scene.camera, scene.grid))
    sensor = SensorParams(analog_gain_dn_per_v=1000.0)  # k = 0.2 DN/e⁻: means of 0–1600 DN fill 8 bits
    factor = 0.02
    frame = make_frame(lit, sensor, factor, rng=5)
    expected = lit.expected(sensor, factor, "pixel")
    k = sensor.dn_per_electron
    z_mean, z_var = [], []
    for column in range(64):
        label = lit.labels[0, column]
        for c in range(3):
            lam = expected.signal_e[label, c] + expected.dark_e[c]
            mean, var = pmf_moments(digital_pmf(lam, k, sensor.read_noise_e, sensor.full_well_e, sensor.bits))
            values = frame.digital_dn[c, :, column].astype(np.float64)
            if var == 0:
                assert np.all(values == mean)
                continue
            n = values.size
            z_mean.append((values.mean() - mean) / np.sqrt(var / n))
            z_var.append((values.var(ddof=1) / var - 1) / np.sqrt(2 / (n - 1)))
    z_mean, z_var = np.array(z_mean), np.array(z_var)
    assert len(z_mean) > 150
    assert np.abs(z_mean).max() < 4.5 and abs(z_mean.mean()) < 4 / np.sqrt(len(z_mean))
    assert np.abs(z_var).max() < 5 and abs(z_var.mean()) < 0.5  # ~normal z of the sample variances (kurtosis)


def test_render_an_image_scene_end_to_end(tmp_path):
    """camsim render on an [image] scene file: frames at the image's size (or its crop), every stage, a DNG whose
    brighter pixels hold larger numbers, and a sidecar naming the image."""
    picture = np.zeros((48, 64, 3), dtype=np.uint8)
    picture[:, 32:] = 230
    iio.imwrite(tmp_path / "half.png", picture)
    scene = tmp_path / "half.toml"
    scene.write_text('name = "half"\n[image]\npath = "half.png"\ncrop = [8, 0, 48, 40]\n[light]\n'
                     'illuminants = ["D65"]\n')
    out = tmp_path / "out"
    assert main(["render", str(scene), "--out", str(out), "-q"]) == 0
    meta = json.loads((out / "half_D65_F1.json").read_text())
    assert (meta["width_px"], meta["height_px"]) == (48, 40) and meta["reflectances"] == "half.png"
    import rawpy

    with rawpy.imread(str(out / "half_D65_F1.dng")) as raw:
        numbers = raw.raw_image.astype(float)
    assert numbers[..., 30:, :3].mean() > 20 * numbers[..., :20, :3].mean() + 1


@pytest.mark.parametrize("case, message", [
    ("missing", "image file not found"),
    ("garbage", "cannot read image"),
    ("colourspace", "not a colour-science RGB colourspace"),
    ("nan", "NaN"),
    ("negative", "negative"),
    ("crop", "reaches beyond"),
    ("size", "size must be [width, height], two positive integers"),
    ("size-float", "size must be [width, height], two positive integers"),
    ("radiance", "kind 'radiance' needs luminance_cd_m2"),
    ("luminance", "luminance_cd_m2 applies to kind 'radiance'"),
    ("aces", "the white of 'ACES2065-1' is 'ACES'"),
    ("skimage", "no image 'nope' ships with scikit-image: skimage: names are astronaut, "),
])
def test_bad_images_are_one_line_errors(tmp_path, capsys, case, message):
    table = {"path": "picture.png"}
    if case == "garbage":
        (tmp_path / "picture.png").write_bytes(b"not a png at all")
    elif case in ("nan", "negative"):
        values = np.full((24, 24, 3), 0.5, dtype=np.float32)  # 24: a DNG's least size is 22 (checked first)
        values[3, 4, 1] = np.nan if case == "nan" else -0.25
        import OpenImageIO as oiio

        out = oiio.ImageOutput.create(str(tmp_path / "picture.exr"))
        out.open(str(tmp_path / "picture.exr"), oiio.ImageSpec(24, 24, 3, oiio.FLOAT))
        out.write_image(values)
        out.close()
        table["path"] = "picture.exr"
    elif case != "missing":
        iio.imwrite(tmp_path / "picture.png", np.full((20, 20, 3), 128, dtype=np.uint8))
    if case == "colourspace":
        table["colourspace"] = "no such space"
    if case == "crop":
        table["crop"] = [10, 10, 20, 5]
    if case == "size":
        table["size"] = [0, 10]
    if case == "size-float":
        table["size"] = [10.5, 10]
    if case in ("radiance", "aces"):
        table["kind"] = "radiance"
    if case == "aces":
        table["colourspace"], table["luminance_cd_m2"] = "ACES2065-1", 100
    if case == "luminance":
        table["luminance_cd_m2"] = 100
    if case == "skimage":
        table["path"] = "skimage:nope"
    lines = "\n".join(f'{key} = {json.dumps(value)}' for key, value in table.items())
    scene = tmp_path / "bad.toml"
    scene.write_text(f'name = "bad"\n[image]\n{lines}\n')
    out = tmp_path / "out"
    capsys.readouterr()
    assert main(["render", str(scene), "--out", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("camsim: error:") and message in err, err
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize("method, statistics, sensor", [
    ("poisson", "pixel", "--cfa RGGB --sensor dsnu_e=2 --sensor prnu_percent=1 --sensor row_noise_e=1"),
    ("gaussian", "pixel", ""),
    ("auto", "paper", ""),
    ("spectral", "paper", "--sensor dsnu_dark_current_percent=10"),
])
def test_every_method_and_stage_on_an_image(tmp_path, method, statistics, sensor):
    """Each method and statistics, Bayer and the fixed-pattern maps render an image scene; the clean layer is the
    expected DN of each pixel's colour (no map: exactly its colour's k · E[f_sat(S + D)])."""
    picture = np.stack(np.meshgrid(np.linspace(0, 255, 32), np.linspace(40, 220, 24)), -1)
    picture = np.concatenate([picture, picture[..., :1]], axis=-1).round().astype(np.uint8)
    iio.imwrite(tmp_path / "grad.png", picture)
    scene = tmp_path / "grad.toml"
    scene.write_text('name = "grad"\n[image]\npath = "grad.png"\n[light]\nilluminants = ["A"]\n')
    out = tmp_path / "out"
    args = ["render", str(scene), "--method", method, "--statistics", statistics, "--out", str(out), "-q",
            *sensor.split()]
    assert main(args) == 0
    from camsim.io.exr import read_exr

    noisy, clean, _ = read_exr(out / "grad_A_F1.exr")
    assert noisy.shape[-2:] == (24, 32) and np.all(np.isfinite(noisy))
    if not sensor:
        lit = light_scene(_image_scene(tmp_path / "grad.png"), "A", load_camera(small_scene().camera,
                                                                                small_scene().grid))
        expected = lit.expected(TABLE1, 1.0, statistics)
        np.testing.assert_allclose(clean, np.moveaxis((expected.clean_e * TABLE1.dn_per_electron)[lit.labels],
                                                      -1, 0), rtol=1e-6)


@pytest.mark.parametrize("method", ["spectral", "poisson"])
def test_paper_statistics_on_an_image_draw_eq4s_moments(tmp_path, method):
    """Under ``paper`` statistics a basis-collapsed image draws, per pixel and channel, S with Eq. 4's mean S̄ and
    variance T² F Σ g Qe² of its colour's spectrum: ``spectral`` by Eq. 4's per-bin Poisson counts (dense rows of
    the factored spectrum, a chunk of pixels at a time), ``poisson`` by the stand-in s · Poisson(S̄ / s). The
    reference is a chart patch whose CSV holds the same recovered spectrum (the dense K × N route). At F = 1e-15 the
    bins' photon means are of order one, so Var S is far from S̄ (what ``pixel`` statistics would give): the test
    fails if the image were drawn under the other statistics."""
    chart = _flat_image_and_its_chart(tmp_path, (160, 200))
    camera = load_camera(chart.camera, chart.grid)
    factor = 1e-15
    reference = light_scene(chart, "D65", camera).expected(IDEAL, factor, "paper")
    mean_ref, var_ref = reference.signal_e[0], reference.signal_var_e2[0]
    assert np.all(var_ref < 0.5 * mean_ref) or np.all(var_ref > 2 * mean_ref)  # Eq. 4 is not Poisson here
    lit = light_scene(_image_scene(tmp_path / "flat.png"), "D65", camera)
    frame = make_frame(lit, IDEAL, factor, statistics="paper", method=method, rng=2024)
    n = lit.labels.size
    for c in range(3):
        values = frame.noisy_dn[c].astype(np.float64).ravel() / IDEAL.dn_per_electron
        mean, var = values.mean(), values.var(ddof=1)
        m4 = np.mean((values - mean) ** 4)
        assert abs(mean - mean_ref[c]) <= 5 * np.sqrt(var_ref[c] / n), (c, mean, mean_ref[c])
        assert abs(var - var_ref[c]) <= 5 * np.sqrt(max(m4 - var**2, 0) / n), (c, var, var_ref[c])


# --- headers and tiles ---------------------------------------------------------------------------------------------

def _write_oiio(path: Path, pixels: np.ndarray, fmt, tile: int = 0) -> None:
    import OpenImageIO as oiio

    spec = oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2] if pixels.ndim == 3 else 1, fmt)
    if tile:
        spec.tile_width = spec.tile_height = tile
    out = oiio.ImageOutput.create(str(path))
    assert out.open(str(path), spec), out.geterror()
    out.write_image(pixels)
    out.close()


@pytest.mark.parametrize("tile", [16, 64])
def test_a_tiled_files_crop_decodes_its_rows_of_tiles(tmp_path, monkeypatch, tile):
    """A tiled TIFF is read in whole rows of tiles from the one that holds the crop's first row (not whole), and
    every crop's rows come back as stored."""
    import OpenImageIO as oiio

    from camsim.scene.sources import image

    codes = (np.arange(70 * 100 * 3) % 251).astype(np.uint8).reshape(70, 100, 3)
    path = tmp_path / "tiled.tif"
    _write_oiio(path, codes, oiio.UINT8, tile)
    monkeypatch.setattr(image, "ROWS_PER_READ", 20)
    reads = []
    real = oiio.ImageInput.read_tiles
    monkeypatch.setattr(oiio.ImageInput, "read_tiles", lambda self, *a: reads.append(a[4:6]) or real(self, *a))
    for rows in (None, (5, 9), (10, 50), (33, 70), (69, 70)):
        reads.clear()
        pixels, integer, bits = image.read_image_codes(str(path), rows)
        first, stop = rows or (0, 70)
        assert integer and bits == 8 and np.array_equal(pixels, codes[first:stop]), rows
        assert reads[0][0] == first - first % tile and reads[-1][1] >= stop, (rows, reads)


def test_the_colour_limit_comes_from_the_header(tmp_path):
    """The most distinct colours a file's codes can make: what its colours may cost to render (a 1-bit PNG is read
    as 8-bit grey codes)."""
    import OpenImageIO as oiio

    from camsim.scene.sources.image import image_colour_limit
    from tests.core.test_pixel_limit import write_constant_png

    write_constant_png(tmp_path / "bits1.png", 30, 20)
    iio.imwrite(tmp_path / "grey.png", np.zeros((20, 30), np.uint8))
    iio.imwrite(tmp_path / "rgb.png", np.zeros((20, 30, 3), np.uint8))
    _write_oiio(tmp_path / "rgb16.png", np.zeros((20, 30, 3), np.uint16), oiio.UINT16)
    _write_exr(tmp_path / "float.exr", np.zeros((20, 30, 3), np.float32))
    limits = {name: image_colour_limit(str(tmp_path / name))
              for name in ("bits1.png", "grey.png", "rgb.png", "rgb16.png", "float.exr")}
    assert limits == {"bits1.png": 256, "grey.png": 256, "rgb.png": 2**24, "rgb16.png": 2**48, "float.exr": None}


@pytest.mark.parametrize("side", [10_000, 14_000])
def test_a_header_of_10_to_the_8_pixels_is_refused_under_max_megapixels_before_decoding(tmp_path, capsys, side):
    """A 1-bit PNG of 10⁸ to 2 × 10⁸ pixels (tens of kilobytes): under camsim's 200-megapixel cap, refused by
    --max-megapixels from its header, in far less CPU time than decoding it takes."""
    import time

    from tests.core.test_pixel_limit import write_constant_png

    png = tmp_path / "large.png"
    write_constant_png(png, side, side)
    scene = tmp_path / "large.toml"
    scene.write_text(f'name = "large"\n[image]\npath = "{png.as_posix()}"\n')
    start = time.process_time()
    assert main(["render", str(scene), "--max-megapixels", "50", "--out", str(tmp_path / "out"), "-q"]) == 2
    assert time.process_time() - start < 3.0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"camsim: error: image {png} is {side} × {side} pixels"), err
    assert "over --max-megapixels 50" in err and not (tmp_path / "out").exists()


@pytest.mark.parametrize("width, height", [(20_001, 10_000), (30_000, 30_000), (100_000, 100_000), (14_000, 14_000)])
def test_a_tiff_header_claiming_a_large_size_is_refused_before_decoding(tmp_path, capsys, width, height):
    """A 24 × 24 TIFF whose header claims 2 × 10⁸ to 10¹⁰ pixels: over camsim's cap (OpenImageIO's own checks of
    a header against the file's size may say so first), or, under it, over --max-megapixels; one line, from the
    header."""
    import OpenImageIO as oiio

    from tests.support.hostile_files import with_tiff_size

    small = tmp_path / "small.tif"
    _write_oiio(small, np.zeros((24, 24, 3), np.uint8), oiio.UINT8)
    (tmp_path / "large.tif").write_bytes(with_tiff_size(small.read_bytes(), width, height))
    scene = tmp_path / "large.toml"
    scene.write_text('name = "large"\n[image]\npath = "large.tif"\n')
    argv = ["render", str(scene), "--max-megapixels", "100", "--out", str(tmp_path / "out"), "-q"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("camsim: error: "), err
    if width * height > 2 * 10**8:  # OpenImageIO's checks of a header against the file may come first
        assert any(said in err for said in (f"{width} × {height} pixels, over camsim's limit of 200 megapixels",
                                             "tiff header claims a", f"claimed to be {width}x{height}")), err
    else:
        assert f"{width} × {height} pixels (196 MP), over --max-megapixels 100" in err, err
