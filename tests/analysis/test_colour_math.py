"""Properties of the pure-array colour analysis (camsim.analysis; MODEL.md §6)."""

import dataclasses
import math
import warnings

import numpy as np
import pytest

from camsim.analysis.delta_e import (
    d65_white_xy,
    d65_white_xyz_y100,
    delta_e_5step,
    lab_scaled_to_y100,
    reference_lab,
)
from camsim.analysis.ellipse import fit_ellipse
from camsim.analysis.snr import delta_snr_percent, snr_empirical, snr_model
from camsim.colour.colorimetry import (
    camera_to_xyz_matrix,
    chromaticity_xy,
    matrix_condition,
    xyz_from_camera,
)
from camsim.light.photons import LIGHT_SPEED_M_S, PLANCK_J_S
from camsim.light.spectra import cmfs_at

WL = np.arange(380.0, 780.0 + 1e-9, 4.0)


def _colour():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import colour
    return colour


def _no_nan(obj):
    for value in dataclasses.asdict(obj).values():
        assert not (isinstance(value, float) and math.isnan(value))


# --- ellipses ---------------------------------------------------------------------------------------------


def _angle_diff_deg(a, b):
    """Difference of two axis directions, modulo 180°, in [−90, 90)."""
    return (a - b + 90.0) % 180.0 - 90.0


@pytest.mark.parametrize("angle_deg", [0.0, 30.0, -45.0, 60.0, 89.5, -89.5, 90.0])
def test_ellipse_recovers_gaussian_cloud(angle_deg):
    rng = np.random.default_rng(20140 + int(angle_deg * 10))
    n, a, b, centre = 20_000, 0.03, 0.01, np.array([0.31, 0.33])
    t = np.radians(angle_deg)
    rot = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    xy = centre + (rng.standard_normal((n, 2)) * [a, b]) @ rot.T
    e = fit_ellipse(xy)
    assert e.status == "ok" and e.n_samples == n
    # 5 σ sampling errors: centre a/√n; √λ relative 1/√(2n); axis angle √(λ1 λ2 / n) / (λ1 − λ2) rad
    assert abs(e.center_x - centre[0]) < 5 * a / np.sqrt(n)
    assert abs(e.center_y - centre[1]) < 5 * a / np.sqrt(n)
    assert e.semi_major == pytest.approx(a, rel=5 / np.sqrt(2 * n))
    assert e.semi_minor == pytest.approx(b, rel=5 / np.sqrt(2 * n))
    angle_tol = np.degrees(5 * a * b / (np.sqrt(n) * (a**2 - b**2)))
    assert abs(_angle_diff_deg(e.angle_deg, angle_deg)) < angle_tol
    assert -90.0 < e.angle_deg <= 90.0
    assert e.size == pytest.approx(np.hypot(e.semi_major, e.semi_minor))
    e2 = fit_ellipse(xy, confidence_sigma=2.0)
    assert e2.semi_major == pytest.approx(2 * e.semi_major) and e2.angle_deg == e.angle_deg


def test_ellipse_degenerate_cases():
    e = fit_ellipse(np.array([[0.3, 0.3], [0.5, 0.1]]))
    assert e.status == "too-few-samples" and e.n_samples == 2
    assert (e.center_x, e.center_y) == pytest.approx((0.4, 0.2))
    assert e.semi_major is None and e.angle_deg is None and e.size is None
    e = fit_ellipse(np.empty((0, 2)))
    assert e.status == "too-few-samples" and e.center_x is None and e.n_samples == 0
    e = fit_ellipse(np.full((7, 2), 0.1))  # 0.1 does not average to exactly 0.1: must still be "constant"
    assert e.status == "constant" and (e.center_x, e.center_y) == (0.1, 0.1)
    assert e.semi_major == 0.0 and e.size == 0.0 and e.angle_deg is None
    x = np.linspace(0.2, 0.4, 50)
    e = fit_ellipse(np.column_stack([x, 2 * x + 0.01]))
    assert e.status == "rank-1" and e.semi_minor == 0.0
    assert e.angle_deg == pytest.approx(np.degrees(np.arctan(2.0)))
    for xy in ([[0.3, 0.3], [0.5, 0.1]], np.full((7, 2), 0.1), np.column_stack([x, 2 * x])):
        _no_nan(fit_ellipse(np.asarray(xy)))
    with pytest.raises(ValueError, match="NaN"):
        fit_ellipse(np.array([[0.1, 0.2], [np.nan, 0.3], [0.2, 0.2]]))


