"""A frame through the optics (issue 30): the scene's ``[optics]`` applied to the expected electrons, then the noise.

The scene's expected signal electrons per pixel and channel S̄ (3, H, W) are gathered through the label map
(:func:`camsim.render.raw_frame.static_signal_e`), the optics' stages (:mod:`camsim.optics.stages`) are applied to
them in the order light meets them:

1. lateral chromatic aberration: channel c's image magnified by m_c about the frame's centre (bilinear, clamped at
   the edges: :func:`camsim.render.warp.average_warp` with one inverse homography), its values × 1/m_c² so that the
   light is redistributed, not created (exact for content that stays within the frame);
2. vignetting: × cos⁴ of each pixel's field angle (or the table's relative illumination), 1 at the centre;
3. the PSF: per spectrum and channel. Each spectrum k (a chart's patch, an image's recovered colour) gives channel c
   the OTF OTF_kc = Σ_λ w_kc(λ) OTF_lens(λ) × OLPF × pixel aperture, w_kc(λ) ∝ Qe_c(λ) g_k(λ). The channel is
   convolved with its mean OTF O_c (w_c(λ): the light channel c receives averaged over the frame's pixels,
   :func:`channel_weights`), and each spectrum's deviation OTF_kc − O_c, decomposed over wavelength into r_c radial
   components B_j (:mod:`camsim.optics.spectral`, r_c the least whose error in every spectrum's OTF is at most
   :data:`OTF_TOLERANCE` at every frequency), is added as r_c more convolutions, each of a per-pixel map of
   amplitudes e_kc Σ_λ w_kc(λ) a_j(λ) (gathered through the labels; an image's colours on a basis: linear in their
   coefficients) through the same CA and vignetting: r_c + 1 forward FFTs and one inverse per channel
   (:func:`camsim.optics.stages.padded_spectrum`: real FFTs in float32, the frame extended by reflection about its
   edge by a margin (:func:`camsim.optics.stages.margin_px`, at most the frame's larger side), so a uniform field
   stays uniform and nothing wraps around). The pixel aperture is relative to the source's full-pixel sampling,
   sinc(√ff f) / sinc(f) per axis (:func:`camsim.optics.stages.pixel_aperture_otf`: none at ff = 1, a gain of up
   to π/2 at Nyquist as ff → 0). A frame whose spectra all weigh the wavelengths alike in a channel (a
   grey chart) needs r_c = 0: the mean OTF alone, one convolution (:func:`camsim.optics.stages.convolve_plane`).
4. the clip at 0 (:func:`camsim.optics.stages.clip_negative`): where that gain makes a sharp edge ring below 0; the
   electrons it added per channel are recorded (``negative_clipped_e``, and as a fraction of the channel's sum,
   ``negative_clipped_fraction``).

What remains against a per-wavelength reference (``tools/optics_colour_edge.py``) is the decomposition's error,
within its bound, and float32 rounding. The frame is then
drawn per pixel from that expectation (:func:`camsim.render.raw_frame.render_expectation_frame`: Poisson(S̄·g +
D̄·d) and every later stage of the sensor), so the noise stays exact; the sidecar records ``method = "poisson"``
and ``optics``: the table, ``channel_wavelength_weights``, ``otf_model`` and the clip's ``negative_clipped_e`` and
``negative_clipped_fraction``. The EXR's clean layer is the
expectation after the optics (:func:`camsim.render.raw_frame.expectation_clean_dn`). Pixel statistics only.
"""

from __future__ import annotations

import dataclasses
import weakref
from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.xp import namespace_of, to_host
from camsim.optics.params import OpticsParams
from camsim.optics.stages import (
    RADIAL_SAMPLES_PER_CY,
    channel_otfs,
    clip_negative,
    convolve_plane,
    cos4_falloff,
    field_angle_rad,
    lens_otf_radial,
    magnification_inverse,
    margin_px,
    padded_shape,
    padded_spectrum,
    plane_of_spectrum,
    table_falloff,
    wavelength_otf_table,
)

