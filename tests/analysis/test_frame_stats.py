"""``camsim analyze`` on frames without chart patches (frame statistics) and scene-file regions ([[region]]).

Independent references, computed here: a flat colour's signal electrons from its spectrum (sRGB decoded by hand,
colour-science's Mallett 2019 basis, D65 and the CIE 1931 observer interpolated with numpy, Eq. 3's photons, the
camera's Qe from the sidecar), so the mean DN is k · S; the exact variance of a pixel about its expectation,
k² (S + D + σ_read² + σ_row²) (+ 1/12 DN² for the quantiser), from the sensor's parameters; a region's XYZ as the
CIE integral of its colours' radiance, weighted by the pixels each covers.
"""

import csv
import json
import re
import warnings

import imageio.v3 as iio
import numpy as np
import pytest

from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.render.pipeline import light_scene
from camsim.render.run import render_scene
from camsim.scene.regions import Region
from camsim.scene.sources import CubeSource, ImageSource
from camsim.sensor.camera import load_camera
from tests.support.helpers import small_scene

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    import colour

H_PLANCK, C_LIGHT = 6.626176e-34, 2.997925e8  # the paper's constants (MODEL.md §2)
COLOUR_A, COLOUR_B = np.array([200, 120, 60]), np.array([50, 100, 180])
ROW_NOISE_E = 10.0


def _srgb_decode(code) -> np.ndarray:
    v = np.asarray(code, dtype=np.float64) / 255.0
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def _on_grid(wavelengths, values, grid) -> np.ndarray:
    return np.interp(grid.wavelengths_nm, wavelengths, values)


def _reflectance(code, grid) -> np.ndarray:
    """The Mallett 2019 spectrum of an 8-bit sRGB colour: linear RGB times the three basis spectra."""
    data = colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019
    basis = np.stack([_on_grid(data.wavelengths, data.values[:, j], grid) for j in range(3)])
    return _srgb_decode(code) @ basis


def _radiance(reflectance, grid, luminance=100.0) -> np.ndarray:
    """Reflectance under D65 scaled so that the perfect white has ``luminance`` cd/m². Unit: W / (m² sr nm)."""
    d65 = colour.SDS_ILLUMINANTS["D65"]
    spd = _on_grid(d65.wavelengths, d65.values, grid)
    ybar = _cmfs(grid)[1]
    return reflectance * spd * luminance / (683.0 * np.sum(spd * ybar) * grid.step_nm)


def _cmfs(grid) -> np.ndarray:
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return np.stack([_on_grid(cmfs.wavelengths, cmfs.values[:, j], grid) for j in range(3)])


def _xyz(radiance, grid) -> np.ndarray:
    return 683.0 * grid.step_nm * (_cmfs(grid) @ radiance)


def _signal_e(code, grid, qe, factor=1.0, exposure_s=1.0) -> np.ndarray:
    """S = T F Σ g Qe with g = λ L δ / (h c) (Eq. 3), per channel. Unit: e⁻."""
    photons = grid.wavelengths_nm * 1e-9 * _radiance(_reflectance(code, grid), grid) * grid.step_nm / (
        H_PLANCK * C_LIGHT)
    return exposure_s * factor * (np.asarray(qe) @ photons)


def _two_colour_png(path, width=120, height=90, split=60):
    picture = np.empty((height, width, 3), dtype=np.uint8)
    picture[:, :split], picture[:, split:] = COLOUR_A, COLOUR_B
    iio.imwrite(path, picture)
    return path


@pytest.fixture(scope="module")
def flat_frame(tmp_path_factory):
    """One frame of a flat sRGB colour (image scene), Table I with row noise, analysed from its DNG and its EXR."""
    folder = tmp_path_factory.mktemp("flat")
    picture = np.broadcast_to(COLOUR_A.astype(np.uint8), (160, 240, 3)).copy()
    iio.imwrite(folder / "flat.png", picture)
    scene = small_scene(name="flat", source=ImageSource(path=folder / "flat.png")).with_sensor(
        row_noise_e=ROW_NOISE_E)
    render_scene(scene, folder / "frames", progress=False)
    results = {}
    for source in ("dng", "exr"):
        out = folder / f"analysis_{source}"
        assert main(["analyze", str(folder / "frames"), "--out", str(out), "--source", source, "-q"]) == 0
        results[source] = json.loads((out / "analysis.json").read_text())["frames"][0]
    return folder, results


