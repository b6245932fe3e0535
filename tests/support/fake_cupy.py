"""A stand-in for CuPy on the CPU: numpy underneath, CuPy's rules on top.

Two uses where no GPU is: checking that array code is written for both namespaces (:mod:`camsim.core.xp`) — the
mistakes CuPy refuses at run time are refused here too — and counting the array calls a piece of code makes, a proxy
for a GPU's kernel launches (each CuPy call costs ~10–20 µs of launch and Python however small its array).

- :class:`DeviceArray` holds a numpy array. It has no ``__array__``: ``numpy.asarray(device_array)`` raises
  ``TypeError`` as CuPy's implicit conversion does; a numpy array (0-d too) as an operand of a device operation,
  an index or a value written into a device array raises ``TypeError`` (CuPy: "Unsupported type"); numbers and numpy
  scalars are taken. ``.get()`` is the explicit copy to the host; ``float()``, ``int()``, ``bool()`` of an array are
  allowed (a synchronisation in CuPy) and counted.
- :func:`installed` puts the stand-in into ``sys.modules`` as ``cupy`` (with ``cupy.random.Generator``,
  ``Philox4x3210``, ``cupy.cuda`` and ``cupyx.scipy.special``), so that ``PairSource(device="cuda")`` and
  :func:`camsim.core.xp.namespace_of` find it. Its generator has CuPy's methods only (``poisson``,
  ``standard_normal``, ``random``).
- :data:`COUNTS` counts ``calls`` (ufuncs, functions, reductions, copies, fancy indexing, random draws: what launches
  a kernel), ``views`` (reshapes, slices, broadcasts: Python only), ``to_device`` and ``to_host`` (transfers,
  ``to_host`` including the synchronising ``float``/``bool`` of an array).
"""

from __future__ import annotations

import contextlib
import sys
import types
from collections import Counter

import numpy as np
from numpy.lib.mixins import NDArrayOperatorsMixin

#: What the stand-in has done since :func:`reset`: ``calls``, ``views``, ``to_device``, ``to_host`` (and per name).
COUNTS: Counter = Counter()
#: Functions of the namespace that make views, not kernels.
_VIEWS = {"broadcast_to", "moveaxis", "swapaxes", "transpose", "expand_dims", "squeeze", "reshape", "ravel"}
#: Functions that allocate without computing.
_ALLOCATIONS = {"empty", "empty_like"}


def reset() -> None:
    COUNTS.clear()


def _count(kind: str, name: str) -> None:
    COUNTS[kind] += 1
    COUNTS[f"{kind}:{name}"] += 1


def _unwrap(value, what: str):
    """``value`` with every DeviceArray replaced by its numpy array; numpy arrays refused (CuPy's TypeError)."""
    if isinstance(value, DeviceArray):
        return value._a
    if isinstance(value, np.ndarray):
        raise TypeError(f"fake cupy: a numpy array where a device array is needed ({what}): Unsupported type "
                        f"{type(value)}")
    if isinstance(value, (list, tuple)):
        return type(value)(_unwrap(v, what) for v in value)
    if isinstance(value, dict):
        return {k: _unwrap(v, what) for k, v in value.items()}
    return value


def _wrap(value):
    if isinstance(value, (np.ndarray, np.generic)) and not isinstance(value, np.dtype):
        return DeviceArray(np.asarray(value))
    if isinstance(value, tuple):
        return tuple(_wrap(v) for v in value)
    if isinstance(value, list):
        return [_wrap(v) for v in value]
    return value


def _is_basic(key) -> bool:
    """Whether an index makes a view (ints, slices, Ellipsis, None) rather than a gather or scatter."""
    keys = key if isinstance(key, tuple) else (key,)
    return all(k is None or k is Ellipsis or isinstance(k, (int, np.integer, slice)) for k in keys)


