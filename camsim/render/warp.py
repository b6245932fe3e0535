"""The time-averaged bilinear warp of a per-pixel image: the one implementation of a moving scene's sampling.

A sequence frame's expectation (:mod:`camsim.render.sequence`) is a weighted sum of the static scene's image seen
through the camera's homography at sub-sample times of each row's exposure::

    out[r, x, c] = Σ_s  weights[s, r] · bilinear(pixels[..., c], H⁻¹[s, r] · (x, r, 1))

one inverse homography per sub-sample s and per output row r (a rolling shutter exposes each row at its own time;
a global shutter has one per sub-sample for every row), one weight per sub-sample and row (1/S for an even
average; a flickering light's share of each sub-interval). ``bilinear`` is between pixel centres (a pixel's centre
at integer coordinates, x the column, y the row); a point outside the image is **clamped** to the nearest edge pixel
(the scene beyond the frame continues its edge). Coordinates are float32 (at 4000 px, steps of 2.4e-4 px); an
affine inverse (last row 0, 0, 1) skips the perspective division.

Two implementations of the one law, which agree to float32 rounding (``tests/render/test_warp.py``):

- **compiled** (numba, the default where numba can be imported): :func:`average_warp` in one nogil kernel per row
  block. Each output row's sums stay in a row buffer (in cache) while every sub-sample, in order, adds its bilinear
  samples to it — per sub-sample one loop of coordinates (the cell and fractions of every pixel of the row) and one
  of gathers and multiply-adds per channel, loops the compiler vectorises — and the row is written once, channels
  last or first (``planar``). The numpy path's float32 coordinate arithmetic, clamping and bilinear order, and the
  same order of the sums from 0, so the two agree to float32 rounding (bit for bit on the tests' random images and
  motions; a sequence's files are the same bytes). Compiled on first use, once per process (numba is imported
  then, not with camsim; 1–2 s; no on-disk cache, as :mod:`camsim.isp.fused`); the row blocks run on camsim's
  threads, and the result does not depend on their number. About 9× the numpy path's speed per sub-sample on one
  thread, per-row inverses (a rolling shutter's) about as fast as one per sub-sample (``docs/benchmarks.md``).
  Where a coordinate is NaN (a singular inverse's w = 0 at 0/0) the kernel takes 0; the numpy path fails there.
- **numpy** (:func:`warp_bilinear`, one sub-sample over a row block at a time): the reference, and the fallback
  where numba cannot be imported (``average_warp(..., compiled=False)`` asks for it; :func:`warp_path` says which
  path a call takes).
"""

from __future__ import annotations

import numpy as np

from camsim.core.compiled import CompiledOnce
from camsim.core.errors import CamsimError

#: What :func:`warp_path` says of each implementation.
COMPILED_PATH = "compiled (numba: each output row's sums over all sub-samples in a row buffer, written once)"
NUMPY_PATH = "numpy (one pass per sub-sample)"
#: Pixels of a warp block: a block's temporaries stay small (in cache, no fresh pages) and blocks run on threads.
WARP_BLOCK_PIXELS = 2**16


def _row_coefficients(inverses: np.ndarray, r0: int, r1: int) -> np.ndarray:
    """The (3, 3) inverse for every row r0:r1, as (r1 − r0 or 1, 3, 3) float64."""
    return inverses if inverses.shape[0] == 1 else inverses[r0:r1]