def test_frame_statistics_of_a_flat_image_agree_with_theory(flat_frame):
    """Mean DN (black-subtracted) = k · S; the residual noisy − clean has bias ~0 and the variance
    k² (S + D + σ_read² + σ_row²) (+ 1/12 DN² from a DNG), each within 4 standard errors."""
    folder, results = flat_frame
    meta = json.loads((folder / "frames" / "flat_D65_F1.json").read_text())
    assert meta["patches"] == []
    k = meta["dn_per_electron"]
    grid = small_scene().grid
    signal = _signal_e(COLOUR_A, grid, meta["qe_e_m2_sr_per_photon"])
    dark = np.array([195.0, 230.0, 218.0])  # Table I's σ²_dark · T, T = 1 s
    for source, result in results.items():
        assert result["patches"] == []
        for c, ch in enumerate(result["frame_statistics"]):
            assert ch["n_pixels"] == 160 * 240 and ch["clip_low_fraction"] == 0 and ch["clip_high_fraction"] == 0
            exact_var = k**2 * (signal[c] + dark[c] + 4.0**2 + ROW_NOISE_E**2) + (1 / 12 if source == "dng" else 0)
            # the mean's standard error: pixel noise over n, row noise over the 160 rows
            se_mean = np.sqrt((exact_var - (k * ROW_NOISE_E) ** 2) / ch["n_pixels"] + (k * ROW_NOISE_E) ** 2 / 160)
            assert abs(ch["mean_dn"] - k * signal[c]) < 4 * se_mean + 0.02, (source, c, ch["mean_dn"], k * signal[c])
            assert ch["residual_status"] == "ok" and ch["n_residual"] == ch["n_pixels"]
            assert abs(ch["residual_mean_dn"]) < 4 * ch["residual_mean_se_dn"], (source, c, ch)
            assert abs(ch["residual_var_dn2"] - exact_var) < 4 * ch["residual_var_se_dn2"], (source, c, ch, exact_var)
            assert ch["residual_var_se_dn2"] < 0.05 * exact_var  # the check has teeth: a 5 % error would show
            assert ch["predicted_var_dn2"] == pytest.approx(exact_var, rel=2e-3)
            assert ch["std_dn"] == pytest.approx(np.sqrt(exact_var), rel=0.05)


