"""A hyperspectral cube: an H × W × B array of reflectance or radiance in a ``.npy``, ENVI or MATLAB file, read
onto the scene's wavelength grid by :mod:`camsim.io.cube_files`."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.io.cube_files import CUBE_READERS, CubeRows, cube_size, read_cube
from camsim.light.rates import FactoredSpectra
from camsim.scene.sources.base import SceneSource, SourceSpectra, typed

CUBE_KINDS = ("reflectance", "radiance")


@dataclass(frozen=True)
class CubeSource(SceneSource):
    """A hyperspectral cube scene (scene-file table ``[cube]``): one label per pixel.

    Attributes
    ----------
    path : pathlib.Path
        The cube file: ``.npy`` (H × W × B), ENVI (``.hdr`` or its binary) or MATLAB ``.mat`` (v4 – v7), read by
        :func:`camsim.io.cube_files.read_cube`.
    kind : {'reflectance', 'radiance'}
        Reflectance (unitless, lit by the scene's illuminants) or radiance (W / (m² sr nm), its own scale).
    wavelengths_nm : tuple of float or None
        The cube's B wavelengths in nm, overriding the file's (a ``.npy`` file has none: without this key its
        bands must be the scene grid's). Cubes off the grid are resampled to it with colour-science.
    variable : str or None
        The cube's variable in a ``.mat`` file that holds several 3-D arrays.
    """

    table = "cube"
    keys = frozenset({"path", "kind", "wavelengths_nm", "variable"})
    has_own_size = True

    path: Path
    kind: str = "reflectance"
    wavelengths_nm: tuple | None = None
    variable: str | None = None

    @classmethod
    def from_table(cls, table: dict, base_dir, where: str) -> CubeSource:
        if "path" not in table:
            raise CamsimError(f"{where}: [cube] needs a path to a cube file ({', '.join(sorted(CUBE_READERS))})")
        kind = typed(table, "kind", str, "reflectance", where)
        if kind not in CUBE_KINDS:
            raise CamsimError(f"{where}: [cube] kind must be one of {CUBE_KINDS}, got {kind!r}")
        wavelengths = typed(table, "wavelengths_nm", list, None, where)
        if wavelengths is not None:
            if not wavelengths or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                          for v in wavelengths):
                raise CamsimError(f"{where}: [cube] wavelengths_nm must be a list of numbers (nm)")
            wavelengths = tuple(float(v) for v in wavelengths)
        return cls(path=base_dir / typed(table, "path", str, "", where), kind=kind, wavelengths_nm=wavelengths,
                   variable=typed(table, "variable", str, None, where))

    def own_size(self) -> tuple[int, int]:
        """(W, H) of the cube, read from the file's header (``.npy`` / ENVI header, MAT directory); no data read."""
        return cube_size(self.path, variable=self.variable)

    def spectra(self, grid, width: int, height: int) -> SourceSpectra:
        """Every pixel its own spectrum (the frame has the cube's size), kept factored on the file.

        The spectra are :class:`camsim.light.rates.FactoredSpectra` whose coefficients are the cube's stored values,
        read block by block from the file (:class:`camsim.io.cube_files.CubeRows`), and whose basis is the
        B → N resampling divided by the file's scale factor (the identity on the grid). Everything linear in the
        spectra — radiance under a light, photon rate, expected electrons (Eqs. 3–6), Eq. 4's variance — is one pass
        over the file into (H · W, 3) arrays: a 12 MP × 101-band cube is never copied whole. The labels are
        (H, W) uint32, pixel p = y · W + x.
        """
        cube = read_cube(self.path, grid, wavelengths_nm=self.wavelengths_nm, variable=self.variable)
        h, w, _ = cube.shape
        labels = np.arange(h * w, dtype=np.uint32).reshape(h, w)
        rows = CubeRows(cube)
        return SourceSpectra(labels, FactoredSpectra(rows, rows.basis()), self.kind, [], [], self.path.name)

