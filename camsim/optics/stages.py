"""The optics' stages, one pure array function each, and the per-channel OTF applied by FFT convolution.

Coordinates: frequencies f in cycles per pixel on the frame's pixel grid (fx along a row, fy down a column), the
pixel's centre at integer coordinates. A wavelength λ's diffraction cut-off is f_c = pitch_µm / (λ_µm · N) cy/px.

The OTF of a channel c is

    OTF_c(fx, fy) = [Σ_λ w_c(λ) · OTF_lens(ρ; λ)] · cos(π fx s) cos(π fy s)
                    · [sinc(√ff fx) / sinc(fx)] · [sinc(√ff fy) / sinc(fy)],

ρ = √(fx² + fy²), with OTF_lens the diffraction OTF of a circular pupil (2/π)(acos ν − ν√(1−ν²)), ν = ρ / f_c(λ),
or, with defocus, the pupil's autocorrelation with the W020 phase (Hopkins 1955; exact, by quadrature:
:func:`defocused_otf`), and w_c(λ) the channel's received-signal weights (:func:`channel_wavelength_weights`); the
OLPF factor is present where that stage is on, the pixel-aperture factor where ff < 1. Every factor is 1 at f = 0:
the PSF conserves energy.

The pixel aperture is relative to the source's own sampling: a scene's pixels are already area integrals over the
whole pixel (the slanted-edge target's exact covered area, a chart's patches constant on pixel boundaries, an
image's area samples), which carry the full pixel's box sinc(fx) sinc(fy); a square aperture of side √ff px is that
box replaced by sinc(√ff fx) sinc(√ff fy), so the stage multiplies by their ratio (:func:`pixel_aperture_otf`): the
identity at ff = 1, and for ff < 1 a gain rising with frequency, up to sinc(√ff/2) / sinc(½) ≤ π/2 ≈ 1.57 at
Nyquist (1.27 at ff = 0.5). That gain sharpens: where the source holds detail near Nyquist that the lens passes (a
sharp edge's aliases), the expectation rings and can fall below 0 next to a dark pixel (a 0 → 1 edge with no lens:
−0.04 at ff = 0.5, −0.08 as ff → 0); :func:`clip_negative` clips it at 0 and reports the electrons that added.

With w_c(λ) the weights of the light the channel receives on average over the frame, this is the channel's mean
OTF; where the spectrum changes within the PSF's reach (an edge between a red and a blue patch), the true image is
Σ_λ PSF_λ ∗ e_c(λ), not PSF_c ∗ Σ_λ e_c(λ): :mod:`camsim.render.optics` adds each spectrum's deviation from the mean
OTF in a few components (:mod:`camsim.optics.spectral`; ``tools/optics_colour_edge.py`` measures both against the
per-wavelength sum).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from camsim.core.xp import fft_namespace, namespace_of, to_host

#: Wavelength of ``defocus_waves``. Unit: µm.
DEFOCUS_REFERENCE_UM = 0.55
#: Samples of the radial OTF table per cycle per pixel (interpolated linearly on the frequency grid).
RADIAL_SAMPLES_PER_CY = 8192
#: Gauss–Legendre nodes per panel of the defocus quadrature (:func:`defocused_otf`).
DEFOCUS_NODES_PER_PANEL = 16
#: Least reflected margin around a frame for the FFT convolution. Unit: px.
MIN_MARGIN_PX = 32


def cutoff_cy_per_px(pixel_pitch_um: float, wavelength_nm, f_number: float) -> np.ndarray:
    """The diffraction cut-off f_c = pitch / (λ N) of each wavelength. Unit: cycles per pixel."""
    return pixel_pitch_um / (np.asarray(wavelength_nm, dtype=np.float64) * 1e-3 * f_number)


def diffraction_otf(nu) -> np.ndarray:
    """The diffraction-limited OTF of a circular pupil at normalised frequency ν = f / f_c (Goodman, Eq. 6-32):
    (2/π)(acos ν − ν √(1 − ν²)) for ν < 1, 0 beyond. Unitless, 1 at ν = 0."""
    nu = np.minimum(np.abs(np.asarray(nu, dtype=np.float64)), 1.0)
    return (2 / np.pi) * (np.arccos(nu) - nu * np.sqrt(1 - nu * nu))


def defocused_otf(nu, w020_waves: float) -> np.ndarray:
    """The OTF of a circular pupil with defocus W020 (peak wavefront error, waves), at ν = f / f_c: the pupil's
    autocorrelation with the phase 2π W020 r² (Hopkins 1955), exact up to the quadrature.

    With the unit pupil displaced by ±ν, the phase difference across the overlap is 2π · 4 W020 ν x, so with
    k = 8π W020 ν: OTF(ν) = (4 / (π k)) ∫₀^√(1−ν²) sin(k (√(1 − y²) − ν)) dy; W020 → 0 gives
    :func:`diffraction_otf`. The integral is taken with y = √(1−ν²) sin φ by composite Gauss–Legendre on
    φ ∈ [0, π/2]. Real
    (the pupil is symmetric), negative where the defocus reverses contrast. Unitless.

    The product approximation "diffraction OTF × defocus OTF", :func:`diffraction_otf` (ν) · 2 J₁(a)/a with
    a = 8π W020 ν (the geometric blur disc), is not used: it is off from this exact OTF by up to 0.06 (absolute, at
    W020 = 0.1 wave), 0.22 (0.25 and 0.5), 0.13 (1), 0.07 (2) and 0.04 (5 waves)."""
    nu = np.minimum(np.abs(np.asarray(nu, dtype=np.float64)), 1.0)
    if w020_waves == 0:
        return diffraction_otf(nu)
    # composite Gauss–Legendre: 16 nodes on each of ⌈|W020|⌉ + 1 (at least 2) panels of [0, π/2] (the integrand's
    # phase k (√(1 − y²) − ν) sweeps at most 8π |W020|, 4 |W020| cycles): within 1e-8 of a 32-node panel per
    # quarter cycle for W020 from 0.5 to 50 waves
    panels = max(2, int(math.ceil(abs(w020_waves))) + 1)
    t, w = np.polynomial.legendre.leggauss(DEFOCUS_NODES_PER_PANEL)
    edges = np.linspace(0, np.pi / 2, panels + 1)
    half_width = (edges[1] - edges[0]) / 2
    phi = ((edges[:-1] + half_width)[:, None] + half_width * t[None, :]).ravel()
    w = np.tile(w * half_width, panels)
    half = np.sqrt(1 - nu * nu)[..., None]  # √(1 − ν²)
    y = half * np.sin(phi)
    dy = half * np.cos(phi)
    k = (8 * np.pi * w020_waves * nu)[..., None]
    span = np.sqrt(1 - y * y) - nu[..., None]
    small = np.abs(k) < 1e-9
    safe_k = np.where(small, 1.0, k)
    integrand = np.where(small, span, np.sin(safe_k * span) / safe_k)
    return (4 / np.pi) * np.sum(integrand * dy * w, axis=-1)


def w020_at(w020_waves_550: float, wavelength_nm) -> np.ndarray:
    """W020 in waves at each wavelength from W020 in waves at 550 nm (the wavefront error in µm is fixed):
    W020 · 0.55 / λ_µm."""
    return w020_waves_550 * DEFOCUS_REFERENCE_UM / (np.asarray(wavelength_nm, dtype=np.float64) * 1e-3)


def lens_otf_radial(rho, wavelength_nm, weights, *, f_number: float, pixel_pitch_um: float, diffraction: bool,
                    w020_waves_550: float) -> np.ndarray:
    """Σ_λ w_c(λ) OTF_lens(ρ; λ) per row c of ``weights`` at radial frequencies ``rho`` (cy/px), shape
    (C, len(rho)) (C = 3 channels): ``weights`` @ :func:`wavelength_otf_table`.

    OTF_lens is the diffraction OTF (:func:`diffraction_otf`) or with defocus Hopkins's (:func:`defocused_otf`); with
    diffraction off the lens factor is 1 (an ideal lens: :class:`camsim.optics.params.OpticsParams` refuses defocus
    without diffraction). ``weights`` (C, N) sum to 1 per row over ``wavelength_nm`` (N,)."""
    weights = np.asarray(weights, dtype=np.float64)
    if not diffraction:
        return np.ones((weights.shape[0], np.size(rho)))
    return weights @ wavelength_otf_table(rho, wavelength_nm, f_number=f_number, pixel_pitch_um=pixel_pitch_um,
                                          w020_waves_550=w020_waves_550)


def wavelength_otf_table(rho, wavelength_nm, *, f_number: float, pixel_pitch_um: float,
                         w020_waves_550: float) -> np.ndarray:
    """Each wavelength's lens OTF (diffraction, with defocus W020) at radial frequencies ``rho`` (cy/px), shape
    (N, len(rho)), read-only; computed once per lens, wavelengths and frequencies (the last two kept: a frame's
    channels, spectra and repeated frames share it). Unitless."""
    rho = np.ascontiguousarray(rho, dtype=np.float64)
    wavelength_nm = np.ascontiguousarray(wavelength_nm, dtype=np.float64)
    return _wavelength_otf_table(rho.tobytes(), wavelength_nm.tobytes(), float(f_number), float(pixel_pitch_um),
                                 float(w020_waves_550))


@lru_cache(maxsize=2)
def _wavelength_otf_table(rho: bytes, wavelength_nm: bytes, f_number: float, pixel_pitch_um: float,
                          w020_waves_550: float) -> np.ndarray:
    rho, wavelength_nm = np.frombuffer(rho), np.frombuffer(wavelength_nm)
    cut = cutoff_cy_per_px(pixel_pitch_um, wavelength_nm, f_number)
    w020 = w020_at(w020_waves_550, wavelength_nm)
    table = np.empty((cut.size, rho.size))
    for i in range(cut.size):
        table[i] = defocused_otf(rho / cut[i], float(w020[i]))
    table.flags.writeable = False
    return table


def olpf_otf(frequency, shift_px: float) -> np.ndarray:
    """One axis of the 4-spot birefringent OLPF (spots at ±s/2 px): cos(π f s). The 2-D OTF is the product over
    fx and fy. Unitless."""
    return np.cos(np.pi * np.asarray(frequency, dtype=np.float64) * shift_px)


def pixel_aperture_otf(frequency, fill_factor: float) -> np.ndarray:
    """One axis of a square pixel aperture of side a = √ff px relative to the source's full-pixel area sampling:
    sinc(a f) / sinc(f) (sinc(x) = sin(π x) / (π x)). The 2-D OTF is the product over fx and fy. Unitless.

    The source's pixels already carry the full pixel's box sinc(f) (module docstring): the frame's total pixel
    factor is then sinc(a f), the aperture's own. 1 at f = 0; exactly 1 at ff = 1; for ff < 1 a gain ≥ 1 rising to
    sinc(a/2) / sinc(½) at Nyquist (≤ π/2). For frequencies on a pixel grid, |f| ≤ ½ (sinc(f) ≥ 2/π there).
    """
    frequency = np.asarray(frequency, dtype=np.float64)
    if fill_factor == 1:
        return np.ones(frequency.shape)
    return np.sinc(math.sqrt(fill_factor) * frequency) / np.sinc(frequency)


def clip_negative(planes) -> np.ndarray:
    """Clip an expectation (C, H, W) at 0 in place; return the electrons that added per plane, (C,) float64 ≥ 0.

    After the pixel aperture's gain (:func:`pixel_aperture_otf`, ff < 1) a sharp edge's ringing can fall below 0;
    a charge's mean cannot. Elsewhere what is clipped is the float32 FFT's rounding (≲ 1e-6 of the frame's values).
    ``planes`` on numpy or CuPy (:mod:`camsim.core.xp`). Unit: e⁻ (as ``planes``)."""
    xp = namespace_of(planes)
    below = xp.empty(planes.shape[0], dtype=xp.float64)
    for c, plane in enumerate(planes):  # (no boolean mask: a device compacts one with a sync per plane)
        below[c] = xp.minimum(plane, 0).sum(dtype=xp.float64)
        xp.maximum(plane, 0, out=plane)
    return 0.0 - np.asarray(to_host(below))  # (0 − 0 is +0, not the −0 of −0)


def channel_wavelength_weights(mean_photon_rate, qe) -> np.ndarray:
    """Each channel's weights over wavelength of the signal it receives: w_c(λ) ∝ Qe_c(λ) · ḡ(λ), summing to 1,
    with ḡ the photon rate averaged over the frame's pixels (a chart's spectra weighted by their pixel counts).

    Parameters
    ----------
    mean_photon_rate : array_like, shape (N,)
        ḡ(λ) on the grid. Unit: photons / (s m² sr) per bin (any: the weights are relative).
    qe : array_like, shape (3, N)
        The camera's Qe_c(λ).

    Returns
    -------
    numpy.ndarray, shape (3, N)
        Each row sums to 1 (a channel that receives nothing: Qe_c alone, normalised; all zero: uniform).
    """
    signal = np.asarray(qe, dtype=np.float64) * np.asarray(mean_photon_rate, dtype=np.float64)[None]
    out = np.empty_like(signal)
    for c in range(signal.shape[0]):
        row = signal[c] if signal[c].sum() > 0 else np.asarray(qe, dtype=np.float64)[c]
        out[c] = row / row.sum() if row.sum() > 0 else np.full(row.shape, 1 / row.size)
    return out


def margin_px(f_number: float, pixel_pitch_um: float, w020_waves_550: float, olpf_shift_px: float) -> int:
    """The reflected margin around a frame for its FFT convolution: :data:`MIN_MARGIN_PX`, plus the OLPF's shift,
    plus 4× the geometric defocus blur radius (4 N |W020| λ / pitch px at 550 nm). Unit: px."""
    defocus_px = 4 * f_number * abs(w020_waves_550) * DEFOCUS_REFERENCE_UM / pixel_pitch_um
    return int(MIN_MARGIN_PX + math.ceil(olpf_shift_px) + math.ceil(4 * defocus_px))


def channel_otf(radial_table, table_step: float, fy, fx, *, olpf_shift_px: float | None,
                fill_factor: float | None) -> np.ndarray:
    """One channel's 2-D OTF (len(fy), len(fx)) float32 on a frequency grid (|f| ≤ ½): its radial lens OTF (sampled
    at ρ = i · ``table_step``, interpolated linearly) × the separable OLPF and pixel-aperture factors (None: off; the
    aperture relative to the source's full-pixel sampling, :func:`pixel_aperture_otf`)."""
    return channel_otfs(np.asarray(radial_table)[None], table_step, fy, fx, olpf_shift_px=olpf_shift_px,
                        fill_factor=fill_factor)[0]


def channel_otfs(radial_tables, table_step: float, fy, fx, *, olpf_shift_px: float | None,
                 fill_factor: float | None, xp=np) -> list:
    """:func:`channel_otf` of each row of ``radial_tables`` (C, M) on one grid, the grid's work shared: ρ is computed
    once, and where the rows' frequencies come in ± pairs (``fftfreq``'s order) only the rows with fy ≥ 0 are
    interpolated and the others copied (every factor is even in fy). The grids are made on ``xp``'s device (numpy,
    or CuPy: :mod:`camsim.core.xp`); the 1-D factors on the host."""
    fy = np.asarray(fy, dtype=np.float64)
    fx = np.asarray(fx, dtype=np.float64)
    height = fy.size
    # the rows r ≥ 1 whose −fy is row height − r (fftfreq: 0, 1, …, −2, −1 over height): compute rows 0 … half
    half = height // 2 + 1 if np.array_equal(np.abs(fy[1:]), np.abs(fy[1:][::-1])) else height
    fyh = fy[:half, None]
    sep_y = np.ones(fyh.shape, dtype=np.float64)
    sep_x = np.ones(fx[None, :].shape, dtype=np.float64)
    if olpf_shift_px is not None:
        sep_y = sep_y * olpf_otf(fyh, olpf_shift_px)
        sep_x = sep_x * olpf_otf(fx[None, :], olpf_shift_px)
    if fill_factor is not None:
        sep_y = sep_y * pixel_aperture_otf(fyh, fill_factor)
        sep_x = sep_x * pixel_aperture_otf(fx[None, :], fill_factor)
    sep_y, sep_x = xp.asarray(sep_y.astype(np.float32)), xp.asarray(sep_x.astype(np.float32))
    fyh, fxd = xp.asarray(fyh), xp.asarray(fx[None, :])
    rho = xp.sqrt(fyh * fyh + fxd ** 2)
    out = []
    for table in np.asarray(radial_tables, dtype=np.float64):
        grid = xp.empty((height, fx.size), dtype=xp.float32)
        top = grid[:half]
        top[...] = xp.interp(rho.ravel(), xp.asarray(np.arange(table.size) * table_step),
                             xp.asarray(table)).reshape(rho.shape)  # (CuPy's interp takes 1-D points)
        top *= sep_y
        top *= sep_x
        if half < height:
            grid[half:] = grid[1:height - half + 1][::-1]
        out.append(grid)
    return out


def padded_shape(height: int, width: int, margin: int) -> tuple[int, int]:
    """The FFT's size for a frame with ``margin`` reflected pixels on every side: a fast length (scipy) each."""
    from scipy.fft import next_fast_len

    return next_fast_len(height + 2 * margin, real=True), next_fast_len(width + 2 * margin, real=True)


def convolve_plane(plane, otf, margin: int, shape: tuple[int, int], *, workers: int | None = None,
                   out=None):
    """One plane (H, W) convolved with the PSF whose OTF is ``otf`` (shape[0], shape[1] // 2 + 1) on the padded
    grid, by real FFTs in float32, on the plane's device (numpy or CuPy: :mod:`camsim.core.xp`).

    The frame is extended by reflection (mirror about its edge, numpy's ``symmetric``: the scene beyond the frame is
    taken to mirror it) to ``shape`` (``margin`` px before the frame on each axis, the rest after it), so the
    convolution is periodic on the padded grid: it conserves the padded sum exactly (OTF(0) = 1), and the frame's
    own sum where the PSF's reach from the frame's content stays within the margin. A uniform frame stays
    uniform. Returns the (H, W) float32 result (in ``out``, if given)."""
    spectrum = padded_spectrum(plane, margin, shape, workers=workers)
    spectrum *= otf
    return plane_of_spectrum(spectrum, margin, shape, np.shape(plane), workers=workers, out=out)


def _fft_threads(xp, workers: int | None) -> dict:
    """The FFT's thread count where it has one (scipy's ``workers``; cuFFT has none)."""
    return {"workers": workers} if xp is np else {}


def padded_spectrum(plane, margin: int, shape: tuple[int, int], *, workers: int | None = None):
    """The real FFT (shape[0], shape[1] // 2 + 1) complex64 of ``plane`` (H, W) extended by reflection to ``shape``
    (:func:`convolve_plane`), on the plane's device."""
    xp = namespace_of(plane)
    plane = xp.asarray(plane, dtype=xp.float32)
    height, width = plane.shape
    pad = ((margin, shape[0] - height - margin), (margin, shape[1] - width - margin))
    return fft_namespace(xp).rfft2(reflect_padded(plane, pad), overwrite_x=True, **_fft_threads(xp, workers))


def reflect_padded(plane, pad):
    """``plane`` (H, W) extended by reflection about its edges (numpy's ``symmetric``: the edge pixel repeated, any
    width, repeating the reflection) by ``pad`` ((top, bottom), (left, right)), on its device: numpy's pad on the
    CPU, two gathers by :func:`symmetric_indices` on a GPU (where CuPy's pad, copying margins piece by piece, took
    0.21 ms for W1's padded plane against the FFT's 0.16 ms)."""
    xp = namespace_of(plane)
    if xp is np:
        return np.pad(plane, pad, mode="symmetric")
    (top, bottom), (left, right) = pad
    height, width = plane.shape
    rows = xp.asarray(symmetric_indices(height, top, height + top + bottom))
    cols = xp.asarray(symmetric_indices(width, left, width + left + right))
    return xp.take(xp.take(plane, rows, axis=0), cols, axis=1)


def symmetric_indices(size: int, before: int, total: int) -> np.ndarray:
    """The indices (total,) into an axis of ``size`` that extend it by ``before`` before and the rest after, by
    reflection about its edges (numpy's ``symmetric``): i ↦ i mod 2·size, folded back from 2·size − 1."""
    i = np.mod(np.arange(total) - before, 2 * size)
    return np.where(i < size, i, 2 * size - 1 - i)


def plane_of_spectrum(spectrum, margin: int, shape: tuple[int, int], size: tuple[int, int], *,
                      workers: int | None = None, out=None):
    """The frame (H, W) = ``size`` float32 of a padded grid's real spectrum (:func:`padded_spectrum`): the inverse
    real FFT, cropped (``spectrum`` is overwritten), on the spectrum's device."""
    xp = namespace_of(spectrum)
    height, width = size
    result = fft_namespace(xp).irfft2(spectrum, s=shape, overwrite_x=True, **_fft_threads(xp, workers))
    if out is None:
        out = xp.empty((height, width), dtype=xp.float32)
    out[...] = result[margin:margin + height, margin:margin + width]
    return out


def field_angle_rad(height: int, width: int, pixel_pitch_um: float, focal_length_mm: float) -> np.ndarray:
    """Each pixel's field angle θ = atan(r · pitch / focal length), r its distance from the frame's centre
    ((W − 1)/2, (H − 1)/2) in px, shape (H, W) float64. Unit: rad."""
    y = (np.arange(height) - (height - 1) / 2) * pixel_pitch_um
    x = (np.arange(width) - (width - 1) / 2) * pixel_pitch_um
    r_um = np.hypot(y[:, None], x[None, :])
    return np.arctan(r_um / (focal_length_mm * 1e3))


def cos4_falloff(theta_rad) -> np.ndarray:
    """The relative illumination cos⁴θ of field angle θ (rad), 1 on the axis. Unitless."""
    return np.cos(np.asarray(theta_rad, dtype=np.float64)) ** 4


def table_falloff(theta_rad, table) -> np.ndarray:
    """The relative illumination interpolated linearly in the field angle from ``table`` ((angle_deg, value) pairs,
    from 0°), relative to its value at 0°; beyond the last angle, the last value. Unitless."""
    angles = np.array([a for a, _ in table], dtype=np.float64)
    values = np.array([v for _, v in table], dtype=np.float64)
    return np.interp(np.degrees(np.asarray(theta_rad, dtype=np.float64)), angles, values / values[0])


def magnification_inverse(magnification: float, height: int, width: int) -> np.ndarray:
    """The inverse homography (3, 3) of a magnification m about the frame's centre c = ((W − 1)/2, (H − 1)/2):
    sensor pixel p → image pixel c + (p − c) / m (lateral chromatic aberration of one channel)."""
    cx, cy = (width - 1) / 2, (height - 1) / 2
    inv = 1.0 / magnification
    return np.array([[inv, 0.0, cx * (1 - inv)], [0.0, inv, cy * (1 - inv)], [0.0, 0.0, 1.0]])
