"""The sampling methods (the docs' model page, Sampling methods): one registry, one dispatcher.

:data:`METHODS` maps each name to a :class:`SamplingMethod`; :func:`get_method` is the one place a name is
checked. The command line, the scene-file reader and the dataset spec take their choices from
:data:`METHOD_NAMES`. ``auto``'s default tolerance, :data:`DEFAULT_TOLERANCE`, is defined below this registry and
the plans (:mod:`camsim.methods.tolerance`), so that no module of the package imports the package itself.

* ``poisson`` — one exact draw per pixel and channel (the default).
* ``table`` — exact as ``poisson``: each spectrum and channel's charge drawn from its exact law by an alias table
  (:mod:`camsim.methods.table`); pixels with laws of their own (fixed-pattern maps, images, ``paper`` statistics)
  are drawn as ``poisson`` draws them.
* ``spectral`` — per-wavelength-bin draws, N× the work: Eq. 4 literally under ``paper`` statistics.
* ``gaussian`` — one moment-matched normal per pixel and channel: fast, wrong at low counts.
* ``auto`` — per spectrum and channel, the Gaussian where its KS distance to the exact law is within the
  tolerance, else the exact draws (under ``paper`` statistics: ``poisson``'s stand-in where it is within the
  tolerance of Eq. 4, else Eq. 4's per-bin draws; :mod:`camsim.methods.plan`).

Eq. 4's correlation between the channels under ``paper`` statistics (shared per-bin counts) is kept by
``spectral``, and by ``auto`` for the spectra it draws by bins; ``poisson`` and ``gaussian`` draw the channels
independently.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from importlib import import_module

from camsim.core.errors import CamsimError
from camsim.methods.tolerance import DEFAULT_TOLERANCE


@dataclass(frozen=True)
class SamplingMethod:
    """A sampling method.

    Attributes
    ----------
    name : str
    summary : str
        One line for help texts.
    draw_module : str
        The module whose ``draw_block(job, r0, r1, rng, scratch)`` draws rows ``r0:r1`` of the frame ``job`` (a
        :class:`camsim.render.frame.FrameJob`): DN before quantisation into ``job.noisy`` and, if quantised, digital
        numbers into ``job.digital``. Imported on first use, so that listing the methods costs nothing.
    planned : bool
        Whether the method decides per spectrum and channel before drawing (:attr:`plan`).
    per_pixel_mean : bool
        Whether it can draw with a different mean at every pixel (PRNU needs it).
    records_sampling : bool
        Whether a frame's sidecar records, per patch and channel, how it was drawn (``sampling``, ``gaussian_ks``).
    """

    name: str
    summary: str
    draw_module: str
    planned: bool = True
    per_pixel_mean: bool = True
    records_sampling: bool = False

    @cached_property
    def draw_block(self):
        """``draw_block(job, r0, r1, rng, scratch)`` of :attr:`draw_module`."""
        return import_module(self.draw_module).draw_block

    def plan(self, expected, sensor, statistics: str, tolerance: float | None = None):
        """The :class:`camsim.methods.plan.DrawPlan` of a frame (None for a method without a plan)."""
        if not self.planned:
            return None
        from camsim.methods.plan import plan_methods

        return plan_methods(expected, sensor, statistics, self.name,
                            DEFAULT_TOLERANCE if tolerance is None else tolerance)


#: The sampling methods by name (:class:`SamplingMethod`): ``poisson``, ``table``, ``spectral``, ``gaussian``, ``auto``.
METHODS = {
    "poisson": SamplingMethod(
        "poisson", "one exact draw per pixel and channel (default)", "camsim.methods.fused"),
    "table": SamplingMethod(
        "table", "exact like poisson, each spectrum's charge drawn from its law's alias table (charts: about 5× "
                 "faster per draw; per-pixel laws fall back to poisson's draws)", "camsim.methods.fused",
        records_sampling=True),
    "spectral": SamplingMethod(
        "spectral", "per-wavelength-bin draws (N× slower, the paper's literal method)", "camsim.methods.spectral",
        planned=False, per_pixel_mean=False),
    "gaussian": SamplingMethod(
        "gaussian", "one moment-matched normal per pixel and channel (fast, wrong at low counts)",
        "camsim.methods.fused", records_sampling=True),
    "auto": SamplingMethod(
        "auto", "per spectrum and channel the Gaussian where its KS distance to the exact law is within "
                "--tolerance, else exact draws", "camsim.methods.fused", records_sampling=True),
}
#: The method names, in the order help texts list them.
METHOD_NAMES = tuple(METHODS)


def get_method(name: str) -> SamplingMethod:
    """The method called ``name``; an unknown name is a :class:`CamsimError` listing the known ones."""
    try:
        return METHODS[name]
    except (KeyError, TypeError):
        raise CamsimError(f"unknown sampling method {name!r}; methods: {', '.join(METHOD_NAMES)}") from None


__all__ = ["DEFAULT_TOLERANCE", "METHODS", "METHOD_NAMES", "SamplingMethod", "get_method"]
