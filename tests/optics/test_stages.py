"""Optics in front of the sensor (issue 30): energy per stage, cos⁴ at stated field angles, each OTF stage against
its closed form written here (the DFT of the PSF the code makes, on the grid), Hopkins's defocus against our own
numerical pupil autocorrelation, the noise after the optics against the exact per-pixel law (χ²), the scene table,
``--optics`` overrides and one-line errors, the sidecar's record and same seed ⇒ same files."""

import dataclasses
import functools
import hashlib
import json

import numpy as np
import pytest

from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.optics.params import F_NUMBER_RANGE, OpticsParams, optics_setting, parse_optics
from camsim.optics.stages import (
    channel_otf,
    convolve_plane,
    cos4_falloff,
    defocused_otf,
    field_angle_rad,
    lens_otf_radial,
    table_falloff,
)
from camsim.render.optics import apply_optics
from tests.support.helpers import chi2_p_counts, cupy_or_skip, small_scene

WAVELENGTHS = np.arange(400.0, 701.0, 10.0)


def _closed_diffraction(nu):
    """(2/π)(acos ν − ν√(1−ν²)), 0 beyond the cut-off (Goodman Eq. 6-32), written independently."""
    nu = np.asarray(nu, dtype=np.float64)
    out = np.zeros_like(nu)
    inside = nu < 1
    v = nu[inside]
    out[inside] = 2 / np.pi * (np.arccos(v) - v * np.sqrt(1 - v * v))
    return out


def _mono_weights(wavelength_nm):
    w = np.zeros((3, WAVELENGTHS.size))
    w[:, int(np.argmin(np.abs(WAVELENGTHS - wavelength_nm)))] = 1
    return w


def _otf_of(height, width, *, f_number=8.0, pitch=2.0, wavelength=550.0, w020=0.0, diffraction=True,
            olpf=None, fill=None):
    """The code's OTF of channel 0 on a (height, width) grid (periodic: no margin)."""
    from scipy import fft

    step = 1 / 8192
    rho = np.arange(int(np.sqrt(0.5) / step) + 2) * step
    radial = lens_otf_radial(rho, WAVELENGTHS, _mono_weights(wavelength), f_number=f_number, pixel_pitch_um=pitch,
                             diffraction=diffraction, w020_waves_550=w020)
    return channel_otf(radial[0], step, fft.fftfreq(height), fft.rfftfreq(width), olpf_shift_px=olpf,
                       fill_factor=fill)


def _psf(otf, height, width):
    """The PSF the convolution applies: a unit impulse at pixel (0, 0) convolved, periodic."""
    delta = np.zeros((height, width), np.float32)
    delta[0, 0] = 1
    return convolve_plane(delta, otf, 0, (height, width), workers=1)


# ---------------------------------------------------------------------------------------------------- energy


@pytest.mark.parametrize("stage", [dict(), dict(w020=1.5), dict(diffraction=False, olpf=1.0),
                                   dict(diffraction=False, fill=0.5), dict(olpf=1.3, fill=0.8, w020=0.7)])
def test_every_blur_stage_conserves_energy_periodic(stage):
    """The PSF stages redistribute light: on the periodic grid (the padding's convention) the sum of electrons is
    unchanged to float32 precision."""
    h, w = 64, 96
    image = np.random.default_rng(1).gamma(2.0, 300.0, (h, w)).astype(np.float32)
    out = convolve_plane(image, _otf_of(h, w, **stage), 0, (h, w), workers=1)
    assert out.sum(dtype=np.float64) == pytest.approx(image.sum(dtype=np.float64), rel=2e-6)
    assert not np.allclose(out, image)  # (it did blur)


def test_frame_energy_away_from_borders_and_a_uniform_field_stays_uniform():
    """apply_optics with the compact stages on (OLPF, pixel aperture, lateral CA): a blob far from the borders keeps
    its sum; a uniform frame stays uniform (the reflected margin: nothing wraps around). (The Airy pattern's tails
    carry light beyond any frame: 1 − EE(r) ≈ 2 λN / (π² r), so its energy is tested on the periodic grid above.)
    Lateral CA conserves the sum to the accuracy of bilinear resampling (it smooths by t(1 − t)/2 · f'' at phase t):
    float precision where the phase cycles (m = 1.1, 0.9), about 1e-3 on this blob at m = 1.01."""
    h, w = 96, 128
    y, x = np.mgrid[:h, :w]
    blob = 1000 * np.exp(-((x - 60.3) ** 2 + (y - 47.6) ** 2) / (2 * 6.0**2))
    planes = np.stack([blob] * 3).astype(np.float32)
    optics = OpticsParams(f_number=11, pixel_pitch_um=2.0, olpf=True, fill_factor=0.7, diffraction=False,
                          lateral_ca=(1.1, 1.0, 0.9))
    weights = np.full((3, WAVELENGTHS.size), 1 / WAVELENGTHS.size)
    out = apply_optics(planes, optics, WAVELENGTHS, weights, workers=1)
    for c in range(3):
        assert out[c].sum(dtype=np.float64) == pytest.approx(planes[c].sum(dtype=np.float64), rel=3e-5)
    flat = np.full((3, 40, 50), 123.0, np.float32)
    assert np.allclose(apply_optics(flat, OpticsParams(f_number=11, olpf=True, defocus_waves=1.0), WAVELENGTHS,
                                    weights, workers=1), 123.0, rtol=1e-5)


