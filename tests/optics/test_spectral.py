"""Per-spectrum OTFs (issue 30, point 2: camsim.optics.spectral, camsim.render.optics.spectral_otf): against a
per-wavelength reference computed here from the closed-form Airy OTF, exact for a grey frame, energy conserving."""

from __future__ import annotations

import numpy as np
import pytest

from camsim.light.rates import FactoredSpectra
from camsim.optics.params import OpticsParams
from camsim.optics.stages import margin_px, padded_shape
from camsim.render.optics import OTF_TOLERANCE, apply_optics, optics_record, spectral_otf

WAVELENGTHS = np.arange(400.0, 701.0, 10.0)
# three Gaussian channels and two spectra: a red-ish ramp and a blue-ish ramp (unit-free)
QE = np.exp(-0.5 * ((WAVELENGTHS[None] - np.array([[610.0], [540.0], [460.0]])) / 40.0) ** 2)
RED = 0.05 + np.clip((WAVELENGTHS - 550.0) / 150.0, 0, 1)
BLUE = 0.05 + np.clip((550.0 - WAVELENGTHS) / 150.0, 0, 1)


def _mean_weights(rates, labels):
    counts = np.bincount(labels.ravel(), minlength=rates.shape[0]) / labels.size
    signal = QE * (counts @ rates)[None]
    return signal / signal.sum(axis=1, keepdims=True)