class DeviceArray(NDArrayOperatorsMixin):
    """A numpy array behind CuPy's rules (module docstring)."""

    __module__ = "cupy"  # camsim.core.xp tells a CuPy array by its type's module
    __array_priority__ = 100

    def __init__(self, array: np.ndarray):
        self._a = array

    # --- what CuPy refuses
    def __array__(self, *args, **kwargs):
        raise TypeError("fake cupy: implicit conversion to a NumPy array is not allowed; use .get()")

    # --- numpy's protocols, as CuPy implements them
    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        out = kwargs.get("out")
        inputs = _unwrap(inputs, f"{ufunc.__name__} operand")
        kwargs = _unwrap(kwargs, f"{ufunc.__name__} argument")
        _count("calls", f"{ufunc.__name__}.{method}" if method != "__call__" else ufunc.__name__)
        result = getattr(ufunc, method)(*inputs, **kwargs)
        if out is not None:
            return out[0] if isinstance(out, tuple) and len(out) == 1 else out
        return _wrap(result)

    def __array_function__(self, func, types_, args, kwargs):
        return _call(func.__name__, func, args, kwargs)

    # --- attributes
    shape = property(lambda self: self._a.shape)
    dtype = property(lambda self: self._a.dtype)
    ndim = property(lambda self: self._a.ndim)
    size = property(lambda self: self._a.size)
    strides = property(lambda self: self._a.strides)
    itemsize = property(lambda self: self._a.itemsize)
    nbytes = property(lambda self: self._a.nbytes)
    flags = property(lambda self: self._a.flags)
    __cuda_array_interface__ = property(lambda self: {"shape": self._a.shape})

    @property
    def T(self):
        _count("views", "T")
        return DeviceArray(self._a.T)

    def __len__(self):
        return len(self._a)

    def __repr__(self):
        return f"fake_cupy.DeviceArray({self._a!r})"

    # --- transfers and synchronisations
    def get(self):
        _count("to_host", "get")
        return self._a.copy()

    def __float__(self):
        _count("to_host", "float")
        return float(self._a)

    def __int__(self):
        _count("to_host", "int")
        return int(self._a)

    def __bool__(self):
        _count("to_host", "bool")
        return bool(self._a)

    def __index__(self):
        _count("to_host", "index")
        return self._a.__index__()

    # --- indexing
    def __getitem__(self, key):
        key = _unwrap(key, "index")
        _count("views" if _is_basic(key) else "calls", "getitem")
        return _wrap(self._a[key])

    def __setitem__(self, key, value):
        key = _unwrap(key, "index")
        value = _unwrap(value, "value written")
        _count("calls", "setitem")
        self._a[key] = value

    # --- methods
    def _method(self, name, *args, view=False, **kwargs):
        _count("views" if view else "calls", name)
        return _wrap(getattr(self._a, name)(*_unwrap(args, name), **_unwrap(kwargs, name)))

    def astype(self, dtype, copy=True, **kwargs):
        if not copy and np.dtype(dtype) == self._a.dtype:
            return self
        return self._method("astype", dtype, **kwargs)

    def copy(self, *args, **kwargs):
        return self._method("copy", *args, **kwargs)

    def reshape(self, *args, **kwargs):
        return self._method("reshape", *args, view=True, **kwargs)

    def ravel(self, *args, **kwargs):
        return self._method("ravel", *args, view=True, **kwargs)

    def transpose(self, *args, **kwargs):
        return self._method("transpose", *args, view=True, **kwargs)

    def view(self, *args, **kwargs):
        return self._method("view", *args, view=True, **kwargs)

    def fill(self, value):
        _count("calls", "fill")
        self._a.fill(value)

    def any(self, *args, **kwargs):
        return self._method("any", *args, **kwargs)

    def all(self, *args, **kwargs):
        return self._method("all", *args, **kwargs)

    def max(self, *args, **kwargs):
        return self._method("max", *args, **kwargs)

    def min(self, *args, **kwargs):
        return self._method("min", *args, **kwargs)

    def sum(self, *args, **kwargs):
        return self._method("sum", *args, **kwargs)

    def mean(self, *args, **kwargs):
        return self._method("mean", *args, **kwargs)


def _call(name: str, function, args, kwargs):
    """A namespace function on device arrays: counted, run by numpy, its arrays returned on the 'device'."""
    args, kwargs = _unwrap(args, name), _unwrap(kwargs, name)
    _count("views" if name in _VIEWS else "allocations" if name in _ALLOCATIONS else "calls", name)
    return _wrap(function(*args, **kwargs))