def test_lateral_ca_magnifies_about_the_centre():
    """A point's image moves from c + d to c + m·d (our own centroid), its sum kept."""
    h, w = 81, 101
    y, x = np.mgrid[:h, :w]
    blob = np.exp(-((x - 80.0) ** 2 + (y - 20.0) ** 2) / (2 * 2.5**2)).astype(np.float32)
    planes = np.stack([blob] * 3)
    optics = OpticsParams(diffraction=False, fill_factor=1.0, lateral_ca=(1.05, 1.0, 0.95))
    out = apply_optics(planes, optics, WAVELENGTHS, np.full((3, WAVELENGTHS.size), 1 / WAVELENGTHS.size), workers=1)
    cx, cy = (w - 1) / 2, (h - 1) / 2
    for c, m in enumerate((1.05, 1.0, 0.95)):
        total = out[c].sum(dtype=np.float64)
        assert total == pytest.approx(blob.sum(dtype=np.float64), rel=5e-3)  # bilinear's smoothing, σ = 2.5 px
        mx, my = (out[c] * x).sum() / total, (out[c] * y).sum() / total
        assert mx == pytest.approx(cx + m * (80 - cx), abs=0.01) and my == pytest.approx(cy + m * (20 - cy), abs=0.01)


# ---------------------------------------------------------------------------------------------------- vignetting


@pytest.mark.parametrize("angle_deg", [0.0, 5.0, 10.0, 20.0, 30.0, 45.0])
def test_cos4_at_stated_field_angles(angle_deg):
    """A pixel r px from the centre with pitch p and focal length f sees θ = atan(r p / f): cos⁴θ to 1e-6, 1 at the
    centre; a frame's flat field through apply_optics (vignetting alone) follows it."""
    r, f_mm = 40, 10.0
    pitch = np.tan(np.radians(angle_deg)) * f_mm * 1e3 / r  # so that pixel r px right of the centre is at θ
    pitch = max(pitch, 1e-3)
    theta = field_angle_rad(81, 81, pitch, f_mm)
    expected = np.cos(np.radians(angle_deg)) ** 4 if angle_deg else 1.0
    assert cos4_falloff(theta)[40, 40 + r] == pytest.approx(expected, abs=1e-6)
    assert cos4_falloff(theta)[40, 40] == 1.0
    flat = np.ones((3, 81, 81), np.float32)
    optics = OpticsParams(diffraction=False, fill_factor=1.0, vignetting="cos4", focal_length_mm=f_mm,
                          pixel_pitch_um=pitch)
    out = apply_optics(flat, optics, WAVELENGTHS, np.full((3, WAVELENGTHS.size), 1 / WAVELENGTHS.size), workers=1)
    # a 100 % fill factor adds no blur (the source's own full-pixel sampling is the aperture): float32 rounding only
    assert out[0, 40, 40 + r] == pytest.approx(expected, abs=1e-6)


def test_relative_illumination_table():
    table = ((0.0, 2.0), (10.0, 1.8), (30.0, 1.0))
    assert table_falloff(np.radians([0.0, 5.0, 10.0, 20.0, 40.0]), table) == pytest.approx(
        [1.0, 0.95, 0.9, 0.7, 0.5], abs=1e-12)


# ---------------------------------------------------------------------------------------------------- OTFs


def test_diffraction_psf_dft_is_the_airy_otf():
    """f/8, 2 µm pitch, 550 nm: f_c = 2 / (0.55 · 8) = 0.4545 cy/px, inside the grid. The DFT of the PSF the
    convolution applies equals (2/π)(acos ν − ν√(1−ν²)), ν = ρ / f_c, zero beyond the cut-off."""
    h, w = 64, 80
    psf = _psf(_otf_of(h, w, f_number=8, pitch=2.0, wavelength=550.0, fill=None), h, w)
    measured = np.fft.rfft2(psf.astype(np.float64))
    fy, fx = np.fft.fftfreq(h)[:, None], np.fft.rfftfreq(w)[None, :]
    closed = _closed_diffraction(np.hypot(fy, fx) / (2 / (0.55 * 8)))
    assert np.abs(measured - closed).max() < 2e-6
    assert psf.sum() == pytest.approx(1, abs=1e-6) and psf[0, 0] == psf.max()