def _edge(height=24, width=48):
    labels = np.zeros((height, width), dtype=np.intp)
    labels[:, width // 2:] = 1
    return labels


def _planes(rates, labels):
    electrons = rates @ QE.T  # (K, 3): e_kc = Σ_λ Qe_c g_k
    return electrons, np.stack([electrons[labels, c] for c in range(3)]).astype(np.float32)


def _airy(nu):
    nu = np.minimum(np.abs(nu), 1.0)
    return (2 / np.pi) * (np.arccos(nu) - nu * np.sqrt(1 - nu * nu))


def _reference(rates, labels, optics):
    """Σ_λ PSF_λ ∗ (Qe_c(λ) g(λ, x)) per channel, float64: each wavelength's Airy OTF × the pixel aperture relative to
    the source's full-pixel box, sinc(√ff f) / sinc(f) per axis (1 at ff = 1), on the same reflected, padded grid; and
    the padded planes' L2 norms per spectrum (for Parseval's bound)."""
    height, width = labels.shape
    margin = margin_px(optics.f_number, optics.pixel_pitch_um, 0.0, 0.0)
    shape = padded_shape(height, width, margin)
    pad = ((margin, shape[0] - height - margin), (margin, shape[1] - width - margin))
    fy, fx = np.fft.fftfreq(shape[0])[:, None], np.fft.rfftfreq(shape[1])[None]
    rho = np.hypot(fy, fx)
    root = np.sqrt(optics.fill_factor)
    aperture = np.sinc(root * fy) / np.sinc(fy) * (np.sinc(root * fx) / np.sinc(fx))
    falloff = np.ones(labels.shape)
    if optics.vignetting == "cos4":  # cos⁴ of the field angle, before the PSF
        y = (np.arange(height) - (height - 1) / 2)[:, None]
        x = (np.arange(width) - (width - 1) / 2)[None]
        falloff = np.cos(np.arctan(np.hypot(y, x) * optics.pixel_pitch_um / (optics.focal_length_mm * 1e3))) ** 4
    out = np.zeros((3,) + labels.shape)
    for i, lam in enumerate(WAVELENGTHS):
        cutoff = optics.pixel_pitch_um / (lam * 1e-3 * optics.f_number)
        field = np.pad(rates[labels, i] * falloff, pad, mode="symmetric")
        blurred = np.fft.irfft2(np.fft.rfft2(field) * _airy(rho / cutoff) * aperture, s=shape)
        out += QE[:, i, None, None] * blurred[None, margin:margin + height, margin:margin + width]
    electrons = rates @ QE.T
    norms = np.array([[np.linalg.norm(np.pad((labels == k) * electrons[k, c], pad, mode="symmetric"))
                       for k in range(rates.shape[0])] for c in range(3)])
    return out, norms


@pytest.mark.parametrize("f_number, tolerance, vignetting", [(4.0, OTF_TOLERANCE, False), (16.0, OTF_TOLERANCE, True),
                                                             (16.0, 1e-5, False)])
def test_per_spectrum_matches_the_per_wavelength_reference_within_the_bound(f_number, tolerance, vignetting):
    """A red | blue edge (with strong cos⁴ vignetting once): ‖camsim − reference‖₂ ≤ Σ_k bound_c ‖plane_kc‖₂
    (Parseval: every spectrum's OTF is within bound_c of its own at every frequency), while one PSF per channel
    misses by far more; a tighter tolerance takes more components."""
    optics = OpticsParams(f_number=f_number, pixel_pitch_um=4.0,
                          **({"vignetting": "cos4", "focal_length_mm": 0.1} if vignetting else {}))
    labels = _edge()
    rates = np.stack([RED, BLUE])
    electrons, planes = _planes(rates, labels)
    weights = _mean_weights(rates, labels)
    spectral = spectral_otf(labels, rates, QE, electrons, weights, WAVELENGTHS, optics, tolerance)
    assert all(0 < b <= tolerance for b in spectral.bounds) and all(r >= 1 for r in spectral.ranks)
    ref, norms = _reference(rates, labels, optics)
    ours = apply_optics(planes, optics, WAVELENGTHS, weights, spectral=spectral, workers=1).astype(np.float64)
    mean = apply_optics(planes, optics, WAVELENGTHS, weights, workers=1).astype(np.float64)
    float32 = 1e-6 * np.linalg.norm(ref.reshape(3, -1), axis=1)  # float32 FFTs and the radial table's interpolation
    for c in range(3):
        allowed = spectral.bounds[c] * norms[c].sum() + float32[c]
        assert np.linalg.norm(ours[c] - ref[c]) <= allowed
        # the mean PSF's colour-edge error is far larger than what the decomposition leaves
        assert np.abs(mean[c] - ref[c]).max() > 10 * np.abs(ours[c] - ref[c]).max()
    if tolerance < OTF_TOLERANCE:
        coarse = spectral_otf(labels, rates, QE, electrons, weights, WAVELENGTHS, optics)
        assert all(a > b for a, b in zip(spectral.ranks, coarse.ranks))


def test_a_grey_frame_is_the_mean_path_exactly():
    """Two spectra of one shape (a grey chart): every spectrum's weights are the mean's, no component is needed
    (r = 0) and the frame is bit-identical to the mean OTF's."""
    optics = OpticsParams(f_number=8.0, pixel_pitch_um=2.0, olpf=True, defocus_waves=0.5)
    labels = _edge()
    rates = np.stack([0.2 * RED, 0.9 * RED])
    electrons, planes = _planes(rates, labels)
    weights = _mean_weights(rates, labels)
    spectral = spectral_otf(labels, rates, QE, electrons, weights, WAVELENGTHS, optics)
    assert spectral.ranks == (0, 0, 0) and max(spectral.bounds) < 1e-12
    assert np.array_equal(apply_optics(planes, optics, WAVELENGTHS, weights, spectral=spectral, workers=1),
                          apply_optics(planes, optics, WAVELENGTHS, weights, workers=1))


def test_energy_is_conserved_per_spectrum():
    """A red square and a blue square on black, with defocus, the OLPF and a 50 % fill factor: every component's OTF
    is 0 at f = 0 on the 2-D grid (the padded sum is the mean OTF's: conserved), and the frame's sum is the
    mean OTF's (the two differ only by what the PSFs' tails carry across the frame's border)."""
    from scipy import fft

    from camsim.render.optics import _grids, radial_samples

    optics = OpticsParams(f_number=11.0, pixel_pitch_um=2.0, olpf=True, defocus_waves=1.0, fill_factor=0.5)
    labels = np.zeros((64, 64), dtype=np.intp)
    labels[20:35, 20:35] = 1
    labels[38:50, 30:48] = 2
    rates = np.stack([0 * RED, RED, BLUE])
    electrons, planes = _planes(rates, labels)
    weights = _mean_weights(rates, labels)
    spectral = spectral_otf(labels, rates, QE, electrons, weights, WAVELENGTHS, optics)
    assert all(r >= 1 for r in spectral.ranks)
    _, step = radial_samples()
    for c in range(3):
        assert np.all(np.abs(spectral.components[c][:, 0]) < 1e-12)
        for grid in _grids(optics, spectral.components[c], step, (64, 64)):
            assert abs(grid[0, 0]) < 1e-9 and grid.shape == (64, 33)
    assert fft.rfftfreq(64)[0] == 0
    out = apply_optics(planes, optics, WAVELENGTHS, weights, spectral=spectral, workers=1).astype(np.float64)
    assert out.min() > -1e-3 * out.max()
    # the padded grid's total: each channel's input sum (what OTF(0) = 1 conserves), through the plain mean path
    mean = apply_optics(planes, optics, WAVELENGTHS, weights, workers=1).astype(np.float64)
    assert np.allclose(out.sum(axis=(1, 2)), mean.sum(axis=(1, 2)), rtol=2e-3)


def test_an_images_factored_spectra_give_the_dense_amplitudes():
    """An image's colours on a basis (Mallett's factored spectra): the per-pixel amplitudes are linear in the
    coefficients, the same as from the dense spectra."""
    optics = OpticsParams(f_number=8.0, pixel_pitch_um=2.0)
    rng = np.random.default_rng(3)
    basis = np.stack([RED, BLUE, np.full_like(RED, 0.3)])
    coefficients = rng.uniform(0, 1, (40, 3))
    labels = rng.integers(0, 40, (16, 20))
    dense = coefficients @ basis
    electrons = dense @ QE.T
    weights = _mean_weights(dense, labels)
    a = spectral_otf(labels, dense, QE, electrons, weights, WAVELENGTHS, optics)
    b = spectral_otf(labels, FactoredSpectra(coefficients, basis), QE, electrons, weights, WAVELENGTHS, optics)
    assert a.ranks == b.ranks and all(r >= 1 for r in a.ranks)
    for c in range(3):
        assert np.allclose(a.amplitudes[c], b.amplitudes[c], rtol=1e-5, atol=1e-6 * electrons.max())
        assert np.isclose(a.bounds[c], b.bounds[c], rtol=1e-9)


def test_the_record_states_the_ranks_and_passes_the_sidecar_schema():
    from camsim.render.sidecar_schema import _optics

    optics = OpticsParams(f_number=16.0, pixel_pitch_um=4.0)
    labels = _edge()
    rates = np.stack([RED, BLUE])
    electrons, _ = _planes(rates, labels)
    weights = _mean_weights(rates, labels)
    spectral = spectral_otf(labels, rates, QE, electrons, weights, WAVELENGTHS, optics)
    record = optics_record(optics, WAVELENGTHS, weights, spectral)
    ranks = ", ".join(str(r) for r in spectral.ranks)
    assert f"this frame: r = ({ranks}) for R, G, B" in record["otf_model"]
    assert f"{OTF_TOLERANCE:g}" in record["otf_model"]
    assert _optics(record) is record


def test_an_images_hull_gives_the_exact_bound(monkeypatch):
    """Past the exact check's size, an image's factored colours are checked at the vertices of their convex hull
    (the bound is convex in the weights): the same ranks and bounds as checking every colour."""
    import camsim.optics.spectral as spectral_module

    optics = OpticsParams(f_number=16.0, pixel_pitch_um=2.0)
    rng = np.random.default_rng(5)
    basis = np.stack([RED, BLUE, np.full_like(RED, 0.3)])
    coefficients = rng.uniform(0, 1, (300, 3))
    labels = rng.integers(0, 300, (20, 30))
    dense = coefficients @ basis
    electrons = dense @ QE.T
    weights = _mean_weights(dense, labels)
    every = spectral_otf(labels, dense, QE, electrons, weights, WAVELENGTHS, optics)
    monkeypatch.setattr(spectral_module, "EXACT_BOUND_SAMPLES", 40 * 6000)  # 40 spectra: the hull's vertices only
    hull = spectral_otf(labels, FactoredSpectra(coefficients, basis), QE, electrons, weights, WAVELENGTHS, optics)
    loose = spectral_otf(labels, dense, QE, electrons, weights, WAVELENGTHS, optics)  # the triangle inequality's
    assert hull.ranks == every.ranks and np.allclose(hull.bounds, every.bounds, rtol=1e-9)
    assert all(a >= b for a, b in zip(loose.ranks, every.ranks)) and max(loose.ranks) > max(every.ranks)


def test_a_lit_scenes_plan_is_made_once_and_scaled_per_exposure():
    """optics_plan keeps the exposure-free part per lit scene: a frame at another F (or exposure) gets exactly the
    amplitudes spectral_otf computes from scratch; another lit scene (another light) its own plan."""
    import camsim.render.optics as optics_module
    from camsim.optics.params import parse_optics
    from camsim.render.optics import channel_weights, optics_plan
    from camsim.render.pipeline import light_scene
    from tests.support.helpers import small_scene

    optics = parse_optics({"f_number": 4.0, "pixel_pitch_um": 4.0, "diffraction": True, "olpf": True})
    scene = small_scene(width=120, height=80, illuminants=("D65", "A"), optics=optics)
    optics_module._PLANS.clear()
    for illuminant in ("D65", "A"):
        lit = light_scene(scene, illuminant)
        for factor in (1.0, 0.013, 7.5):
            signal_e = lit.expected(scene.sensor, factor, "pixel").signal_e
            weights, planned = optics_plan(lit, signal_e, optics)
            fresh = spectral_otf(lit.labels, lit.photon_rate, lit.qe, signal_e, channel_weights(lit),
                                 lit.grid.wavelengths_nm, optics)
            np.testing.assert_array_equal(weights, channel_weights(lit))
            assert planned.ranks == fresh.ranks and planned.bounds == fresh.bounds
            for a, b in zip(planned.amplitudes, fresh.amplitudes):
                np.testing.assert_array_equal(a, b)
    assert len(optics_module._PLANS) == 2