def warp_bilinear(pixels: np.ndarray, inverse: np.ndarray, out: np.ndarray, weight=1.0,
                  rows: tuple[int, int] | None = None) -> None:
    """``out += weight · pixels(H⁻¹ p)`` at every pixel p of rows r0:r1: bilinear, clamped at the edges.

    Parameters
    ----------
    pixels : numpy.ndarray, shape (H, W, C), float32, C-contiguous
        The image, channels last (one gather fetches a pixel's C values together).
    inverse : numpy.ndarray, shape (3, 3) or (R, 3, 3)
        H⁻¹: sensor pixel (x, y, 1) → image pixel (homogeneous); one for every row, or one per row of r0:r1
        (R = r1 − r0).
    out : numpy.ndarray, shape (R, W, C), float32
        Accumulated in place (R = H without ``rows``).
    weight : float or numpy.ndarray of shape (R,)
        One weight, or one per row.
    rows : (r0, r1), optional
        Only the sensor rows r0:r1.
    """
    height, width, channels = pixels.shape
    r0, r1 = (0, height) if rows is None else rows
    inv = np.asarray(inverse, dtype=np.float64)
    f32 = np.float32
    x = np.arange(width, dtype=np.float32)[None, :]
    y = np.arange(r0, r1, dtype=np.float32)[:, None]
    if inv.ndim == 2:
        a = [[f32(inv[i, j]) for j in range(3)] for i in range(3)]
        affine = inv[2, 0] == 0 and inv[2, 1] == 0 and inv[2, 2] == 1
    else:  # one matrix per row: (R, 1) coefficients
        a = [[inv[:, i, j].astype(np.float32)[:, None] for j in range(3)] for i in range(3)]
        affine = bool(np.all(inv[:, 2, 0] == 0) and np.all(inv[:, 2, 1] == 0) and np.all(inv[:, 2, 2] == 1))
    qx = a[0][0] * x + (a[0][1] * y + a[0][2])
    qy = a[1][0] * x + (a[1][1] * y + a[1][2])
    if not affine:
        w = a[2][0] * x + (a[2][1] * y + a[2][2])
        qx /= w
        qy /= w
    qx = np.broadcast_to(qx, (r1 - r0, width)).copy() if qx.shape != (r1 - r0, width) else qx
    qy = np.broadcast_to(qy, (r1 - r0, width)).copy() if qy.shape != (r1 - r0, width) else qy
    np.clip(qx, 0, width - 1, out=qx)
    np.clip(qy, 0, height - 1, out=qy)
    x0 = np.floor(qx)
    y0 = np.floor(qy)
    np.minimum(x0, max(width - 2, 0), out=x0)
    np.minimum(y0, max(height - 2, 0), out=y0)
    qx -= x0  # the fractions
    qy -= y0
    index = y0.astype(np.int64)
    index *= width
    index += x0.astype(np.int64)
    index = index.ravel()
    dx = 1 if width > 1 else 0
    dy = width if height > 1 else 0
    fx, fy = qx.reshape(-1, 1), qy.reshape(-1, 1)
    flat = pixels.reshape(-1, channels)
    acc = out.reshape(-1, channels)
    take = lambda i: np.take(flat, i, axis=0)  # noqa: E731 (rows of C values: far faster than flat[i])
    top = take(index)  # (1 − fx) a + fx b, rows y0 and y0 + 1, then (1 − fy) top + fy bottom
    top += (take(index + dx) - top) * fx
    bottom = take(index + dy)
    bottom += (take(index + dx + dy) - bottom) * fx
    bottom -= top
    bottom *= fy
    top += bottom
    weight = np.asarray(weight, dtype=np.float64)
    if weight.ndim:
        top = top.reshape(r1 - r0, width, channels)
        top *= weight.astype(np.float32)[:, None, None]
    elif weight != 1:
        top *= f32(weight)
    acc += top.reshape(-1, channels)


def _is_identity(inverses: np.ndarray) -> bool:
    return bool(np.all(inverses == np.eye(3)))



