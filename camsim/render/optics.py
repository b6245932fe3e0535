"""A frame through the optics (issue 30): the scene's ``[optics]`` applied to the expected electrons, then the noise.

The scene's expected signal electrons per pixel and channel S̄ (3, H, W) are gathered through the label map
(:func:`camsim.render.raw_frame.static_signal_e`), the optics' stages (:mod:`camsim.optics.stages`) are applied to
them in the order light meets them:

1. lateral chromatic aberration: channel c's image magnified by m_c about the frame's centre (bilinear, clamped at
   the edges: :func:`camsim.render.warp.average_warp` with one inverse homography), its values × 1/m_c² so that the
   light is redistributed, not created (exact for content that stays within the frame);
2. vignetting: × cos⁴ of each pixel's field angle (or the table's relative illumination), 1 at the centre;
3. the PSF: per channel, FFT convolution with OTF_c = Σ_λ w_c(λ) OTF_lens(λ) × OLPF × pixel aperture
   (:func:`camsim.optics.stages.convolve_plane`: real FFTs in float32, the frame extended by reflection about its
   edge by a margin (:func:`camsim.optics.stages.margin_px`, at most the frame's larger side), so a uniform field
   stays uniform and nothing wraps around). The pixel aperture is relative to the source's full-pixel sampling,
   sinc(√ff f) / sinc(f) per axis (:func:`camsim.optics.stages.pixel_aperture_otf`: none at ff = 1, a gain of up
   to π/2 at Nyquist as ff → 0);
4. the clip at 0 (:func:`camsim.optics.stages.clip_negative`): where that gain makes a sharp edge ring below 0; the
   electrons it added per channel are recorded (``negative_clipped_e``, and as a fraction of the channel's sum,
   ``negative_clipped_fraction``).

w_c(λ) are the weights over wavelength of the signal channel c receives, averaged over the frame's pixels (each
spectrum of a chart or target weighted by its pixel count; an image's or a cube's recovered spectra, per pixel, the
same way): one PSF per channel (the colour-edge approximation: :mod:`camsim.optics.stages`). The frame is then
drawn per pixel from that expectation (:func:`camsim.render.raw_frame.render_expectation_frame`: Poisson(S̄·g +
D̄·d) and every later stage of the sensor), so the noise stays exact; the sidecar records ``method = "poisson"``
and ``optics``: the table, ``channel_wavelength_weights``, ``otf_model`` and the clip's ``negative_clipped_e`` and
``negative_clipped_fraction``. The EXR's clean layer is the
expectation after the optics (:func:`camsim.render.raw_frame.expectation_clean_dn`). Pixel statistics only.
"""

from __future__ import annotations

import numpy as np

from camsim.core.errors import CamsimError
from camsim.optics.params import OpticsParams
from camsim.optics.stages import (
    RADIAL_SAMPLES_PER_CY,
    channel_otfs,
    clip_negative,
    cos4_falloff,
    convolve_plane,
    field_angle_rad,
    lens_otf_radial,
    magnification_inverse,
    margin_px,
    padded_shape,
    table_falloff,
)

#: The sidecar's one-line statement of the OTF applied (the model MTF of the analysis is its magnitude with the
#: source's full-pixel box replaced by the aperture's: a total pixel factor sinc(sqrt(ff) f) per axis).
OTF_MODEL = ("OTF_c(fx, fy) = [sum_lambda w_c(lambda) * OTF_lens(rho / f_c(lambda); W020(lambda))] * "
             "cos(pi fx s) cos(pi fy s) [olpf] * [sinc(sqrt(ff) fx) / sinc(fx)] [sinc(sqrt(ff) fy) / sinc(fy)] "
             "[ff = fill_factor < 1: the pixel aperture relative to the source's full-pixel area sampling, so the "
             "frame's total pixel factor is sinc(sqrt(ff) f) per axis; none at ff = 1], "
             "rho = sqrt(fx^2 + fy^2) cy/px, f_c = pixel_pitch_um / (lambda_um f_number); OTF_lens = (2/pi)(acos nu "
             "- nu sqrt(1 - nu^2)) [diffraction], with defocus the exact pupil autocorrelation with the W020 phase "
             "(Hopkins 1955, W020(lambda) = W020_550 * 0.55 / lambda_um waves), 1 without diffraction; w_c = "
             "Qe_c(lambda) * mean photon rate over the frame's pixels, normalised; applied by FFT to the expected "
             "electrons (reflected margin), after lateral CA (magnification about the centre, x 1/m^2) and "
             "vignetting, then clipped at 0 (negative_clipped_e per channel), before the noise")


