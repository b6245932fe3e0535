"""Datasets: many frames from a spec (grid and random draws of scenes, illuminants, light levels, exposure and
sensor parameters), rendered in parallel and resumably, with a JSON Lines manifest. See :mod:`camsim.dataset.spec`
for the spec format (:mod:`camsim.dataset.raws` for a ``[raws]`` spec's, :mod:`camsim.dataset.spec_parts` for what
both are made of: parameters, frames, ids and seeds), :mod:`camsim.dataset.runner` for the run,
:mod:`camsim.dataset.manifest` for the output layout, :mod:`camsim.dataset.backends` for the back-ends,
:mod:`camsim.dataset.frame_render` for one frame and :mod:`camsim.dataset.srgb` for its developed sRGB pair.

Importing the package is cheap; the names below load their modules on first use.
"""

_EXPORTS = {
    "DatasetSpec": "camsim.dataset.spec_parts",
    "FrameSpec": "camsim.dataset.spec_parts",
    "load_spec": "camsim.dataset.spec",
    "plan_spec": "camsim.dataset.spec",
    "run_dataset": "camsim.dataset.runner",
    "read_manifest": "camsim.dataset.manifest",
}
__all__ = list(_EXPORTS)


def __getattr__(name):
    if name in _EXPORTS:
        import importlib

        return getattr(importlib.import_module(_EXPORTS[name]), name)
    raise AttributeError(f"module 'camsim.dataset' has no attribute {name!r}")
