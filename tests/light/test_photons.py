"""Spectra, photons, absolute scale and chart geometry against colour-science and known values."""

import dataclasses
import warnings

import numpy as np
import pytest

from camsim.core.errors import CamsimError
from camsim.light.photons import LIGHT_SPEED_M_S, PLANCK_J_S, photon_radiance
from camsim.light.spectra import WavelengthGrid, illuminant_spd
from camsim.render.pipeline import frame_sensor, light_scene, lit_scene
from camsim.scene.chart import ChartGeometry
from camsim.scene.radiance import scene_radiance
from camsim.sensor.camera import AnchorScale, PhysicalScale, absolute_qe, load_camera
from camsim.sensor.expected import expected_signal
from camsim.sensor.params import PRESETS
from tests.support.helpers import ROOT, WHITE, small_scene
from tests.support.theory import white_response

with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    import colour

GRID = WavelengthGrid()
TABLE1 = PRESETS["paper-table1"]


def test_paper_grid():
    wl = GRID.wavelengths_nm
    assert wl.size == 101 and wl[0] == 380 and wl[-1] == 780 and np.all(np.diff(wl) == 4)


@pytest.mark.parametrize("illuminant", ["D65", "A", "FL2"])
def test_white_is_100_cd_m2_with_the_illuminant_chromaticity(illuminant):
    radiance = scene_radiance(small_scene(), illuminant)
    sd = colour.SpectralDistribution(dict(zip(GRID.wavelengths_nm, radiance.white_radiance)))
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    xyz = colour.sd_to_XYZ(sd, cmfs=cmfs, k=683, method="Integration")
    assert xyz[1] == pytest.approx(100.0, rel=2e-3)  # colour-science integrates on its own 1 nm CMFs
    expected_xy = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"][illuminant]
    np.testing.assert_allclose(colour.XYZ_to_xy(xyz), expected_xy, atol=1.5e-3)


def test_per_spectrum_normalisation_puts_every_patch_at_the_luminance():
    radiance = scene_radiance(small_scene(normalisation="per-spectrum"), "D65")
    ybar = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].copy().align(GRID.shape()).values[:, 1]
    luminance = 683 * radiance.radiance @ ybar * GRID.step_nm
    np.testing.assert_allclose(luminance, 100.0, rtol=1e-3)


def test_photon_radiance_eq3():
    radiance = np.zeros(GRID.size)
    i = np.searchsorted(GRID.wavelengths_nm, 500.0)
    radiance[i] = 1.0  # 1 W/(m² sr nm) in the 500 nm bin
    g = photon_radiance(radiance, GRID.wavelengths_nm, GRID.step_nm)
    assert g[i] == pytest.approx(500e-9 * 4.0 / (PLANCK_J_S * LIGHT_SPEED_M_S), rel=1e-12)
    assert g[i] == pytest.approx(1.00672e19, rel=1e-4)
    assert np.count_nonzero(g) == 1


def test_photon_counts_at_100_cd_m2_are_about_1e16_per_bin():
    """MODEL.md §4: with 100 cd/m² scenes, per-bin counts are ~1e16 photons/(s m² sr) at F = 1."""
    radiance = scene_radiance(small_scene(), "D65")
    g = photon_radiance(radiance.white_radiance, GRID.wavelengths_nm, GRID.step_nm)
    assert 3e15 < g[GRID.wavelengths_nm == 560][0] < 3e16


@pytest.mark.parametrize("reference", ["D65", "A", "FL11"])
def test_anchor_perfect_white_gives_8000_electrons(camera, reference):
    """The anchor: the perfect white under the reference illuminant at 100 cd/m², F = 1, T = 1 s gives 8000 e⁻ in
    the strongest channel; S scales as F · T."""
    radiance = scene_radiance(small_scene(), reference)
    g_white = photon_radiance(radiance.white_radiance, GRID.wavelengths_nm, GRID.step_nm)
    qe = absolute_qe(camera, AnchorScale(reference_illuminant=reference), GRID)
    white = expected_signal(g_white[None], qe, TABLE1, 1.0, "pixel").signal_e[0]
    assert white.max() == pytest.approx(8000.0, rel=1e-12)
    for factor, exposure in ((0.1, 1.0), (1.0, 0.5), (1e-3, 2.0)):
        sensor = dataclasses.replace(TABLE1, exposure_s=exposure)
        scaled = expected_signal(g_white[None], qe, sensor, factor, "pixel").signal_e[0]
        np.testing.assert_allclose(scaled, white * factor * exposure, rtol=1e-12)


