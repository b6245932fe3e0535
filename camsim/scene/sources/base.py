"""What every kind of scene source provides: its spectra and a label map, before any light or camera."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camsim.core.schema import typed  # noqa: F401  (the sources' table reader, kept importable from here)


@dataclass(frozen=True)
class SourceSpectra:
    """A scene source on the wavelength grid: a label map plus K spectra.

    Attributes
    ----------
    labels : numpy.ndarray, shape (H, W), unsigned integer
        Index into ``spectra`` for every pixel.
    spectra : numpy.ndarray, shape (K, N)
        Reflectance (unitless, 1 = the perfect white) or, for an emissive source, radiance (W / (m² sr nm)).
    kind : {'reflectance', 'radiance'}
    patch_names : list of str
        Names of the measured patches (the first ``len(patch_names)`` spectra; empty without patches).
    patch_rects : list of (x, y, w, h)
        Patch rectangles in pixels.
    name : str
        The reflectance set or file the spectra come from (the sidecar's ``reflectances``).
    surround : bool
        Whether the spectrum after the patches is a surround (a chart's), which the sidecar reports.
    target : dict or None
        A synthetic target's geometry and parameters (:mod:`camsim.scene.sources.target`), the sidecar's ``target``.
    recovery : dict or None
        An image's RGB → spectrum recovery and what fell outside its gamut
        (:meth:`camsim.scene.sources.image.ImageSource.spectra`), the sidecar's ``recovery``; None for spectral sources.
    """

    labels: np.ndarray
    spectra: np.ndarray
    kind: str
    patch_names: list
    patch_rects: list
    name: str
    surround: bool = True
    target: dict | None = None
    recovery: dict | None = None


class SceneSource:
    """Base class of the scene sources registered in :data:`camsim.scene.sources.SOURCES`.

    A source is a frozen dataclass read from its own table of a scene file (``[chart]``, ``[cube]``, …) by
    :meth:`from_table`, and gives its spectra with :meth:`spectra`. A new kind of scene is one module with one
    such class, registered in :mod:`camsim.scene.sources`.
    """

    #: The scene-file table this source is read from.
    table: str = ""
    #: The keys that table may hold.
    keys: frozenset = frozenset()
    #: Whether the source fixes the frame size (:meth:`own_size`), as a cube does; else [frame] sets it.
    has_own_size: bool = False

    @classmethod
    def from_table(cls, table: dict, base_dir, where: str) -> SceneSource:
        """The source described by its scene-file table (keys already checked against :attr:`keys`)."""
        raise NotImplementedError

    def own_size(self) -> tuple[int, int] | None:
        """(W, H) when the source fixes the frame size (:attr:`has_own_size`), None when [frame] sets it."""
        return None

    def spectra(self, grid, width: int, height: int) -> SourceSpectra:
        """The source's label map (for a frame of ``width`` × ``height`` where it has no size of its own) and
        spectra on ``grid``."""
        raise NotImplementedError
