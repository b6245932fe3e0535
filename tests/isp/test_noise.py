"""Noise through the ISP (issue 26, point 4) against closed forms written here, independently of camsim.isp.

The thing under test is :mod:`camsim.isp` (its stages, through :func:`camsim.isp.develop_stages`, and
:func:`camsim.isp.noise.noise_through_isp`). The expectations are computed in this module from

- the sensor model's closed form of a pixel's temporal noise: Poisson charge (signal S and dark D electrons, one
  Poisson variable of mean S + D) plus Gaussian read noise σ_r, times the gain k: σ² = k² (S + D + σ_r²) DN²
  (no PRNU and no DSNU in these frames: every pixel has the same variance; ``noisy_dn`` is the signal before the
  ADC, so there is no quantisation step);
- the white-balance gains and the colour matrix that the development *records* (``Developed.record``), and the
  white and black levels of the sensor;
- the sRGB transfer function and its first three derivatives, written out here (IEC 61966-2-1);
- the bilinear demosaicing kernels and Malvar, He & Cutler's (ICASSP 2004) 5 × 5 kernels, written out here from
  the paper's coefficients; a linear demosaicing's output noise has variance Σ_k w_k² τ²_k and covariance between
  neighbours Σ_q w_p(q) w_p'(q) τ²_q (the overlap of the two pixels' kernels), with τ² the variance of each mosaic
  site after white balance. The oracle's kernels are checked on their own first: colour-demosaicing's bilinear and
  Malvar 2004 on a mosaic of Gaussian white noise give the variances, correlations and NPS it predicts.

The tolerances are sampling errors, not fudge factors. A sample variance s² of n Gaussian values of variance σ²
has standard error σ² √(2 / (n − 1)) (the χ² law; with correlated values, as after demosaicing, n is replaced by
n / Σ_lag ρ_lag², the sum of the squared correlations between a pixel and the pixels of its lattice — computed from
the kernels too — which is the exact large-n variance of a Gaussian field's sample variance); a sample covariance
of independent pairs has variance (σ_i² σ_j² + c_ij²) / (n − 1); a sample correlation has standard error about
(1 − ρ²) / √n_eff (Fisher's large-n form, with the same n_eff); a radial NPS bin averages periodogram ordinates,
each exponential (standard deviation = mean), of which a quarter of the bin's frequencies are independent (the
conjugate symmetry of a real field's DFT, and the coherence of frequencies ½ apart in a field of period 2). Each
check allows 5 standard errors (a two-sided false alarm about once in 1.7 million checks; the frames' seeds are
fixed, so a run is repeatable). The Poisson charge's excess kurtosis 1 / (S + D) ≤ 0.001 at the light levels below
adds less than 0.05 % to the variance of a variance and is left out.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from camsim import isp
from camsim.isp.noise import noise_through_isp, write_noise_report
from camsim.render.pipeline import scene_frame
from camsim.scene.scene_file import load_scene

K_SE = 5.0  # standard errors allowed in every sampling check
PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")


# --- the oracle: closed forms written here -------------------------------------------------------------------


def srgb(x):
    """The sRGB transfer function (IEC 61966-2-1), linear → encoded."""
    x = np.asarray(x, dtype=np.float64)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.abs(x) ** (1 / 2.4) - 0.055)


def srgb_derivatives(x: float) -> tuple[float, float, float]:
    """f′, f″, f‴ of the sRGB transfer function at x > 0.0031308 (the power segment): f = 1.055 x^(1/2.4) − 0.055."""
    a = 1 / 2.4
    d1 = 1.055 * a * x ** (a - 1)
    d2 = 1.055 * a * (a - 1) * x ** (a - 2)
    d3 = 1.055 * a * (a - 1) * (a - 2) * x ** (a - 3)
    return d1, d2, d3


def colour_at(pattern: str, y: int, x: int) -> int:
    """The channel (0 R, 1 G, 2 B) of the mosaic site at row y, column x."""
    return "RGB".index(pattern[(y % 2) * 2 + (x % 2)])


BILINEAR_G = np.array([[0, 1, 0], [1, 4, 1], [0, 1, 0]]) / 4
BILINEAR_RB = np.array([[1, 2, 1], [2, 4, 2], [1, 2, 1]]) / 4

# Malvar, He & Cutler 2004, Fig. 2: the coefficients, divided by 8 (α = 1/2, β = 5/8, γ = 3/4)
MALVAR_G_AT_RB = np.array([[0, 0, -1, 0, 0],
                           [0, 0, 2, 0, 0],
                           [-1, 2, 4, 2, -1],
                           [0, 0, 2, 0, 0],
                           [0, 0, -1, 0, 0]]) / 8
MALVAR_AT_G_ROW = np.array([[0, 0, 0.5, 0, 0],  # R (or B) at a green site whose row holds R (or B)
                            [0, -1, 0, -1, 0],
                            [-1, 4, 5, 4, -1],
                            [0, -1, 0, -1, 0],
                            [0, 0, 0.5, 0, 0]]) / 8
MALVAR_AT_G_COLUMN = MALVAR_AT_G_ROW.T  # … whose column holds it
MALVAR_OPPOSITE = np.array([[0, 0, -1.5, 0, 0],  # R at a blue site, B at a red one
                            [0, 2, 0, 2, 0],
                            [-1.5, 0, 6, 0, -1.5],
                            [0, 2, 0, 2, 0],
                            [0, 0, -1.5, 0, 0]]) / 8


def bilinear_weights(pattern: str, dy: int, dx: int, channel: int) -> np.ndarray:
    """(5, 5) weights on the mosaic around a site (row dy, column dx of the 2 × 2 cell) giving the site's value of
    ``channel``: the bilinear kernel on that channel's sites only."""
    kernel = BILINEAR_G if channel == 1 else BILINEAR_RB
    w = np.zeros((5, 5))
    for i in range(3):
        for j in range(3):
            if colour_at(pattern, dy + i - 1, dx + j - 1) == channel:
                w[i + 1, j + 1] = kernel[i, j]
    return w