def test_frame_statistics_are_written_and_printed(flat_frame, capsys):
    folder, _ = flat_frame
    out = folder / "printed"
    assert main(["analyze", str(folder / "frames"), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "no patches: frame statistics below" in printed and "var/model" in printed
    rows = list(csv.DictReader((out / "frame_statistics.csv").open()))
    assert [r["channel"] for r in rows] == ["R", "G", "B"] and all(r["residual_status"] == "ok" for r in rows)
    assert (out / "analysis.csv").read_text().count("\n") == 1  # the header only: no patch rows


def test_without_the_exr_the_residual_is_named_missing(flat_frame, tmp_path):
    folder, _ = flat_frame
    for suffix in (".dng", ".json"):
        (tmp_path / f"flat{suffix}").write_bytes((folder / "frames" / f"flat_D65_F1{suffix}").read_bytes())
    out = tmp_path / "out"
    assert main(["analyze", str(tmp_path / "flat.dng"), "--out", str(out), "-q"]) == 0
    stats = json.loads((out / "analysis.json").read_text())["frames"][0]["frame_statistics"]
    assert all(ch["residual_status"] == "no-clean-layer" and ch["residual_mean_dn"] is None for ch in stats)


def test_a_region_takes_its_pixels_mean_xyz_factored(tmp_path):
    """Image (factored spectra): a region inside one colour has that colour's XYZ; one over both has the
    pixel-weighted mean of the two."""
    png = _two_colour_png(tmp_path / "two.png")
    regions = (Region("inside_a", (5, 5, 40, 30)), Region("inside_b", (70, 10, 30, 50)),
               Region("across", (40, 20, 30, 40)))  # 20 columns of A, 10 of B
    scene = small_scene(source=ImageSource(path=png), regions=regions)
    lit = light_scene(scene, "D65", load_camera(scene.camera, scene.grid))
    grid = scene.grid
    xyz_a = _xyz(_radiance(_reflectance(COLOUR_A, grid), grid), grid)
    xyz_b = _xyz(_radiance(_reflectance(COLOUR_B, grid), grid), grid)
    np.testing.assert_allclose(lit.patch_xyz[0], xyz_a, rtol=1e-4)
    np.testing.assert_allclose(lit.patch_xyz[1], xyz_b, rtol=1e-4)
    np.testing.assert_allclose(lit.patch_xyz[2], (20 * xyz_a + 10 * xyz_b) / 30, rtol=1e-4)


def test_a_region_takes_its_pixels_mean_xyz_dense(tmp_path):
    """A cube (one dense spectrum per pixel): the same, with spectra given on the grid."""
    grid = small_scene().grid
    first = 0.2 + 0.6 * (grid.wavelengths_nm - 380) / 400  # a rising and a falling reflectance
    second = 0.9 - 0.7 * (grid.wavelengths_nm - 380) / 400
    cube = np.empty((40, 50, grid.wavelengths_nm.size))
    cube[:, :25], cube[:, 25:] = first, second
    np.save(tmp_path / "cube.npy", cube)
    regions = (Region("first", (0, 0, 25, 40)), Region("across", (20, 10, 20, 10)))  # 5 columns first, 15 second
    scene = small_scene(source=CubeSource(path=tmp_path / "cube.npy"), regions=regions)
    lit = light_scene(scene, "D65", load_camera(scene.camera, grid))
    xyz_first, xyz_second = (_xyz(_radiance(r, grid), grid) for r in (first, second))
    np.testing.assert_allclose(lit.patch_xyz[0], xyz_first, rtol=1e-9)
    np.testing.assert_allclose(lit.patch_xyz[1], (5 * xyz_first + 15 * xyz_second) / 20, rtol=1e-9)


def _scene_file(tmp_path, regions: str, source: str = None) -> str:
    _two_colour_png(tmp_path / "two.png")
    path = tmp_path / "scene.toml"
    path.write_text('name = "two"\n' + (source or '[image]\npath = "two.png"\n') + regions)
    return str(path)


@pytest.mark.parametrize("case, regions, source, message", [
    ("outside", '[[region]]\nname = "a"\nrect = [100, 0, 40, 10]\n', None, "does not lie inside the 120x90"),
    ("empty", '[[region]]\nname = "a"\nrect = [0, 0, 0, 10]\n', None, "positive width and height"),
    ("twice", '[[region]]\nname = "a"\nrect = [0, 0, 5, 5]\n[[region]]\nname = "a"\nrect = [5, 5, 5, 5]\n', None,
     "used twice"),
    ("not ints", '[[region]]\nname = "a"\nrect = [0, 0, 5.5, 5]\n', None, r"\[x, y, width, height\]"),
    ("no name", '[[region]]\nrect = [0, 0, 5, 5]\n', None, "needs a name"),
    ("unknown key", '[[region]]\nname = "a"\nrect = [0, 0, 5, 5]\ncolour = 1\n', None, "unknown key"),
    ("chart", '[[region]]\nname = "a"\nrect = [0, 0, 5, 5]\n', "[chart]\n", "already has 24 patches"),
])
def test_bad_regions_are_one_error_line(tmp_path, capsys, case, regions, source, message):
    scene = _scene_file(tmp_path, regions, source)
    assert main(["render", scene, "--out", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("camsim: error: "), err
    assert re.search(message, err[0]), err[0]
    assert not (tmp_path / "out" / "two_D65_F1.json").exists()


def test_region_errors_from_the_api_are_camsim_errors(tmp_path):
    png = _two_colour_png(tmp_path / "two.png")
    scene = small_scene(source=ImageSource(path=png), regions=(Region("big", (0, 0, 121, 90)),))
    with pytest.raises(CamsimError, match="does not lie inside"):
        light_scene(scene, "D65")
    with pytest.raises(CamsimError, match="does not lie inside"):  # a chart frame's size is known up front
        small_scene(regions=(Region("big", (0, 0, 721, 10)),))


def test_analyze_measures_a_region_of_an_image_frame(tmp_path):
    """The region's patch rows: mean DN (black subtracted) = k · S of its colour, its sidecar XYZ the colour's, an
    ellipse and a ΔE (against itself, the F = 1 frame)."""
    scene = _scene_file(tmp_path, '[[region]]\nname = "left"\nrect = [4, 4, 50, 80]\n'
                                  '[light]\nilluminants = ["D65"]\n')
    out = tmp_path / "out"
    assert main(["render", scene, "--out", str(out), "-q"]) == 0
    assert main(["analyze", str(out), "--out", str(tmp_path / "an"), "--subtract-black", "-q"]) == 0
    rows = [r for r in csv.DictReader((tmp_path / "an" / "analysis.csv").open())]
    assert [(r["patch_name"], r["channel"]) for r in rows] == [("left", "R"), ("left", "G"), ("left", "B")]
    meta = json.loads((out / "two_D65_F1.json").read_text())
    assert [p["name"] for p in meta["patches"]] == ["left"] and meta["surround"] is None
    k, grid = meta["dn_per_electron"], small_scene().grid
    signal = _signal_e(COLOUR_A, grid, meta["qe_e_m2_sr_per_photon"])
    for c, row in enumerate(rows):
        n = int(row["n_pixels"])
        assert n == (50 - 6) * (80 - 6)  # the default 3-pixel border
        se = float(row["std_dn"]) / np.sqrt(n)
        assert abs(float(row["mean_dn"]) - k * signal[c]) < 4 * se + 0.02, (c, row["mean_dn"], k * signal[c])
    xyz = _xyz(_radiance(_reflectance(COLOUR_A, grid), grid), grid)
    np.testing.assert_allclose(meta["patches"][0]["xyz_cd_m2"], xyz, rtol=1e-4)
    assert rows[0]["ellipse_status"] == "ok" and rows[0]["delta_e_status"] == "ok"


def test_a_pedestals_frame_is_measured_about_its_own_black(tmp_path):
    """With a pedestal P the DNG holds floor(x + ½) + P: the residual is measured about it (bias ~0, not P) and a
    dark frame's pixels, whose clean value is within 5 σ of 0 but P above the ADC's floor, are not taken as clipped."""
    picture = np.broadcast_to(COLOUR_A.astype(np.uint8), (80, 120, 3)).copy()
    iio.imwrite(tmp_path / "flat.png", picture)
    scene = small_scene(name="flat", source=ImageSource(path=tmp_path / "flat.png")).with_sensor(
        pedestal_dn=64, dark_current=False, read_noise_e=40.0).replace(intensity_factors=(0.001,))  # σ 1.1 DN
    render_scene(scene, tmp_path / "frames", progress=False)
    assert main(["analyze", str(tmp_path / "frames"), "--out", str(tmp_path / "a"), "--source", "dng", "-q"]) == 0
    result = json.loads((tmp_path / "a" / "analysis.json").read_text())["frames"][0]
    for ch in result["frame_statistics"]:
        assert ch["residual_status"] == "ok" and ch["n_residual"] == ch["n_pixels"], ch
        assert abs(ch["residual_mean_dn"]) < 4 * ch["residual_mean_se_dn"], ch
        assert abs(ch["residual_var_dn2"] / ch["predicted_var_dn2"] - 1) < 4 * ch["residual_var_se_dn2"] / ch[
            "predicted_var_dn2"], ch