#: The largest error the per-spectrum decomposition may leave in any spectrum's OTF, at any frequency (OTF(0) = 1):
#: :mod:`camsim.optics.spectral`. Unitless.
OTF_TOLERANCE = 1e-3

#: The sidecar's statement of the OTF applied (the model MTF of the analysis is its magnitude, with the frame's
#: mean weights ``channel_wavelength_weights``; its pixel factor in all sinc(sqrt(ff) f) per axis); :func:`otf_model`
#: appends the frame's ranks and bounds.
OTF_MODEL = ("OTF_kc(fx, fy) = [sum_lambda w_kc(lambda) * OTF_lens(rho / f_c(lambda); W020(lambda))] * "
             "cos(pi fx s) cos(pi fy s) [olpf] * [sinc(sqrt(ff) fx) / sinc(fx)] [sinc(sqrt(ff) fy) / sinc(fy)] "
             "[ff = fill_factor < 1: the pixel aperture relative to the source's full-pixel area sampling, so the "
             "frame's total pixel factor is sinc(sqrt(ff) f) per axis; none at ff = 1], "
             "rho = sqrt(fx^2 + fy^2) cy/px, f_c = pixel_pitch_um / (lambda_um f_number); OTF_lens = (2/pi)(acos nu "
             "- nu sqrt(1 - nu^2)) [diffraction], with defocus the exact pupil autocorrelation with the W020 phase "
             "(Hopkins 1955, W020(lambda) = W020_550 * 0.55 / lambda_um waves), 1 without diffraction; per spectrum "
             "k (a chart's patch, an image's recovered colour) and channel c, w_kc = Qe_c(lambda) g_k(lambda), "
             "normalised; applied as the channel's mean OTF O_c (channel_wavelength_weights: w_c = Qe_c(lambda) * "
             "the photon rate averaged over the frame's pixels, normalised) on the whole channel plus the deviation "
             "OTF_kc - O_c in r_c radial components B_j (SVD over wavelength of OTF_lens - O_c weighted by each "
             "wavelength's largest w_kc; r_c the least with max_k |error of OTF_kc| <= "
             f"{OTF_TOLERANCE:g} at every frequency), each an FFT convolution of a per-pixel amplitude map "
             "e_kc sum_lambda w_kc a_j; applied to the expected electrons (reflected margin), after lateral CA "
             "(magnification about the centre, x 1/m^2) and vignetting, then clipped at 0 (negative_clipped_e per "
             "channel), before the noise")


def check_optics_scene(scene) -> None:
    """Refuse, before any work, what the optics cannot render (one line each)."""
    if scene.optics is None:
        return
    if scene.source.table == "raw":
        raise CamsimError("[optics] does not apply to a raw scene: its electrons were already formed by a lens")
    if scene.statistics != "pixel":
        raise CamsimError("[optics] draws pixel statistics (the frame is drawn per pixel after the optics); set "
                          "statistics = 'pixel'")


def mean_photon_rate(lit, counts=None) -> np.ndarray:
    """ḡ(λ): the photon rate averaged over the frame's pixels, shape (N,): each spectrum weighted by its pixel
    count (a factored image's coefficients averaged first, blockwise for a cube's file); ``counts``: the pixels of
    each spectrum, if already counted."""
    if counts is None:
        counts = np.bincount(lit.labels.ravel(), minlength=lit.photon_rate.shape[0])
    counts = np.asarray(counts, dtype=np.float64)
    counts /= counts.sum()
    rate = lit.photon_rate
    if isinstance(rate, np.ndarray):
        return counts @ rate
    coefficients = rate.coefficients
    if isinstance(coefficients, np.ndarray):
        return (counts @ np.asarray(coefficients, dtype=np.float64)) @ rate.basis
    mean = np.zeros(rate.basis.shape[0])
    for start, block in coefficients.blocks():
        mean += counts[start:start + block.shape[0]] @ block
    return mean @ rate.basis


def channel_weights(lit, counts=None) -> np.ndarray:
    """Each channel's weights over the lit scene's wavelengths (3, N):
    :func:`camsim.optics.stages.channel_wavelength_weights` of the frame's mean photon rate and the camera's Qe (the
    mean OTF's; ``counts``: the pixels of each spectrum, if already counted)."""
    from camsim.optics.stages import channel_wavelength_weights

    return channel_wavelength_weights(mean_photon_rate(lit, counts), lit.qe)


