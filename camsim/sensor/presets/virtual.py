"""Virtual cameras (as LED trains on them): plausible sensors drawn around the published calibrations.

A virtual camera is a camera preset with fits (ELD's and LED's cameras: :attr:`CameraPreset.fits`), a system gain K
drawn log-uniformly over the camera's range [K_min, K_max] (or over the union of the cameras' ranges), and each
noise scale drawn from its fit with the fit's residual scatter, ln σ = slope · ln K + bias + N(0, residual σ²), the
three scatters independent; the Tukey shape is one of the camera's published shapes, uniformly (ELD's baseline;
the A7M4, whose source gives only a span, draws uniformly over it). Everything else (levels, well, CFA) is the
preset's. :func:`virtual_camera_overrides` turns one draw into the preset's name and the sensor parameters that
differ from its default ISO, in the model's units.
"""

from __future__ import annotations

import math

import numpy as np

from camsim.core.errors import CamsimError
from camsim.sensor.presets.model import CameraPreset, IsoPoint

#: What ``k_range`` may be: each camera's own range, or the union of the listed cameras' ranges.
K_RANGES = ("camera", "union")
#: The sensor parameters a virtual camera sets (with ``preset``).
VIRTUAL_KEYS = ("preset", "analog_gain_dn_per_v", "read_noise_model", "read_noise_e", "tukey_lambda", "row_noise_e")


def cameras_with_fits(presets: dict, distinct: bool = False) -> tuple:
    """The names of the presets a virtual camera can be drawn from (those with fits); ``distinct``: one per set of
    fits (``sony-a7s2`` and ``sony-a7s2-eld`` share ELD's A7S2 fits: "all" cameras draws it once)."""
    names, seen = [], set()
    for name, p in presets.items():
        if p.fits and not (distinct and p.k_range_dn_per_e in seen):
            names.append(name)
            seen.add(p.k_range_dn_per_e)
    return tuple(names)


def virtual_point(camera: CameraPreset, k_dn_per_e: float, scatter: dict, shape_u: float) -> IsoPoint:
    """The figures of one virtual camera of ``camera`` at system gain K.

    Parameters
    ----------
    k_dn_per_e : float
        The drawn K. Unit: DN/e⁻.
    scatter : dict
        A standard normal per noise quantity (``tukey_scale_dn``, ``gaussian_sigma_dn``, ``row_sigma_dn``).
    shape_u : float
        A uniform variate in [0, 1) choosing the Tukey shape.
    """
    if not camera.fits:
        raise CamsimError(f"camera preset {camera.name} has no noise fits to draw virtual cameras from; cameras "
                          "with fits: ELD's and LED's")
    sigmas = {q: float(fit.at(k_dn_per_e) * math.exp(fit.residual_sigma * scatter[q]))
              for q, fit in camera.fits.items()}
    shapes = camera.tukey_shapes
    if camera.name == "sony-a7m4":  # LED gives the span only
        shape = shapes[0] + (shapes[-1] - shapes[0]) * shape_u
    else:
        shape = shapes[min(len(shapes) - 1, int(shape_u * len(shapes)))]
    k_min = camera.k_range_dn_per_e[0]
    return IsoPoint(iso=100.0 * k_dn_per_e / k_min, k_dn_per_e=float(k_dn_per_e), tukey_lambda=float(shape), **sigmas)


def virtual_camera_overrides(camera: CameraPreset, point: IsoPoint, read_noise_model: str | None = None) -> dict:
    """The preset name and sensor parameters (:data:`VIRTUAL_KEYS`) of the virtual camera ``point`` of ``camera``:
    on top of the preset's sensor at its default ISO they give ``camera.sensor(point=point)``."""
    sensor = camera.sensor(point=point, read_noise_model=read_noise_model)
    return {"preset": camera.name, "analog_gain_dn_per_v": sensor.analog_gain_dn_per_v,
            "read_noise_model": sensor.read_noise_model, "read_noise_e": sensor.read_noise_e,
            "tukey_lambda": sensor.tukey_lambda, "row_noise_e": sensor.row_noise_e}


def draw_virtual_cameras(cameras: list, n: int, streams: dict, k_range: str = "camera",
                         read_noise_model: str | None = None) -> list:
    """``n`` virtual cameras, each a dict of :data:`VIRTUAL_KEYS`, from the uniform/normal ``streams``.

    Parameters
    ----------
    cameras : list of CameraPreset
        Drawn from uniformly.
    streams : dict
        numpy Generators by name: ``camera``, ``k``, ``shape`` (uniforms) and one per noise quantity (normals), each
        consumed one value per camera in order (a longer draw starts with a shorter one's values).
    k_range : {'camera', 'union'}
        K log-uniform over the chosen camera's range, or over the union of the cameras' ranges (the camera's fits
        then extend beyond its own range).
    """
    if k_range not in K_RANGES:
        raise CamsimError(f"k_range must be one of {K_RANGES}, got {k_range!r}")
    pick = streams["camera"].random(n)
    k_u = streams["k"].random(n)
    shape_u = streams["shape"].random(n)
    quantities = ("tukey_scale_dn", "gaussian_sigma_dn", "row_sigma_dn")
    normals = {q: streams[q].standard_normal(n) for q in quantities}
    union = (min(c.k_range_dn_per_e[0] for c in cameras), max(c.k_range_dn_per_e[1] for c in cameras))
    out = []
    for i in range(n):
        camera = cameras[min(len(cameras) - 1, int(pick[i] * len(cameras)))]
        lo, hi = camera.k_range_dn_per_e if k_range == "camera" else union
        k = float(np.clip(math.exp(math.log(lo) + (math.log(hi) - math.log(lo)) * k_u[i]), lo, hi))
        point = virtual_point(camera, k, {q: normals[q][i] for q in quantities}, shape_u[i])
        out.append(virtual_camera_overrides(camera, point, read_noise_model))
    return out
