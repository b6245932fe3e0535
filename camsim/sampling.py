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

from functools import lru_cache

import numpy as np
from scipy import stats

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


#: Runs of at least this many pixels per value of the Poisson law's support use the histogram sampler.
HISTOGRAM_MIN_PIXELS_PER_VALUE = 4
#: Largest mean for the histogram sampler (its support is λ ± 13 √λ; float32 holds its integers exactly).
HISTOGRAM_MAX_LAMBDA = 1e6


@lru_cache(maxsize=4096)
def _poisson_support(lam: float):
    """Values λ ± (13 √λ + 20), clipped at 0, as float32, and their Poisson probabilities (normalised)."""
    half = 13.0 * np.sqrt(lam) + 20.0
    values = np.arange(max(0, int(np.floor(lam - half))), int(np.ceil(lam + half)) + 1)
    pmf = stats.poisson.pmf(values, lam)
    return values.astype(np.float32), pmf / pmf.sum()


def poisson_run(rng: np.random.Generator, lam: float, shape) -> np.ndarray:
    """``shape`` independent Poisson(λ) draws for one mean, exactly, about twice as fast as numpy's sampler.

    n iid draws are their histogram — Multinomial(n, pmf) — in a uniformly random order; so the run draws the
    histogram over the support λ ± (13 √λ + 20) (the tails beyond hold < 1e-38), repeats the values and shuffles
    them. Short runs (fewer than :data:`HISTOGRAM_MIN_PIXELS_PER_VALUE` pixels per support value) and huge means
    use numpy's Poisson sampler.

    Returns
    -------
    numpy.ndarray of ``shape``, float32 (histogram sampler) or int64 (numpy's sampler). Unit: counts.
    """
    n = int(np.prod(shape))
    if not 0 < lam <= HISTOGRAM_MAX_LAMBDA or n < HISTOGRAM_MIN_PIXELS_PER_VALUE * (26 * np.sqrt(lam) + 41):
        return poisson(rng, lam, size=shape)
    values, pmf = _poisson_support(float(lam))
    draws = np.repeat(values, rng.multinomial(n, pmf))
    rng.shuffle(draws)
    return draws.reshape(shape)