def test_olpf_psf_is_four_spots():
    """s = 2 px puts the four spots on pixels (±1, ±1): a quarter each, nothing elsewhere (our own PSF)."""
    h, w = 32, 40
    psf = _psf(_otf_of(h, w, diffraction=False, olpf=2.0), h, w)
    expected = np.zeros((h, w))
    for dy in (-1, 1):
        for dx in (-1, 1):
            expected[dy % h, dx % w] = 0.25
    assert np.abs(psf - expected).max() < 1e-6


def test_pixel_aperture_psf_dft_is_the_box_ratio():
    """The aperture relative to the source's full-pixel sampling: the DFT of the stage's PSF is
    [sin(0.6 π f) / (0.6 π f)] / [sin(π f) / (π f)] per axis (side 0.6 px), written out here; 1 at f = 0, rising to
    sinc(0.3) / sinc(0.5) = 1.36 at Nyquist; at ff = 1 the stage is the identity."""
    h, w = 48, 64
    ff = 0.36  # side 0.6 px
    psf = _psf(_otf_of(h, w, diffraction=False, fill=ff), h, w)
    measured = np.fft.rfft2(psf.astype(np.float64))
    fy, fx = np.fft.fftfreq(h)[:, None], np.fft.rfftfreq(w)[None, :]

    def ratio(f):
        f = np.where(f == 0, 1e-300, f)
        return (np.sin(0.6 * np.pi * f) / (0.6 * np.pi * f)) / (np.sin(np.pi * f) / (np.pi * f))

    closed = ratio(fy) * ratio(fx)
    assert np.abs(measured - closed).max() < 4e-6
    assert closed[0, -1] == pytest.approx(np.sin(0.3 * np.pi) / 0.3 / 2, abs=1e-12)  # Nyquist along x: 1.348
    identity = _psf(_otf_of(h, w, diffraction=False, fill=1.0), h, w)
    assert identity[0, 0] == pytest.approx(1, abs=1e-6) and np.abs(identity).sum() == pytest.approx(1, abs=1e-5)


def _aperture_kernel(side, taps=40):
    """h[k] = ∫_{−½}^{½} [sinc(side f) / sinc(f)] cos(2π f k) df by quadrature (scipy.integrate.quad): one axis of
    the aperture stage's PSF on the pixel grid, an infinite grid's (its taps fall as 1/k²)."""
    from scipy.integrate import quad

    def gain(f):
        return 1.0 if f == 0 else (np.sin(np.pi * side * f) / (side * np.sin(np.pi * f)))

    return np.array([quad(lambda f: gain(f) * np.cos(2 * np.pi * f * k), -0.5, 0.5, limit=200)[0]
                     for k in range(taps)])