def malvar_weights(pattern: str, dy: int, dx: int, channel: int) -> np.ndarray:
    """(5, 5) weights of Malvar 2004 on the mosaic around a site (every colour's sites)."""
    own = colour_at(pattern, dy, dx)
    if own == channel:
        w = np.zeros((5, 5))
        w[2, 2] = 1.0
        return w
    if channel == 1:
        return MALVAR_G_AT_RB
    if own == 1:
        return MALVAR_AT_G_ROW if colour_at(pattern, dy, dx + 1) == channel else MALVAR_AT_G_COLUMN
    return MALVAR_OPPOSITE


WEIGHTS = {"bilinear": bilinear_weights, "malvar2004": malvar_weights}


def covariance(weights, pattern, tau2, site, channel, offset, channel2=None) -> float:
    """Cov(out_c(p), out_c2(p + offset)) for p a site of class ``site`` = (dy, dx), the mosaic's noise independent
    with variance ``tau2[colour]`` at each site: Σ_q w_p(q) w_{p+o}(q) τ²_q, the overlap of the two kernels."""
    channel2 = channel if channel2 is None else channel2
    dy, dx = site
    oy, ox = offset
    total = 0.0
    w1 = weights(pattern, dy, dx, channel)
    w2 = weights(pattern, (dy + oy) % 2, (dx + ox) % 2, channel2)
    for i in range(5):
        for j in range(5):
            i2, j2 = i - oy, j - ox  # the same mosaic site seen from p + o
            if 0 <= i2 < 5 and 0 <= j2 < 5 and w1[i, j] and w2[i2, j2]:
                total += w1[i, j] * w2[i2, j2] * tau2[colour_at(pattern, dy + i - 2, dx + j - 2)]
    return total


def cross_covariance(method, pattern, tau2, site, offset, matrix=None) -> np.ndarray:
    """(3, 3): Cov(y_j(p), y_k(p + offset)) of y = matrix · (the demosaiced noise), p a site of class ``site``:
    matrix · C · matrixᵀ with C[j, k] = :func:`covariance` of channels j and k."""
    c = np.array([[covariance(WEIGHTS[method], pattern, tau2, site, j, offset, k) for k in range(3)]
                  for j in range(3)])
    m = np.eye(3) if matrix is None else np.asarray(matrix, dtype=np.float64)
    return m @ c @ m.T


def predicted_demosaic_noise(method, pattern, tau2, matrix=None) -> dict:
    """{(site (dy, dx), channel): (variance, corr_h, corr_v, Σ_lag ρ²)} of a linear demosaicing's output noise,
    or of ``matrix`` times it.

    Σ_lag ρ² sums, over the lags (2a, 2b) of the site's own lattice that the kernels reach (|a|, |b| ≤ 2), the
    squared correlation between the pixel and the pixel at that lag: the factor by which correlation inflates
    the variance of a sample variance over the lattice."""
    out = {}
    for dy in range(2):
        for dx in range(2):
            cov = {o: cross_covariance(method, pattern, tau2, (dy, dx), o, matrix)
                   for o in [(0, 0), (0, 1), (1, 0)] + [(2 * a, 2 * b) for a in range(-2, 3) for b in range(-2, 3)]}
            var_h = np.diag(cross_covariance(method, pattern, tau2, (dy, (dx + 1) % 2), (0, 0), matrix))
            var_v = np.diag(cross_covariance(method, pattern, tau2, ((dy + 1) % 2, dx), (0, 0), matrix))
            for c in range(3):
                var = cov[0, 0][c, c]
                lags = sum((cov[2 * a, 2 * b][c, c] / var) ** 2 for a in range(-2, 3) for b in range(-2, 3))
                out[(dy, dx), c] = (var, cov[0, 1][c, c] / math.sqrt(var * var_h[c]),
                                    cov[1, 0][c, c] / math.sqrt(var * var_v[c]), lags)
    return out


def predicted_nps(method, pattern, tau2, shape, bins, matrix=None) -> np.ndarray:
    """The expected radial NPS of each channel of a linear demosaicing's noise (times ``matrix``) on a window of
    ``shape``, relative to its mean over the frequency plane, in ``bins`` radial bins of equal width from 0 to 0.5
    cycles per pixel: shape (3, bins).

    The expected periodogram of the (period-2) noise field on an Ny × Nx window is
    S(f) = ¼ Σ_sites Σ_lags (1 − |l_y| / Ny)(1 − |l_x| / Nx) Cov_site(l) cos(2π f·l), over the lags the kernels
    reach (|l| ≤ 4); its mean over the frequency grid is the lag-0 term."""
    ny, nx = shape
    fy = np.fft.fftfreq(ny)
    fx = np.fft.fftfreq(nx)
    lags = range(-4, 5)
    # ¼ Σ_sites Cov_site(l) per lag and channel, tapered by the window
    cov = np.zeros((9, 9, 3))
    for a, ly in enumerate(lags):
        for b, lx in enumerate(lags):
            total = sum(np.diag(cross_covariance(method, pattern, tau2, (dy, dx), (ly, lx), matrix))
                        for dy in range(2) for dx in range(2))
            cov[a, b] = 0.25 * (1 - abs(ly) / ny) * (1 - abs(lx) / nx) * total
    ey = np.exp(2j * np.pi * np.outer(fy, np.array(lags)))  # (ny, 9)
    ex = np.exp(2j * np.pi * np.outer(fx, np.array(lags)))  # (nx, 9)
    index = np.floor(np.hypot(fy[:, None], fx[None, :]) / 0.5 * bins).astype(int)
    inside = index < bins
    counts = np.bincount(index[inside], minlength=bins)
    out = np.empty((3, bins))
    for c in range(3):
        spectrum = np.real(ey @ cov[:, :, c] @ ex.T)  # Σ_l cov(l) e^{2πi f·l}: real, cov being even in l
        relative = spectrum / spectrum.mean()
        out[c] = np.bincount(index[inside], weights=relative[inside], minlength=bins) / counts
    return out