# --- camera → XYZ -------------------------------------------------------------------------------------------


def _qe_for_sensitivity(c, k):
    """QE whose "paper" radiance sensitivity k Qe λ δ / (h c) equals c."""
    return c * PLANCK_J_S * LIGHT_SPEED_M_S / (k * WL * 1e-9 * 4.0)


def test_paper_matrix_inverts_cmf_mixing():
    a = np.array([[0.9, 0.3, 0.05], [0.2, 1.1, 0.1], [0.0, 0.15, 1.3]])
    k = 0.028334
    qe = _qe_for_sensitivity(a @ cmfs_at(WL), k)
    m, cond = camera_to_xyz_matrix(qe, WL, k, method="paper", return_condition=True)
    np.testing.assert_allclose(m, np.linalg.inv(a), rtol=1e-9, atol=1e-12)
    assert 1 < cond < 1e3
    # the printed Eq. 16 weights bins by h c / λ instead of λ: a different matrix
    m_lit = camera_to_xyz_matrix(qe, WL, k, method="paper-literal")
    assert not np.allclose(m_lit / np.abs(m_lit).max(), m / np.abs(m).max(), rtol=1e-3)


def test_least_squares_recovers_known_matrix():
    rng = np.random.default_rng(5)
    m0 = np.array([[0.41, 0.36, 0.18], [0.21, 0.72, 0.07], [0.02, 0.12, 0.95]])
    dn = rng.uniform(0, 200, (24, 3))
    m = camera_to_xyz_matrix(None, None, 1.0, method="least-squares", training=(dn, dn @ m0.T))
    np.testing.assert_allclose(m, m0, rtol=1e-10)
    with pytest.raises(ValueError, match="rank-deficient"):
        camera_to_xyz_matrix(None, None, 1.0, method="least-squares", training=(dn[:, [0, 0, 1]], dn))
    with pytest.raises(ValueError, match="needs training"):
        camera_to_xyz_matrix(None, None, 1.0, method="least-squares")


def test_singular_camera_raises_clear_error():
    t = cmfs_at(WL)
    qe = np.stack([t[1], t[1], t[2]])  # two identical channels
    for method in ("paper", "paper-literal"):
        with pytest.raises(ValueError, match="singular"):
            camera_to_xyz_matrix(qe, WL, 0.03, method=method)
    with pytest.raises(ValueError, match="unknown camera"):
        camera_to_xyz_matrix(t, WL, 0.03, method="magic")
    with pytest.raises(ValueError, match="only used by"):
        camera_to_xyz_matrix(t, WL, 0.03, training=(np.eye(3), np.eye(3)))
    assert matrix_condition(np.ones((3, 3))) > 1e12
    assert matrix_condition(np.eye(3)) == 1.0


def test_xyz_from_camera_rows():
    m = np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.0, 3.0]])
    dn = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 2.0]])
    np.testing.assert_allclose(xyz_from_camera(dn, m), [[1.0, 0.0, 0.5], [2.0, 1.0, 6.0]])
    assert xyz_from_camera(np.ones((4, 5, 3)), m).shape == (4, 5, 3)


# --- chromaticity ---------------------------------------------------------------------------------------