@dataclass(frozen=True, eq=False)
class SpectralOtf:
    """The per-spectrum part of a frame's OTFs (:mod:`camsim.optics.spectral`): per channel c, r_c radial components
    and their per-spectrum amplitudes, mapped to the pixels through the labels.

    Attributes
    ----------
    labels : numpy.ndarray, shape (H, W)
        Each pixel's spectrum (row of the amplitudes).
    components : tuple of numpy.ndarray
        Per channel, B_j(ρ) (r_c, M) at the radial samples of :func:`radial_samples`. Unitless.
    amplitudes : tuple of numpy.ndarray
        Per channel, (r_c, K) float32: e_kc Σ_λ w_kc(λ) a_j(λ), the amplitude of component j in a pixel of spectrum k.
        Unit: e⁻.
    bounds : tuple of float
        Per channel, the largest error of any spectrum's OTF at any frequency. Unitless.
    """

    labels: np.ndarray
    components: tuple
    amplitudes: tuple
    bounds: tuple

    @property
    def ranks(self) -> tuple[int, ...]:
        return tuple(int(c.shape[0]) for c in self.components)


def radial_samples() -> tuple[np.ndarray, float]:
    """The radial frequencies ρ (cy/px) of the lens OTF's table, 0 to past the grid's corner √0.5, and their step."""
    step = 1.0 / RADIAL_SAMPLES_PER_CY
    return np.arange(int(np.ceil(np.sqrt(0.5) / step)) + 2) * step, step


def _row_blocks(rate, rows: int = 65536):
    """(start, dense rows float64) of a (K, N) photon rate (an array or factored spectra), ``rows`` at a time."""
    for start in range(0, rate.shape[0], rows):
        yield start, np.asarray(rate[start:start + rows], dtype=np.float64)


def _extreme_weights(photon_rate, qe_c, spread, most: int) -> np.ndarray | None:
    """Normalised weights w_kc(λ) (V, N) of a few spectra whose convex hull holds every used spectrum's weights, or
    None where more than ``most`` would be needed: the bound max_ρ |Σ_λ w(λ) E(λ, ρ)| is convex in w, so its
    largest value over the spectra is at one of them. Dense spectra: all the used ones. An image's factored
    spectra (J ≤ 4 basis spectra): w_kc = x_k · (B_j Qe_c) with x_k = coefficients_k / Σ_λ g_k Qe_c on the
    hyperplane x · (B Qe_c) = 1: the vertices of their convex hull there (scipy's Qhull)."""
    from camsim.light.rates import FactoredSpectra

    index = np.nonzero(spread)[0]
    if (index.size > most and isinstance(photon_rate, FactoredSpectra)
            and isinstance(photon_rate.coefficients, np.ndarray) and 2 <= photon_rate.basis.shape[0] <= 4):
        from scipy.spatial import ConvexHull, QhullError

        per_basis = photon_rate.basis * qe_c  # (J, N)
        x = np.asarray(photon_rate.coefficients[index], dtype=np.float64) * spread[index, None]
        _, _, vt = np.linalg.svd(per_basis.sum(axis=1)[None])  # rows 1 … J − 1: the hyperplane's directions
        y = x @ vt[1:].T
        try:
            vertices = (ConvexHull(y).vertices if y.shape[1] > 1
                        else np.array([np.argmin(y[:, 0]), np.argmax(y[:, 0])]))
        except (QhullError, ValueError):  # degenerate (e.g. collinear colours): all of them, or the looser bound
            vertices = None
        if vertices is not None and vertices.size <= most:
            return x[vertices] @ per_basis
    if index.size > most:
        return None
    return np.asarray(photon_rate[index], dtype=np.float64) * qe_c * spread[index, None]