def check_optics_scene(scene) -> None:
    """Refuse, before any work, what the optics cannot render (one line each)."""
    if scene.optics is None:
        return
    if scene.source.table == "raw":
        raise CamsimError("[optics] does not apply to a raw scene: its electrons were already formed by a lens")
    if scene.statistics != "pixel":
        raise CamsimError("[optics] draws pixel statistics (the frame is drawn per pixel after the optics); set "
                          "statistics = 'pixel'")


def mean_photon_rate(lit) -> np.ndarray:
    """ḡ(λ): the photon rate averaged over the frame's pixels, shape (N,): each spectrum weighted by its pixel
    count (a factored image's coefficients averaged first, blockwise for a cube's file)."""
    counts = np.bincount(lit.labels.ravel(), minlength=lit.photon_rate.shape[0]).astype(np.float64)
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


def channel_weights(lit) -> np.ndarray:
    """Each channel's weights over the lit scene's wavelengths (3, N): :func:`camsim.optics.stages.channel_wavelength_weights`
    of the frame's mean photon rate and the camera's Qe."""
    from camsim.optics.stages import channel_wavelength_weights

    return channel_wavelength_weights(mean_photon_rate(lit), lit.qe)


def optics_otfs(optics: OpticsParams, wavelengths_nm, weights, shape: tuple[int, int]) -> list[np.ndarray]:
    """The three channels' OTFs on the padded grid ``shape``, (shape[0], shape[1] // 2 + 1) float32 each."""
    from scipy import fft

    fy = fft.fftfreq(shape[0])
    fx = fft.rfftfreq(shape[1])
    step = 1.0 / RADIAL_SAMPLES_PER_CY
    rho = np.arange(int(np.ceil(np.sqrt(0.5) / step)) + 2) * step
    radial = lens_otf_radial(rho, wavelengths_nm, weights, f_number=optics.f_number,
                             pixel_pitch_um=optics.pixel_pitch_um, diffraction=optics.diffraction,
                             w020_waves_550=optics.w020_waves_550)
    return channel_otfs(radial, step, fy, fx, olpf_shift_px=optics.olpf_shift_px if optics.olpf else None,
                        fill_factor=optics.fill_factor if optics.fill_factor < 1 else None)