def _build():
    """Compile the kernel (numba imported here). Returns it."""
    import numba

    jit = numba.njit(cache=False, nogil=True, fastmath=False, error_model="numpy", boundscheck=False)

    @jit
    def warp_rows(pixels, coef, affine, identity, weights, out, planar, r0, r1):
        """Rows r0:r1 of Σ_s weights[s, r] · pixels(H⁻¹[s, r] p) (module docstring) written into ``out``, (H, W, C),
        or (C, H, W) where ``planar``: per row, the sums (C, W) from 0, each sub-sample in order adding its samples
        in float32 as :func:`warp_bilinear` (the same operations on the same values, so the same roundings).
        ``coef`` (S, 1|H, 9) float32 the inverses' entries row by row, ``affine`` (S, 1|H) bool, ``identity`` (S,)
        bool, ``weights`` (S, 1|H) float32."""
        height, width, channels = pixels.shape
        samples = coef.shape[0]
        per_row = coef.shape[1] > 1
        weight_rows = weights.shape[1] > 1
        zero = np.float32(0.0)
        x_max = np.float32(width - 1)
        y_max = np.float32(height - 1)
        ix_max = max(width - 2, 0)
        iy_max = max(height - 2, 0)
        step_x = channels if width > 1 else 0
        step_y = width * channels if height > 1 else 0
        flat_pixels = pixels.reshape(-1)
        base = np.empty(width, dtype=np.int64)
        fxs = np.empty(width, dtype=np.float32)
        fys = np.empty(width, dtype=np.float32)
        acc = np.empty((channels, width), dtype=np.float32)
        xs = np.arange(width).astype(np.float32)
        for r in range(r0, r1):
            y = np.float32(r)
            acc[:] = zero
            for s in range(samples):
                k = r if per_row else 0
                ws = weights[s, r if weight_rows else 0]
                if identity[s]:
                    for c in range(channels):
                        for x in range(width):
                            acc[c, x] += pixels[r, x, c] * ws
                    continue
                a0, a1, a2 = coef[s, k, 0], coef[s, k, 3], coef[s, k, 6]
                b0 = coef[s, k, 1] * y + coef[s, k, 2]
                b1 = coef[s, k, 4] * y + coef[s, k, 5]
                b2 = coef[s, k, 7] * y + coef[s, k, 8]
                if affine[s, k]:
                    for x in range(width):
                        qx = a0 * xs[x] + b0
                        qy = a1 * xs[x] + b1
                        qx = qx if qx > zero else zero
                        qx = qx if qx < x_max else x_max
                        qy = qy if qy > zero else zero
                        qy = qy if qy < y_max else y_max
                        ix = min(np.int64(qx), ix_max)
                        iy = min(np.int64(qy), iy_max)
                        fxs[x] = qx - np.float32(ix)
                        fys[x] = qy - np.float32(iy)
                        base[x] = (iy * width + ix) * channels
                else:
                    for x in range(width):
                        h = a2 * xs[x] + b2
                        qx = (a0 * xs[x] + b0) / h
                        qy = (a1 * xs[x] + b1) / h
                        qx = qx if qx > zero else zero
                        qx = qx if qx < x_max else x_max
                        qy = qy if qy > zero else zero
                        qy = qy if qy < y_max else y_max
                        ix = min(np.int64(qx), ix_max)
                        iy = min(np.int64(qy), iy_max)
                        fxs[x] = qx - np.float32(ix)
                        fys[x] = qy - np.float32(iy)
                        base[x] = (iy * width + ix) * channels
                for c in range(channels):
                    row = acc[c]
                    for x in range(width):
                        i00 = base[x] + c
                        fx, fy = fxs[x], fys[x]
                        p, q = flat_pixels[i00], flat_pixels[i00 + step_y]
                        top = p + (flat_pixels[i00 + step_x] - p) * fx
                        bottom = q + (flat_pixels[i00 + step_y + step_x] - q) * fx
                        row[x] += (top + (bottom - top) * fy) * ws
            if planar:
                for c in range(channels):
                    for x in range(width):
                        out[c, r, x] = acc[c, x]
            else:
                for x in range(width):
                    for c in range(channels):
                        out[r, x, c] = acc[c, x]

    return {"warp_rows": warp_rows, "numba": numba.__version__}


_KERNELS = CompiledOnce(_build)


def warp_kernels() -> dict | None:
    """The compiled kernel (compiled on the first call in a process), or None where numba cannot be imported."""
    return _KERNELS.get()


def warp_path(compiled: bool | None = None) -> str:
    """Which implementation :func:`average_warp` takes with ``compiled``: :data:`COMPILED_PATH` or
    :data:`NUMPY_PATH` (``None``: the compiled one where numba can be imported)."""
    if compiled is False:
        return NUMPY_PATH
    if warp_kernels() is None:
        if compiled:
            raise CamsimError(f"the compiled warp needs numba, which cannot be imported ({_KERNELS.why})")
        return NUMPY_PATH
    return COMPILED_PATH


