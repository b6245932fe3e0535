"""The ISP's fused path: one compiled pass per image (numba), for the ``srgb`` pairs of :mod:`camsim.pairs`.

Where the white balance, the colour matrix and the gain are one 3 × 3 matrix after demosaicing — a three-chip frame,
or bilinear demosaicing (:data:`camsim.isp.stages.PER_CHANNEL_LINEAR`) — :func:`camsim.isp.develop` runs its stages as
numpy passes, one operation over the whole image at a time. Here one compiled loop does, per output pixel: the
normalisation (black off, ÷ white − black, in float32 as :func:`camsim.isp.normalise`), the bilinear demosaicing
(the same float32 sums, in the same order, with the same border rule as camsim's bilinear: the mosaic mirrored
without its edge row), the fused matrix A = gain · M · diag(white-balance gains), the clip to [0, 1] and the tone
curve, writing straight into the output (a batch's slot). The matrix is computed in float64 from the float32
demosaiced values and rounded once to float32; the curve is taken in float32.

The sRGB curve's power x^(1/2.4) is computed without a call to a power function (a scalar call per value would cost
more than all the rest; this form vectorises, eight float32 values at a time): x is brought into [2^(−1/2), 1] by
exact scalings by 2^8, 2^4, 2^2, 2 and an inexact one by √2 (each undone by its factor 2^(−5k/12) afterwards), and
m^(5/12) there is a degree-8 polynomial (:data:`POWER_DEGREE`), the Chebyshev interpolant of the power on that
interval (within 7.3e-12 of it on a grid of 2 million points, in float64), evaluated in float32. Checked once on
every float32 in [0.0031308, 1] (70 439 397 values, 2026-11-26): the power within 1.03e-7 of x^(5/12)
(:data:`POWER_ERROR`), the curve 1.055 x^(1/2.4) − 0.055 within 1.87e-7 of the formula in float64
(:data:`CURVE_ERROR`: about three float32 units in the last place near 1); the tests check a part of them. Below
the threshold the curve is 12.92 x. Unlike the numpy path, a NaN becomes 0 (the clip), not a NaN in the output.

The kernels are compiled by numba on first use, once per process (numba is imported then, not with camsim); numba's
on-disk cache is not used (it writes its files beside the package, which an installed camsim may not allow). Without
numba the pairs take the numpy stages (:func:`camsim.isp.develop.develop_pair`); each pair's record says which path
made it (:data:`FUSED_PATH`, :data:`STAGES_PATH`).
"""

from __future__ import annotations

import math

import numpy as np

from camsim.core.compiled import CompiledOnce
from camsim.core.errors import CamsimError
from camsim.isp.stages import DEMOSAIC_PAD, _workspace
from camsim.sensor.cfa import cfa_sites

__all__ = ["FUSED_PATH", "STAGES_PATH", "POWER_DEGREE", "POWER_ERROR", "CURVE_ERROR", "fused_applies", "fused_kernels",
           "develop_pair_into", "develop_into"]

#: What a pair's record says (its ``path``) when the compiled kernel developed it, or the numpy stages.
FUSED_PATH = "fused (numba: normalise, bilinear, matrix, clip, tone curve in one pass)"
STAGES_PATH = "stages (numpy, one pass per operation)"
#: The degree of the polynomial for m^(5/12) on [2^(−1/2), 1]; the largest error of the kernel's float32 power
#: x^(5/12) and of its sRGB curve over every float32 in [0.0031308, 1] (module docstring).
POWER_DEGREE = 8
POWER_ERROR = 1.1e-7
CURVE_ERROR = 1.9e-7
_SRGB_THRESHOLD = 0.0031308
_LOW = 2.0 ** -0.5
#: The tone curves the kernel knows, by code.
_TONES = {"linear": 0, "srgb": 1, "filmic": 2}
#: The bilinear quantities at a site, in the kernel's order: own value, horizontal, vertical, diagonal, cross sums.
_OWN, _HORIZONTAL, _VERTICAL, _DIAGONAL, _CROSS = range(5)