def test_a_single_bright_pixel_rings_below_zero_and_the_clip_is_recorded():
    """No lens, ff = 0.25 (side ½ px), one bright pixel of E e⁻ in a black field: the stage's PSF is h[i]·h[j] (our
    own quadrature of the gain), whose negative lobes (one tap of each sign) carry 2·P·N of the unit sum (P, N the
    sums of h's positive and negative taps): the expectation is clipped at 0, and the electrons the clip added,
    E·2PN, are what apply_optics records, as the fraction 2PN of the channel's sum."""
    h1 = _aperture_kernel(0.5)
    full = np.concatenate([h1[:0:-1], h1])  # taps −39 … 39
    assert full.sum() == pytest.approx(1, abs=2e-3) and h1[1] < 0  # the gain is 1 at f = 0; a negative first tap
    positive, negative = full[full > 0].sum(), -full[full < 0].sum()
    expected_fraction = 2 * positive * negative
    size, energy = 161, 1.0e4
    planes = np.zeros((3, size, size), np.float32)
    planes[:, size // 2, size // 2] = energy
    weights = np.full((3, WAVELENGTHS.size), 1 / WAVELENGTHS.size)
    clip = {}
    out = apply_optics(planes, OpticsParams(diffraction=False, fill_factor=0.25), WAVELENGTHS, weights, workers=1,
                       clip=clip)
    assert out.min() == 0.0
    c = size // 2
    assert out[0, c, c] == pytest.approx(energy * h1[0] ** 2, rel=1e-3)  # the peak: the gain raised it
    assert out[0, c, c + 2] == pytest.approx(energy * h1[0] * h1[2], rel=2e-3)  # a positive tap, kept
    assert out[0, c, c + 1] == 0.0  # h[0] h[1] < 0: clipped
    for k in range(3):
        assert clip["negative_clipped_fraction"][k] == pytest.approx(expected_fraction, rel=2e-2)
        assert clip["negative_clipped_e"][k] == pytest.approx(energy * expected_fraction, rel=2e-2)
        # the sum after the clip: the impulse's plus what the clip added
        assert out[k].sum(dtype=np.float64) == pytest.approx(energy + clip["negative_clipped_e"][k], rel=1e-4)
    # ff = 1: no stage, nothing clipped beyond float rounding
    clip = {}
    same = apply_optics(planes, OpticsParams(diffraction=False, fill_factor=1.0), WAVELENGTHS, weights, workers=1,
                        clip=clip)
    assert np.allclose(same, planes, atol=1e-2) and max(clip["negative_clipped_e"]) < 1e-5 * energy


def _pupil_autocorrelation(nu, w020, n=801):
    """OTF(ν) of the unit pupil with phase 2π W020 r², by direct summation of the overlap of the pupils shifted
    by ±ν along x (our own grid quadrature, independent of the code's 1-D integral)."""
    x = np.linspace(-1, 1, n)
    X, Y = np.meshgrid(x, x)
    inside = lambda a, b: (a * a + b * b) <= 1  # noqa: E731
    plus, minus = X + nu, X - nu
    overlap = inside(plus, Y) & inside(minus, Y)
    phase = 2 * np.pi * w020 * ((plus**2 + Y**2) - (minus**2 + Y**2))
    area = inside(X, Y).sum()
    return float(np.sum(np.where(overlap, np.cos(phase), 0.0)) / area)


@pytest.mark.parametrize("w020", [0.0, 0.25, 1.0, 2.0])
def test_defocus_otf_against_a_numerical_pupil_autocorrelation(w020):
    nus = np.array([0.05, 0.2, 0.4, 0.6, 0.8, 0.95])
    code = defocused_otf(nus, w020)
    ours = np.array([_pupil_autocorrelation(v, w020) for v in nus])
    assert np.abs(code - ours).max() < 6e-3  # the 801² grid's error
    if w020 == 0:
        assert code == pytest.approx(_closed_diffraction(nus), abs=1e-12)
    assert defocused_otf(np.array([0.0]), w020)[0] == pytest.approx(1.0, abs=1e-12)


def test_defocus_um_is_w020_over_8_n_squared():
    assert OpticsParams(f_number=4, defocus_um=12.0).w020_waves_550 == pytest.approx(12 / 128 / 0.55)
    with pytest.raises(CamsimError, match="at most one"):
        OpticsParams(defocus_um=1.0, defocus_waves=0.5)
    with pytest.raises(CamsimError, match="needs diffraction = true"):
        OpticsParams(defocus_waves=0.5, diffraction=False)


# ---------------------------------------------------------------------------------------------------- noise


@functools.cache
def _dn_law(lam, dn_per_electron, read_noise_e, full_well_e, bits, pedestal_dn):
    """:func:`camsim.sensor.dn_law.dn_pmf`, each law computed once: it is most of the noise test's time, and the
    frames of its devices and colour filter arrays share most of their pixels' charges."""
    from camsim.sensor.dn_law import dn_pmf

    return dn_pmf(lam, dn_per_electron, read_noise_e, full_well_e, bits, pedestal_dn)


def _summed_law(lams, sensor):
    """The expected histogram of digital numbers of pixels with charges ``lams`` (each its own law,
    :func:`camsim.sensor.dn_law.dn_pmf`; pixels grouped by λ to 0.1 e⁻, which moves a mean by ≤ 0.05 k DN, a
    fifth of the test's standard error): (first level, counts)."""
    keys, counts = np.unique(np.round(np.asarray(lams, dtype=np.float64), 1), return_counts=True)
    laws = [_dn_law(float(lam), sensor.dn_per_electron, sensor.read_noise_e, sensor.full_well_e, sensor.bits,
                    sensor.pedestal_dn) for lam in keys]
    first = min(law.first for law in laws)
    total = np.zeros(max(law.first + law.pmf.size for law in laws) - first)
    for law, n in zip(laws, counts):
        total[law.first - first:law.first - first + law.pmf.size] += n * law.pmf
    return first, total


@pytest.fixture(params=["cpu", "numpy", "cuda"])
def device(request):
    """Where an optics frame is drawn: the block renderer (cpu), the array path on numpy (the GPU's code on the
    CPU), or on CuPy where it sees a GPU (else skipped)."""
    if request.param == "cuda":
        cupy_or_skip()
    return request.param


@pytest.mark.parametrize("cfa", [None, "RGGB"])
def test_noise_after_optics_follows_the_exact_per_pixel_law(cfa, device):
    """slanted_edge_lens (f/4, diffraction, OLPF) on flat regions far from the edge: each pixel's charge mean is its
    clean value / k (no PRNU, DSNU: λ = S̄ + D̄ after the optics — within 2 % of the flat side's own, the rest the
    Airy pattern's edge-spread tail λN (R − 1) / (π² x) from the other side: 0.8 % at 50 px), and the digital numbers
    follow the sum of the per-pixel laws (camsim.sensor.dn_law.dn_pmf): χ², and the mean; on every device."""
    from camsim.render.pipeline import scene_frame
    from camsim.scene.scene_file import load_scene
    from camsim.sensor.cfa import cfa_sites

    scene = load_scene("slanted_edge_lens").replace(width=240, height=160).with_sensor(
        prnu_percent=0.0, dsnu_e=0.0, cfa=cfa)
    frame, info = scene_frame(scene, "D65", 1.0, workers=1, device=device)
    sensor = frame.sensor
    k = sensor.dn_per_electron
    assert info.optics is not None and info.method == "poisson"
    rows = slice(10, 150)
    for side, cols, label in (("dark", slice(4, 70), 0), ("bright", slice(172, 236), -1)):
        for c in range(3):
            own = float(frame.expected.signal_e[label, c] + frame.expected.dark_e[c])
            lams = frame.clean_dn()[c, rows, cols] / k
            mask = np.ones(lams.shape, bool)
            if cfa:
                mask[:] = False
                for dy, dx, ch in cfa_sites(cfa):
                    if ch == c:
                        mask[(rows.start + dy) % 2::2, (cols.start + dx) % 2::2] = True
            assert np.all(np.abs(lams[mask] / own - 1) < 0.02), (side, c)
            values = frame.digital_dn[0 if cfa else c, rows, cols][mask].astype(np.int64)
            first, expected = _summed_law(lams[mask], sensor)
            assert values.min() >= first and values.max() < first + expected.size
            observed = np.bincount(values - first, minlength=expected.size).astype(float)
            assert chi2_p_counts(observed, expected) > 1e-4, (side, c)
            levels = first + np.arange(expected.size)
            mean = expected @ levels / expected.sum()
            sd = np.sqrt(expected @ (levels - mean) ** 2 / expected.sum() / values.size)
            assert abs(values.mean() - mean) < 5 * sd, (side, c)


def test_the_edge_is_blurred_as_the_otf_says():
    """The clean layer across the edge: the optics spread it (10–90 % width grows); the flat levels 50 px from the
    edge move by the Airy pattern's tails only (at f/16, λN ≈ 2.2 px: a few % of the other side's light)."""
    from camsim.render.pipeline import scene_frame
    from camsim.scene.scene_file import load_scene

    sharp = load_scene("slanted_edge").replace(width=120, height=80, intensity_factors=(1.0,))
    lens = load_scene("slanted_edge_lens").replace(width=120, height=80)
    lens = lens.replace(optics=parse_optics({"f_number": 16, "olpf": True}))
    a = scene_frame(sharp, "D65", 1.0, workers=1)[0].clean_dn()[1, 40]
    b = scene_frame(lens, "D65", 1.0, workers=1)[0].clean_dn()[1, 40]

    def width(row):
        lo, hi = row[:20].mean(), row[-20:].mean()
        t = (row - lo) / (hi - lo)
        return np.sum((t > 0.1) & (t < 0.9))

    assert width(b) > width(a) + 1
    assert b[:20].mean() == pytest.approx(a[:20].mean(), rel=0.05) and b[-20:].mean() == pytest.approx(
        a[-20:].mean(), rel=0.05)
    assert b[:20].mean() > a[:20].mean() and b[-20:].mean() < a[-20:].mean()  # light spread from bright to dark


# ---------------------------------------------------------------------------------------------------- table, CLI


@pytest.mark.parametrize("table, message", [
    ({"f_number": 0}, "f_number must be ≥ 0.5 and ≤ 10000"),
    ({"f_number": "f/4"}, "f_number must be a number"),
    ({"fill_factor": 1.5}, r"fill_factor must be in \(0, 1\]"),
    ({"vignetting": "lens"}, "vignetting must be one of none, cos4, table"),
    ({"vignetting": "table"}, "needs relative_illumination"),
    ({"vignetting": "table", "relative_illumination": [[5, 1], [10, 0.9]]}, "from 0"),
    ({"vignetting": "table", "relative_illumination": [[0, 1], [10, -1]]}, "positive"),
    ({"relative_illumination": [[0, 1], [10, 0.9]]}, "applies with vignetting"),
    ({"lateral_ca": [1, 1]}, "lateral_ca must be"),
    ({"lateral_ca": [1, 1, 3]}, "within"),
    ({"aperture": 2}, "unknown key"),
])
def test_bad_tables(table, message):
    with pytest.raises(CamsimError, match=message):
        parse_optics(table)


def test_optics_setting_types_by_the_schema():
    assert optics_setting("f_number=8") == ("f_number", 8.0)
    assert optics_setting("olpf=true") == ("olpf", True)
    assert optics_setting("lateral_ca=[1.001, 1, 0.999]") == ("lateral_ca", [1.001, 1.0, 0.999])
    assert optics_setting("relative_illumination=[[0, 1], [20, 0.8]]")[1] == ((0.0, 1.0), (20.0, 0.8))
    with pytest.raises(CamsimError, match="NAME one of"):
        optics_setting("focal=3")


def _digests(folder):
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())
            if p.suffix in (".dng", ".exr", ".json")}


