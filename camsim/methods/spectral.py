"""``spectral``: per-wavelength-bin draws (cost ∝ N bins), then the readout stages in sequence on electrons.

``paper`` statistics: Poisson(F g(λi)) photons / (s m² sr) per bin, shared by the three channels and weighted by
T · Qe (Eq. 4 literally, so the channels are correlated as the paper's model says). ``pixel`` statistics:
per-bin detected electrons Poisson(T F g Qe) per channel, summed: equal in distribution to ``poisson``, a live
check of the thinning argument. Dark current is added as Poisson(D̄), or Poisson(D̄ d) per pixel with the
dark-current DSNU map d; with photon noise off the charge is S̄ plus that dark draw. Then saturation, read noise,
row noise, gain and the ADC (:mod:`camsim.sensor.stages`), plane by plane.
Where the full well acts, a spectrum far above it has its per-bin means scaled down to the saturation cap of
:func:`camsim.sensor.stages.cap_mean_e` (:func:`bin_scale`), and the dark mean is capped alike.
"""

from __future__ import annotations

import numpy as np

from camsim.sensor.cfa import cfa_sites
from camsim.sensor.expected import ExpectedSignal
from camsim.sensor.kernels import label_runs, poisson
from camsim.sensor.params import SensorParams
from camsim.sensor.stages import (
    add_black_level_error_dn,
    add_read_noise_e,
    add_row_noise,
    cap_mean_e,
    collect_charge_e,
    draw_read_noise_e,
    electrons_to_dn,
    quantise_dn,
    saturate_e,
    saturation_level_e,
)


