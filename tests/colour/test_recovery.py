"""RGB → spectrum recovery (camsim.colour.recovery) against colour-science's own data and functions."""

import numpy as np
import pytest

from camsim.colour import recovery
from camsim.colour.recovery import (
    RECOVERY_METHODS,
    basis_matrix,
    clear_cache,
    mallett_basis,
    rgb_to_distinct_spectra,
    rgb_to_spectra,
)
from camsim.core.errors import CamsimError
from camsim.light.spectra import CMFS_NAME, WavelengthGrid, camera_sensitivities, illuminant_spd, import_colour

GRID = WavelengthGrid()  # 380–780 nm every 4 nm
#: Round-trip tolerance (CIE 2000 ΔE under D65) for colours inside sRGB that the method does not clip.
ROUND_TRIP_DE00 = {"Mallett 2019": 0.1, "Otsu 2018": 0.2, "Jakob 2019": 0.1}


@pytest.fixture(scope="module")
def colour():
    return import_colour()


@pytest.fixture(scope="module")
def chart_srgb(colour):
    """Linear sRGB (D65) of the ColorChecker N Ohta patches inside sRGB's gamut (cyan is outside), (23, 3)."""
    chart = colour.SDS_COLOURCHECKERS["ColorChecker N Ohta"]
    cmfs, d65 = colour.MSDS_CMFS[CMFS_NAME], colour.SDS_ILLUMINANTS["D65"]
    xyz = np.array([colour.sd_to_XYZ(sd, cmfs, d65) / 100 for sd in chart.values()])
    rgb = colour.XYZ_to_RGB(xyz, "sRGB", illuminant=colour.CCS_ILLUMINANTS[CMFS_NAME]["D65"],
                            chromatic_adaptation_transform=None)
    inside = rgb.min(axis=1) >= 0
    assert inside.sum() == 23
    return rgb[inside]


def independent_delta_e(colour, rgb, spectra, colourspace="sRGB"):
    """ΔE00 under D65 between linear RGB and the spectra, with colour.sd_to_XYZ and colour.RGB_to_XYZ."""
    cmfs, d65 = colour.MSDS_CMFS[CMFS_NAME], colour.SDS_ILLUMINANTS["D65"]
    wl = GRID.wavelengths_nm
    xyz = np.array([colour.sd_to_XYZ(colour.SpectralDistribution(s, wl), cmfs, d65, method="Integration") / 100
                    for s in np.atleast_2d(spectra)])
    white = colour.sd_to_XYZ(colour.SpectralDistribution(np.ones(wl.size), wl), cmfs, d65, method="Integration")
    lab = colour.XYZ_to_Lab(xyz, colour.XYZ_to_xy(white))
    d65_xy = colour.CCS_ILLUMINANTS[CMFS_NAME]["D65"]
    target = colour.XYZ_to_Lab(colour.RGB_to_XYZ(np.atleast_2d(rgb), colourspace, illuminant=d65_xy), d65_xy)
    return np.asarray(colour.delta_E(target, lab, method="CIE 2000"))


def common_wavelengths(step_nm):
    """Indices into GRID of the wavelengths that also lie on a step_nm grid from 380 nm (380 + 20 k for 5, 10)."""
    return np.flatnonzero(np.isclose((GRID.wavelengths_nm - 380) % step_nm, 0))


# ------------------------------------------------------------------------------------------------ Mallett


def test_colour_science_basis_sums_to_one_and_ours_keeps_it(colour):
    data = colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019
    np.testing.assert_allclose(data.values.sum(axis=1), 1.0, atol=1e-5)
    basis = mallett_basis(GRID)
    assert basis.shape == (3, GRID.size)
    np.testing.assert_allclose(basis.sum(axis=0), 1.0, atol=1e-5)
    assert basis.min() >= 0.0 and basis.max() <= 1.0
    white = rgb_to_spectra([1.0, 1.0, 1.0])
    np.testing.assert_allclose(white, 1.0, atol=1e-5)
    # Where the 4 nm grid meets colour-science's 5 nm samples (every 20 nm) the basis is its data, unchanged.
    on_data = common_wavelengths(5)
    rows = np.searchsorted(data.wavelengths, GRID.wavelengths_nm[on_data])
    np.testing.assert_array_equal(basis[:, on_data], data.values[rows].T)


