"""Fast exact samplers and block helpers: pure numpy, importing no camsim module but :mod:`camsim.core.xp`.

These are the kernels every sampling method and stage draws with:

* :func:`poisson` — the generator's Poisson sampler (numpy's, or CuPy's on a GPU), extended past its largest mean
  (a rounded normal there);
* :func:`poisson_run` — n iid Poisson(λ) draws of one mean as a multinomial histogram plus a shuffle (exact,
  about twice numpy's per-draw speed);
* :func:`standard_normal_f32` — float32 Box–Muller normals (three times numpy's float32 ziggurat);
* :func:`tukey_lambda` — heavy-tailed Tukey-λ draws by inverse CDF (numpy or CuPy);
* :func:`label_runs` — the rectangles of equal label of a block (a chart's row block is a few of them).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from camsim.core.xp import generator_namespace, on_device

#: numpy's Poisson sampler refuses means above about 9.2e18; beyond this the Poisson law is a Gaussian to
#: within a relative skew of 1e-9, and a rounded normal draw is used.
POISSON_LAM_MAX = 1e18


def poisson(rng, lam, size=None):
    """Poisson draws that also accept means beyond numpy's limit (rounded Gaussian there).

    ``rng`` is a ``numpy.random.Generator`` or a ``cupy.random.Generator``: the means are taken to its device and
    drawn there. Unit: counts (int64, or float64 when a mean exceeds :data:`POISSON_LAM_MAX`).
    """
    xp = generator_namespace(rng)
    lam = xp.asarray(lam, dtype=xp.float64)
    if lam.size == 0 or bool(lam.max() <= POISSON_LAM_MAX):
        return rng.poisson(lam, size=size)
    shape = size if size is not None else lam.shape
    lam = xp.broadcast_to(lam, shape)
    big = lam > POISSON_LAM_MAX
    out = xp.empty(shape, dtype=xp.float64)
    out[~big] = rng.poisson(lam[~big])
    if xp is np:
        out[big] = np.rint(rng.normal(lam[big], np.sqrt(lam[big])))
    else:  # CuPy's generator has no normal(loc, scale): the same transform of its standard normals
        out[big] = xp.rint(lam[big] + xp.sqrt(lam[big]) * rng.standard_normal(int(xp.count_nonzero(big))))
    return out


#: Runs of at least this many pixels per value of the Poisson law's support use the histogram sampler.
HISTOGRAM_MIN_PIXELS_PER_VALUE = 4
#: Largest mean for the histogram sampler (its support is λ ± 13 √λ; float32 holds its integers exactly).
HISTOGRAM_MAX_LAMBDA = 1e6


@lru_cache(maxsize=4096)
def _poisson_support(lam: float):
    """Values λ ± (13 √λ + 20), clipped at 0, as float32, and their Poisson probabilities (normalised)."""
    from scipy import stats  # here, not at import: the command line starts without scipy

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
    if (not isinstance(rng, np.random.Generator) or not 0 < lam <= HISTOGRAM_MAX_LAMBDA
            or n < HISTOGRAM_MIN_PIXELS_PER_VALUE * (26 * np.sqrt(lam) + 41)):
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
    if 2.0 * scale * scale < FLOAT32_MAX:  # σ folded into the radius: no extra pass
        radius *= np.float32(-2.0 * scale * scale)
        np.sqrt(radius, out=radius)
    else:  # σ² beyond float32 (σ ≳ 1.3e19, which the frame's values still hold): σ after the root
        radius *= np.float32(-2.0)
        np.sqrt(radius, out=radius)
        radius *= np.float32(scale)
    u2 *= np.float32(2.0 * np.pi)
    np.sin(u2, out=u1)
    u1 *= radius
    np.cos(u2, out=u2)
    u2 *= radius
    if flat.size % 2:
        flat[-1] = scale * rng.standard_normal(dtype=np.float32)
    return out


#: The largest float32, as a Python float.
FLOAT32_MAX = float(np.finfo(np.float32).max)

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
    first_rows = labels[bands[:-1]]
    if first_rows.shape[0] + np.count_nonzero(first_rows[:, 1:] != first_rows[:, :-1]) > budget:
        return None  # counted in one pass: a fragmented block (an image's) is refused before any run is built
    runs = []
    for r0, r1 in zip(bands[:-1], bands[1:]):
        row = labels[r0]
        edges = np.concatenate(([0], np.flatnonzero(row[1:] != row[:-1]) + 1, [width]))
        runs.extend((int(r0), int(r1), int(c0), int(c1), int(row[c0])) for c0, c1 in zip(edges[:-1], edges[1:]))
        if len(runs) > budget:
            return None
    return runs


def tukey_lambda_variance(lam: float) -> float:
    """Variance of the standard Tukey lambda law, x = (u^λ − (1 − u)^λ) / λ (λ = 0: the logistic law)."""
    if abs(lam) < 1e-9:
        return np.pi**2 / 3
    return 2 / lam**2 * (1 / (1 + 2 * lam) - math.gamma(lam + 1) ** 2 / math.gamma(2 * lam + 2))


def tukey_lambda(rng: np.random.Generator, out: np.ndarray, lam: float, std: float) -> np.ndarray:
    """Fill ``out`` with Tukey lambda draws of shape ``lam``, scaled to standard deviation ``std``.

    Inverse-CDF sampling on float64 uniforms in (0, 1); heavier tails than the Gaussian for λ < 0.14. ``rng`` and
    ``out`` are numpy's or CuPy's (CuPy's uniforms come from 32-bit cuRAND draws, single precision near 1: the
    upper tail is cut where 1 − u < 2⁻²⁴, about 20 σ at λ = −0.1, a probability of 6e-8).

    ``lam`` and ``std`` are numbers, or host arrays broadcasting against ``out`` (one shape and σ per frame of a
    batch drawn at once).
    """
    xp = generator_namespace(rng)
    u = rng.random(out.shape)
    u[u == 0] = np.finfo(float).tiny
    if np.ndim(lam) == 0 and np.ndim(std) == 0:
        x = xp.log(u / (1 - u)) if abs(lam) < 1e-9 else (u**lam - (1 - u) ** lam) / lam
        out[...] = x * (std / np.sqrt(tukey_lambda_variance(lam)))
        return out
    lam, std = np.broadcast_arrays(np.asarray(lam, dtype=np.float64), np.asarray(std, dtype=np.float64))
    variance = np.array([tukey_lambda_variance(float(v)) for v in lam.ravel()]).reshape(lam.shape)
    logistic = np.abs(lam) < 1e-9
    shape = on_device(xp, np.where(logistic, 1.0, lam))
    x = (u**shape - (1 - u) ** shape) / shape
    if logistic.any():  # λ = 0: the logistic law, where the frames have it
        x = xp.where(on_device(xp, logistic), xp.log(u / (1 - u)), x)
    out[...] = x * on_device(xp, std / np.sqrt(variance))
    return out


class AliasTable:
    """Walker's alias table of a discrete law over ``values``: draws by one 63-bit word each (:func:`alias_draw`).

    m = 2^b columns (the law's support padded with zero-probability entries). A draw's word w picks the column
    j = w >> (63 − b) (its top b bits) and keeps ``values[j]`` if its low 63 − b bits, the coin, are below the
    column's own probability in units of 2^-(63−b), else takes ``values[alias[j]]``; with the column's bits in
    front, that is one comparison, w < ``limits[j]`` = (j << (63 − b)) + threshold_j. The columns' own
    probabilities are exact to float64 rounding and their coins to 2^-(63−b) (≤ 2^-47 for 65 536 values), so the
    law drawn is the given one to within that resolution.

    Attributes
    ----------
    shift : int
        63 − b.
    limits : numpy.ndarray, int64, shape (m,)
    pairs : numpy.ndarray, float32, shape (2m,)
        ``values[j]`` and ``values[alias[j]]`` side by side: the draw is ``pairs[2j + (w ≥ limits[j])]``.
    """

    __slots__ = ("shift", "limits", "pairs")

    def __init__(self, shift: int, limits: np.ndarray, pairs: np.ndarray):
        self.shift, self.limits, self.pairs = shift, limits, pairs


def alias_columns(probabilities, columns: int | None = None) -> tuple:
    """Walker's alias construction, vectorised (the sweep of Hübschle-Schneider & Sanders, 2019).

    Light columns (mass below 1/m, in index order) are laid end to end by their deficits on one line, the heavy
    ones by their excesses on another; a light column is aliased to the heavy whose excess interval holds the start
    of its deficit, and a heavy column exhausted by the light that straddles the end of its interval gives its own
    overshoot to the next heavy (its alias). Every column then holds mass 1/m in all, and item i's total mass,
    own part plus the alias parts pointing to it, is p_i (to float64 rounding; ``tests/methods/test_table.py``).

    Parameters
    ----------
    probabilities : numpy.ndarray, shape (n,)
        Non-negative, not all 0 (normalised here).
    columns : int, optional
        m, a power of two ≥ n (default: the smallest).

    Returns
    -------
    own : numpy.ndarray, float64, shape (m,)
        Each column's own probability, in [0, 1].
    alias : numpy.ndarray, intp, shape (m,)
    """
    p = np.asarray(probabilities, dtype=np.float64)
    n = p.size
    m = columns if columns is not None else 1 << max(1, int(np.ceil(np.log2(max(n, 1)))))
    if m < n or m & (m - 1):
        raise ValueError(f"columns must be a power of two ≥ {n}, got {m}")
    q = np.zeros(m)
    q[:n] = p * (m / p.sum())
    light, heavy = np.flatnonzero(q < 1.0), np.flatnonzero(q >= 1.0)
    own, alias = np.ones(m), np.arange(m)
    if light.size == 0 or heavy.size == 0:  # every column full (or rounding left no heavy: all within 1e-16)
        return own, alias
    deficit = 1.0 - q[light]
    d_end = np.cumsum(deficit)
    d_start = d_end - deficit
    excess_end = np.cumsum(q[heavy] - 1.0)
    j = np.minimum(np.searchsorted(excess_end, d_start, side="right"), heavy.size - 1)
    alias[light], own[light] = heavy[j], q[light]
    covering = np.searchsorted(d_start, excess_end, side="left") - 1  # the light straddling each heavy's end
    over = np.where(covering >= 0, d_end[np.maximum(covering, 0)] - excess_end, 0.0)
    over = np.clip(over, 0.0, 1.0)
    over[-1] = 0.0  # the last heavy ends the line
    own[heavy] = 1.0 - over
    alias[heavy[:-1]] = heavy[1:]
    return own, alias


def alias_table(values, probabilities, columns: int | None = None) -> AliasTable:
    """:class:`AliasTable` of the law P(``values[i]``) = ``probabilities[i]`` (values stored as float32), with
    ``columns`` columns (default: the fewest, a power of two)."""
    own, alias = alias_columns(probabilities, columns)
    m = own.size
    shift = 63 - (m.bit_length() - 1)
    thresholds = np.minimum(np.round(own * 2.0**shift), 2.0**shift).astype(np.int64)
    limits = (np.arange(m, dtype=np.int64) << shift) + thresholds
    padded = np.zeros(m, dtype=np.float32)
    padded[: len(values)] = values
    pairs = np.empty(2 * m, dtype=np.float32)
    pairs[0::2], pairs[1::2] = padded, padded[alias]
    return AliasTable(shift, limits, pairs)


def alias_words(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` raw words of ``rng``'s bit generator, 63 bits each (int64, ≥ 0): the draws of :func:`alias_draw_words`."""
    words = rng.bit_generator.random_raw(n).view(np.int64)
    np.bitwise_and(words, np.int64(0x7FFFFFFFFFFFFFFF), out=words)
    return words


def alias_draw_words(table: AliasTable, words: np.ndarray, out: np.ndarray) -> np.ndarray:
    """One draw of ``table``'s law per word of ``words`` (:func:`alias_words`), into ``out`` (float32, C-contiguous,
    ``words.size`` values).

    About 6 ns a draw besides the words' 3.5 (numpy's Poisson sampler: about 50 here): a shift, a gather of the
    limits, a comparison and a gather of the values.
    """
    flat = out.reshape(-1)
    if not np.shares_memory(flat, out):
        raise ValueError("alias_draw_words needs a C-contiguous output array")
    column = words >> table.shift
    over = words >= table.limits[column]
    column <<= 1
    column += over
    np.take(table.pairs, column, out=flat)
    return out


def alias_draw(rng: np.random.Generator, table: AliasTable, out: np.ndarray) -> np.ndarray:
    """Fill ``out`` (float32, C-contiguous) with independent draws of ``table``'s law, one word of ``rng`` each."""
    return alias_draw_words(table, alias_words(rng, out.size), out)
