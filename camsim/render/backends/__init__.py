"""Where a frame is drawn: the CPU's block renderer (the default) or the array path on a device.

==========  ===============================================================================================
device      what draws the frame
==========  ===============================================================================================
``cpu``     :func:`camsim.render.frame.render_frame`: row blocks on a thread pool, every method, both statistics
``cuda``    :func:`camsim.render.backends.array_path.render_frame_xp` with CuPy on an NVIDIA GPU (optional extra
            ``gpu``: ``pip install '.[gpu]'`` in camsim's folder, which installs ``cupy-cuda12x``)
``numpy``   the same array path with numpy as its namespace, on the CPU: the GPU's code, run where there is no
            GPU (the tests prove it against the exact law; ``tools/bench_gpu.py`` times it). Python API only
==========  ===============================================================================================

The array path draws the per-pixel exact law of ``pixel`` statistics (Poisson(S̄ + D̄) per pixel and channel, the
fixed-pattern maps, full well, read noise Gaussian or Tukey λ, row noise, gain, pedestal and ADC). The exact
methods ``poisson`` and ``table`` draw that law on the CPU too; ``gaussian`` and ``auto`` approximate it within
their tolerance, and an exact draw is always within it, so on a device they are drawn exactly (the sidecar then
says ``method: poisson`` and ``method_requested``). ``spectral`` (per-bin draws) and ``paper`` statistics are
refused on a device with a one-line error. CuPy is imported only when a device is asked for.
"""

from __future__ import annotations

import numpy as np

from camsim.core.errors import CamsimError
from camsim.methods import get_method

#: The devices of ``camsim render --device``.
DEVICES = ("cpu", "cuda")
#: The devices of the array path (:func:`array_module`): ``numpy`` is its code on the CPU.
ARRAY_DEVICES = ("numpy", "cuda")
#: What ``pip`` needs for ``--device cuda``.
GPU_INSTALL_HINT = "pip install '.[gpu]' in camsim's folder (CuPy for CUDA 12: cupy-cuda12x)"


def cuda_module():
    """CuPy, checked to see a GPU; a :class:`CamsimError` in one line where CuPy is missing or sees no GPU."""
    try:
        import cupy
    except Exception as exc:  # ImportError, or a CUDA library CuPy cannot load
        raise CamsimError(f"--device cuda needs CuPy, which cannot be imported ({type(exc).__name__}: "
                          f"{str(exc).splitlines()[0] if str(exc) else 'not installed'}); {GPU_INSTALL_HINT}, "
                          f"or render on the CPU (--device cpu)") from None
    try:
        count = int(cupy.cuda.runtime.getDeviceCount())
    except Exception as exc:  # cupy.cuda.runtime.CUDARuntimeError: no driver, no device
        message = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise CamsimError(f"--device cuda: CuPy finds no usable NVIDIA GPU ({message}); render on the CPU "
                          f"(--device cpu)") from None
    if count < 1:
        raise CamsimError("--device cuda: CuPy finds no NVIDIA GPU; render on the CPU (--device cpu)")
    return cupy


def array_module(device: str):
    """The array namespace of ``device``: numpy for ``numpy``, CuPy for ``cuda`` (:func:`cuda_module`)."""
    if device == "numpy":
        return np
    if device == "cuda":
        return cuda_module()
    raise CamsimError(f"unknown array device {device!r}; devices: {', '.join(ARRAY_DEVICES)}")


def check_device(device: str):
    """Refuse an unknown device, or ``cuda`` without CuPy or a GPU (:func:`cuda_module`), before any work."""
    if device not in DEVICES + ARRAY_DEVICES:
        raise CamsimError(f"unknown device {device!r}; devices: {', '.join(DEVICES)}")
    if device != "cpu":
        array_module(device)


def device_method(method: str, statistics: str) -> str:
    """The method a device draws for ``method`` under ``statistics``: ``poisson`` (the exact per-pixel law).

    Raises
    ------
    CamsimError
        For ``paper`` statistics and for ``spectral``, which render on the CPU only.
    """
    get_method(method)
    if statistics != "pixel":
        raise CamsimError(f"{statistics} statistics render on the CPU only (--device cpu); a device draws pixel "
                          "statistics, each pixel's exact Poisson law")
    if method == "spectral":
        raise CamsimError("method spectral (per-wavelength-bin draws) renders on the CPU only (--device cpu); a "
                          "device draws each pixel from its exact law (method poisson; table, gaussian and auto "
                          "map to it)")
    return "poisson"


def seed_sequence(rng) -> np.random.SeedSequence:
    """The ``SeedSequence`` of a frame's seed: a ``SeedSequence`` as it is, an int, or a fresh child of a numpy
    ``Generator`` (``Generator.spawn``: two frames drawn with one generator differ)."""
    if isinstance(rng, np.random.SeedSequence):
        return rng
    if isinstance(rng, np.random.Generator):
        return rng.spawn(1)[0].bit_generator.seed_seq
    return np.random.SeedSequence(rng)


def device_generator(xp, seed):
    """The random generator of the array path on ``xp`` for ``seed`` (a ``SeedSequence``, an int, a numpy
    ``Generator``, or an ``xp`` generator, returned as it is).

    numpy: ``Generator(PCG64(seed))``. CuPy: ``cupy.random.Generator(Philox4x3210(seed))`` — cuRAND's counter-based
    Philox, cheap to seed per frame or batch. CuPy seeds cuRAND with one 32-bit word of the ``SeedSequence``
    (``generate_state(1, uint32)``), so two seeds collide with probability 2⁻³² per pair.
    """
    if xp is np:
        if isinstance(seed, np.random.Generator):
            return seed
        return np.random.Generator(np.random.PCG64(seed_sequence(seed)))
    if type(seed).__module__.startswith("cupy"):
        return seed
    return xp.random.Generator(xp.random.Philox4x3210(seed_sequence(seed)))


def device_record(xp) -> dict:
    """What a frame's sidecar says of the device that drew it: ``device`` and, on a GPU, ``device_name`` and
    ``device_library`` (the same seed, device and library version give the same bits)."""
    if xp is np:
        return {"device": "numpy", "device_library": f"numpy {np.__version__}"}
    name = xp.cuda.runtime.getDeviceProperties(xp.cuda.Device().id)["name"]
    name = name.decode() if isinstance(name, bytes) else str(name)
    return {"device": "cuda", "device_name": name, "device_library": f"cupy {xp.__version__}"}


def device_name() -> str:
    """The GPU's name, or ``"none"`` where CuPy is missing or sees no GPU (never raises)."""
    try:
        return device_record(cuda_module())["device_name"]
    except Exception:
        return "none"


__all__ = ["ARRAY_DEVICES", "DEVICES", "GPU_INSTALL_HINT", "array_module", "check_device", "cuda_module",
           "device_generator", "device_method", "device_name", "device_record", "seed_sequence"]
