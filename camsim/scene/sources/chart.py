"""A reflectance chart: a grid of flat patches on a surround — K spectra and a label map, nothing per pixel."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from camsim.core.errors import CamsimError
from camsim.light.spectra import reflectance_set
from camsim.scene.chart import ChartGeometry
from camsim.scene.sources.base import SceneSource, SourceSpectra, typed


@dataclass(frozen=True)
class ChartSource(SceneSource):
    """A reflectance chart (scene-file table ``[chart]``).

    Attributes
    ----------
    reflectances : str
        A colour-science ``SDS_COLOURCHECKERS`` name or a CSV of reflectances.
    geometry : ChartGeometry
        Patches across and down, gaps and margins.
    surround_reflectance : float
        Reflectance of the surround, in [0, 1] (unitless).
    base_dir : pathlib.Path or None
        Where a reflectance CSV is looked for.
    """

    table = "chart"
    keys = frozenset({"reflectances", "columns", "rows", "gap_fraction", "margin_fraction", "surround_reflectance"})

    reflectances: str = "ColorChecker N Ohta"
    geometry: ChartGeometry = field(default_factory=ChartGeometry)
    surround_reflectance: float = 0.05
    base_dir: object = None

    @classmethod
    def from_table(cls, table: dict, base_dir, where: str) -> ChartSource:
        surround = typed(table, "surround_reflectance", float, 0.05, where)
        if not 0 <= surround <= 1:
            raise CamsimError(f"{where}: surround_reflectance must be in [0, 1], got {surround}")
        return cls(
            reflectances=typed(table, "reflectances", str, "ColorChecker N Ohta", where),
            geometry=ChartGeometry(
                columns=typed(table, "columns", int, 6, where),
                rows=typed(table, "rows", int, 4, where),
                gap_fraction=typed(table, "gap_fraction", float, 0.15, where),
                margin_fraction=typed(table, "margin_fraction", float, 0.04, where),
            ),
            surround_reflectance=surround,
            base_dir=base_dir,
        )

    def spectra(self, grid, width: int, height: int) -> SourceSpectra:
        """The patches' reflectances plus the surround's (K = patches + 1) and the chart's label map."""
        names, refl = reflectance_set(self.reflectances, grid, self.base_dir)
        geometry = self.geometry
        if len(names) != geometry.n_patches:
            raise CamsimError(
                f"reflectance set {self.reflectances!r} has {len(names)} spectra but the chart is "
                f"{geometry.columns} × {geometry.rows}"
            )
        refl = np.vstack([refl, np.full((1, grid.size), self.surround_reflectance)])
        return SourceSpectra(geometry.label_map(width, height), refl, "reflectance", names,
                             geometry.rects(width, height), self.reflectances)