def average_warp(pixels: np.ndarray, inverses: np.ndarray, weights: np.ndarray, *,
                 workers: int | None = None, compiled: bool | None = None, planar: bool = False,
                 out: np.ndarray | None = None) -> np.ndarray:
    """Σ_s weights[s, r] · pixels(H⁻¹[s, r] p) at every pixel p = (x, r) (module docstring).

    Parameters
    ----------
    pixels : numpy.ndarray, shape (H, W, C), float32
        The image, channels last.
    inverses : numpy.ndarray, shape (S, 1, 3, 3) or (S, H, 3, 3), float64
        Per sub-sample, the inverse homography (sensor pixel → image pixel) of every row, or of each row.
    weights : numpy.ndarray, shape (S, 1) or (S, H), float64
        Per sub-sample, the weight of every row, or of each row.
    workers : int, optional
        Threads over row blocks (default: every core). The result does not depend on it: each block sums its
        sub-samples in order.
    compiled : bool, optional
        The implementation (module docstring): None (default) the compiled kernel where numba can be imported,
        else numpy; False numpy; True the compiled kernel (a CamsimError without numba). The two agree to float32
        rounding.
    planar : bool
        Return the channels first, (C, H, W) C-contiguous (the compiled kernel writes them so; the numpy path
        copies).
    out : numpy.ndarray, optional
        Where to write the result: C-contiguous float32 of the result's shape (its values are overwritten; a
        sequence keeps one for all its frames, sparing fresh pages). Default: a new array.

    Returns
    -------
    numpy.ndarray, shape (H, W, C), or (C, H, W) where ``planar``, float32
        ``out`` where given.
    """
    from concurrent.futures import ThreadPoolExecutor

    from camsim.render.frame import default_workers

    pixels = np.ascontiguousarray(pixels, dtype=np.float32)
    inverses = np.asarray(inverses, dtype=np.float64)
    weights = np.asarray(weights, dtype=np.float64)
    height, width = pixels.shape[:2]
    samples = inverses.shape[0]
    if inverses.ndim != 4 or weights.ndim != 2 or inverses.shape[2:] != (3, 3) \
            or inverses.shape[1] not in (1, height) or weights.shape[0] != samples \
            or weights.shape[1] not in (1, height):
        raise ValueError(f"average_warp: inverses {inverses.shape} and weights {weights.shape} do not fit "
                         f"{samples} sub-samples of {height} rows")
    shape = (pixels.shape[2], height, width) if planar else pixels.shape
    if out is not None and not (isinstance(out, np.ndarray) and out.shape == shape and out.dtype == np.float32
                                and out.flags.c_contiguous and out.flags.writeable):
        raise ValueError(f"average_warp: out must be a writeable C-contiguous float32 array of shape {shape}")
    result = out
    identity = [_is_identity(inverses[s]) for s in range(samples)]
    rows = max(1, WARP_BLOCK_PIXELS // width)

    is_compiled = warp_path(compiled) == COMPILED_PATH
    if is_compiled:
        kernel = _KERNELS.get()["warp_rows"]
        coef = np.ascontiguousarray(inverses.astype(np.float32).reshape(samples, inverses.shape[1], 9))
        affine = np.ascontiguousarray((inverses[..., 2, 0] == 0) & (inverses[..., 2, 1] == 0)
                                      & (inverses[..., 2, 2] == 1))
        identity_flags = np.array(identity, dtype=np.bool_)
        weights32 = np.ascontiguousarray(weights.astype(np.float32))
        out = np.empty(shape, dtype=np.float32) if result is None else result

        def block(r0: int) -> None:  # every value of the rows written
            kernel(pixels, coef, affine, identity_flags, weights32, out, planar, r0, min(height, r0 + rows))
    else:
        out = np.zeros_like(pixels) if result is None or planar else result
        out[...] = 0

        def block(r0: int) -> None:
            r1 = min(height, r0 + rows)
            for s in range(samples):
                weight = weights[s, 0] if weights.shape[1] == 1 else weights[s, r0:r1]
                if identity[s]:
                    w = np.asarray(weight, dtype=np.float32)
                    out[r0:r1] += pixels[r0:r1] * (w[:, None, None] if w.ndim else w)
                else:
                    inverse = _row_coefficients(inverses[s], r0, r1)
                    warp_bilinear(pixels, inverse[0] if inverse.shape[0] == 1 else inverse, out[r0:r1], weight,
                                  rows=(r0, r1))

    starts = range(0, height, rows)
    workers = default_workers() if workers is None else max(1, int(workers))
    if workers == 1 or len(starts) == 1:
        for r0 in starts:
            block(r0)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(block, starts))
    if planar and not is_compiled:  # the numpy path's: a copy
        if result is None:
            return np.ascontiguousarray(np.moveaxis(out, -1, 0))
        result[...] = np.moveaxis(out, -1, 0)
        return result
    return out
