"""A hyperspectral cube: an H × W × N ``.npy`` array of reflectance or radiance on the scene's grid."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camsim.errors import CamsimError
from camsim.sources.base import SceneSource, SourceSpectra, typed

CUBE_KINDS = ("reflectance", "radiance")


@dataclass(frozen=True)
class CubeSource(SceneSource):
    """A hyperspectral cube scene (scene-file table ``[cube]``): one label per pixel.

    Attributes
    ----------
    path : pathlib.Path
        The ``.npy`` file, H × W × N on the scene's wavelength grid.
    kind : {'reflectance', 'radiance'}
        Reflectance (unitless, lit by the scene's illuminants) or radiance (W / (m² sr nm), its own scale).
    """

    table = "cube"
    keys = frozenset({"path", "kind"})
    has_own_size = True

    path: Path
    kind: str = "reflectance"

    @classmethod
    def from_table(cls, table: dict, base_dir, where: str) -> CubeSource:
        if "path" not in table:
            raise CamsimError(f"{where}: [cube] needs a path to an H × W × N .npy file")
        kind = typed(table, "kind", str, "reflectance", where)
        if kind not in CUBE_KINDS:
            raise CamsimError(f"{where}: [cube] kind must be one of {CUBE_KINDS}, got {kind!r}")
        return cls(path=base_dir / typed(table, "path", str, "", where), kind=kind)

    def own_size(self) -> tuple[int, int]:
        """(W, H) of the cube, read from the file's header."""
        try:
            height, width = np.load(self.path, mmap_mode="r", allow_pickle=False).shape[:2]
        except FileNotFoundError:
            raise CamsimError(f"cube file not found: {self.path}") from None
        except (OSError, ValueError) as exc:
            raise CamsimError(f"cannot read cube {self.path}: {exc}") from None
        return int(width), int(height)

    def spectra(self, grid, width: int, height: int) -> SourceSpectra:
        """Every pixel its own spectrum (the frame has the cube's size)."""
        cube = load_cube(self.path, grid.size)
        h, w = cube.shape[:2]
        labels = np.arange(h * w, dtype=np.uint32).reshape(h, w)
        return SourceSpectra(labels, cube.reshape(-1, grid.size), self.kind, [], [], self.path.name)


def load_cube(path, n_bins: int) -> np.ndarray:
    """Load a hyperspectral cube (``.npy``, H × W × N, float) and check it against the scene grid."""
    try:
        cube = np.load(path, allow_pickle=False)
    except FileNotFoundError:
        raise CamsimError(f"cube file not found: {path}") from None
    except (OSError, ValueError, EOFError) as exc:
        raise CamsimError(f"cannot read cube file {path}: {exc}") from None
    if cube.ndim != 3:
        raise CamsimError(f"cube {path} must be H × W × N, got shape {cube.shape}")
    if cube.shape[2] != n_bins:
        raise CamsimError(
            f"cube {path} has {cube.shape[2]} wavelength bins but the scene's grid has {n_bins}: "
            "set [spectral] to the cube's grid"
        )
    cube = np.asarray(cube, dtype=np.float64)
    if not np.all(np.isfinite(cube)):
        raise CamsimError(f"cube {path} contains NaN or infinite values")
    if np.any(cube < 0):
        raise CamsimError(f"cube {path} has negative values")
    return cube