def test_cli_overrides_sidecar_and_same_seed_same_files(tmp_path, capsys):
    from camsim.render.sidecar_schema import check_sidecar

    args = ["render", "slanted_edge_lens", "--size", "64x48", "-q", "--optics", "f_number=8",
            "--optics", "vignetting=cos4", "--optics", "lateral_ca=[1.002, 1, 0.998]", "--sensor", "cfa=RGGB"]
    assert main(args + ["--out", str(tmp_path / "a")]) == 0
    assert main(args + ["--out", str(tmp_path / "b")]) == 0
    a, b = _digests(tmp_path / "a"), _digests(tmp_path / "b")
    assert a == b and len(a) == 4  # DNG, EXR, JSON, manifest
    meta = json.loads((tmp_path / "a" / "slanted_edge_lens_D65_F1.json").read_text())
    check_sidecar(meta, "sidecar")
    optics = meta["optics"]
    assert optics["f_number"] == 8.0 and optics["vignetting"] == "cos4" and optics["olpf"] is True
    assert optics["lateral_ca"] == [1.002, 1.0, 0.998] and optics["diffraction"] is True
    weights = np.array(optics["channel_wavelength_weights"]["weights"])
    assert weights.shape == (3, len(meta["wavelengths_nm"])) and np.allclose(weights.sum(axis=1), 1)
    assert "Hopkins" in optics["otf_model"] and "sinc(sqrt(ff) fx) / sinc(fx)" in optics["otf_model"]
    assert len(optics["negative_clipped_e"]) == 3 and all(0 <= v < 1e-3 for v in optics["negative_clipped_fraction"])
    # each channel's weights peak where its Qe × D65 does: R at longer wavelengths than B
    wl = np.array(optics["channel_wavelength_weights"]["wavelength_nm"])
    assert (weights[0] @ wl) > (weights[1] @ wl) > (weights[2] @ wl)
    # a scene without [optics] gets one from --optics; without it, no optics record (today's files unchanged)
    assert main(["render", "slanted_edge", "--size", "64x48", "-F", "1", "-q", "--optics", "olpf=true",
                 "--out", str(tmp_path / "c")]) == 0
    assert json.loads((tmp_path / "c" / "slanted_edge_D65_F1.json").read_text())["optics"]["olpf"] is True
    assert main(["render", "slanted_edge", "--size", "64x48", "-F", "1", "-q", "--out", str(tmp_path / "d")]) == 0
    assert "optics" not in json.loads((tmp_path / "d" / "slanted_edge_D65_F1.json").read_text())
    bad = dict(meta, optics=dict(optics, f_number=-1))
    with pytest.raises(CamsimError, match="optics"):
        check_sidecar(bad, "sidecar")
    with pytest.raises(CamsimError, match="negative_clipped_e"):
        check_sidecar(dict(meta, optics=dict(optics, negative_clipped_e=[-1.0, 0.0, 0.0])), "sidecar")


