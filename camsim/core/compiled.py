"""Compiled kernels made once per process: numba is imported, and the kernels compiled, on first use only.

Two modules keep compiled kernels (:mod:`camsim.isp.fused`, the ISP's one-pass develop; :mod:`camsim.render.warp`,
the time-averaged warp of a moving scene); each holds one :class:`CompiledOnce` of its ``_build`` function. numba's
on-disk cache is not used (it writes beside the package, which an installed camsim may not allow).
"""

from __future__ import annotations

import threading
from collections.abc import Callable


class CompiledOnce:
    """The kernels ``build()`` returns (a dict), made on the first :meth:`get` in a process under a lock.

    Where ``build`` raises ImportError (numba cannot be imported), :meth:`get` returns None and :attr:`why` says why;
    its callers then take their numpy paths.
    """

    def __init__(self, build: Callable[[], dict]):
        self._build = build
        self._lock = threading.Lock()
        self.state: dict = {}  # "kernels" (dict or None) and "why" once built; tests may replace it

    def get(self) -> dict | None:
        """The kernels (compiled on the first call), or None without numba."""
        with self._lock:
            if "kernels" not in self.state:
                try:
                    self.state["kernels"] = self._build()
                except ImportError as exc:
                    self.state["kernels"], self.state["why"] = None, str(exc)
            return self.state["kernels"]

    @property
    def why(self) -> str | None:
        """Why the kernels could not be made (numba's import error), or None."""
        return self.state.get("why")