def _power_coefficients() -> tuple:
    """The power-basis coefficients, lowest first, of m^(5/12) on [2^(−1/2), 1] in t = (m − c) / r ∈ [−1, 1]
    (c, r the interval's centre and half-width): the Chebyshev interpolant of degree :data:`POWER_DEGREE`."""
    from numpy.polynomial import Chebyshev, Polynomial

    interpolant = Chebyshev.interpolate(lambda m: m ** (5.0 / 12.0), POWER_DEGREE, domain=[_LOW, 1.0])
    return tuple(float(c) for c in interpolant.convert(kind=Polynomial, domain=[_LOW, 1.0], window=[-1, 1]).coef)


def _build():
    """Compile the kernels (numba imported here). Returns a dict of them."""
    import numba

    jit = numba.njit(cache=False, nogil=True, fastmath=False, error_model="numpy")
    f32 = np.float32
    threshold = f32(_SRGB_THRESHOLD)
    c0, c1, c2, c3, c4, c5, c6, c7, c8 = (f32(c) for c in _power_coefficients())
    centre, inverse_radius = f32((_LOW + 1.0) / 2.0), f32(2.0 / (1.0 - _LOW))
    low8, low4, low2, low1, low_half = f32(2.0 ** -8), f32(2.0 ** -4), f32(0.25), f32(0.5), f32(_LOW)
    up8, up4, up2, up1, up_half = f32(256.0), f32(16.0), f32(4.0), f32(2.0), f32(math.sqrt(2.0))
    f8, f4, f2, f1, fh = (f32(2.0 ** (-40 / 12)), f32(2.0 ** (-20 / 12)), f32(2.0 ** (-10 / 12)), f32(2.0 ** (-5 / 12)),
                          f32(2.0 ** (-5 / 24)))
    zero, one, slope, scale, offset = f32(0.0), f32(1.0), f32(12.92), f32(1.055), f32(0.055)
    fa, fb, fc, fd, fe = f32(2.51), f32(0.03), f32(2.43), f32(0.59), f32(0.14)

    @jit
    def power(x):
        """x^(5/12) for float32 x in [2^−15, 1], in float32 (module docstring)."""
        factor = one
        low = x < low8
        x = x * up8 if low else x
        factor = factor * f8 if low else factor
        low = x < low4
        x = x * up4 if low else x
        factor = factor * f4 if low else factor
        low = x < low2
        x = x * up2 if low else x
        factor = factor * f2 if low else factor
        low = x < low1
        x = x * up1 if low else x
        factor = factor * f1 if low else factor
        low = x < low_half
        x = x * up_half if low else x
        factor = factor * fh if low else factor
        t = (x - centre) * inverse_radius
        p = ((((((((c8 * t + c7) * t + c6) * t + c5) * t + c4) * t + c3) * t + c2) * t + c1) * t + c0)
        return factor * p

    @jit
    def tone_row(lin, tone, out, y):
        """``out[:, y, :]`` = the curve of ``lin`` (3, W) float32, clipped to [0, 1] (NaN → 0); float32 and
        branch-free per value, so that the loop vectorises."""
        width = lin.shape[1]
        if tone == 2:  # filmic: Narkowicz 2015 on max(x, 0), then sRGB's (float32, as the numpy path)
            for c in range(3):
                for x in range(width):
                    v = lin[c, x]
                    v = v if v > zero else zero
                    lin[c, x] = v * (fa * v + fb) / (v * (fc * v + fd) + fe)
        for c in range(3):
            row, target = lin[c], out[c, y]
            if tone == 0:
                for x in range(width):
                    v = row[x]
                    v = v if v > zero else zero
                    target[x] = v if v < one else one
            else:
                for x in range(width):
                    v = row[x]
                    v = v if v > zero else zero
                    v = v if v < one else one
                    high = scale * power(v if v > threshold else threshold) - offset
                    target[x] = slope * v if v <= threshold else high

    @jit
    def three_chip(raw, scale, offset, a, tone, lin, out):
        _, height, width = raw.shape
        for y in range(height):
            for x in range(width):
                r = np.float64(np.float32(raw[0, y, x]) * scale[0] - offset[0])
                g = np.float64(np.float32(raw[1, y, x]) * scale[1] - offset[1])
                b = np.float64(np.float32(raw[2, y, x]) * scale[2] - offset[2])
                lin[0, x] = a[0, 0] * r + a[0, 1] * g + a[0, 2] * b
                lin[1, x] = a[1, 0] * r + a[1, 1] * g + a[1, 2] * b
                lin[2, x] = a[2, 0] * r + a[2, 1] * g + a[2, 2] * b
            tone_row(lin, tone, out, y)

    @jit
    def bayer(raw, scale, offset, which, a, tone, padded, q, rgb, lin, out):
        height, width = raw.shape
        # normalise into the interior of padded (float32: x · s − b · s, as camsim.isp.normalise)
        for y in range(height):
            for dx in range(2):
                s = 2 * (y & 1) + dx
                sc, off = scale[s], offset[s]
                for x in range(dx, width, 2):
                    padded[y + 1, x + 1] = np.float32(raw[y, x]) * sc - off
        # the 1-pixel mirror without the edge row (camsim.isp.stages._mirror_edges)
        for x in range(1, width + 1):
            padded[0, x] = padded[2, x]
            padded[height + 1, x] = padded[height - 1, x]
        for y in range(height + 2):
            padded[y, 0] = padded[y, 2]
            padded[y, width + 1] = padded[y, width - 1]
        half, quarter = np.float32(0.5), np.float32(0.25)
        for y in range(height):
            # the row's bilinear quantities, the float32 sums of camsim.isp.stages._bilinear_padded
            for x in range(width):
                vertical = padded[y, x + 1] + padded[y + 2, x + 1]
                horizontal = padded[y + 1, x] + padded[y + 1, x + 2]
                q[0, x] = padded[y + 1, x + 1]
                q[1, x] = horizontal * half
                q[2, x] = vertical * half
                q[3, x] = ((padded[y, x] + padded[y + 2, x]) + (padded[y, x + 2] + padded[y + 2, x + 2])) * quarter
                q[4, x] = (horizontal + vertical) * quarter
            # each colour at each site: its quantity
            for dx in range(2):
                s = 2 * (y & 1) + dx
                for c in range(3):
                    k = which[s, c]
                    for x in range(dx, width, 2):
                        rgb[c, x] = q[k, x]
            for x in range(width):
                r, g, b = np.float64(rgb[0, x]), np.float64(rgb[1, x]), np.float64(rgb[2, x])
                lin[0, x] = a[0, 0] * r + a[0, 1] * g + a[0, 2] * b
                lin[1, x] = a[1, 0] * r + a[1, 1] * g + a[1, 2] * b
                lin[2, x] = a[2, 0] * r + a[2, 1] * g + a[2, 2] * b
            tone_row(lin, tone, out, y)

    return {"bayer": bayer, "three_chip": three_chip, "power": power, "numba": numba.__version__}