@pytest.mark.parametrize("option, message", [
    ("f_number=-2", "f_number must be ≥ 0.5 and ≤ 10000"),
    ("fill_factor=2", "fill_factor must be in"),
    ("wobble=1", "NAME one of"),
    ("vignetting=table", "needs relative_illumination"),
    ("relative_illumination=[[0, 1], [5]]", "relative_illumination"),
])
def test_cli_bad_values_are_one_line_exit_2(tmp_path, capsys, option, message):
    out = tmp_path / "o"
    assert main(["render", "slanted_edge_lens", "--size", "64x48", "-q", "--optics", option,
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("camsim: error: ") and err.count("\n") == 1 and message in err, err
    assert not out.exists()


def test_scene_file_optics_and_refusals(tmp_path, capsys):
    path = tmp_path / "s.toml"
    from camsim.scene.builtin_scenes import builtin_scene_path

    text = builtin_scene_path("slanted_edge_lens").read_text()
    path.write_text(text.replace('statistics = "pixel"', 'statistics = "paper"'))
    assert main(["render", str(path), "--size", "64x48", "-q", "--out", str(tmp_path / "p")]) == 2
    assert "statistics = 'pixel'" in capsys.readouterr().err and not (tmp_path / "p").exists()
    path.write_text(text.replace("olpf = true", "olpf = 1"))
    assert main(["render", str(path), "-q", "--out", str(tmp_path / "q")]) == 2
    assert "olpf must be true or false" in capsys.readouterr().err
    path.write_text(text.replace("fill_factor = 1.0", "fill_factor = 1.0\nzoom = 2"))
    assert main(["render", str(path), "-q", "--out", str(tmp_path / "r")]) == 2
    assert "unknown key(s): zoom" in capsys.readouterr().err


def test_colour_edge_approximation_is_measured():
    """tools/optics_colour_edge.py: camsim's per-spectrum OTFs against the per-wavelength reference. A grey edge (one
    spectral shape) has no approximation error; at a red | blue edge one PSF per channel (the frame's mean light) is
    off by of order 1 % at f/8, the per-spectrum OTFs by less than their 1e-3 bound."""
    import importlib.util

    from tests.support.helpers import ROOT

    spec = importlib.util.spec_from_file_location("optics_colour_edge", ROOT / "tools" / "optics_colour_edge.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    grey = tool.colour_edge_difference(8.0, left="grey0.2", right="grey0.8", size=(24, 48))
    assert np.all(grey["max_rel_pixel"] < 2e-5)
    colour = tool.colour_edge_difference(8.0, left="red", right="blue", size=(24, 48))
    assert np.all(colour["mean_max_rel_pixel"] > 1e-3) and np.all(colour["mean_max_rel_pixel"] < 0.05)
    assert all(abs(x - 24) <= 6 for x in colour["mean_where_px"])  # at the edge
    assert np.all(colour["max_rel_pixel"] < 1e-3) and all(r >= 1 for r in colour["ranks"])


def test_a_sequence_sees_the_scene_through_the_optics():
    """With [sequence] and [optics], the optics blur the static scene before the motion: the reference's clean layer
    is the optics frame's expectation (camsim render without the sequence), and every sidecar records the optics."""
    from camsim.render.pipeline import light_scene, scene_frame
    from camsim.render.sequence import render_sequence_frames
    from camsim.scene.scene_file import load_scene
    from camsim.scene.sequence import SequenceParams

    scene = load_scene("slanted_edge_lens").replace(width=64, height=48).with_sensor(exposure_s=0.01)
    scene = scene.replace(optics=parse_optics({"f_number": 11, "olpf": True}))
    lit = light_scene(scene, "D65")
    still, _ = scene_frame(scene, "D65", 1.0, lit=lit, workers=1)
    seq = scene.replace(sequence=SequenceParams(frames=1, frame_interval_s=0.02, pan_px_per_s=(10.0, 0.0)))
    (_, ref, ref_extra), (_, _, extra) = render_sequence_frames(seq, lit, seq.sensor, 1.0, workers=1)
    assert np.array_equal(ref.clean_dn(), still.clean_dn())
    assert ref_extra["optics"]["f_number"] == 11.0 and extra["optics"]["olpf"] is True


@pytest.mark.parametrize("table, message", [
    ({"defocus_waves": 1e9}, "beyond"),
    ({"defocus_um": -1e9}, "beyond"),
    ({"olpf_shift_px": 1e9}, "at most 64"),
    ({"f_number": float("inf")}, "finite"),
])
def test_hostile_values_are_one_line(table, message):
    with pytest.raises(CamsimError, match=message):
        parse_optics(table)


def test_extreme_lenses_stay_bounded():
    """A huge f-number blurs a frame to its mean (OTF 0 but at f = 0), a tiny one leaves it as it is; a large defocus
    keeps the margin within the frame's size; a 1-pixel-wide frame is blurred along its length only."""
    rng = np.random.default_rng(5)
    planes = rng.random((3, 20, 30)).astype(np.float32)
    weights = np.full((3, WAVELENGTHS.size), 1 / WAVELENGTHS.size)
    wide = apply_optics(planes, OpticsParams(f_number=F_NUMBER_RANGE[1]), WAVELENGTHS, weights, workers=1)
    assert np.allclose(wide, wide.mean(axis=(1, 2), keepdims=True), atol=1e-4)
    sharp_lens = OpticsParams(fill_factor=1.0)
    object.__setattr__(sharp_lens, "f_number", 1e-6)  # below the schema's 0.5: the stage's own bound holds
    sharp = apply_optics(planes, sharp_lens, WAVELENGTHS, weights, workers=1)
    assert np.allclose(sharp, planes, atol=1e-5)
    defocused = apply_optics(planes, OpticsParams(defocus_waves=20), WAVELENGTHS, weights, workers=1)
    assert np.all(np.isfinite(defocused))
    line = apply_optics(planes[:, :, :1], OpticsParams(f_number=16), WAVELENGTHS, weights, workers=1)
    assert line.shape == (3, 20, 1) and np.all(np.isfinite(line))


@pytest.mark.parametrize("cfa", [None, "RGGB"])
def test_the_optics_on_a_device_give_the_cpus_expectation(cfa, device):
    """Every stage (lateral CA, cos⁴ vignetting, diffraction with defocus per spectrum, the OLPF, a fill factor < 1,
    the clip) on the array path's device against the CPU's: the numpy path is the CPU's code (the
    same bits), CuPy's cuFFT rounds its float32 otherwise (≤ 2e-6 of the frame's largest value). The frame's sidecar
    says where it was drawn; its clean layer is the expectation's."""
    from camsim.core.xp import to_host
    from camsim.optics.params import parse_optics
    from camsim.render.backends import array_module
    from camsim.render.optics import optics_signal
    from camsim.render.pipeline import light_scene, scene_frame

    optics = parse_optics({"f_number": 2.8, "pixel_pitch_um": 3.0, "focal_length_mm": 8.0, "diffraction": True,
                           "defocus_waves": 0.25, "olpf": True, "fill_factor": 0.5, "vignetting": "cos4",
                           "lateral_ca": [1.002, 1.0, 0.997]})
    scene = small_scene(width=200, height=132, optics=optics).with_sensor(cfa=cfa)
    lit = light_scene(scene, "D65")
    signal_e = lit.expected(scene.sensor, 1.0, "pixel").signal_e
    reference, record = optics_signal(lit, signal_e, optics, workers=1)
    assert "r = (0, 0, 0)" not in record["otf_model"]  # the per-spectrum components are applied
    if device == "cpu":
        return
    xp = array_module(device)
    signal, device_record = optics_signal(lit, signal_e, optics, labels=xp.asarray(lit.labels), workers=1)
    again, _ = optics_signal(lit, signal_e, optics, labels=xp.asarray(lit.labels), workers=1)  # (kept OTF grids)
    signal = to_host(signal)
    np.testing.assert_array_equal(to_host(again), signal)
    if device == "numpy":
        np.testing.assert_array_equal(signal, reference)
        assert device_record == record
    else:
        assert np.max(np.abs(signal - reference)) <= 2e-6 * reference.max()
        assert device_record["otf_model"] == record["otf_model"]
    frame, info = scene_frame(scene, "D65", 1.0, workers=1, device=device)
    assert info.device["device"] == device and info.optics["otf_model"] == record["otf_model"]
    k = frame.sensor.dn_per_electron
    dark = frame.expected.dark_e.reshape(3, 1, 1)
    np.testing.assert_allclose(frame.clean_dn(), (reference + dark) * k, rtol=1e-5, atol=1e-3 * k)


@pytest.mark.parametrize("size,before,after", [(7, 3, 5), (4, 9, 2), (1, 2, 3), (5, 0, 11), (3000, 33, 39)])
def test_symmetric_indices_are_numpys_symmetric_pad(size, before, after):
    """The GPU's padding (two gathers by symmetric_indices) is numpy's pad(mode='symmetric'), margins wider than the
    axis included."""
    from camsim.optics.stages import symmetric_indices

    axis = np.arange(size) * 1.5 + 2
    expected = np.pad(axis, (before, after), mode="symmetric")
    np.testing.assert_array_equal(axis[symmetric_indices(size, before, size + before + after)], expected)


def test_a_devices_otf_grids_are_kept_per_frame_and_remade_for_another():
    """_grids on a device (here numpy behind another module object, as CuPy is told from numpy by identity) keeps the
    last GRIDS_KEPT channels' grids: the same tables give the kept grids (equal to numpy's own), other tables or
    another OLPF new ones, and the oldest is dropped."""
    import types

    import camsim.render.optics as optics_module

    device = types.ModuleType("device")
    device.__getattr__ = lambda name: getattr(np, name)
    optics = parse_optics({"f_number": 4.0, "pixel_pitch_um": 4.0, "diffraction": True, "olpf": True})
    rho, step = optics_module.radial_samples()
    tables = [np.vstack([np.exp(-rho * (1 + c)), np.exp(-rho * (2 + c)) * rho]) for c in range(4)]
    optics_module._DEVICE_GRIDS.clear()
    first = optics_module._grids(optics, tables[0], step, (24, 32), device)
    again = optics_module._grids(optics, tables[0], step, (24, 32), device)
    assert all(a is b for a, b in zip(first, again))
    for grid, own in zip(first, optics_module._grids(optics, tables[0], step, (24, 32), np)):
        np.testing.assert_array_equal(grid, own)
    other = optics_module._grids(dataclasses.replace(optics, olpf=False), tables[0], step, (24, 32), device)
    assert not any(a is b for a, b in zip(first, other))
    for table in tables[1:]:
        optics_module._grids(optics, table, step, (24, 32), device)
    assert len(optics_module._DEVICE_GRIDS) == optics_module.GRIDS_KEPT
    assert not any(a is b for a, b in zip(first, optics_module._grids(optics, tables[0], step, (24, 32), device)))