@dataclass(frozen=True, eq=False)
class SpectralBasis:
    """What of a frame's per-spectrum OTFs does not depend on its exposure (:func:`spectral_basis`): per channel c the
    components B_j (r_c, M), each spectrum's projections Σ_λ g_k(λ) Qe_c(λ) a_j(λ) (K, r_c) and the error bound, and
    Σ_λ g_k Qe_c (K, 3) of the used spectra (0 for the others). :meth:`otf` scales the projections by a frame's
    electrons into a :class:`SpectralOtf`."""

    components: tuple
    projections: tuple
    bounds: tuple
    totals: np.ndarray

    def otf(self, labels, signal_e) -> SpectralOtf:
        """The frame's :class:`SpectralOtf`: amplitudes e_kc Σ_λ w_kc a_j = projections_kc · e_kc / Σ_λ g_k Qe_c."""
        signal_e = np.asarray(signal_e, dtype=np.float64)
        amplitudes = []
        for c in range(3):
            total = self.totals[:, c]
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(total > 0, signal_e[:, c] / total, 0.0)  # e_kc / Σ_λ g_k Qe_c
            amplitudes.append((self.projections[c] * ratio[:, None]).T.astype(np.float32))
        return SpectralOtf(labels, self.components, tuple(amplitudes), self.bounds)


def spectral_otf(labels, photon_rate, qe, signal_e, weights, wavelengths_nm, optics: OpticsParams,
                 tolerance: float = OTF_TOLERANCE, counts=None) -> SpectralOtf:
    """Each spectrum's OTF per channel as the mean OTF's deviation in few components (:mod:`camsim.optics.spectral`):
    :func:`spectral_basis` scaled by the frame's electrons (:meth:`SpectralBasis.otf`).

    Parameters
    ----------
    labels : numpy.ndarray, shape (H, W)
        Each pixel's spectrum, 0 … K − 1.
    photon_rate : numpy.ndarray or FactoredSpectra, shape (K, N)
        g_k(λ), any unit (the weights are relative).
    qe : array_like, shape (3, N)
    signal_e : array_like, shape (K, 3)
        e_kc, the expected electrons of a pixel of spectrum k in channel c (∝ Σ_λ Qe_c g_k). Unit: e⁻.
    weights : array_like, shape (3, N)
        The frame's mean weights w_c(λ) (:func:`channel_weights`): the mean OTF's.
    wavelengths_nm : array_like, shape (N,)
    optics : OpticsParams
    tolerance : float
        The largest error left in any spectrum's OTF at any frequency.
    counts : array_like, shape (K,), optional
        The pixels of each spectrum (``np.bincount`` of the labels), if already counted.
    """
    count = np.shape(signal_e)[0]
    used = (np.bincount(labels.ravel(), minlength=count) if counts is None else np.asarray(counts)) > 0
    basis = spectral_basis(photon_rate, qe, used, weights, wavelengths_nm, optics, tolerance)
    return basis.otf(labels, signal_e)