def test_mallett_matches_colour_science_rgb_to_sd(colour):
    rgb = np.array([0.7, 0.2, 0.45])
    ours = rgb_to_spectra(rgb)
    reference = colour.recovery.RGB_to_sd_Mallett2019(rgb)
    idx = common_wavelengths(5)
    np.testing.assert_allclose(ours[idx], reference[GRID.wavelengths_nm[idx]], rtol=1e-12)


def test_mallett_is_linear():
    c1, c2, a, b = np.array([0.2, 0.5, 0.1]), np.array([0.9, 0.05, 0.3]), 0.7, 1.9
    combined = rgb_to_spectra(a * c1 + b * c2)
    np.testing.assert_allclose(combined, a * rgb_to_spectra(c1) + b * rgb_to_spectra(c2), rtol=1e-12, atol=1e-15)


def test_matrix_route_equals_full_spectrum_route():
    """electrons = rgb @ M.T with one 3 × 3 M per camera and illuminant, against integrating every spectrum."""
    _, qe = camera_sensitivities("Nikon 5100 (NPL)", GRID)
    wl_m = GRID.wavelengths_nm * 1e-9
    photon = wl_m * GRID.step_nm / (6.626176e-34 * 2.997925e8)  # λ δ / (h c)
    for light in ("D65", "A"):
        weights = qe * illuminant_spd(light, GRID) * photon  # (3, N)
        rgb = np.random.default_rng(4).random((7, 5, 3)) * 1.3
        via_matrix = rgb @ basis_matrix(mallett_basis(GRID), weights).T
        via_spectra = np.einsum("hwn,kn->hwk", rgb_to_spectra(rgb), weights)
        assert via_matrix.shape == (7, 5, 3)
        np.testing.assert_allclose(via_matrix, via_spectra, rtol=1e-12)


def test_basis_matrix_shape_mismatch_is_an_error():
    with pytest.raises(CamsimError, match="share N"):
        basis_matrix(np.ones((3, 10)), np.ones((3, 11)))


# ------------------------------------------------------------------------------------------- round trips


@pytest.mark.parametrize("method", ["Mallett 2019", "Otsu 2018"])
def test_round_trip_on_the_chart(colour, chart_srgb, method):
    result = rgb_to_distinct_spectra(chart_srgb, method)
    assert not result.outside.any()
    de = independent_delta_e(colour, chart_srgb, result.expand())
    assert de.max() < ROUND_TRIP_DE00[method], de.max()
    # the recorded ΔE (camsim's own sums on the grid) agrees with colour-science's integration
    np.testing.assert_allclose(result.delta_e[result.labels], de, atol=0.02)


def test_round_trip_jakob_on_two_patches(colour, chart_srgb):
    rgb = chart_srgb[[0, 13]]  # dark skin, green
    result = rgb_to_distinct_spectra(rgb, "Jakob 2019")
    assert not result.outside.any()
    de = independent_delta_e(colour, rgb, result.expand())
    assert de.max() < ROUND_TRIP_DE00["Jakob 2019"], de.max()


@pytest.mark.slow
def test_round_trip_jakob_on_the_chart(colour, chart_srgb):
    result = rgb_to_distinct_spectra(chart_srgb, "Jakob 2019")
    assert not result.outside.any()
    de = independent_delta_e(colour, chart_srgb, result.expand())
    assert de.max() < ROUND_TRIP_DE00["Jakob 2019"], de.max()


def test_otsu_on_the_grid_is_colour_sciences_spectrum_held_beyond_730_nm(colour):
    rgb = np.array([0.3, 0.5, 0.2])
    ours = rgb_to_spectra(rgb, "Otsu 2018")
    xyz = colour.RGB_to_XYZ(rgb, "sRGB", illuminant=colour.CCS_ILLUMINANTS[CMFS_NAME]["D65"])
    reference = colour.recovery.XYZ_to_sd_Otsu2018(xyz)  # 380–730 nm every 10 nm, clipped to [0, 1]
    wl = GRID.wavelengths_nm
    idx = common_wavelengths(10)
    idx = idx[wl[idx] <= 730]
    np.testing.assert_allclose(ours[idx], reference[wl[idx]], rtol=1e-12)
    np.testing.assert_allclose(ours[wl >= 730], reference.values[-1], rtol=1e-12)


