"""Layer 7, scenes: what is in front of the camera, and the spectral radiance it sends; imports only the layers
below (:mod:`camsim.core` to :mod:`camsim.methods`).

:mod:`camsim.scene.scene_file` (scene files: :func:`load_scene`, :class:`Scene`), :mod:`camsim.scene.sources`
(one module per kind of source: chart, cube, image, synthetic target), :mod:`camsim.scene.chart` (chart geometry),
:mod:`camsim.scene.builtin_scenes` (the scene files shipped in ``camsim/scenes/``, by name),
:mod:`camsim.scene.regions` (``[[region]]`` rectangles) and :mod:`camsim.scene.radiance` (a scene under one
illuminant as spectral radiance). ``tests/test_layers.py`` checks the layers.

``load_scene`` and ``Scene`` are also here (``from camsim.scene import load_scene``), imported on first use so that
importing a module of this package stays cheap; camsim's own modules import them from
:mod:`camsim.scene.scene_file`.
"""

from importlib import import_module

_EXPORTS = {"load_scene": "camsim.scene.scene_file", "Scene": "camsim.scene.scene_file"}

__all__ = list(_EXPORTS)


def __getattr__(name: str):
    if name in _EXPORTS:
        value = getattr(import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'camsim.scene' has no attribute {name!r}")


def __dir__():
    return sorted([*globals(), *__all__])