def apply_optics(signal_e, optics: OpticsParams, wavelengths_nm, weights, *, workers: int | None = None,
                 clip: dict | None = None) -> np.ndarray:
    """The expected electrons (3, H, W) after the optics (module docstring: lateral CA, vignetting, the PSF, the clip
    at 0).

    Parameters
    ----------
    signal_e : numpy.ndarray, shape (3, H, W)
        S̄ per pixel and channel before the optics. Unit: e⁻.
    optics : OpticsParams
    wavelengths_nm : array_like, shape (N,)
    weights : array_like, shape (3, N)
        w_c(λ), each row summing to 1 (:func:`channel_weights`).
    workers : int, optional
        Threads of the FFTs and the warp (the result does not depend on them).
    clip : dict, optional
        Filled with the clip's record: ``negative_clipped_e`` (3 floats, e⁻ added per channel by clipping at 0) and
        ``negative_clipped_fraction`` (that over the channel's sum before the clip; 0 where the sum is 0).

    Returns
    -------
    numpy.ndarray, shape (3, H, W), float32, ≥ 0. Unit: e⁻.
    """
    from camsim.render.frame import default_workers

    workers = default_workers() if workers is None else workers
    out = np.array(signal_e, dtype=np.float32, copy=True)
    height, width = out.shape[1:]
    if any(m != 1 for m in optics.lateral_ca):
        from camsim.render.warp import average_warp

        for c, m in enumerate(optics.lateral_ca):
            if m == 1:
                continue
            inverse = magnification_inverse(m, height, width)[None, None]
            warped = average_warp(out[c][..., None], inverse, np.ones((1, 1)), workers=workers)[..., 0]
            np.multiply(warped, np.float32(1 / (m * m)), out=out[c])
    if optics.vignetting != "none":
        theta = field_angle_rad(height, width, optics.pixel_pitch_um, optics.focal_length_mm)
        falloff = cos4_falloff(theta) if optics.vignetting == "cos4" else table_falloff(
            theta, optics.relative_illumination)
        out *= falloff.astype(np.float32)[None]
    margin = min(margin_px(optics.f_number, optics.pixel_pitch_um, optics.w020_waves_550,
                           optics.olpf_shift_px if optics.olpf else 0.0), max(height, width))
    shape = padded_shape(height, width, margin)
    for c, otf in enumerate(optics_otfs(optics, wavelengths_nm, weights, shape)):
        convolve_plane(out[c], otf, margin, shape, workers=workers, out=out[c])
    added = clip_negative(out)
    if clip is not None:
        totals = out.sum(axis=(1, 2), dtype=np.float64) - added
        clip["negative_clipped_e"] = [float(v) for v in added]
        clip["negative_clipped_fraction"] = [float(a / t) if t > 0 else 0.0 for a, t in zip(added, totals)]
    return out


def optics_record(optics: OpticsParams, wavelengths_nm, weights, clip: dict | None = None) -> dict:
    """The sidecar's ``optics``: the table's keys, ``channel_wavelength_weights``, ``otf_model`` and the clip's
    record (``apply_optics``'s ``clip``: ``negative_clipped_e``, ``negative_clipped_fraction``)."""
    return {**optics.record(),
            "channel_wavelength_weights": {"wavelength_nm": [float(v) for v in wavelengths_nm],
                                           "weights": np.asarray(weights, dtype=np.float64).tolist()},
            "otf_model": OTF_MODEL, **(clip or {})}


def optics_frame(lit, sensor, intensity_factor: float, optics: OpticsParams, *, rng, workers: int | None = None):
    """One frame of ``lit`` through ``optics``, drawn per pixel: ``(frame, record)``, a
    :class:`camsim.render.raw_frame.ExpectationFrame` (its clean layer per pixel) and the sidecar's ``optics``."""
    from camsim.render.raw_frame import ExpectationFrame, expectation_clean_dn, render_expectation_frame, static_signal_e
    from camsim.sensor.cfa import mosaic_of

    expected = lit.expected(sensor, intensity_factor, "pixel")
    weights = channel_weights(lit)
    wavelengths = lit.grid.wavelengths_nm
    clip = {}
    signal = apply_optics(static_signal_e(lit.labels, expected.signal_e), optics, wavelengths, weights,
                          workers=workers, clip=clip)
    source = signal if sensor.cfa is None else mosaic_of(signal, sensor.cfa)[None]
    draw = render_expectation_frame(source, sensor, rng=rng, workers=workers)
    del source
    clean = draw.clean_dn if sensor.cfa is None else expectation_clean_dn(signal, sensor, draw.maps, workers)
    frame = ExpectationFrame(draw.noisy_dn, draw.digital_dn, lit.labels, expected, sensor, None, draw.maps,
                          draw.black_level_error_dn, clean)
    return frame, optics_record(optics, wavelengths, weights, clip)