def radial_periodogram(plane, bins) -> np.ndarray:
    """The radial profile of a plane's periodogram |DFT(x − x̄)|² relative to its mean (written here, for the
    oracle's own check)."""
    power = np.abs(np.fft.fft2(plane - plane.mean())) ** 2
    fy = np.fft.fftfreq(plane.shape[0])[:, None]
    fx = np.fft.fftfreq(plane.shape[1])[None, :]
    index = np.floor(np.hypot(fy, fx) / 0.5 * bins).astype(int)
    inside = index < bins
    return (np.bincount(index[inside], weights=power[inside] / power.mean(), minlength=bins)
            / np.bincount(index[inside], minlength=bins))


def nps_tolerance(predicted, shape, bins) -> np.ndarray:
    """K_SE standard errors of a radial NPS bin: each periodogram ordinate is exponential (standard deviation =
    its mean); a bin of n frequencies holds n / 2 independent ones (a real field's DFT is conjugate symmetric),
    and n / 4 for a field of period 2 (f and f + ½ are coherent)."""
    return K_SE * predicted / np.sqrt(nps_bin_counts(shape, bins) / 4)


def site_statistics(plane, dy, dx):
    """(sample variance, correlation with the right neighbour, with the lower one, n) of a plane's pixels of one
    site class (rows dy::2, columns dx::2), measured here with numpy."""
    x = plane[dy::2, dx::2]
    right = plane[dy::2, dx + 1::2]
    below = plane[dy + 1::2, dx::2]
    w, h = min(x.shape[1], right.shape[1]), min(x.shape[0], below.shape[0])
    rho_h = np.corrcoef(x[:, :w].ravel(), right[:, :w].ravel())[0, 1]
    rho_v = np.corrcoef(x[:h].ravel(), below[:h].ravel())[0, 1]
    return x.var(ddof=1), rho_h, rho_v, x.size


def check_site_statistics(planes, predicted, what):
    """Every site class and channel of ``planes`` (3, H, W; H, W even, starting on the pattern's first site) has
    the predicted variance and neighbour correlations, within K_SE standard errors."""
    for ((dy, dx), c), (var, corr_h, corr_v, lags) in predicted.items():
        sample, rho_h, rho_v, n = site_statistics(planes[c], dy, dx)
        where = (what, (dy, dx), "RGB"[c])
        assert abs(sample - var) <= variance_tolerance(var, n, lags), (where, "variance", sample, var)
        assert abs(rho_h - corr_h) <= correlation_tolerance(corr_h, n, lags), (where, "corr_h", rho_h, corr_h)
        assert abs(rho_v - corr_v) <= correlation_tolerance(corr_v, n, lags), (where, "corr_v", rho_v, corr_v)


def nps_bin_counts(shape, bins) -> np.ndarray:
    """The number of frequencies of an Ny × Nx window's DFT in each radial bin."""
    fy = np.fft.fftfreq(shape[0])[:, None]
    fx = np.fft.fftfreq(shape[1])[None, :]
    index = np.floor(np.hypot(fy, fx) / 0.5 * bins).astype(int)
    return np.bincount(index[index < bins], minlength=bins)


def pixel_variance_dn2(frame) -> np.ndarray:
    """The closed-form temporal variance of one pixel per channel (R, G, B), k² (S + D + σ_r²). Unit: DN²."""
    sensor, expected = frame.sensor, frame.expected
    assert expected.signal_e.shape[0] == 1, "a flat frame has one spectrum"
    electrons = expected.signal_e[0] + expected.dark_e + sensor.read_noise_e ** 2
    return sensor.dn_per_electron ** 2 * electrons


def clean_mosaic(clean_rgb: np.ndarray, pattern: str) -> np.ndarray:
    """The clean layer of a Bayer frame as a mosaic: each site its own colour's expected value."""
    out = np.empty(clean_rgb.shape[1:], dtype=clean_rgb.dtype)
    for dy in range(2):
        for dx in range(2):
            out[dy::2, dx::2] = clean_rgb[colour_at(pattern, dy, dx), dy::2, dx::2]
    return out


def variance_tolerance(var: float, n: int, lag_sum: float = 1.0) -> float:
    """K_SE standard errors of a sample variance: var √(2 Σρ² / (n − 1))."""
    return K_SE * var * math.sqrt(2.0 * lag_sum / (n - 1))


def correlation_tolerance(rho: float, n: int, lag_sum: float = 1.0) -> float:
    """K_SE standard errors of a sample correlation, (1 − ρ²) / √(n / Σρ²)."""
    return K_SE * (1 - rho ** 2) / math.sqrt(n / lag_sum)


# --- frames ----------------------------------------------------------------------------------------------------


def flat_frame(size: int, factor: float, cfa: str | None = None, seed: int = 1):
    """A flat field (the built-in ``flat`` scene: reflectance 1 under D65, the emva-12bit sensor: 0.4 DN/e⁻, read
    noise 3 e⁻, 25 e⁻ dark) without PRNU and DSNU, ``size`` × ``size``, and its FrameInfo."""
    scene = load_scene("flat").replace(width=size, height=size).with_sensor(
        prnu_percent=0.0, dsnu_e=0.0, quantisation=False, **({"cfa": cfa} if cfa else {}))
    return scene_frame(scene, "D65", factor, seed=seed)


def raw_layers(frame):
    """(noisy, clean) raw numbers of a frame as the ISP takes them: (3, H, W), or a mosaic (H, W). Unit: DN."""
    pattern = frame.sensor.cfa
    if pattern is None:
        return frame.noisy_dn, frame.clean_dn()
    return frame.noisy_dn[0], clean_mosaic(frame.clean_dn(), pattern)


def developed_noise(frame, facts, settings):
    """(noise per stage (float64), clean stages, the development's record)."""
    noisy, clean = raw_layers(frame)
    noisy_stages = isp.develop_stages(noisy, facts, settings)
    clean_stages = isp.develop_stages(clean, facts, settings)
    noise = {k: np.asarray(noisy_stages[k], np.float64) - np.asarray(clean_stages[k], np.float64)
             for k in noisy_stages}
    return noise, clean_stages, noisy_stages, isp.develop(clean, facts, settings).record


