"""The search: for each light level F, the exposure time and ISO that score best, from the closed-form moments
(:mod:`camsim.optimise.model`), over a grid of exposures (log-spaced up to the user's limit) and the camera
preset's published ISO points within the user's range.

Objectives (``snr``, ``delta-e``, ``both``):

* ``snr`` — the mean over the scene's patches and channels of Eq. 14's SNR in dB (maximised);
* ``delta-e`` — the mean over the patches of E[ΔE_ab] of a sample against the patch's noise-free colour, by the
  paper's procedure (every sample scaled to Y = 100; minimised), each channel's value Gaussian with the model's
  mean and variance (Gauss–Hermite quadrature);
* ``both`` — the Pareto front of the two; the table gives its SNR end and its ΔE end.

A setting that brings any patch near the well or the top of the ADC is not allowed (the moments would not hold
there, and a clipped patch loses its colour): the light level caps T · F.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from camsim.core.errors import CamsimError
from camsim.optimise.model import (
    expected_delta_e,
    lab_of,
    noise_terms_e2,
    saturation_free,
    snr_db,
)

OBJECTIVES = ("snr", "delta-e", "both")
#: Exposure grid: this many values per decade, over this many decades below the longest allowed exposure.
EXPOSURES_PER_DECADE, EXPOSURE_DECADES = 8, 4


@dataclass(frozen=True)
class Choice:
    """The best setting at one light level, for one objective."""

    intensity_factor: float
    exposure_s: float
    iso: float | None
    snr_db: float
    delta_e: float | None
    dominant_noise: str  # the largest variance term at the median patch: shot, dark, read, row or quantisation
    limited_by: str  # "exposure limit", "saturation" or "neither" (an interior optimum)
    objective: str


@dataclass
class OptimiseResult:
    """Everything the search found: the grids it scored and the best settings."""

    preset: str
    isos: list
    exposures_s: np.ndarray
    factors: list
    objective: str
    snr_grid: dict = field(default_factory=dict)  # F -> (nT, nI) mean SNR dB (NaN where not allowed)
    delta_e_grid: dict = field(default_factory=dict)  # F -> (nT, nI) mean E[ΔE] (NaN where not allowed)
    choices: list = field(default_factory=list)  # Choice, per F (two per F for "both")
    fronts: dict = field(default_factory=dict)  # F -> [(T, ISO, snr, ΔE)] for "both"
    search_s: float = 0.0


def iso_axis(camera, iso_range) -> list:
    """The ISO settings searched: the camera preset's published points within ``iso_range`` (all without one);
    ``[None]`` for a preset without an ISO axis."""
    if camera is None or len(camera.iso_points) == 1:
        if iso_range is not None:
            name = "this preset" if camera is None else camera.name
            raise CamsimError(f"--iso-range needs a camera preset with an ISO axis; {name} has none")
        return [None] if camera is None else [camera.iso_points[0].iso]
    points = [p.iso for p in camera.iso_points]
    if iso_range is None:
        return points
    low, high = iso_range
    if not (math.isfinite(low) and math.isfinite(high) and 0 < low <= high):
        raise CamsimError(f"--iso-range needs 0 < A ≤ B, got {low:g} {high:g}")
    inside = [iso for iso in points if low * (1 - 1e-9) <= iso <= high * (1 + 1e-9)]
    if not inside:
        raise CamsimError(f"--iso-range {low:g}–{high:g} holds none of {camera.name}'s ISO points "
                          f"({points[0]:g}–{points[-1]:g})")
    return inside


def exposure_axis(max_exposure_s: float) -> np.ndarray:
    """Exposures searched: :data:`EXPOSURES_PER_DECADE` a decade over :data:`EXPOSURE_DECADES` decades, ending at
    the longest allowed. Unit: s."""
    if not (math.isfinite(max_exposure_s) and max_exposure_s > 0):
        raise CamsimError(f"--max-exposure must be a positive number of seconds, got {max_exposure_s:g}")
    n = EXPOSURES_PER_DECADE * EXPOSURE_DECADES + 1
    return max_exposure_s * np.logspace(-EXPOSURE_DECADES, 0, n)


@dataclass(frozen=True)
class PatchRates:
    """The scene's patches under its light at F = 1: signal electrons per second of exposure, their noise-free
    colour, and the camera → XYZ matrix."""

    names: list
    rates_e_per_s: np.ndarray  # (P, 3)
    to_xyz: np.ndarray  # (3, 3)
    white_xy: np.ndarray  # (2,)
    reference_lab: np.ndarray  # (P, 3)


def patch_rates(scene, illuminant: str, sensor) -> PatchRates:
    """The rates of ``scene``'s patches (``pixel`` statistics; the rates do not depend on the ISO)."""
    import dataclasses

    from camsim.analysis.delta_e import d65_white_xy
    from camsim.colour.colorimetry import camera_to_xyz_matrix
    from camsim.render.pipeline import light_scene

    lit = light_scene(scene, illuminant)
    names = list(lit.radiance.patch_names)
    if not names or lit.radiance.patch_weights is not None:
        raise CamsimError(f"camsim optimise needs a scene with patches (a chart), not {scene.source.table}")
    one_second = dataclasses.replace(sensor, exposure_s=1.0)
    rates = np.asarray(lit.expected(one_second, 1.0, "pixel").signal_e[: len(names)], dtype=np.float64)
    to_xyz = camera_to_xyz_matrix(lit.qe, scene.grid.wavelengths_nm, 1.0)
    white = d65_white_xy()
    return PatchRates(names, rates, to_xyz, white, lab_of(rates, to_xyz, white))


