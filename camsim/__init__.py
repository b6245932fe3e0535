"""camsim: a physically grounded camera simulator.

Spectral scenes (a label map plus K spectra for charts, or a hyperspectral cube) pass through the image-sensor
model of the 2014 low-light colour-measurement paper (photons, dark current, saturation, read noise, gain,
quantisation) into 8-bit raw DNG and float EXR frames. The docs' model page states the model.

The few objects a Python user needs are here (imported on first use, so ``import camsim`` is instant):

* :func:`load_scene` — a scene file (or a built-in scene) as a :class:`Scene`;
* :func:`scene_frame` — one frame of a scene (a :class:`Frame` and its :class:`FrameInfo`);
* :func:`render_scene` — every frame of a scene into a folder, as ``camsim render`` does;
* :func:`write_frame`, :func:`load_frame` — the frame files (DNG, EXR, JSON sidecar), both ways;
* :func:`analyse_paths` with :class:`AnalysisSettings` — the measurements of ``camsim analyze``;
* :class:`SensorParams`, :data:`PRESETS` and :func:`preset` — the sensor; :data:`METHODS` — the samplers;
* :data:`CAMERA_PRESETS` and :func:`sensor_preset` — real cameras at an ISO (``sensor_preset("sony-a7s2", 3200)``).

Example
-------
>>> import camsim
>>> scene = camsim.load_scene("scenes/macbeth_26.toml").replace(width=120, height=80)  # doctest: +SKIP
>>> frame, info = camsim.scene_frame(scene, "D65", 0.1, seed=7)                      # doctest: +SKIP
>>> frame.digital_dn.shape                                                            # doctest: +SKIP
(3, 80, 120)
"""

from importlib import import_module

__version__ = "0.1.0"

#: Public name -> the module that defines it.
_EXPORTS = {
    "load_scene": "camsim.scene.scene_file",
    "Scene": "camsim.scene.scene_file",
    "scene_frame": "camsim.render.pipeline",
    "make_frame": "camsim.render.pipeline",
    "light_scene": "camsim.render.pipeline",
    "render_scene": "camsim.render.run",
    "Frame": "camsim.render.frame",
    "FrameInfo": "camsim.render.frame_files",
    "write_frame": "camsim.render.frame_files",
    "load_frame": "camsim.render.frame_files",
    "analyse_paths": "camsim.analysis.analyze",
    "AnalysisSettings": "camsim.analysis.patches",
    "SensorParams": "camsim.sensor.params",
    "PRESETS": "camsim.sensor.params",
    "preset": "camsim.sensor.params",
    "CAMERA_PRESETS": "camsim.sensor.presets",
    "sensor_preset": "camsim.sensor.presets",
    "METHODS": "camsim.methods",
    "CamsimError": "camsim.core.errors",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'camsim' has no attribute {name!r}")


def __dir__():
    return sorted(__all__)