def linear_factors(frame, record):
    """From the record and the sensor: the white-balance gains g (3,), the matrix M (3, 3) (identity if off), the
    digital gain, and the normalisation's scale 1 / (white − black) per channel — the black and white levels
    taken from the sensor itself (``noisy_dn`` is before the ADC: the mean dark level ``dark_level_dn``)."""
    stages = record["stages"]
    gains = np.asarray(stages["white_balance"]["gains"], dtype=np.float64)
    m = stages["matrix"]["matrix"]
    m = np.eye(3) if m is None else np.asarray(m, dtype=np.float64)
    gain = float(stages["gain"]["value"])
    scale = 1.0 / (frame.sensor.max_dn - np.asarray(frame.sensor.dark_level_dn, dtype=np.float64))
    np.testing.assert_allclose(stages["black"]["black_dn"], frame.sensor.dark_level_dn, rtol=1e-12)
    assert stages["black"]["white_dn"] == frame.sensor.max_dn
    return gains, m, gain, scale


@pytest.fixture(scope="module")
def three_chip():
    frame, info = flat_frame(256, 0.25)
    return frame, info, isp.facts_from_info(frame, info)


@pytest.fixture(scope="module", params=["RGGB", "GBRG"])
def bayer(request):
    frame, info = flat_frame(320, 0.25, cfa=request.param)
    return frame, info, isp.facts_from_info(frame, info)


# --- the oracle checked on its own: colour-demosaicing on white noise -----------------------------------------