def asarray(value, dtype=None, order=None):
    """CuPy's ``asarray``: a device array as it is (cast if ``dtype`` differs), anything else copied to the device."""
    if isinstance(value, DeviceArray):
        if dtype is None or np.dtype(dtype) == value.dtype:
            return value
        return value.astype(dtype)
    if isinstance(value, (list, tuple)) and any(isinstance(v, DeviceArray) for v in value):
        return _call("array", np.array, (value,), {"dtype": dtype})
    _count("to_device", "asarray")
    return DeviceArray(np.array(value, dtype=dtype, order=order or "K"))


def ascontiguousarray(value, dtype=None):
    if not isinstance(value, DeviceArray):
        return asarray(np.ascontiguousarray(value, dtype=dtype))
    if value._a.flags.c_contiguous and (dtype is None or np.dtype(dtype) == value.dtype):
        return value
    return _call("ascontiguousarray", np.ascontiguousarray, (value,), {"dtype": dtype})


class _Namespace(types.ModuleType):
    """A module whose functions are numpy's (or ``source``'s) behind :func:`_call`."""

    def __init__(self, name: str, source):
        super().__init__(name)
        self._source = source

    def __getattr__(self, name: str):
        if name.startswith("__"):
            raise AttributeError(name)
        value = getattr(self._source, name)
        if isinstance(value, type) or not callable(value):  # dtypes, constants
            return value
        return lambda *args, **kwargs: _call(name, value, args, kwargs)


class Philox4x3210:
    __module__ = "cupy.random._bit_generator"

    def __init__(self, seed=None):
        self._bit_generator = np.random.Philox(seed)


class Generator:
    """CuPy's generator: ``poisson``, ``standard_normal`` and ``random`` only (numpy's ``normal``, ``integers``, … are
    missing there)."""

    __module__ = "cupy.random._generator"

    def __init__(self, bit_generator: Philox4x3210):
        self._g = np.random.Generator(bit_generator._bit_generator)

    def poisson(self, lam=1.0, size=None):
        _count("calls", "random.poisson")
        return DeviceArray(np.asarray(self._g.poisson(_unwrap(lam, "poisson mean"), size=size)))

    def standard_normal(self, size=None, dtype=np.float64):
        _count("calls", "random.standard_normal")
        return DeviceArray(np.asarray(self._g.standard_normal(size, dtype=dtype)))

    def random(self, size=None, dtype=np.float64):
        _count("calls", "random.random")
        return DeviceArray(np.asarray(self._g.random(size, dtype=dtype)))


class _Stream:
    def synchronize(self):
        _count("to_host", "synchronize")


class _Device:
    id = 0


def _modules() -> dict:
    from scipy import special

    cupy = _Namespace("cupy", np)
    cupy.__version__ = "fake"
    cupy.ndarray = DeviceArray
    cupy.asarray = asarray
    cupy.array = asarray
    cupy.ascontiguousarray = ascontiguousarray
    random = types.ModuleType("cupy.random")
    random.Generator, random.Philox4x3210 = Generator, Philox4x3210
    cupy.random = random
    cuda = types.ModuleType("cupy.cuda")
    cuda.runtime = types.SimpleNamespace(getDeviceCount=lambda: 1,
                                         getDeviceProperties=lambda i: {"name": b"fake cupy (numpy)"})
    cuda.get_current_stream = _Stream
    cuda.Device = _Device
    cupy.cuda = cuda
    cupyx = types.ModuleType("cupyx")
    cupyx_scipy = types.ModuleType("cupyx.scipy")
    cupyx_special = _Namespace("cupyx.scipy.special", special)
    cupyx.scipy, cupyx_scipy.special = cupyx_scipy, cupyx_special
    return {"cupy": cupy, "cupy.random": random, "cupy.cuda": cuda, "cupyx": cupyx, "cupyx.scipy": cupyx_scipy,
            "cupyx.scipy.special": cupyx_special}


@contextlib.contextmanager
def installed():
    """The stand-in as ``cupy`` (and ``cupyx``) in ``sys.modules`` for the block; what was there before put back."""
    modules = _modules()
    saved = {name: sys.modules.get(name) for name in modules}
    sys.modules.update(modules)
    try:
        yield modules["cupy"]
    finally:
        for name, module in saved.items():
            if module is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = module
