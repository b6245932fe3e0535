"""Scene sources: what is in front of the camera, one module per kind, registered here.

:data:`SOURCES` maps a scene file's table name to its source class (:class:`camsim.scene.sources.base.SceneSource`):
``[chart]`` (:class:`ChartSource`, a reflectance chart: a label map plus K spectra), ``[cube]``
(:class:`CubeSource`, a hyperspectral cube: ``.npy``, ENVI or ``.mat``), ``[image]`` (:class:`ImageSource`, an
RGB picture whose distinct colours are recovered as spectra, kept factored on a three-spectrum basis) and
``[target]`` (:class:`TargetSource`, a synthetic dead-leaves chart, slanted edge or flat field: a label map plus K
spectra) and ``[raw]`` (:class:`RawSource`, a real camera's raw file: per site the electrons it recorded, drawn
by :mod:`camsim.render.raw_render`, not from spectra). A new kind of scene is one module with one class, added to
:data:`SOURCES`.
"""

from camsim.scene.sources.base import SceneSource, SourceSpectra
from camsim.scene.sources.chart import ChartSource
from camsim.scene.sources.cube import CubeSource
from camsim.scene.sources.image import ImageSource
from camsim.scene.sources.raw import RawSource
from camsim.scene.sources.target import TargetSource

#: Source classes by their scene-file table name.
SOURCES = {cls.table: cls for cls in (ChartSource, CubeSource, ImageSource, TargetSource, RawSource)}

__all__ = ["SOURCES", "ChartSource", "CubeSource", "ImageSource", "RawSource", "SceneSource", "SourceSpectra",
           "TargetSource"]
