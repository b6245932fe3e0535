"""Drawing the collected charge S + D per pixel and channel (MODEL.md §4–5).

One function per sampling method, a registry :data:`METHODS`, and one entry point :func:`draw_electrons`.
Each method takes a block of the label map and fills a float32 (3, h, w) array with electrons (signal plus
dark, before saturation), for either photon statistics:

* ``poisson`` — one draw per pixel and channel. ``pixel`` statistics: S + D ~ Poisson(S̄ + D̄), exact by Poisson
  thinning and additivity (one draw covers photons *and* dark current). ``paper`` statistics: S is drawn as a
  scaled Poisson s · Poisson(S̄ / s) with s = Var S / S̄, which matches the mean and variance of Eq. 4 for every
  channel (but not the cross-channel correlation of the shared per-bin photon counts), plus D ~ Poisson(D̄).
* ``spectral`` — per-bin draws, cost ∝ N. ``paper``: Poisson(F g(λi)) photons / (s m² sr) per bin, shared by the
  three channels and weighted by T · Qe (Eq. 4 literally). ``pixel``: per-bin detected electrons
  Poisson(T F g Qe) per channel, summed (a live check of the thinning argument).
"""

from __future__ import annotations

import numpy as np

from camsim.errors import CamsimError
from camsim.expected import ExpectedSignal
from camsim.sensor import SensorParams

#: numpy's Poisson sampler refuses means above about 9.2e18; beyond this the Poisson law is a Gaussian to
#: within a relative skew of 1e-9, and a rounded normal draw is used.
POISSON_LAM_MAX = 1e18


def poisson(rng: np.random.Generator, lam, size=None) -> np.ndarray:
    """Poisson draws that also accept means beyond numpy's limit (rounded Gaussian there).

    Unit: counts (int64, or float64 when a mean exceeds :data:`POISSON_LAM_MAX`).
    """
    lam = np.asarray(lam, dtype=np.float64)
    if lam.size == 0 or lam.max() <= POISSON_LAM_MAX:
        return rng.poisson(lam, size=size)
    shape = size if size is not None else lam.shape
    lam = np.broadcast_to(lam, shape)
    big = lam > POISSON_LAM_MAX
    out = np.empty(shape, dtype=np.float64)
    out[~big] = rng.poisson(lam[~big])
    out[big] = np.rint(rng.normal(lam[big], np.sqrt(lam[big])))
    return out


def _dark(rng, out_c, dark_c: float):
    """Add D ~ Poisson(D̄) to one channel in place."""
    if dark_c > 0:
        out_c += rng.poisson(dark_c, size=out_c.shape)


def draw_poisson(labels, expected: ExpectedSignal, sensor: SensorParams, statistics: str, rng, out):
    """One draw per pixel and channel (plus one for dark current under ``paper`` statistics)."""
    S = expected.signal_e
    dark = expected.dark_e
    for c in range(3):
        out_c = out[c]
        if not sensor.photon_noise:
            out_c[...] = S[:, c].astype(np.float32)[labels]
            _dark(rng, out_c, dark[c])
        elif statistics == "pixel":
            out_c[...] = poisson(rng, (S[:, c] + dark[c])[labels])
        else:
            var = expected.signal_var_e2[:, c]
            with np.errstate(divide="ignore", invalid="ignore"):
                step = np.where(S[:, c] > 0, var / S[:, c], 0.0)
                lam = np.where(step > 0, S[:, c] / step, 0.0)
            out_c[...] = step[labels] * poisson(rng, lam[labels])
            _dark(rng, out_c, dark[c])
    return out


def draw_spectral(labels, expected: ExpectedSignal, sensor: SensorParams, statistics: str, rng, out):
    """Per-bin draws for every pixel (cost ∝ number of bins)."""
    if not sensor.photon_noise:
        return draw_poisson(labels, expected, sensor, statistics, rng, out)
    T = sensor.exposure_s
    rate = expected.photon_rate
    qe = expected.qe
    n_bins = rate.shape[1]
    flat = labels.ravel()
    out_flat = out.reshape(3, -1)
    chunk = max(1, 2**19 // (3 * n_bins))
    for start in range(0, flat.size, chunk):
        lab = flat[start : start + chunk]
        bins = rate[lab]  # (m, N): F g per pixel
        if statistics == "paper":
            counts = poisson(rng, bins)  # photons / (s m² sr), shared by the three channels
            signal = T * (counts @ qe.T)  # (m, 3)
        else:
            lam = (T * bins)[:, None, :] * qe[None, :, :]  # (m, 3, N) detected electrons per bin
            signal = poisson(rng, lam).sum(axis=2)
        out_flat[:, start : start + chunk] = signal.T
    for c in range(3):
        _dark(rng, out[c], expected.dark_e[c])
    return out


#: Sampling methods by name.
METHODS = {"poisson": draw_poisson, "spectral": draw_spectral}


def draw_electrons(labels, expected, sensor, statistics, method, rng, out):
    """Fill ``out`` with the collected charge S + D of each pixel and channel.

    Parameters
    ----------
    labels : numpy.ndarray, shape (h, w), unsigned integer
        Spectrum index per pixel.
    expected : ExpectedSignal
    sensor : SensorParams
    statistics : {'pixel', 'paper'}
    method : str
        A key of :data:`METHODS`.
    rng : numpy.random.Generator
    out : numpy.ndarray, shape (3, h, w), float32
        Filled in place. Unit: e⁻.
    """
    if method not in METHODS:
        raise CamsimError(f"unknown sampling method {method!r}; methods: {', '.join(METHODS)}")
    return METHODS[method](labels, expected, sensor, statistics, rng, out)