@pytest.mark.parametrize("illuminant", ["A", "FL2", "D50"])  # smooth enough for 4 nm against 5 nm
def test_one_camera_under_every_light(camera, illuminant):
    """MODEL.md §3: Qe is anchored once (on D65) and is the same under every light; the perfect white at the same
    luminance then gives each light's own electrons: under CIE A 0.80× the D65 anchor in the strongest channel
    (R 1.38×, G 0.76×, B 0.40× of D65's channels) with the Nikon 5100 curves, from colour-science's data alone."""
    scene = small_scene()
    reference = light_scene(scene, "D65", camera)
    lit = light_scene(scene, illuminant, camera)
    np.testing.assert_array_equal(lit.qe, reference.qe)  # one camera
    assert reference.white_signal_e_per_s.max() == pytest.approx(8000.0, rel=1e-12)
    theory = white_response(illuminant) / white_response("D65")
    np.testing.assert_allclose(lit.white_signal_e_per_s / reference.white_signal_e_per_s, theory, rtol=2e-3)
    if illuminant == "A":
        assert lit.white_signal_e_per_s.max() / 8000 == pytest.approx(0.8013, abs=2e-4)


def test_auto_exposure_meters_the_white_and_scales_dark_with_exposure(camera):
    """``exposure = "auto"``: T = target / (F · white e⁻/s of the strongest channel); dark charge = σ²_dark · T;
    the white then reaches the target under every light and F; an exposure limit caps T."""
    scene = small_scene().replace(exposure="auto", exposure_target_e=6000.0)
    for illuminant, factor in (("D65", 1.0), ("A", 0.1), ("FL2", 1e-3)):
        lit = light_scene(scene, illuminant, camera)
        sensor = frame_sensor(scene, lit, factor)
        white_rate = (lit.qe @ lit.white_photon_rate).max()  # e⁻/s at F = 1
        assert sensor.exposure_s == pytest.approx(6000.0 / (factor * white_rate), rel=1e-12)
        white = expected_signal(lit.white_photon_rate[None], lit.qe, sensor, factor, "pixel")
        assert white.signal_e.max() == pytest.approx(6000.0, rel=1e-12)
        np.testing.assert_allclose(white.dark_e, np.array(TABLE1.dark_current_e_per_s) * sensor.exposure_s,
                                   rtol=1e-12)
        np.testing.assert_array_equal(lit.qe, light_scene(scene, "D65", camera).qe)
    capped = frame_sensor(scene.replace(exposure_max_s=2.0), light_scene(scene, "D65", camera), 1e-3)
    assert capped.exposure_s == 2.0
    assert frame_sensor(small_scene(), light_scene(scene, "A", camera), 0.1).exposure_s == TABLE1.exposure_s


@pytest.mark.parametrize("illuminant", ["D65", "A", "FL2"])
def test_channel_ratios_match_an_independent_colour_science_integration(camera, illuminant):
    """Σ L · s per channel with colour-science on its native 5 nm data, against camsim's S on the 4 nm grid."""
    scene = small_scene()
    radiance = scene_radiance(scene, illuminant)
    expected = lit_scene(radiance, camera, scene.scale, GRID).expected(TABLE1, 1.0, "pixel")
    sens = colour.MSDS_CAMERA_SENSITIVITIES["Nikon 5100 (NPL)"]
    chart = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    light = colour.SDS_ILLUMINANTS[illuminant].copy().align(sens.shape)
    for index, sd in enumerate(chart.values()):
        signal = sd.copy().align(sens.shape) * light
        rgb = colour.sd_to_XYZ(signal, cmfs=sens, illuminant=colour.sd_ones(sens.shape), k=1, method="Integration")
        ours = expected.signal_e[index]
        np.testing.assert_allclose(ours / ours[1], rgb / rgb[1], rtol=0.01)


def test_white_patch_electrons_follow_its_reflectance(camera, d65_radiance):
    expected = lit_scene(d65_radiance, camera, AnchorScale(), GRID).expected(TABLE1, 1.0, "pixel")
    white = expected.signal_e[WHITE]
    assert 0.85 * 8000 < white.max() < 0.92 * 8000  # the ColorChecker white reflects ~ 88–90 %
    surround = expected.signal_e[-1]
    np.testing.assert_allclose(surround.max(), 0.05 * 8000, rtol=1e-9)  # flat 5 % surround