def spectral_basis(photon_rate, qe, used, weights, wavelengths_nm, optics: OpticsParams,
                   tolerance: float = OTF_TOLERANCE) -> SpectralBasis:
    """:func:`spectral_otf`'s part that holds for every exposure of the lit scene: ``used`` (K,) bool, the spectra
    some pixel has; the other arguments as there."""
    from camsim.optics.spectral import EXACT_BOUND_SAMPLES, deviation_basis, residuals

    qe = np.asarray(qe, dtype=np.float64)
    used = np.asarray(used, dtype=bool)
    count = used.size
    if not optics.diffraction:  # the lens OTF is 1 at every wavelength: nothing depends on the spectrum
        return SpectralBasis((np.zeros((0, 1)),) * 3, (np.zeros((count, 0)),) * 3, (0.0, 0.0, 0.0),
                             np.zeros((count, 3)))
    totals = np.asarray(photon_rate @ qe.T, dtype=np.float64)  # (K, 3): Σ_λ g_k Qe_c
    envelope = np.zeros(qe.shape)
    for start, rows in _row_blocks(photon_rate):
        keep = used[start:start + rows.shape[0]]
        for c in range(3):
            total = totals[start:start + rows.shape[0], c]
            ok = keep & (total > 0)
            if ok.any():
                envelope[c] = np.maximum(envelope[c], (rows[ok] * qe[c] / total[ok, None]).max(axis=0))
    rho, _ = radial_samples()
    table = wavelength_otf_table(rho, wavelengths_nm, f_number=optics.f_number, pixel_pitch_um=optics.pixel_pitch_um,
                                 w020_waves_550=optics.w020_waves_550)  # (N, M): OTF(ρ; λ)
    means = np.asarray(weights, dtype=np.float64) @ table
    components, projections, bounds = [], [], []
    for c in range(3):
        spread = np.where(used & (totals[:, c] > 0), 1 / np.where(totals[:, c] > 0, totals[:, c], 1), 0.0)
        coefficients, basis = deviation_basis(table, means[c], envelope[c])
        rank, bound = basis.shape[0], 0.0
        dense = _extreme_weights(photon_rate, qe[c], spread, EXACT_BOUND_SAMPLES // rho.size)
        for r, residual in residuals(table, means[c], coefficients, basis):
            if dense is not None:  # max_k max_ρ |Σ_λ w_kc(λ) E_r(λ, ρ)|
                worst = max((float(np.abs(dense[i:i + 1024] @ residual).max()) for i in range(0, len(dense), 1024)),
                            default=0.0)
            else:  # max_k Σ_λ w_kc(λ) max_ρ |E_r(λ, ρ)|
                worst = float(np.max(np.asarray(photon_rate @ (qe[c] * np.abs(residual).max(axis=1))) * spread))
            if worst <= tolerance or r == basis.shape[0]:
                rank, bound = r, worst
                break
        components.append(basis[:rank])
        projections.append(np.asarray(photon_rate @ (qe[c][:, None] * coefficients[:, :rank])))
        bounds.append(bound)
    return SpectralBasis(tuple(components), tuple(projections), tuple(bounds),
                         np.where(used[:, None], totals, 0.0))


def optics_otfs(optics: OpticsParams, wavelengths_nm, weights, shape: tuple[int, int], xp=np) -> list:
    """The three channels' mean OTFs on the padded grid ``shape``, (shape[0], shape[1] // 2 + 1) float32 each, on
    ``xp``'s device."""
    rho, step = radial_samples()
    radial = lens_otf_radial(rho, wavelengths_nm, weights, f_number=optics.f_number,
                             pixel_pitch_um=optics.pixel_pitch_um, diffraction=optics.diffraction,
                             w020_waves_550=optics.w020_waves_550)
    return _grids(optics, radial, step, shape, xp)


#: A GPU's OTF grids of the last frames (key → grids): :data:`GRIDS_KEPT` of them (a frame's three channels; 25 MB a
#: grid of W1's padded size), so repeated frames of one light reuse them; none are kept on the CPU, whose memory a
#: frame's grids would grow by a quarter (issue 30's bound: 1.5 ×)
_DEVICE_GRIDS: dict = {}
GRIDS_KEPT = 3


def _grids(optics: OpticsParams, radial, step: float, shape: tuple[int, int], xp=np) -> list:
    from scipy import fft

    def made():
        return channel_otfs(radial, step, fft.fftfreq(shape[0]), fft.rfftfreq(shape[1]),
                            olpf_shift_px=optics.olpf_shift_px if optics.olpf else None,
                            fill_factor=optics.fill_factor if optics.fill_factor < 1 else None, xp=xp)

    if xp is np:
        return made()
    radial = np.ascontiguousarray(radial, dtype=np.float64)
    key = (xp, tuple(shape), step, optics.olpf, optics.olpf_shift_px, optics.fill_factor, radial.shape,
           radial.tobytes())
    return list(_kept(_DEVICE_GRIDS, key, GRIDS_KEPT, made))


def _kept(cache: dict, key, most: int, made, valid=lambda value: True):
    """``cache[key]``, made by ``made()`` where it is missing or not ``valid``; the entry moved to the end and the
    oldest beyond ``most`` dropped (a small LRU cache in a dict)."""
    value = cache.pop(key, None)
    if value is None or not valid(value):
        value = made()
    cache[key] = value
    while len(cache) > most:
        cache.pop(next(iter(cache)))
    return value


def apply_optics(signal_e, optics: OpticsParams, wavelengths_nm, weights, *, spectral: SpectralOtf | None = None,
                 workers: int | None = None, clip: dict | None = None) -> np.ndarray:
    """The expected electrons (3, H, W) after the optics (module docstring: lateral CA, vignetting, the PSF, the clip
    at 0).

    Parameters
    ----------
    signal_e : array, shape (3, H, W)
        S̄ per pixel and channel before the optics, on numpy or CuPy (the optics run on its device: the lateral
        CA's warp on the CPU, its planes copied there and back). Unit: e⁻.
    optics : OpticsParams
    wavelengths_nm : array_like, shape (N,)
    weights : array_like, shape (3, N)
        w_c(λ), each row summing to 1 (:func:`channel_weights`): the mean OTF of each channel.
    spectral : SpectralOtf, optional
        Each spectrum's deviation from the mean OTF (:func:`spectral_otf`; its labels on the signal's device or
        copied there); None: the mean OTF alone (exact where every pixel's light has one spectral shape per
        channel).
    workers : int, optional
        Threads of the FFTs and the warp (the result does not depend on them).
    clip : dict, optional
        Filled with the clip's record: ``negative_clipped_e`` (3 floats, e⁻ added per channel by clipping at 0) and
        ``negative_clipped_fraction`` (that over the channel's sum before the clip; 0 where the sum is 0).

    Returns
    -------
    array, shape (3, H, W), float32, ≥ 0, on the signal's device. Unit: e⁻.
    """
    from camsim.render.frame import default_workers

    workers = default_workers() if workers is None else workers
    xp = namespace_of(signal_e)
    out = xp.array(signal_e, dtype=xp.float32, copy=True)
    height, width = out.shape[1:]
    falloff = None
    if optics.vignetting != "none":
        theta = field_angle_rad(height, width, optics.pixel_pitch_um, optics.focal_length_mm)
        falloff = xp.asarray((cos4_falloff(theta) if optics.vignetting == "cos4" else table_falloff(
            theta, optics.relative_illumination)).astype(np.float32))

    def before_psf(plane, c):  # lateral CA, then vignetting, in place on one channel's (H, W) float32 plane
        m = optics.lateral_ca[c]
        if m != 1:  # the warp's kernel runs on the CPU
            from camsim.render.warp import average_warp

            inverse = magnification_inverse(m, height, width)[None, None]
            warped = average_warp(to_host(plane)[..., None], inverse, np.ones((1, 1)), workers=workers)[..., 0]
            np.multiply(warped, np.float32(1 / (m * m)), out=warped)
            plane[...] = xp.asarray(warped)
        if falloff is not None:
            plane *= falloff

    for c in range(3):
        before_psf(out[c], c)
    margin = min(margin_px(optics.f_number, optics.pixel_pitch_um, optics.w020_waves_550,
                           optics.olpf_shift_px if optics.olpf else 0.0), max(height, width))
    shape = padded_shape(height, width, margin)
    if spectral is None or not any(spectral.ranks):
        for c, otf in enumerate(optics_otfs(optics, wavelengths_nm, weights, shape, xp)):
            convolve_plane(out[c], otf, margin, shape, workers=workers, out=out[c])
        return _clipped(out, clip)
    rho, step = radial_samples()
    means = lens_otf_radial(rho, wavelengths_nm, weights, f_number=optics.f_number,
                            pixel_pitch_um=optics.pixel_pitch_um, diffraction=optics.diffraction,
                            w020_waves_550=optics.w020_waves_550)
    labels = xp.asarray(spectral.labels)
    for c in range(3):  # the mean OTF and the components on the grid, one channel at a time (memory)
        otf, *grids = _grids(optics, np.vstack([means[c:c + 1], spectral.components[c]]), step, shape, xp)
        if not grids:
            convolve_plane(out[c], otf, margin, shape, workers=workers, out=out[c])
            continue
        spectrum = padded_spectrum(out[c], margin, shape, workers=workers)
        spectrum *= otf
        del otf
        for j, grid in enumerate(grids):
            plane = xp.asarray(spectral.amplitudes[c][j])[labels]
            before_psf(plane, c)
            part = padded_spectrum(plane, margin, shape, workers=workers)
            del plane
            part *= grid
            spectrum += part
            del part
            grids[j] = None
        plane_of_spectrum(spectrum, margin, shape, (height, width), workers=workers, out=out[c])
    return _clipped(out, clip)


def _clipped(out: np.ndarray, clip: dict | None) -> np.ndarray:
    """``out`` clipped at 0 (:func:`camsim.optics.stages.clip_negative`), its record into ``clip``."""
    added = clip_negative(out)
    if clip is not None:
        # each plane's sum on its own (a GPU reduces a whole plane fast, three outputs of 12 M values each slowly)
        totals = np.array([float(plane.sum(dtype=np.float64)) for plane in out]) - added
        clip["negative_clipped_e"] = [float(v) for v in added]
        clip["negative_clipped_fraction"] = [float(a / t) if t > 0 else 0.0 for a, t in zip(added, totals)]
    return out


def otf_model(spectral: SpectralOtf | None) -> str:
    """The sidecar's ``otf_model``: :data:`OTF_MODEL` and the frame's ranks r_c and error bounds."""
    if spectral is None:
        return OTF_MODEL + "; this frame: the mean OTF alone (r = 0)"
    ranks = ", ".join(str(r) for r in spectral.ranks)
    bounds = ", ".join(f"{b:.2g}" for b in spectral.bounds)
    return OTF_MODEL + f"; this frame: r = ({ranks}) for R, G, B, error bounds ({bounds})"


def optics_record(optics: OpticsParams, wavelengths_nm, weights, spectral: SpectralOtf | None = None,
                  clip: dict | None = None) -> dict:
    """The sidecar's ``optics``: the table's keys, ``channel_wavelength_weights`` (the frame's mean), ``otf_model``
    (with the frame's ranks and bounds) and the clip's record (``apply_optics``'s ``clip``: ``negative_clipped_e``,
    ``negative_clipped_fraction``)."""
    return {**optics.record(),
            "channel_wavelength_weights": {"wavelength_nm": [float(v) for v in wavelengths_nm],
                                           "weights": np.asarray(weights, dtype=np.float64).tolist()},
            "otf_model": otf_model(spectral), **(clip or {})}


#: (id(lit scene), optics) → (a weak reference to the lit scene, its plan: weights and SpectralBasis): the last
#: :data:`PLANS_KEPT` plans, so a render's frames of one light (its F, a dataset's exposures) share them
_PLANS: dict = {}
PLANS_KEPT = 4


def optics_plan(lit, signal_e, optics: OpticsParams, labels=None) -> tuple[np.ndarray, SpectralOtf]:
    """What the OTFs of a frame depend on, made on the host: each channel's mean weights w_c(λ) (3, N)
    (:func:`channel_weights`) and the per-spectrum components (:func:`spectral_otf`) of the lit scene and its
    expected electrons per spectrum ``signal_e`` (K, 3). The part that holds for every exposure
    (:func:`spectral_basis`, the weights) is made once per lit scene and optics (kept for the last
    :data:`PLANS_KEPT`); ``labels``: the label map on a device, where its pixels are counted (a GPU counts 12 MP in
    well under a millisecond, numpy in about 60 ms)."""
    def made():
        on = lit.labels if labels is None else labels
        counts = np.asarray(to_host(namespace_of(on).bincount(on.ravel(), minlength=lit.photon_rate.shape[0])))
        weights = channel_weights(lit, counts)
        basis = spectral_basis(lit.photon_rate, lit.qe, counts > 0, weights, lit.grid.wavelengths_nm, optics)
        weights.flags.writeable = False
        return weakref.ref(lit), (weights, basis)

    _, (weights, basis) = _kept(_PLANS, (id(lit), optics), PLANS_KEPT, made, lambda kept: kept[0]() is lit)
    return weights, basis.otf(lit.labels, signal_e)


def optics_signal(lit, signal_e, optics: OpticsParams, *, static=None, labels=None, workers: int | None = None):
    """The lit scene's expected electrons through ``optics``, per spectrum: ``(signal (3, H, W) float32, record)``.
    ``signal_e`` (K, 3) per spectrum; ``static``: its (3, H, W) planes if already made
    (:func:`camsim.render.raw_frame.static_signal_e`); ``labels``: the label map on the device where the optics are to
    run (numpy or CuPy; default the lit scene's, on the CPU): the planes, the FFTs and the result are there, the
    plan (:func:`optics_plan`) on the host."""
    from camsim.render.raw_frame import static_signal_e

    weights, spectral = optics_plan(lit, signal_e, optics, labels)
    labels = lit.labels if labels is None else labels
    if labels is not lit.labels:
        spectral = dataclasses.replace(spectral, labels=labels)
    if static is None:
        static = static_signal_e(labels, signal_e)
    clip = {}
    wavelengths = lit.grid.wavelengths_nm
    signal = apply_optics(static, optics, wavelengths, weights, spectral=spectral, workers=workers, clip=clip)
    return signal, optics_record(optics, wavelengths, weights, spectral, clip)


def optics_frame_xp(xp, lit, expected, sensor, optics: OpticsParams, *, rng, labels=None):
    """One frame of ``lit`` through ``optics`` on ``xp``'s device (numpy or CuPy): the optics on the device
    (:func:`optics_signal`), then every pixel drawn from its own mean by the array path
    (:func:`camsim.render.backends.array_path.render_frame_xp` with ``signal_e``). Returns ``(DeviceFrame, signal
    (3, H, W) float32 on the device, record)``; ``labels``: the label map already on the device, if it is."""
    from camsim.render.backends.array_path import render_frame_xp

    labels = xp.asarray(lit.labels) if labels is None else labels
    signal, record = optics_signal(lit, expected.signal_e, optics, labels=labels)
    drawn = render_frame_xp(xp, labels, expected, sensor, rng=rng, signal_e=signal)
    return drawn, signal, record


def optics_frame(lit, sensor, intensity_factor: float, optics: OpticsParams, *, rng, workers: int | None = None,
                 device: str = "cpu"):
    """One frame of ``lit`` through ``optics``, drawn per pixel: ``(frame, record)``, a
    :class:`camsim.render.raw_frame.ExpectationFrame` (its clean layer per pixel) and the sidecar's ``optics``.

    ``device``: ``cpu`` (the block renderer's draws, :func:`camsim.render.raw_frame.render_expectation_frame`) or
    ``cuda`` / ``numpy`` (:func:`optics_frame_xp`; the pixels copied to the host); the clean layer on the CPU,
    :func:`camsim.render.raw_frame.expectation_clean_dn` of the expectation either way."""
    from camsim.render.raw_frame import ExpectationFrame, expectation_clean_dn, render_expectation_frame
    from camsim.sensor.cfa import mosaic_of

    expected = lit.expected(sensor, intensity_factor, "pixel")
    if device != "cpu":
        from camsim.render.backends import array_module
        from camsim.sensor.fixed_pattern import fixed_pattern

        drawn, signal, record = optics_frame_xp(array_module(device), lit, expected, sensor, optics, rng=rng)
        maps = fixed_pattern(sensor, lit.labels.shape)
        clean = expectation_clean_dn(to_host(signal), sensor, maps, workers)
        return ExpectationFrame(to_host(drawn.noisy_dn), to_host(drawn.digital_dn), lit.labels, expected, sensor,
                                None, maps, drawn.black_level_error_dn, clean), record
    signal, record = optics_signal(lit, expected.signal_e, optics, workers=workers)
    source = signal if sensor.cfa is None else mosaic_of(signal, sensor.cfa)[None]
    draw = render_expectation_frame(source, sensor, rng=rng, workers=workers)
    del source
    clean = draw.clean_dn if sensor.cfa is None else expectation_clean_dn(signal, sensor, draw.maps, workers)
    frame = ExpectationFrame(draw.noisy_dn, draw.digital_dn, lit.labels, expected, sensor, None, draw.maps,
                          draw.black_level_error_dn, clean)
    return frame, record
