"""The sampling methods (MODEL.md §5): one registry, one dispatcher.

:data:`METHODS` maps each name to a :class:`SamplingMethod`; :func:`get_method` is the one place a name is
checked. The command line, the scene-file reader and the dataset spec take their choices from
:data:`METHOD_NAMES`.

* ``poisson`` — one exact draw per pixel and channel (the default).
* ``spectral`` — per-wavelength-bin draws, N× the work: Eq. 4 literally under ``paper`` statistics.
* ``gaussian`` — one moment-matched normal per pixel and channel: fast, wrong at low counts.
* ``auto`` — per spectrum and channel, the Gaussian where its KS distance to the exact law is within the
  tolerance, else the exact draws.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from camsim.errors import CamsimError
from camsim.methods import fused, spectral
from camsim.methods.plan import DEFAULT_TOLERANCE, DrawPlan, plan_methods


@dataclass(frozen=True)
class SamplingMethod:
    """A sampling method.

    Attributes
    ----------
    name : str
    summary : str
        One line for help texts.
    plan : callable or None
        ``plan(expected, sensor, statistics, tolerance) -> DrawPlan``, decided per spectrum and channel before
        anything is drawn; None for methods without a plan.
    draw_block : callable
        ``draw_block(job, r0, r1, rng, scratch)``: rows ``r0:r1`` of the frame ``job`` (a
        :class:`camsim.render.FrameJob`), DN before quantisation into ``job.noisy`` and, if quantised, digital
        numbers into ``job.digital``.
    per_pixel_mean : bool
        Whether it can draw with a different mean at every pixel (PRNU needs it).
    records_sampling : bool
        Whether a frame's sidecar records, per patch and channel, how it was drawn (``sampling``, ``gaussian_ks``).
    """

    name: str
    summary: str
    plan: Callable[..., DrawPlan] | None
    draw_block: Callable
    per_pixel_mean: bool = True
    records_sampling: bool = False


def _plan(method: str):
    return lambda expected, sensor, statistics, tolerance: plan_methods(expected, sensor, statistics, method,
                                                                        tolerance)


METHODS = {
    "poisson": SamplingMethod(
        "poisson", "one exact draw per pixel and channel (default)", _plan("poisson"), fused.draw_block),
    "spectral": SamplingMethod(
        "spectral", "per-wavelength-bin draws (N× slower, the paper's literal method)", None, spectral.draw_block,
        per_pixel_mean=False),
    "gaussian": SamplingMethod(
        "gaussian", "one moment-matched normal per pixel and channel (fast, wrong at low counts)",
        _plan("gaussian"), fused.draw_block, records_sampling=True),
    "auto": SamplingMethod(
        "auto", "per spectrum and channel the Gaussian where its KS distance to the exact law is within the "
                "tolerance, else poisson", _plan("auto"), fused.draw_block, records_sampling=True),
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