def test_physical_scale_is_etendue_times_qe(camera, d65_radiance):
    scale = PhysicalScale(pixel_pitch_um=4.0, f_number=2.0, transmittance=0.8, peak_qe=0.6)
    etendue = np.pi * 0.8 * (4e-6) ** 2 / (4 * 2.0**2)
    assert scale.etendue_m2_sr == pytest.approx(etendue, rel=1e-12)
    qe = absolute_qe(camera, scale, GRID)
    assert qe.max() == pytest.approx(etendue * 0.6, rel=1e-12)
    # 100 cd/m² white at f/2, τ 0.8: sensor illuminance π L τ / 4N² ≈ 15.7 lx; one lux is ~4.1e15 photons/(s m²)
    # at 555 nm, so a 16 µm² pixel receives ~1e6 photons/s: with QE 0.6 and a third of the band per channel, a few
    # 1e5 e⁻/s (thousands of electrons at 1/100 s, as in a real camera).
    g = photon_radiance(d65_radiance.white_radiance, GRID.wavelengths_nm, GRID.step_nm)
    assert 1e5 < (qe @ g).max() < 1e6


def test_energy_basis_divides_by_wavelength():
    energy = load_camera("Nikon 5100 (NPL)", GRID, "energy")
    photon = load_camera("Nikon 5100 (NPL)", GRID, "photon")
    ratio = energy.relative_qe / np.where(photon.relative_qe > 0, photon.relative_qe, np.nan)
    ratio = ratio * GRID.wavelengths_nm
    finite = ratio[np.isfinite(ratio)]
    np.testing.assert_allclose(finite, finite[0], rtol=1e-9)


def test_illuminant_must_cover_the_grid():
    with pytest.raises(CamsimError, match="covers 350–690 nm"):
        illuminant_spd("ISO 7589 Photoflood", GRID)
    assert illuminant_spd("ISO 7589 Photoflood", WavelengthGrid(400, 680, 10)).shape == (29,)


@pytest.mark.parametrize("bad", [(380, 780, 0), (780, 380, 4), (380, 781, 4), (380, float("nan"), 4)])
def test_bad_grids(bad):
    with pytest.raises(CamsimError):
        WavelengthGrid(*bad)


def test_chart_label_map():
    geometry = ChartGeometry()
    labels = geometry.label_map(600, 400)
    rects = geometry.rects(600, 400)
    assert labels.shape == (400, 600) and labels.dtype == np.uint8 and len(rects) == 24
    for index, (x, y, w, h) in enumerate(rects):
        assert np.all(labels[y : y + h, x : x + w] == index)
        assert np.count_nonzero(labels == index) == w * h  # patches are disjoint rectangles
    assert np.count_nonzero(labels == 24) == 600 * 400 - sum(w * h for *_, w, h in rects)
    # row-major from the top left
    assert rects[1][0] > rects[0][0] and rects[6][1] > rects[0][1]
    with pytest.raises(CamsimError, match="too small"):
        geometry.rects(10, 8)


SONY = ROOT / ".." / "shared" / "data" / "sfu" / "sony_dxc930_rgb_sensitivities_380_780_4nm.csv"


@pytest.mark.skipif(not SONY.is_file(), reason="SFU Sony DXC-930 curves not present in ../shared/data/sfu/")
def test_paper_camera_from_the_shared_csv():
    """The paper's Sony DXC-930, read from the shared data (never copied), on its own 4 nm grid."""
    scene = small_scene(camera=str(SONY.resolve()))
    camera = load_camera(scene.camera, GRID)
    assert camera.name == SONY.name
    data = np.loadtxt(SONY, delimiter=",", skiprows=1)
    radiance = scene_radiance(scene, "A")
    expected = lit_scene(radiance, camera, scene.scale, GRID).expected(TABLE1, 1.0, "pixel")
    # the CSV is on the scene grid: S ∝ Σ L · s exactly (energy basis), no resampling involved
    direct = radiance.radiance @ data[:, 1:]
    np.testing.assert_allclose(expected.signal_e / expected.signal_e[:, 1:2], direct / direct[:, 1:2], rtol=1e-9)