def optimise(rates: PatchRates, sensors: list, exposures_s: np.ndarray, factors, objective: str = "snr",
             preset: str = "") -> OptimiseResult:
    """Score every (T, ISO) at every F and pick the best (module docstring).

    Parameters
    ----------
    rates : PatchRates
    sensors : list of SensorAtIso
        One per ISO searched.
    exposures_s : numpy.ndarray
        Exposures searched, ascending. Unit: s.
    factors : sequence of float
        Light levels F.
    objective : {'snr', 'delta-e', 'both'}
    """
    if objective not in OBJECTIVES:
        raise CamsimError(f"--objective must be one of {', '.join(OBJECTIVES)}, got {objective!r}")
    start = time.perf_counter()
    t = np.asarray(exposures_s, dtype=np.float64)[:, None, None]  # (nT, 1, 1)
    result = OptimiseResult(preset, [s.iso for s in sensors], np.asarray(exposures_s), list(factors), objective)
    want_de = objective in ("delta-e", "both")
    for factor in factors:
        snr = np.full((t.shape[0], len(sensors)), np.nan)
        de = np.full_like(snr, np.nan)
        per_setting = {}
        for j, sensor in enumerate(sensors):
            signal = factor * rates.rates_e_per_s[None] * t  # (nT, P, 3)
            dark = sensor.dark_current_e_per_s[None, None, :] * t
            allowed = saturation_free(signal, dark, sensor)
            scores = np.mean(snr_db(signal, dark, sensor), axis=(1, 2))
            snr[allowed, j] = scores[allowed]
            if want_de and np.any(allowed):
                variance = sum(noise_terms_e2(signal[allowed], dark[allowed], sensor).values())
                de[allowed, j] = np.nanmean(expected_delta_e(signal[allowed], variance, rates.reference_lab,
                                                             rates.to_xyz, rates.white_xy), axis=-1)
            per_setting[j] = (signal, dark, allowed)
        result.snr_grid[factor] = snr
        if want_de:
            result.delta_e_grid[factor] = de
        if not np.any(np.isfinite(snr)):
            raise CamsimError(f"at F = {factor:g} every setting saturates a patch (even {t[0, 0, 0]:.3g} s at "
                              "the lowest ISO): lower the light or allow shorter exposures")
        goals = {"snr": [("snr", snr, np.nanargmax)], "delta-e": [("delta-e", de, np.nanargmin)],
                 "both": [("snr", snr, np.nanargmax), ("delta-e", de, np.nanargmin)]}[objective]
        for name, grid, pick in goals:
            i, j = np.unravel_index(pick(grid), grid.shape)
            result.choices.append(_choice(factor, i, j, exposures_s, sensors, per_setting, snr, de if want_de
                                          else None, rates, name))
        if objective == "both":
            result.fronts[factor] = _pareto(snr, de, exposures_s, result.isos)
    result.search_s = time.perf_counter() - start
    return result


def _choice(factor, i, j, exposures_s, sensors, per_setting, snr, de, rates, objective) -> Choice:
    signal, dark, allowed = per_setting[j]
    terms = noise_terms_e2(signal[i], dark[i], sensors[j])
    median = {name: float(np.median(value)) for name, value in terms.items()}
    if i == len(exposures_s) - 1:
        limited = "exposure limit"
    elif not allowed[i + 1]:
        limited = "saturation"
    else:
        limited = "neither"
    return Choice(intensity_factor=factor, exposure_s=float(exposures_s[i]), iso=sensors[j].iso,
                  snr_db=float(snr[i, j]), delta_e=None if de is None else float(de[i, j]),
                  dominant_noise=max(median, key=median.get), limited_by=limited, objective=objective)


def _pareto(snr, de, exposures_s, isos) -> list:
    """The settings no other beats in both SNR (higher) and ΔE (lower): [(T, ISO, SNR dB, ΔE)], by SNR."""
    points = [(float(snr[i, j]), float(de[i, j]), float(exposures_s[i]), isos[j])
              for i, j in zip(*np.nonzero(np.isfinite(snr) & np.isfinite(de)))]
    points.sort(key=lambda p: (-p[0], p[1]))
    front, best_de = [], np.inf
    for s, d, t, iso in points:
        if d < best_de:
            front.append((t, iso, s, d))
            best_de = d
    return front