def test_jakob_is_colour_sciences_sigmoid_on_the_grid(colour):
    rgb = np.array([0.25, 0.4, 0.6])
    ours = rgb_to_spectra(rgb, "Jakob 2019")
    xyz = colour.RGB_to_XYZ(rgb, "sRGB", illuminant=colour.CCS_ILLUMINANTS[CMFS_NAME]["D65"])
    reference = colour.recovery.XYZ_to_sd_Jakob2019(xyz)  # 360–780 nm every 5 nm
    idx = common_wavelengths(5)
    np.testing.assert_allclose(ours[idx], reference[GRID.wavelengths_nm[idx]], rtol=1e-9)


# ------------------------------------------------------------------------------------------------ cache


def test_cache_recovers_each_distinct_colour_once(monkeypatch, colour):
    clear_cache()
    calls = []
    original = colour.recovery.XYZ_to_sd_Otsu2018

    def counting(xyz, *args, **kwargs):
        calls.append(np.array(xyz))
        return original(xyz, *args, **kwargs)

    monkeypatch.setattr(colour.recovery, "XYZ_to_sd_Otsu2018", counting)
    palette = np.array([[0.1, 0.2, 0.3], [0.5, 0.5, 0.5], [0.8, 0.3, 0.1], [0.05, 0.6, 0.2]])
    index = np.random.default_rng(2).integers(0, 4, size=(6, 9))
    image = palette[index]
    first = rgb_to_distinct_spectra(image, "Otsu 2018")
    assert len(calls) == 4 and first.computed == 4
    assert first.spectra.shape == (4, GRID.size) and first.labels.shape == (6, 9)
    np.testing.assert_array_equal(first.colours[first.labels], image)  # labels point at each pixel's colour
    expanded = first.expand()
    for k in range(4):  # identical colours, identical spectra
        same = expanded[index == k]
        assert np.array_equal(same, np.broadcast_to(same[0], same.shape))
    second = rgb_to_distinct_spectra(image[::-1], "Otsu 2018")  # across calls: nothing recomputed
    assert len(calls) == 4 and second.computed == 0
    np.testing.assert_array_equal(second.expand(), expanded[::-1])
    third = rgb_to_distinct_spectra(np.vstack([palette, [[0.3, 0.3, 0.9]]]), "Otsu 2018")
    assert len(calls) == 5 and third.computed == 1
    clear_cache()
    rgb_to_distinct_spectra(palette, "Otsu 2018")
    assert len(calls) == 9


def test_quantised_colours_share_the_encoded_code(colour):
    srgb_encode = colour.models.eotf_inverse_sRGB
    base = 0.2
    step = 1 / 255
    code = np.rint(srgb_encode(base) * 255)
    # two linear values whose sRGB encodings round to the same 8-bit code, one that does not
    near = colour.models.eotf_sRGB((code + 0.3) / 255)
    far = colour.models.eotf_sRGB((code + 1) / 255)
    rgb = np.array([[base, 0.5, 0.5], [near, 0.5, 0.5], [far, 0.5, 0.5]])
    colours, labels = recovery.distinct_colours(rgb, "sRGB", bits=8)
    assert labels[0] == labels[1] != labels[2]
    np.testing.assert_allclose(colours[labels[0], 0], colour.models.eotf_sRGB(code * step), rtol=1e-12)
    exact, exact_labels = recovery.distinct_colours(rgb)
    assert len(set(exact_labels.tolist())) == 3 and exact.shape == (3, 3)


# ------------------------------------------------------------------------------------------- out of gamut


@pytest.mark.parametrize("method", list(RECOVERY_METHODS))
def test_black_is_zero(method):
    spectrum = rgb_to_spectra([0.0, 0.0, 0.0], method)
    assert np.array_equal(spectrum, np.zeros(GRID.size))


@pytest.mark.parametrize("method", list(RECOVERY_METHODS))
@pytest.mark.parametrize("bad", [[0.2, -0.01, 0.3], [0.2, np.nan, 0.3], [0.1, 0.2]])
def test_negative_nonfinite_or_misshapen_rgb_is_refused(method, bad):
    with pytest.raises(CamsimError):
        rgb_to_spectra(bad, method)


def test_mallett_above_one_is_linear_and_exceeds_unit_reflectance(colour):
    rgb = np.array([1.8, 1.2, 0.4])
    spectrum = rgb_to_spectra(rgb)
    np.testing.assert_allclose(spectrum, 2 * rgb_to_spectra(rgb / 2), rtol=1e-12)
    assert spectrum.max() > 1
    assert independent_delta_e(colour, rgb, spectrum).max() < ROUND_TRIP_DE00["Mallett 2019"]