def standard_normal_f32(rng: np.random.Generator, out: np.ndarray, work: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """Fill ``out`` (C-contiguous float32) with standard normal draws: Box–Muller on float32 uniforms.

    Exact transform of uniforms u1, u2 (multiples of 2^-24): z = √(−2 ln(1 − u1)) · (sin, cos)(2π u2), each pair
    giving two independent normals. Three times faster than numpy's float32 ziggurat here (vectorised log, sqrt,
    sin, cos); the one price is that |z| ≤ √(48 ln 2) = 5.77, a tail of probability 8e-9 (0.3 expected samples
    in a whole 12-megapixel three-channel frame).

    Parameters
    ----------
    out : numpy.ndarray, float32, C-contiguous
        Filled in place.
    work : numpy.ndarray, float32, at least ``out.size // 2`` elements
        Scratch space.
    scale : float
        Standard deviation of the draws (folded into the radius: no extra pass over ``out``).
    """
    flat = out.reshape(-1)
    if not np.shares_memory(flat, out):
        raise ValueError("standard_normal_f32 needs a C-contiguous output array")
    half = flat.size // 2
    rng.random(out=flat, dtype=np.float32)
    u1, u2, radius = flat[:half], flat[half : 2 * half], work[:half]
    np.subtract(np.float32(1.0), u1, out=radius)  # in (0, 1]: the logarithm stays finite
    np.log(radius, out=radius)
    radius *= np.float32(-2.0 * scale * scale)
    np.sqrt(radius, out=radius)
    u2 *= np.float32(2.0 * np.pi)
    np.sin(u2, out=u1)
    u1 *= radius
    np.cos(u2, out=u2)
    u2 *= radius
    if flat.size % 2:
        flat[-1] = scale * rng.standard_normal(dtype=np.float32)
    return out


#: Below this mean number of pixels per run of equal labels, the label map is drawn pixel by pixel (a gather
#: of per-pixel means); at or above it, run by run with one scalar mean per run.
MIN_PIXELS_PER_RUN = 64


def label_runs(labels: np.ndarray):
    """Rectangles of equal label covering a block: ``[(r0, r1, c0, c1, label), ...]``, or None if fragmented.

    Consecutive identical rows form a band; each band is split into runs of equal label. A chart block is a few
    bands of ~13 runs, so its noise can be drawn with one scalar Poisson mean per rectangle — faster than
    numpy's per-element means and with no per-pixel mean array at all. A cube (every pixel its own label) gives
    None, and is drawn pixel by pixel.
    """
    height, width = labels.shape
    budget = labels.size / MIN_PIXELS_PER_RUN  # most runs allowed
    changes = np.flatnonzero(np.any(labels[1:] != labels[:-1], axis=1)) + 1
    if changes.size + 1 > budget:
        return None
    bands = np.concatenate(([0], changes, [height]))
    runs = []
    for r0, r1 in zip(bands[:-1], bands[1:]):
        row = labels[r0]
        edges = np.concatenate(([0], np.flatnonzero(row[1:] != row[:-1]) + 1, [width]))
        runs.extend((int(r0), int(r1), int(c0), int(c1), int(row[c0])) for c0, c1 in zip(edges[:-1], edges[1:]))
        if len(runs) > budget:
            return None
    return runs


def exact_charge(rng, expected: ExpectedSignal, sensor: SensorParams, statistics: str, c: int, index, size=None,
                 gain=None):
    """Collected charge S + D of one channel, drawn exactly, for pixels of spectrum ``index``.

    Parameters
    ----------
    c : int
        Channel.
    index : int or numpy.ndarray of int
        One label (then ``size`` gives the shape) or one label per pixel.
    gain : numpy.ndarray, optional
        PRNU: per-pixel factor on the mean signal (shape ``size`` or that of ``index``).

    Returns
    -------
    numpy.ndarray
        Unit: e⁻. ``pixel`` statistics: one draw Poisson(S̄ + D̄) per pixel; ``paper``: s · Poisson(S̄ / s) plus
        Poisson(D̄); photon noise off: S̄ plus Poisson(D̄).
    """
    S = expected.signal_e[index, c]
    D = expected.dark_e[c]
    shape = size if size is not None else np.shape(index)
    if gain is not None:  # per-pixel means: numpy's sampler, one mean per pixel
        S = S * gain
        size = None
    if sensor.photon_noise and statistics == "pixel":  # one draw covers photons and dark current
        return poisson(rng, S + D) if size is None else poisson_run(rng, S + D, size)
    if sensor.photon_noise:
        var = expected.signal_var_e2[index, c] * (1 if gain is None else gain)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = np.where(S > 0, var / S, 0.0)
            lam = np.where(step > 0, S / step, 0.0)
        charge = step * poisson(rng, lam, size=size)
    else:
        charge = np.broadcast_to(np.asarray(S, dtype=np.float64), shape)
    return charge + rng.poisson(D, size=shape) if D > 0 else charge


def draw_poisson(labels, expected: ExpectedSignal, sensor: SensorParams, statistics: str, rng, out):
    """One draw per pixel and channel (plus one for dark current under ``paper`` statistics)."""
    runs = label_runs(labels)
    for c in range(3):
        if runs is None:
            out[c][...] = exact_charge(rng, expected, sensor, statistics, c, labels)
            continue
        for r0, r1, c0, c1, label in runs:
            out[c][r0:r1, c0:c1] = exact_charge(rng, expected, sensor, statistics, c, label, (r1 - r0, c1 - c0))
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
    out_flat = [out[c].reshape(-1) for c in range(3)]  # rows of a C-contiguous plane: views, not copies
    assert all(np.shares_memory(flat_c, out) for flat_c in out_flat)
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
        for c in range(3):
            out_flat[c][start : start + chunk] = signal[:, c]
    for c in range(3):
        if expected.dark_e[c] > 0:
            out[c] += rng.poisson(expected.dark_e[c], size=out[c].shape)
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