@pytest.mark.parametrize("method", ["bilinear", "malvar2004"])
@pytest.mark.parametrize("pattern", ["RGGB", "GBRG"])
def test_oracle_predicts_colour_demosaicing_on_white_noise(method, pattern):
    """The oracle's kernels are the published ones: on a mosaic of independent Gaussian noise (a different
    variance per colour), colour-demosaicing's own bilinear and Malvar 2004 give, at every site class and channel,
    the predicted variance and neighbour correlations (5 standard errors)."""
    import colour_demosaicing

    demosaic = {"bilinear": colour_demosaicing.demosaicing_CFA_Bayer_bilinear,
                "malvar2004": colour_demosaicing.demosaicing_CFA_Bayer_Malvar2004}[method]
    rng = np.random.default_rng(7)
    tau = np.array([1.0, 0.6, 1.7])
    size = 400
    mosaic = np.empty((size, size))
    for dy in range(2):
        for dx in range(2):
            mosaic[dy::2, dx::2] = tau[colour_at(pattern, dy, dx)] * rng.standard_normal((size // 2, size // 2))
    out = np.moveaxis(np.asarray(demosaic(mosaic, pattern), dtype=np.float64), -1, 0)[:, 4:-4, 4:-4]
    check_site_statistics(out, predicted_demosaic_noise(method, pattern, tau ** 2), (method, pattern))
    nps = predicted_nps(method, pattern, tau ** 2, out[0].shape, 8)
    for c in range(3):
        predicted = nps[c]
        measured = radial_periodogram(out[c], 8)
        assert np.all(np.abs(measured - predicted) <= nps_tolerance(predicted, out[c].shape, 8)), (
            method, c, measured, predicted)


def test_oracle_bilinear_values_by_hand():
    """Spot values of the bilinear oracle, by hand: at an R site the G output averages 4 G sites (¼ each: variance
    σ²/4), at a G site of the red row the R output averages 2 R sites (½ each: σ²/2) and at a B site 4 R sites
    (¼ each: σ²/4); the G output at a G site is the site itself, and the G outputs at an R site and its right
    neighbour (a G site) share that G site with weights ¼ and 1: covariance σ²/4, correlation (σ²/4)/√(σ²/4 · σ²)
    = ½."""
    pred = predicted_demosaic_noise("bilinear", "RGGB", np.array([1.0, 1.0, 1.0]))
    assert pred[(0, 0), 1][0] == pytest.approx(0.25)
    assert pred[(0, 1), 0][0] == pytest.approx(0.5)
    assert pred[(1, 1), 0][0] == pytest.approx(0.25)
    assert pred[(0, 1), 1][0] == pytest.approx(1.0)
    assert pred[(0, 0), 1][1] == pytest.approx(0.5)


# --- three-chip flat field: through the matrix exactly, through the tone curve to first order ----------------


def test_raw_noise_of_the_flat_frame_is_the_closed_form(three_chip):
    """The premise: the raw noise noisy − clean of the flat frame has the closed-form variance k² (S + D + σ_r²)
    per channel (5 standard errors of the χ² law) and no correlation between channels."""
    frame, _, _ = three_chip
    noisy, clean = raw_layers(frame)
    n = (np.asarray(noisy, np.float64) - clean).reshape(3, -1)
    var = pixel_variance_dn2(frame)
    sample = np.cov(n)
    for c in range(3):
        assert abs(sample[c, c] - var[c]) <= variance_tolerance(var[c], n.shape[1]), (c, sample[c, c], var[c])
    for i, j in ((0, 1), (0, 2), (1, 2)):
        assert abs(sample[i, j]) <= K_SE * math.sqrt(var[i] * var[j] / (n.shape[1] - 1))


def test_three_chip_covariance_through_the_matrix(three_chip):
    """Linear sRGB noise covariance = A Σ_raw Aᵀ with A = gain · M · diag(g) · diag(1 / (white − black)):
    exactly on the frame's own raw sample covariance (float32 rounding only), and within 5 standard errors of
    the closed form Σ_raw = diag(k² (S + D + σ_r²)) (a sample covariance of n independent pairs has variance
    (Σ_ii Σ_jj + Σ_ij²) / (n − 1))."""
    frame, _, facts = three_chip
    settings = isp.IspSettings(gain=1.5, tone="srgb")
    noise, _, _, record = developed_noise(frame, facts, settings)
    gains, m, gain, scale = linear_factors(frame, record)
    assert record["stages"]["matrix"]["matrix"] is not None and gain == 1.5
    a = gain * m @ np.diag(gains * scale)
    raw = noise["raw"].reshape(3, -1)
    out = noise["srgb_linear"].reshape(3, -1) * gain  # srgb_linear is before the gain
    gained = noise["gained"].reshape(3, -1)
    n = raw.shape[1]
    sample_out = np.cov(gained)
    np.testing.assert_allclose(gained, out, atol=1e-6)  # float32 rounding of values below 1
    # exact: the same samples through A
    exact = a @ np.cov(raw) @ a.T
    scale_ij = np.sqrt(np.outer(np.diag(exact), np.diag(exact)))
    assert np.all(np.abs(sample_out - exact) <= 1e-4 * scale_ij), (sample_out, exact)
    # the closed form, within the sampling error
    predicted = a @ np.diag(pixel_variance_dn2(frame)) @ a.T
    for i in range(3):
        for j in range(3):
            se = math.sqrt((predicted[i, i] * predicted[j, j] + predicted[i, j] ** 2) / (n - 1))
            assert abs(sample_out[i, j] - predicted[i, j]) <= K_SE * se, (i, j, sample_out[i, j], predicted[i, j])
    # the matrix mixes the channels: the developed channels' noise is correlated (not a property of the raw)
    rho_rg = predicted[0, 1] / math.sqrt(predicted[0, 0] * predicted[1, 1])
    assert abs(rho_rg) > 10 * K_SE / math.sqrt(n)


def test_three_chip_tone_curve_first_order(three_chip):
    """Through the sRGB curve f: the toned values are f of the gained ones (written out here), and the toned noise
    variance is f′(μ)² σ² to first order, μ the clean value, σ² the propagated closed-form variance.

    Second order (f(μ + n) − f(μ) = f′ n + f″ n² / 2 + f‴ n³ / 6): Var = f′² σ² + f′ f″ κ₃ + (f″² / 2 + f′ f‴) σ⁴
    + …, κ₃ the noise's third cumulant (Poisson: Σ_j A_cj³ k³ (S_j + D_j); the Gaussian read noise has none). Both
    corrections are computed and must be below the χ² tolerance here (they are below 0.1 % of the variance); the
    sharper check divides the toned sample variance by the gained one (the same samples): its ratio to f′(μ)² is
    1 + (f″ / f′) m₃ / σ² + (f″² / (2 f′²) + f‴ / f′) σ² + …, m₃ the sample third moment, whose standard error
    √(15 σ⁶ / n) sets the tolerance."""
    frame, _, facts = three_chip
    settings = isp.IspSettings(gain=1.0, tone="srgb")
    noise, clean_stages, noisy_stages, record = developed_noise(frame, facts, settings)
    gains, m, gain, scale = linear_factors(frame, record)
    a = gain * m @ np.diag(gains * scale)
    k = frame.sensor.dn_per_electron
    charge = frame.expected.signal_e[0] + frame.expected.dark_e
    sigma2 = np.diag(a @ np.diag(pixel_variance_dn2(frame)) @ a.T)
    kappa3 = (a * k) ** 3 @ charge
    gained = np.asarray(noisy_stages["gained"], np.float64)
    toned = np.asarray(noisy_stages["toned"], np.float64)
    n = gained[0].size
    # the tone stage is the sRGB function, element by element (float32 arithmetic in the ISP)
    np.testing.assert_allclose(toned, srgb(np.clip(gained, 0, 1)), atol=3e-6)
    for c in range(3):
        mu = float(np.asarray(clean_stages["gained"][c], np.float64).mean())
        assert np.ptp(clean_stages["gained"][c]) <= 1e-6 * mu  # flat: one clean value
        assert gained[c].min() > 0.0031308 and gained[c].max() < 1  # the power segment, no clipping
        d1, d2, d3 = srgb_derivatives(mu)
        first = d1 ** 2 * sigma2[c]
        second = d1 * d2 * kappa3[c] + (d2 ** 2 / 2 + d1 * d3) * sigma2[c] ** 2
        tolerance = variance_tolerance(first, n)
        assert abs(second) < 0.1 * tolerance  # the first order is all that the sample can tell
        t = noise["toned"][c].ravel()
        assert abs(t.var(ddof=1) - first) <= tolerance, (c, t.var(ddof=1), first)
        # the same samples: toned over gained variance against f'(μ)², the residual set by the third moment
        g = noise["gained"][c].ravel()
        ratio = t.var(ddof=1) / g.var(ddof=1) / d1 ** 2
        expected = 1 + (d2 ** 2 / (2 * d1 ** 2) + d3 / d1) * sigma2[c]
        se = abs(d2 / d1) * math.sqrt(15 * sigma2[c] ** 3 / n) / sigma2[c]
        assert abs(ratio - expected) <= K_SE * se + abs(d2 / d1) * abs(kappa3[c]) / sigma2[c], (c, ratio, expected)
        # the linear law without f' is far off: the curve's slope is what changes the noise
        assert abs(t.var(ddof=1) - sigma2[c]) > 5 * tolerance


# --- Bayer flat field: linear demosaicing, and the matrix after it --------------------------------------------

MARGIN = 4  # pixels left out at each edge (the 5 × 5 kernels' reach, and even: the site classes keep their phase)


def mosaic_variances(frame, record):
    """(σ² per channel of the raw mosaic (DN²), τ² per channel after normalising and white balance)."""
    gains, _, _, scale = linear_factors(frame, record)
    sigma2 = pixel_variance_dn2(frame)
    return sigma2, (gains * scale) ** 2 * sigma2


@pytest.mark.parametrize("method", ["bilinear", "malvar2004"])
def test_bayer_linear_demosaicing_noise(bayer, method):
    """Through a linear demosaicing (bilinear; Malvar 2004) and then the colour matrix: at each CFA site class and
    channel, the variance and the neighbour correlations are the kernels' Σ w² τ² and kernel overlaps (times M), in
    the mosaic stages the sites' own variance and no correlation."""
    frame, _, facts = bayer
    pattern = frame.sensor.cfa
    settings = isp.IspSettings(demosaic=method, gain=1.0)
    noise, _, _, record = developed_noise(frame, facts, settings)
    _, m, gain, _ = linear_factors(frame, record)
    assert gain == 1.0 and record["stages"]["matrix"]["matrix"] is not None
    sigma2, tau2 = mosaic_variances(frame, record)
    crop = np.s_[..., MARGIN:-MARGIN, MARGIN:-MARGIN]
    for stage, variances in (("raw", sigma2), ("white_balanced", tau2)):
        plane = noise[stage][crop]
        for dy in range(2):
            for dx in range(2):
                c = colour_at(pattern, dy, dx)
                sample, rho_h, rho_v, n = site_statistics(plane, dy, dx)
                assert abs(sample - variances[c]) <= variance_tolerance(variances[c], n), (stage, dy, dx)
                assert abs(rho_h) <= correlation_tolerance(0.0, n) and abs(rho_v) <= correlation_tolerance(0.0, n)
    check_site_statistics(noise["demosaiced"][crop], predicted_demosaic_noise(method, pattern, tau2),
                          (method, pattern, "demosaiced"))
    check_site_statistics(noise["srgb_linear"][crop], predicted_demosaic_noise(method, pattern, tau2, m),
                          (method, pattern, "srgb_linear"))


# --- noise_through_isp reports what the oracle predicts --------------------------------------------------------


def rows_by(rows, **keys):
    return [r for r in rows if all(r[k] == v for k, v in keys.items())]


def one_row(rows, **keys):
    found = rows_by(rows, **keys)
    assert len(found) == 1, (keys, len(found))
    return found[0]


@pytest.mark.parametrize("method", ["bilinear", "malvar2004"])
def test_noise_through_isp_on_a_bayer_flat(bayer, method):
    """noise_through_isp's rows on the Bayer flat field: the raw and white-balanced sites' std and (absent)
    correlation, and after demosaicing and the matrix every site class's std and neighbour correlations, the
    channel's pooled std and correlation, and its radial NPS — each the oracle's value within K_SE standard
    errors."""
    frame, _, facts = bayer
    pattern = frame.sensor.cfa
    settings = isp.IspSettings(demosaic=method, gain=1.0)
    noisy, clean = raw_layers(frame)
    rows = noise_through_isp(noisy, clean, facts, settings)
    record = isp.develop(clean, facts, settings).record
    _, m, _, _ = linear_factors(frame, record)
    sigma2, tau2 = mosaic_variances(frame, record)
    names = {}  # (dy, dx) → R, G1 (the green of R's row), G2, B
    red_row = next(dy for dy in range(2) for dx in range(2) if colour_at(pattern, dy, dx) == 0)
    for dy in range(2):
        for dx in range(2):
            c = colour_at(pattern, dy, dx)
            names[dy, dx] = "G1" if c == 1 and dy == red_row else "G2" if c == 1 else "RGB"[c]
    assert {r["stage"] for r in rows} == set(isp.STAGE_NAMES)
    assert {r["region"] for r in rows} == {"frame"}
    n_site = ((320 - 2 * MARGIN) // 2) ** 2
    for stage, variances in (("raw", sigma2), ("white_balanced", tau2)):
        for (dy, dx), site in names.items():
            c = colour_at(pattern, dy, dx)
            row = one_row(rows, stage=stage, site=site)
            assert row["domain"] == "mosaic" and row["channel"] == "RGB"[c] and row["pixels"] == n_site
            assert abs(row["std"] ** 2 - variances[c]) <= variance_tolerance(variances[c], n_site)
            assert abs(row["corr_h"]) <= correlation_tolerance(0, n_site)
            assert abs(row["corr_v"]) <= correlation_tolerance(0, n_site)
            assert abs(row["mean"]) <= K_SE * math.sqrt(variances[c] / n_site)
        for c in range(3):  # the channel's sites together: white noise, a flat NPS
            row = one_row(rows, stage=stage, channel="RGB"[c], site="all")
            shape = (320 - 2 * MARGIN,) * 2
            assert np.all(np.abs(np.array(row["nps"]) - 1) <= nps_tolerance(np.ones(8), shape, 8)), row["nps"]
    assert rows_by(rows, stage="raw", site="all", channel="G")[0]["pixels"] == 2 * n_site
    shape = (320 - 2 * MARGIN,) * 2
    for stage, matrix in (("demosaiced", None), ("srgb_linear", m)):
        predicted = predicted_demosaic_noise(method, pattern, tau2, matrix)
        all_nps = predicted_nps(method, pattern, tau2, shape, 8, matrix)
        for ((dy, dx), c), (var, corr_h, corr_v, lags) in predicted.items():
            row = one_row(rows, stage=stage, channel="RGB"[c], site=names[dy, dx])
            assert row["domain"] == "rgb" and row["pixels"] == n_site and row["nps"] is None
            assert abs(row["std"] ** 2 - var) <= variance_tolerance(var, n_site, lags), (stage, row, var)
            assert abs(row["corr_h"] - corr_h) <= correlation_tolerance(corr_h, n_site, lags), (stage, row, corr_h)
            assert abs(row["corr_v"] - corr_v) <= correlation_tolerance(corr_v, n_site, lags), (stage, row, corr_v)
        for c in range(3):
            row = one_row(rows, stage=stage, channel="RGB"[c], site="all")
            sites = [predicted[s, c] for s in names]
            pooled = sum(v for v, *_ in sites) / 4
            lags = max(v[3] for v in sites)
            rho_h = sum(cross_covariance(method, pattern, tau2, s, (0, 1), matrix)[c, c] for s in names) / (4 * pooled)
            rho_v = sum(cross_covariance(method, pattern, tau2, s, (1, 0), matrix)[c, c] for s in names) / (4 * pooled)
            assert row["pixels"] == 4 * n_site
            assert abs(row["std"] ** 2 - pooled) <= variance_tolerance(pooled, n_site, lags)
            assert abs(row["corr_h"] - rho_h) <= correlation_tolerance(rho_h, n_site, lags)
            assert abs(row["corr_v"] - rho_v) <= correlation_tolerance(rho_v, n_site, lags)
            nps = all_nps[c]
            assert np.all(np.abs(np.array(row["nps"]) - nps) <= nps_tolerance(nps, shape, 8)), (row["nps"], nps)
            np.testing.assert_allclose(row["nps_frequency"], (np.arange(8) + 0.5) / 16)


def test_noise_through_isp_on_a_three_chip_flat(three_chip):
    """On the three-chip flat field (no demosaicing): the gained stage's std is the propagated closed form, the
    toned stage's f′(μ) times it (first order), no stage correlates neighbours, and every NPS is flat."""
    frame, _, facts = three_chip
    settings = isp.IspSettings(gain=1.0, tone="srgb")
    noisy, clean = raw_layers(frame)
    rows = noise_through_isp(noisy, clean, facts, settings)
    record = isp.develop(clean, facts, settings).record
    gains, m, gain, scale = linear_factors(frame, record)
    a = gain * m @ np.diag(gains * scale)
    sigma2 = np.diag(a @ np.diag(pixel_variance_dn2(frame)) @ a.T)
    n = 256 * 256
    assert {r["site"] for r in rows} == {"all"} and {r["domain"] for r in rows} == {"rgb"}
    for c in range(3):
        gained = one_row(rows, stage="gained", channel="RGB"[c])
        toned = one_row(rows, stage="toned", channel="RGB"[c])
        assert gained["pixels"] == n and gained["unit"] == "white level" and toned["unit"] == "sRGB value"
        assert abs(gained["std"] ** 2 - sigma2[c]) <= variance_tolerance(sigma2[c], n)
        d1 = srgb_derivatives(gained["signal"])[0]
        assert abs(toned["std"] ** 2 - d1 ** 2 * sigma2[c]) <= variance_tolerance(d1 ** 2 * sigma2[c], n)
        assert toned["signal"] == pytest.approx(float(srgb(gained["signal"])), rel=1e-5)
        assert toned["clipped_fraction"] == 0.0 and gained["clipped_fraction"] is None
        for row in rows_by(rows, channel="RGB"[c]):
            assert abs(row["corr_h"]) <= correlation_tolerance(0, n)
            assert abs(row["corr_v"]) <= correlation_tolerance(0, n)
            assert np.all(np.abs(np.array(row["nps"]) - 1) <= K_SE / np.sqrt(nps_bin_counts((256, 256), 8) / 2))


# --- regions, the report, errors -------------------------------------------------------------------------------


def test_noise_through_isp_regions_and_margin(bayer):
    """Regions are (x, y, width, height) rectangles, shrunk by the margin; a (1, H, W) mosaic is taken as (H, W);
    a region outside the frame, or shapes that differ, are one-line CamsimErrors."""
    from camsim.core.errors import CamsimError

    frame, _, facts = bayer
    noisy, clean = raw_layers(frame)
    settings = isp.IspSettings(demosaic="bilinear")
    rows = noise_through_isp(noisy[None], clean[None], facts, settings,
                             regions={"left": (0, 0, 100, 320), "corner": (200, 200, 40, 60)}, margin=2)
    assert [r["region"] for r in rows if r["stage"] == "raw" and r["site"] == "all"] == ["left"] * 3 + ["corner"] * 3
    assert one_row(rows, region="left", stage="toned", channel="G", site="all")["pixels"] == 96 * 316
    assert one_row(rows, region="corner", stage="raw", channel="G", site="all")["pixels"] == 36 * 56 // 2
    with pytest.raises(CamsimError, match="does not lie inside"):
        noise_through_isp(noisy, clean, facts, settings, regions={"out": (300, 0, 40, 40)})
    with pytest.raises(CamsimError, match="shape"):
        noise_through_isp(noisy, clean[:, :-2], facts, settings)
    from camsim.scene.regions import Region

    rows = noise_through_isp(noisy, clean, facts, settings, regions=[Region("a", (10, 10, 40, 40)),
                                                                     ("b", [50, 50, 20, 20])])
    assert {r["region"] for r in rows} == {"a", "b"}
    for bad in ([("a", (0, 0, 10, 10)), ("a", (20, 20, 10, 10))], [("a", (0, 0, 10.5, 10))],
                [("a", (0, 0, float("inf"), 10))], [(0, 0, 10, 10)], {"tiny": (0, 0, 10, 10)}):
        with pytest.raises(CamsimError):
            noise_through_isp(noisy, clean, facts, settings, regions=bad)
    for margin in (-1, 1.5, True):
        with pytest.raises(CamsimError, match="margin"):
            noise_through_isp(noisy, clean, facts, settings, margin=margin)


@pytest.mark.slow
def test_write_noise_report(tmp_path, three_chip):
    """The CSV has a header of NOISE_COLUMNS and the NPS bins, one line per row, the numbers of the rows; the
    figure is a PNG; both appear together, and a folder that is not there leaves no file."""
    import csv

    from camsim.core.errors import CamsimError
    from camsim.isp.noise import NOISE_COLUMNS

    frame, _, facts = three_chip
    noisy, clean = raw_layers(frame)
    rows = noise_through_isp(noisy, clean, facts, isp.IspSettings())
    paths = write_noise_report(rows, tmp_path, "flat")
    assert [p.name for p in paths] == ["flat_noise_stages.csv", "flat_noise_stages.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in paths)
    with open(paths[0], newline="", encoding="utf-8") as handle:
        table = list(csv.DictReader(handle))
    assert list(table[0])[:len(NOISE_COLUMNS)] == list(NOISE_COLUMNS)
    assert [k for k in table[0] if k.startswith("nps_f")] == [f"nps_f{f:.3f}" for f in rows[0]["nps_frequency"]]
    assert len(table) == len(rows)
    for line, row in zip(table, rows):
        assert line["stage"] == row["stage"] and float(line["std"]) == pytest.approx(row["std"], rel=1e-5)
        assert (line["clipped_fraction"] == "") == (row["clipped_fraction"] is None)
    assert paths[1].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    several = noise_through_isp(noisy, clean, facts, isp.IspSettings(),
                                regions={f"r{i}": (40 * i, 0, 40, 40) for i in range(6)})
    assert [p.name for p in write_noise_report(several, tmp_path, "six")] == ["six_noise_stages.csv",
                                                                             "six_noise_stages.png"]
    with pytest.raises((CamsimError, OSError)):
        write_noise_report(rows, tmp_path / "missing", "flat")
    assert not (tmp_path / "missing").exists()
    with pytest.raises(CamsimError):
        write_noise_report([], tmp_path, "empty")


@pytest.mark.parametrize("pattern", PATTERNS)
def test_clean_mosaic(pattern):
    """clean_mosaic keeps at each site its own colour's plane: planes filled with 0, 1, 2 give the pattern's
    colour indices, read here from the pattern's letters."""
    from camsim.isp.noise import clean_mosaic

    planes = np.stack([np.full((4, 6), c, dtype=np.float32) for c in range(3)])
    expected = np.array([["RGB".index(pattern[2 * (y % 2) + x % 2]) for x in range(6)] for y in range(4)])
    np.testing.assert_array_equal(clean_mosaic(planes, pattern), expected)


def test_clipped_fraction_near_white(three_chip):
    """With a gain that puts the flat field's clean linear sRGB just under 1, the toned rows' clipped fraction is
    the Gaussian tail P(x > 1) = Φ((μ − 1) / σ) of the propagated closed form (5 binomial standard errors; the
    Poisson skewness, about 0.02 here, moves the tail by less than 0.001)."""
    from scipy.stats import norm

    frame, _, facts = three_chip
    noisy, clean = raw_layers(frame)
    unit = isp.develop_stages(clean, facts, isp.IspSettings(gain=1.0))["gained"]
    settings = isp.IspSettings(gain=0.97 / float(np.asarray(unit[1], np.float64).mean()))
    record = isp.develop(clean, facts, settings).record
    gains, m, gain, scale = linear_factors(frame, record)
    a = gain * m @ np.diag(gains * scale)
    sigma = np.sqrt(np.diag(a @ np.diag(pixel_variance_dn2(frame)) @ a.T))
    rows = noise_through_isp(noisy, clean, facts, settings)
    n = 256 * 256
    for c in range(3):
        mu = one_row(rows, stage="gained", channel="RGB"[c])["signal"]
        p = norm.sf((1 - mu) / sigma[c]) + norm.cdf(-mu / sigma[c])
        measured = one_row(rows, stage="toned", channel="RGB"[c])["clipped_fraction"]
        assert 0.05 < p < 0.5
        assert abs(measured - p) <= K_SE * math.sqrt(p * (1 - p) / n) + 0.001, (c, measured, p)


def test_noise_layers_from_files(tmp_path):
    """noise_layers reads a written frame's EXR (named directly, or through its DNG): the noisy layer is the
    frame's noisy_dn, the clean one its clean layer as a mosaic (built here), the facts' black level the dark
    level before the ADC; without the EXR it says so in one line."""
    from camsim.core.errors import CamsimError
    from camsim.isp.noise import noise_layers
    from camsim.render.frame_files import write_frame

    scene = load_scene("flat").replace(width=64, height=48).with_sensor(cfa="GRBG", prnu_percent=0.0, dsnu_e=0.0)
    frame, info = scene_frame(scene, "D65", 0.1, seed=3)
    write_frame(tmp_path, "f", frame, info)
    for name in ("f.dng", "f.exr"):
        noisy, clean, facts = noise_layers(tmp_path / name)
        np.testing.assert_array_equal(noisy, frame.noisy_dn[0])
        np.testing.assert_array_equal(clean, clean_mosaic(frame.clean_dn(), "GRBG"))
        np.testing.assert_allclose(facts.black_dn, frame.sensor.dark_level_dn)
        assert facts.cfa_pattern == "GRBG"
    rows = noise_through_isp(noisy, clean, facts, isp.IspSettings(demosaic="bilinear"))
    assert one_row(rows, stage="raw", channel="G", site="all")["pixels"] == (64 - 8) * (48 - 8) // 2
    (tmp_path / "f.exr").unlink()
    with pytest.raises(CamsimError, match="EXR"):
        noise_layers(tmp_path / "f.dng")


def test_noise_through_isp_per_patch_of_a_three_chip_chart():
    """A three-chip ColorChecker (the macbeth_26 scene's Table I sensor, 8 bits, no fixed pattern), measured patch
    by patch through the regions: at each patch the gained noise variance is A diag(k² (S_c + D_c + σ_r²)) Aᵀ of
    that patch's own signal, and the toned variance f′(μ)² times it (plus the second-order terms, computed) where
    the patch lies in the sRGB curve's power segment, 5 standard errors from μ to its ends."""
    scene = load_scene("macbeth_26").replace(width=360, height=240, illuminants=("D65",)).with_sensor(
        quantisation=False)
    frame, info = scene_frame(scene, "D65", 1.0, seed=5)
    facts = isp.facts_from_info(frame, info)
    settings = isp.IspSettings(gain=1.0)
    regions = dict(zip(info.patch_names, info.patch_rects))
    rows = noise_through_isp(frame.noisy_dn, frame.clean_dn(), facts, settings, regions=regions)
    record = isp.develop(frame.clean_dn(), facts, settings).record
    gains, m, gain, scale = linear_factors(frame, record)
    a = gain * m @ np.diag(gains * scale)
    sensor, expected = frame.sensor, frame.expected
    k = sensor.dn_per_electron
    toned_checked = 0
    for name, (x, y, w, h) in regions.items():
        label = np.unique(frame.labels[y:y + h, x:x + w])
        assert label.size == 1, name
        charge = expected.signal_e[label[0]] + expected.dark_e
        raw_var = k ** 2 * (charge + sensor.read_noise_e ** 2)
        sigma2 = np.diag(a @ np.diag(raw_var) @ a.T)
        kappa3 = (a * k) ** 3 @ charge
        for c in range(3):
            gained = one_row(rows, region=name, stage="gained", channel="RGB"[c])
            n = gained["pixels"]
            assert n == w * h
            assert abs(gained["std"] ** 2 - sigma2[c]) <= variance_tolerance(sigma2[c], n), (name, c)
            mu, sigma = gained["signal"], math.sqrt(sigma2[c])
            if mu - 5 * sigma > 0.0031308 and mu + 5 * sigma < 1:
                d1, d2, d3 = srgb_derivatives(mu)
                predicted = d1 ** 2 * sigma2[c] + (d2 ** 2 / 2 + d1 * d3) * sigma2[c] ** 2
                skew_bound = abs(d1 * d2 * kappa3[c])
                toned = one_row(rows, region=name, stage="toned", channel="RGB"[c])
                assert abs(toned["std"] ** 2 - predicted) <= variance_tolerance(predicted, n) + skew_bound, (
                    name, c, toned["std"] ** 2, predicted)
                toned_checked += 1
    assert toned_checked >= 60, toned_checked  # most of the 24 × 3 patch channels lie in the power segment
