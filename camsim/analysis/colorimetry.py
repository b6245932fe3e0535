"""The old address of :func:`camsim.colorimetry.camera_to_xyz_matrix`, kept only because
:mod:`camsim.experiments.runner` still imports it from here; the colorimetry itself lives in the core module
:mod:`camsim.colorimetry`. Remove this module when that import points there."""

from camsim.colorimetry import camera_to_xyz_matrix

__all__ = ["camera_to_xyz_matrix"]
