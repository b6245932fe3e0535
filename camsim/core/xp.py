"""Array namespaces: numpy on the CPU, CuPy on an NVIDIA GPU — the one switch of camsim's array code.

The stages (:mod:`camsim.sensor.stages`) and the device path (:mod:`camsim.render.backends.array_path`) are written
once, against what numpy and CuPy share: the module functions (``xp.minimum``, ``xp.where``, …) and the methods of
their random generators that take the same arguments (``poisson(lam)``, ``standard_normal(size, dtype)``,
``random(size, dtype)``).
A stage's per-frame parameter (a gain, a read-noise σ, a full well) is a number for one frame, or, for a batch of
frames drawn together, a numpy array on the host that broadcasts against the values (one value per frame: shape
(B, 1, 1, 1) for (B, planes, H, W)): the conditions on it are read on the host, and :func:`on_device` copies it to the
values' device once where it enters the arithmetic (no per-frame transfer, no implicit one).
The namespace of an array is found from its type, so CuPy is imported only by code that already holds a CuPy array
or generator: importing camsim never imports CuPy (nor does this module import any camsim module).
"""

from __future__ import annotations

import numpy as np


def _is_cupy(value) -> bool:
    return type(value).__module__.split(".", 1)[0] == "cupy"


def namespace_of(*values):
    """The array namespace of ``values``: ``cupy`` if any of them is a CuPy array, else ``numpy``.

    Python numbers, numpy arrays and None count as numpy.
    """
    for value in values:
        if _is_cupy(value):
            import cupy

            return cupy
    return np


def generator_namespace(rng):
    """The array namespace a random generator draws into: ``cupy`` for a ``cupy.random.Generator``, else ``numpy``."""
    return namespace_of(rng)


def special_namespace(xp):
    """The special functions of ``xp``: ``scipy.special`` for numpy, ``cupyx.scipy.special`` for CuPy."""
    if xp is np:
        from scipy import special

        return special
    from cupyx.scipy import special

    return special


def fft_namespace(xp):
    """The FFTs of ``xp``: ``scipy.fft`` for numpy (its ``workers`` threads), ``cupyx.scipy.fft`` for CuPy (cuFFT)."""
    if xp is np:
        from scipy import fft

        return fft
    from cupyx.scipy import fft

    return fft


def on_device(xp, value, dtype=None):
    """``value`` ready to combine with ``xp``'s arrays: a number as it is (cast to ``dtype``'s scalar type when
    given), an array copied to ``xp``'s device (one explicit transfer; an array already there is not copied unless
    ``dtype`` asks for a cast)."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]  # a numpy scalar: CuPy takes those, not 0-d numpy arrays
    if not hasattr(value, "shape") or (isinstance(value, np.generic)):
        return value if dtype is None else np.dtype(dtype).type(value)
    return xp.asarray(value, dtype=dtype)


def to_host(array) -> np.ndarray | None:
    """``array`` as a numpy array (a copy from the device for CuPy; numpy arrays and None as they are)."""
    if array is None or isinstance(array, np.ndarray):
        return array
    if _is_cupy(array):
        return array.get()
    return np.asarray(array)


def synchronize(xp) -> None:
    """Wait until the device has finished the work queued so far (nothing to wait for with numpy)."""
    if xp is not np:
        xp.cuda.get_current_stream().synchronize()


__all__ = ["fft_namespace", "generator_namespace", "namespace_of", "on_device", "special_namespace", "synchronize",
           "to_host"]