def test_xy_of_d65():
    colour = _colour()
    xy, n_bad = chromaticity_xy(d65_white_xyz_y100()[None])
    np.testing.assert_allclose(xy[0], [0.3127, 0.3290], atol=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        xyz = colour.sd_to_XYZ(colour.SDS_ILLUMINANTS["D65"])
    xy, n_bad = chromaticity_xy(xyz)
    np.testing.assert_allclose(xy[0], [0.3127, 0.3290], atol=1e-4)
    assert n_bad == 0


def test_xy_undefined_samples_counted_and_excluded():
    good = np.array([[20.0, 30.0, 50.0], [1.0, -0.2, 0.4]])  # positive sum: defined, even with a negative Y
    bad = np.array([[0.0, 0.0, 0.0], [-1.0, -1.0, -1.0], [1.0, -2.0, 0.5], [np.nan, 1.0, 1.0], [np.inf, 1.0, 1.0]])
    xy, n_bad = chromaticity_xy(np.concatenate([bad[:2], good[:1], bad[2:], good[1:]]))
    assert n_bad == 5 and xy.shape == (2, 2) and np.all(np.isfinite(xy))
    np.testing.assert_allclose(xy, [[0.2, 0.3], [1 / 1.2, -0.2 / 1.2]])
    xy, n_bad = chromaticity_xy(bad)
    assert xy.shape == (0, 2) and n_bad == 5


# --- Lab and ΔE -----------------------------------------------------------------------------------------


def test_lab_matches_colour_science():
    colour = _colour()
    xyz = np.array([[95.0, 100.0, 108.0], [50.0, 100.0, 20.0], [130.0, 100.0, 60.0]])
    expected = colour.XYZ_to_Lab(xyz / 100, illuminant=np.array([0.3127, 0.3290]))
    lab, n_bad = lab_scaled_to_y100(xyz)
    np.testing.assert_allclose(lab, expected, rtol=1e-12)
    lab_scaled, _ = lab_scaled_to_y100(xyz * np.array([[0.37], [2e-3], [5e4]]))  # step 2 removes the scale
    np.testing.assert_allclose(lab_scaled, expected, rtol=1e-10)
    assert n_bad == 0 and np.all(lab[:, 0] == pytest.approx(100.0))
    np.testing.assert_allclose(d65_white_xy(), [0.3127, 0.3290])


def test_delta_e_textbook_pair():
    colour = _colour()
    de = colour.delta_E(np.array([50, 2.6772, -79.7751]), np.array([50, 0, -82.7485]), method="CIE 1976")
    assert de == pytest.approx(4.0011, abs=1e-4)


def _xyz_from_lab(lab, scales):
    colour = _colour()
    xyz = colour.Lab_to_XYZ(np.asarray(lab, dtype=float), illuminant=d65_white_xy()) * 100
    return xyz * np.asarray(scales)[:, None]


def test_delta_e_zero_for_identical_and_five_for_shift():
    xyz = np.tile([[41.0, 35.0, 12.0]], (6, 1))
    ref, n_bad = reference_lab(xyz[:1])
    result = delta_e_5step(xyz, ref)
    assert (result.mean, result.std, result.n_samples, result.n_undefined) == (0.0, 0.0, 6, 0)
    ref_lab = np.array([100.0, 10.0, -20.0])
    rng = np.random.default_rng(11)
    scales = rng.uniform(0.01, 50, 40)
    ref, _ = reference_lab(_xyz_from_lab(np.tile(ref_lab, (40, 1)), scales))
    np.testing.assert_allclose(ref, ref_lab, atol=1e-9)
    shifted = _xyz_from_lab(np.tile(ref_lab + [0, 3, 4], (40, 1)), scales[::-1])
    result = delta_e_5step(shifted, ref)
    assert result.mean == pytest.approx(5.0, abs=1e-9) and result.std < 1e-9 and result.n_samples == 40


def test_delta_e_excludes_unscalable_samples():
    ok = _xyz_from_lab([[100.0, 0.0, 3.0], [100.0, 4.0, 0.0]], [1.0, 7.0])
    bad = np.array([[10.0, 0.0, 5.0], [10.0, -1.0, 5.0], [np.nan, 10.0, 5.0], [1.0, np.inf, 1.0]])
    lab, n_bad = lab_scaled_to_y100(np.concatenate([bad, ok]))
    assert n_bad == 4 and lab.shape == (2, 3) and np.all(np.isfinite(lab))
    ref = np.array([100.0, 0.0, 0.0])
    result = delta_e_5step(np.concatenate([ok, bad]), ref)
    assert result.n_undefined == 4 and result.n_samples == 2
    assert result.mean == pytest.approx(3.5) and result.std == pytest.approx(np.std([3.0, 4.0], ddof=1))
    result = delta_e_5step(bad, ref)
    assert result == type(result)(None, None, 0, 4)
    one = delta_e_5step(ok[:1], ref)
    assert one.mean == pytest.approx(3.0) and one.std is None
    assert reference_lab(bad) == (None, 4)
    with pytest.raises(ValueError, match="reference_lab"):
        delta_e_5step(ok, None)


# --- SNR ------------------------------------------------------------------------------------------------


def test_snr_model_hand_computed():
    k = 0.028334
    m = snr_model(1000.0, 230.0, 1000.0, 4.0, k, quantisation=False)
    assert m.signal_dn == pytest.approx(28.334)
    assert m.variance_dn2 == pytest.approx(0.000802815556 * 1246)  # k² (1000 + 230 + 4²) = 1.000308182776
    assert m.snr == pytest.approx(1e6 / 1246)  # 802.568…: k cancels without quantisation
    assert m.snr_db == pytest.approx(29.0448196, abs=1e-6)
    q = snr_model(1000.0, 230.0, 1000.0, 4.0, k, quantisation=True)
    assert q.variance_dn2 == pytest.approx(1.000308182776 + 1 / 12)
    assert q.snr == pytest.approx(28.334**2 / (1.000308182776 + 1 / 12))  # 740.85
    assert q.snr_db == pytest.approx(28.6973014, abs=1e-6)


def test_snr_model_quantised_numerator_hand_computed():
    """Eq. 14's numerator [k S]_nb: the integer part of k S, clipped to [0, 2^nb − 1]; SNR 0 where k S < 1 DN."""
    k = 0.5
    # k S = 2.7, 0.9, 400 DN (8 bits: 400 clips to 255); variance k² (S + 0 + 0) + 1/3 = 1.35 + 1/3, … by hand
    signal = np.array([5.4, 1.8, 800.0])
    m = snr_model(signal, 0.0, signal, 0.0, k, quantisation=True, quantisation_term="mean-square", numerator_bits=8)
    np.testing.assert_array_equal(m.signal_dn, [2.0, 0.0, 255.0])
    np.testing.assert_allclose(m.variance_dn2, [1.35 + 1 / 3, 0.45 + 1 / 3, 200.0 + 1 / 3])
    np.testing.assert_allclose(m.snr, [4.0 / (1.35 + 1 / 3), 0.0, 255.0**2 / (200.0 + 1 / 3)])
    plain = snr_model(signal, 0.0, signal, 0.0, k, quantisation=True, quantisation_term="mean-square")
    np.testing.assert_allclose(plain.signal_dn, [2.7, 0.9, 400.0])  # without numerator_bits: k S


def test_snr_model_vectorised_and_edge_cases():
    m = snr_model(np.array([0.0, 0.0, 100.0, 100.0]), 0.0, np.array([0.0, 0.0, 100.0, 0.0]),
                  np.array([0.0, 2.0, 0.0, 0.0]), 1.0, quantisation=False)
    np.testing.assert_allclose(m.snr, [0.0, 0.0, 100.0, np.inf])
    np.testing.assert_array_equal(m.snr_db, [-np.inf, -np.inf, 20.0, np.inf])
    assert not np.any(np.isnan(m.snr_db))
    with pytest.raises(ValueError):
        snr_model(-1.0, 0.0, 0.0, 0.0, 1.0, quantisation=False)


def test_snr_empirical_matches_model():
    k, black = 0.028334, 64.0
    model = snr_model(1000.0, 230.0, 1000.0, 4.0, k, quantisation=False)
    rng = np.random.default_rng(14)
    n = 200_000
    samples = black + model.signal_dn + np.sqrt(model.variance_dn2) * rng.standard_normal(n)
    snr, snr_db, status = snr_empirical(samples, black)
    assert status == "ok"
    # relative standard error of the SNR ≈ √(2/n) (variance) plus 2/(√n · √SNR) (mean): use 5 σ
    rel_tol = 5 * (np.sqrt(2 / n) + 2 / np.sqrt(n * model.snr))
    assert snr == pytest.approx(float(model.snr), rel=rel_tol)
    assert snr_db == pytest.approx(10 * np.log10(snr))
    assert snr_empirical([70.0], black) == (None, None, "too-few-samples")
    assert snr_empirical(np.full(50, 70.0), black) == (None, None, "constant")
    snr0, db0, status0 = snr_empirical([63.0, 65.0], black)
    assert (snr0, db0, status0) == (0.0, None, "ok")


def test_delta_snr_percent():
    assert delta_snr_percent(100.0, 90.0) == pytest.approx(10.0)
    assert delta_snr_percent(100.0, 110.0) == pytest.approx(-10.0)
    assert delta_snr_percent(50.0, 50.0) == 0.0
    assert delta_snr_percent(0.0, 5.0) is None
    assert delta_snr_percent(None, 5.0) is None
    assert delta_snr_percent(5.0, None) is None
