"""Real cameras: published noise calibrations with an ISO axis (:data:`CAMERA_PRESETS`), preset files written by
``camsim calibrate``, and the one entry point every command resolves a ``preset`` name with (:func:`sensor_preset`).

A ``preset`` is either one of the model's sensor presets (:data:`camsim.sensor.params.PRESETS`: ``paper-table1`` …, no
ISO axis), a camera preset by name (``sony-a7s2``), or a camera preset file (a path ending in ``.toml``).
"""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

from camsim.core.errors import CamsimError
from camsim.sensor.params import PRESETS, SensorParams, preset, with_overrides
from camsim.sensor.presets.data import build_presets
from camsim.sensor.presets.files import read_preset_file
from camsim.sensor.presets.model import CameraPreset, IsoPoint, NoiseFit

#: The built-in camera presets, by name.
CAMERA_PRESETS = build_presets()


def preset_names() -> tuple:
    """Every preset name: the model's sensor presets, then the cameras."""
    return tuple(PRESETS) + tuple(CAMERA_PRESETS)


def is_preset_file(name: str) -> bool:
    return str(name).endswith(".toml")


@lru_cache(maxsize=32)
def _file_preset(path: str, mtime_ns: int) -> CameraPreset:
    return read_preset_file(path)


def camera_preset(name: str, base_dir: str | Path | None = None) -> CameraPreset | None:
    """The camera preset ``name`` (built-in, or a ``.toml`` file, relative to ``base_dir``), or None for a sensor
    preset of the model; an unknown name is a :class:`CamsimError`."""
    if is_preset_file(name):
        path = Path(name)
        if not path.is_absolute() and base_dir is not None:
            path = Path(base_dir) / path
        from camsim.core.input_files import open_input

        with open_input(path, "camera preset file") as handle:  # a regular file (not a FIFO), no NUL byte
            mtime = os.fstat(handle.fileno()).st_mtime_ns
        return _file_preset(str(path.resolve()), mtime)
    if name in CAMERA_PRESETS:
        return CAMERA_PRESETS[name]
    if name in PRESETS:
        return None
    raise CamsimError(f"unknown preset {name!r}; presets: {', '.join(preset_names())}, or a preset file PATH.toml")


def preset_for_camera(make: str | None, model: str | None, unique_camera_model: str | None = None) -> str | None:
    """The name of the first built-in camera preset whose camera a raw file's Make and Model (or UniqueCameraModel)
    name (:meth:`CameraPreset.matches`), or None. Where two presets describe one camera (``sony-a7s2`` and
    ``sony-a7s2-eld``) the first listed wins; only presets of Bayer sensors are candidates."""
    for name, camera in CAMERA_PRESETS.items():
        if camera.cfa is not None and camera.matches(make, model, unique_camera_model):
            return name
    return None


def sensor_preset(name: str, iso: float | None = None, base_dir: str | Path | None = None,
                  **overrides) -> SensorParams:
    """The sensor of preset ``name`` at ``iso``, with sensor parameters ``overrides`` applied last.

    A camera preset takes its read-noise law from ``overrides["read_noise_model"]`` when given (the Gaussian σ or
    the Tukey law's); a model preset has no ISO axis, so ``iso`` must be None there.
    """
    camera = camera_preset(name, base_dir)
    if camera is None:
        if iso is not None:
            raise CamsimError(f"preset {name} has no ISO axis; --iso needs a camera preset "
                              f"({', '.join(CAMERA_PRESETS)})")
        return preset(name, **overrides)
    return with_overrides(camera.sensor(iso, overrides.get("read_noise_model")), **overrides)


__all__ = ["CAMERA_PRESETS", "CameraPreset", "IsoPoint", "NoiseFit", "camera_preset", "is_preset_file",
           "preset_for_camera", "preset_names", "read_preset_file", "sensor_preset"]