_KERNELS = CompiledOnce(_build)


def fused_kernels() -> dict | None:
    """The compiled kernels (compiled on the first call in a process; each dtype of input on its first use), or None
    where numba cannot be imported."""
    return _KERNELS.get()


def fused_applies(facts, settings, shape) -> bool:
    """Whether the kernel develops a frame of ``shape`` with these facts and settings: a three-chip (3, H, W) frame,
    or a Bayer (H, W) mosaic of more than :data:`camsim.isp.stages.DEMOSAIC_PAD` pixels on each side with bilinear
    demosaicing (a smaller mosaic takes colour-demosaicing's border rules, the stage path)."""
    if settings.tone not in _TONES:
        return False
    if facts.cfa_pattern is None:
        return len(shape) == 3 and shape[0] == 3
    return settings.demosaic == "bilinear" and len(shape) == 2 and min(shape) > DEMOSAIC_PAD


def _site_quantities(cfa_pattern: str) -> np.ndarray:
    """(4, 3) int64: at site 2 · (y mod 2) + (x mod 2), which bilinear quantity colour c takes (own value,
    horizontal / 2, vertical / 2, diagonal / 4, cross / 4), as camsim's bilinear chooses it."""
    which = np.zeros((4, 3), dtype=np.int64)
    where = {"RGB".index(letter): (i // 2, i % 2) for i, letter in enumerate(cfa_pattern) if letter != "G"}
    for dy, dx, own in cfa_sites(cfa_pattern):
        for c in range(3):
            if c == own:
                k = _OWN
            elif c == 1:  # green at a red or blue site
                k = _CROSS
            else:
                cy, cx = where[c]
                k = _HORIZONTAL if cy == dy else _VERTICAL if cx == dx else _DIAGONAL
            which[2 * dy + dx, c] = k
    return which


def develop_into(raw, facts, settings, plan, out) -> None:
    """One frame through the kernel into ``out`` ((3, H, W) float32, C-contiguous); the caller has checked
    :func:`fused_applies` and :func:`fused_kernels`."""
    from camsim.isp.develop import _fused_matrix

    kernels = _KERNELS.get()
    if not (out.dtype == np.float32 and out.flags.c_contiguous and out.ndim == 3 and out.shape[0] == 3
            and out.shape[1:] == raw.shape[-2:]):
        raise CamsimError(f"the ISP's output must be a C-contiguous float32 array of shape (3, {raw.shape[-2]}, "
                          f"{raw.shape[-1]})")
    black = np.asarray(facts.black_dn if settings.black else np.zeros(3), dtype=np.float64)
    scale = 1.0 / (facts.white_dn - black)
    a = np.ascontiguousarray(_fused_matrix(plan), dtype=np.float64)
    tone = _TONES[settings.tone]
    raw = np.ascontiguousarray(raw)
    if raw.dtype not in (np.float32, np.float64):
        raw = raw.astype(np.float32)
    if facts.cfa_pattern is None:
        lin = np.empty((3, raw.shape[-1]), dtype=np.float32)
        kernels["three_chip"](raw, scale.astype(np.float32), (black * scale).astype(np.float32), a, tone, lin,
                              out)
        return
    channel = np.zeros(4, dtype=np.int64)
    for dy, dx, c in cfa_sites(facts.cfa_pattern):
        channel[2 * dy + dx] = c
    height, width = raw.shape
    padded = _workspace("fused.padded", (height + 2, width + 2))
    q, rgb = np.empty((5, width), dtype=np.float32), np.empty((3, width), dtype=np.float32)
    lin = np.empty((3, width), dtype=np.float32)
    kernels["bayer"](raw, scale[channel].astype(np.float32), (black * scale)[channel].astype(np.float32),
                     _site_quantities(facts.cfa_pattern), a, tone, padded, q, rgb, lin, out)


def develop_pair_into(noisy, clean, facts, settings, out_noisy, out_clean) -> tuple[dict, str]:
    """A noisy frame and its clean target developed into ``out_noisy`` and ``out_clean`` ((3, H, W) float32,
    C-contiguous: a batch's slots) with the same plan: by the kernel where :func:`fused_applies` and numba is there,
    else by :func:`camsim.isp.develop._develop_pair_into` (the numpy stages). Returns (the ISP's record, the path:
    :data:`FUSED_PATH` or :data:`STAGES_PATH`)."""
    from camsim.isp.develop import _develop_pair_into, _plan

    noisy, clean = np.asarray(noisy), np.asarray(clean)
    if noisy.shape != clean.shape:
        raise CamsimError(f"noisy and clean frames differ in shape: {noisy.shape} and {clean.shape}")
    if not fused_applies(facts, settings, noisy.shape) or fused_kernels() is None:
        return _develop_pair_into(noisy, clean, facts, settings, out_noisy, out_clean), STAGES_PATH
    plan = _plan(facts, settings)
    develop_into(noisy, facts, settings, plan, out_noisy)
    develop_into(clean, facts, settings, plan, out_clean)
    return plan.record, FUSED_PATH