@pytest.mark.parametrize("method", ["Otsu 2018", "Jakob 2019"])
def test_bounded_methods_scale_colours_above_one(colour, method):
    rgb = np.array([1.5, 1.2, 0.9])
    spectrum = rgb_to_spectra(rgb, method)
    np.testing.assert_allclose(spectrum, 1.5 * rgb_to_spectra(rgb / 1.5, method), rtol=1e-12)
    assert spectrum.max() > 1
    assert independent_delta_e(colour, rgb, spectrum).max() < ROUND_TRIP_DE00[method]


def test_mallett_outside_srgb_clips_negative_srgb_and_records_it(colour):
    prophoto = np.array([[0.0, 0.0, 1.0], [0.3, 0.3, 0.3]])
    result = rgb_to_distinct_spectra(prophoto, "Mallett 2019", colourspace="ProPhoto RGB")
    srgb = colour.RGB_to_RGB(prophoto, "ProPhoto RGB", "sRGB", chromatic_adaptation_transform="CAT02")
    assert srgb[0].min() < 0 and srgb[1].min() >= 0  # the blue primary lies outside sRGB, the grey inside
    spectra = result.expand()
    np.testing.assert_allclose(spectra, np.maximum(srgb, 0) @ mallett_basis(GRID), rtol=1e-12, atol=1e-15)
    assert spectra.min() >= 0
    assert result.outside[result.labels].tolist() == [True, False]
    assert result.delta_e[result.labels[0]] > 5  # recorded: the clip misses the colour
    with pytest.raises(CamsimError, match="ΔE00 above 1"):
        rgb_to_distinct_spectra(prophoto, "Mallett 2019", colourspace="ProPhoto RGB", max_delta_e=1.0)


def test_mallett_in_another_colourspace_inside_srgb_is_the_srgb_colour(colour):
    srgb = np.array([0.5, 0.4, 0.3])
    p3 = colour.RGB_to_RGB(srgb, "sRGB", "Display P3")
    result = rgb_to_distinct_spectra(p3, colourspace="Display P3")
    assert result.outside.tolist() == [False]
    # equal to the sRGB route to the rounding of sRGB's standard matrices (4 decimals, IEC 61966-2-1), which
    # colour-science uses as given: its RGB → XYZ and XYZ → RGB matrices are inverse to about 1e-4
    np.testing.assert_allclose(result.expand(), rgb_to_spectra(srgb), rtol=2e-4)


def test_otsu_records_its_clip(colour):
    result = rgb_to_distinct_spectra(np.array([[0.0, 0.0, 1.0], [0.4, 0.4, 0.4]]), "Otsu 2018")
    xyz = colour.RGB_to_XYZ(result.colours, "sRGB", illuminant=colour.CCS_ILLUMINANTS[CMFS_NAME]["D65"])
    unclipped = [colour.recovery.XYZ_to_sd_Otsu2018(x, clip=False).values for x in xyz]
    expected = [bool(v.min() < 0 or v.max() > 1) for v in unclipped]
    assert expected == [True, False]  # sRGB blue needs the clip, the grey does not
    assert result.outside.tolist() == expected
    assert result.spectra.min() >= 0 and result.spectra.max() <= 1


@pytest.mark.slow
def test_jakob_flags_a_colour_outside_the_spectral_locus(colour):
    prophoto_blue = np.array([0.0, 0.0, 0.5])
    xy = colour.XYZ_to_xy(colour.RGB_to_XYZ(prophoto_blue, "ProPhoto RGB"))
    assert xy[1] < 0.01  # ProPhoto's blue primary: below the purple line's reach, outside the locus
    result = rgb_to_distinct_spectra(prophoto_blue, "Jakob 2019", colourspace="ProPhoto RGB")
    assert result.outside.tolist() == [True]
    assert result.delta_e[0] > 5
    assert result.spectra.min() > 0 and result.spectra.max() < 1


# ----------------------------------------------------------------------------------------------- names


def test_unknown_method_colourspace_or_bits_is_a_camsim_error():
    with pytest.raises(CamsimError, match="unknown recovery method 'Smits 1999'"):
        rgb_to_spectra([0.1, 0.2, 0.3], "Smits 1999")
    with pytest.raises(CamsimError, match="unknown RGB colourspace 'sRGB2'"):
        rgb_to_spectra([0.1, 0.2, 0.3], colourspace="sRGB2")
    with pytest.raises(CamsimError, match="bits"):
        rgb_to_distinct_spectra([0.1, 0.2, 0.3], "Otsu 2018", bits=0)