def draw_bins(labels, expected: ExpectedSignal, sensor: SensorParams, statistics: str, rng, out,
              saturation_e: float | None = None, dark_gain=None, dark: bool = True):
    """Fill ``out`` (3, h, w) float32 with the collected charge S + D of every pixel, by per-bin draws. Unit: e⁻.

    ``saturation_e``: with a full well, the charge at and above which every pixel is saturated (the full well
    minus the most negative DSNU offset); a spectrum whose mean charge is far above it has its bins' means scaled
    down to the saturation cap (:func:`camsim.sensor.stages.cap_mean_e`, :func:`bin_scale`), and the dark mean is
    capped. ``dark_gain``: the dark-current DSNU map d of these pixels, (3, h, w), or None: the dark charge is then
    Poisson(D̄ d), one draw per pixel and channel.
    ``dark`` False: the signal S alone (``auto``'s Eq. 4 path adds the dark charge itself, per channel).
    """
    if not sensor.photon_noise:
        return _draw_without_photon_noise(labels, expected, sensor, statistics, rng, out, saturation_e, dark_gain)
    T = sensor.exposure_s
    rate = expected.photon_rate
    qe = expected.qe
    scale = None if saturation_e is None else bin_scale(expected, statistics, saturation_e)
    n_bins = rate.shape[1]
    flat = labels.ravel()
    out_flat = [out[c].reshape(-1) for c in range(3)]  # rows of a C-contiguous plane: views, not copies
    assert all(np.shares_memory(flat_c, out) for flat_c in out_flat)
    chunk = max(1, 2**19 // (3 * n_bins))
    for start in range(0, flat.size, chunk):
        lab = flat[start : start + chunk]
        bins = rate[lab]  # (m, N): F g per pixel
        if statistics == "paper":
            if scale is not None:
                bins = bins * scale[lab][:, None]
            counts = poisson(rng, bins)  # photons / (s m² sr), shared by the three channels
            signal = T * (counts @ qe.T)  # (m, 3)
        else:
            lam = (T * bins)[:, None, :] * qe[None, :, :]  # (m, 3, N) detected electrons per bin
            if scale is not None:
                lam *= scale[lab][:, :, None]
            signal = poisson(rng, lam).sum(axis=2)
        for c in range(3):
            out_flat[c][start : start + chunk] = signal[:, c]
    for c in range(3) if dark else ():
        dark_mean = expected.dark_e[c]
        if not dark_mean > 0:
            continue
        mean = dark_mean if dark_gain is None else dark_mean * dark_gain[c]
        mean = mean if saturation_e is None else cap_mean_e(mean, saturation_e)
        out[c] += poisson(rng, mean, size=out[c].shape)
    return out


def bin_scale(expected: ExpectedSignal, statistics: str, saturation_e: float):
    """Factors ≤ 1 on the per-bin means of each spectrum that put its mean charge at the saturation cap, or None.

    ``pixel`` statistics, shape (K, 3): channel κ's bins draw independent Poisson counts whose sum is
    Poisson(S̄_κ); scaling them by α_κ = cap / S̄_κ makes it Poisson(cap) exactly, the ``poisson`` method's capped
    law (:func:`camsim.sensor.stages.cap_mean_e`). ``paper`` statistics, shape (K,): the bins' photon counts are shared
    by the channels, so one factor per spectrum, α = max over channels (with S̄_κ > 0) of cap_κ / S̄_κ, where
    cap_κ = min(S̄_κ, M(L, s_κ)) with s_κ = Var S_κ / S̄_κ (unchanged by the scaling): every channel then keeps a mean
    of at least its M, or its own, so each saturates or is drawn as before, and the law of each channel's
    saturated value moves by at most ε in total variation. None: no spectrum reaches the cap.
    """
    signal = expected.signal_e
    with np.errstate(divide="ignore", invalid="ignore"):
        if statistics == "paper":
            step = np.where(signal > 0, expected.signal_var_e2 / signal, 0.0)
            ratio = np.where(signal > 0, cap_mean_e(signal, saturation_e, step) / signal, 0.0)
            scale = np.where(np.any(signal > 0, axis=1), ratio.max(axis=1), 1.0)
        else:
            scale = np.where(signal > 0, cap_mean_e(signal, saturation_e) / signal, 1.0)
    return None if np.all(scale >= 1) else np.minimum(scale, 1.0)


def _draw_without_photon_noise(labels, expected: ExpectedSignal, sensor: SensorParams, statistics: str, rng, out,
                               saturation_e: float | None = None, dark_gain=None):
    """S̄ plus Poisson(D̄) (or Poisson(D̄ d)) per pixel and channel (nothing to draw per bin), rectangle by
    rectangle."""
    runs = label_runs(labels)
    for c in range(3):
        def charge(index, size=None, where=(slice(None),)):
            return collect_charge_e(rng, expected.signal_e[index, c], expected.dark_e[c],
                                    expected.signal_var_e2[index, c], statistics=statistics,
                                    photon_noise=sensor.photon_noise, size=size, saturation_e=saturation_e,
                                    dark_gain=None if dark_gain is None else dark_gain[c][where])

        if runs is None:
            out[c][...] = charge(labels)
            continue
        for r0, r1, c0, c1, label in runs:
            out[c][r0:r1, c0:c1] = charge(label, (r1 - r0, c1 - c0), (slice(r0, r1), slice(c0, c1)))
    return out


def draw_block(job, r0: int, r1: int, rng: np.random.Generator, scratch) -> None:
    """Rows ``r0:r1`` of a frame: per-bin charge of the three channels (a CFA keeps each site's own) with the dark
    charge (per pixel with the dark-current DSNU), the offset DSNU, then saturation, read noise, row noise, gain and
    the ADC on each plane."""
    sensor = job.sensor
    block = job.noisy[:, r0:r1]
    offset, _, dark_gain = job.maps_rows(r0, r1)
    level = saturation_level_e(sensor.full_well_e, offset) if sensor.saturation else None
    if sensor.cfa is None:
        draw_bins(job.labels[r0:r1], job.expected, sensor, job.statistics, rng, block, level, dark_gain)
        if offset is not None:
            block += offset
    else:
        rgb = np.empty((3, r1 - r0, block.shape[2]), dtype=np.float32)
        draw_bins(job.labels[r0:r1], job.expected, sensor, job.statistics, rng, rgb, level, dark_gain)
        for dy, dx, c in cfa_sites(sensor.cfa):
            site = (slice(dy, None, 2), slice(dx, None, 2))
            block[0][site] = rgb[c][site]
            if offset is not None:
                block[0][site] += offset[c][site]
    read = sensor.read_noise and sensor.read_noise_e > 0
    for p in range(block.shape[0]):
        e = block[p]
        if sensor.saturation:
            saturate_e(e, sensor.full_well_e, out=e)
        if read:
            noise = draw_read_noise_e(rng, scratch.plane[: r1 - r0], sensor.read_noise_e, sensor.read_noise_model,
                                      sensor.tukey_lambda, scratch.work)
            add_read_noise_e(e, noise, out=e)
        if sensor.row_noise_e > 0:
            add_row_noise(e, sensor.row_noise_e, rng)
        electrons_to_dn(e, sensor.dn_per_electron, out=e)
        if job.black_level_error_dn is not None:
            add_black_level_error_dn(e, job.black_level_error_dn, sensor.cfa, p)
        if job.digital is not None:
            quantise_dn(e, sensor.bits, out=job.digital[p, r0:r1], pedestal_dn=sensor.pedestal_dn)
