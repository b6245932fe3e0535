"""Regions named in a scene file (``[[region]]``): rectangles of a frame that the analysis measures as patches.

A chart's patches are its spectra: patch i is spectrum i everywhere inside its rectangle. A region is any
rectangle of any scene (an image, a cube, a dead-leaves target): the pixels inside it may show many spectra.
What the model expects of a region is the mean over its pixels: per spectrum the number of its pixels inside the
rectangle (:func:`region_weights`), and the weighted mean of the spectra's rows (:func:`weighted_rows`) —
computed on the K spectra (or a factored image's coefficients), never as a per-pixel spectrum cube.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError
from camsim.light.rates import FactoredSpectra

#: The keys a ``[[region]]`` table may hold.
REGION_KEYS = frozenset({"name", "rect"})


@dataclass(frozen=True)
class Region:
    """A named rectangle of the frame.

    Attributes
    ----------
    name : str
        The patch name it gets in the sidecar and the analysis.
    rect : tuple of int
        (x, y, width, height) of the top-left corner and the size. Unit: pixels.
    """

    name: str
    rect: tuple


def parse_regions(tables, where: str) -> tuple:
    """The :class:`Region` of each ``[[region]]`` table of a scene file (its size checked later, against the frame).

    Raises
    ------
    CamsimError
        One line: not an array of tables, unknown keys, a missing or non-string name, a rect that is not four
        integers, a width or height that is not positive, a negative corner, a name used twice.
    """
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise CamsimError(f"{where}: region must be an array of tables ([[region]] with name and rect)")
    regions, seen = [], set()
    for number, table in enumerate(tables, 1):
        unknown = set(table) - REGION_KEYS
        if unknown:
            raise CamsimError(f"{where}: unknown key(s) in region {number}: {', '.join(sorted(unknown))}")
        name, rect = table.get("name"), table.get("rect")
        if not isinstance(name, str) or not name:
            raise CamsimError(f"{where}: region {number} needs a name (a non-empty string), got {name!r}")
        ints = isinstance(rect, list) and len(rect) == 4 and all(
            isinstance(v, int) and not isinstance(v, bool) for v in rect)
        if not ints:
            raise CamsimError(f"{where}: region '{name}': rect must be [x, y, width, height] in whole pixels, "
                              f"got {rect!r}")
        x, y, w, h = rect
        if w <= 0 or h <= 0 or x < 0 or y < 0:
            raise CamsimError(f"{where}: region '{name}': rect {rect} needs x, y ≥ 0 and a positive width and "
                              "height (pixels)")
        if name in seen:
            raise CamsimError(f"{where}: region name '{name}' is used twice: names must be unique")
        seen.add(name)
        regions.append(Region(name, tuple(rect)))
    return tuple(regions)


def check_regions(regions, width: int, height: int, where: str = "scene") -> None:
    """Refuse regions that do not lie inside a ``width`` × ``height`` frame (pixels), or repeat a name.

    Raises
    ------
    CamsimError
        One line naming the region, its rect and the frame size.
    """
    seen = set()
    for region in regions:
        x, y, w, h = region.rect
        if min(w, h) <= 0 or min(x, y) < 0 or x + w > width or y + h > height:
            raise CamsimError(f"{where}: region '{region.name}' rect [{x}, {y}, {w}, {h}] does not lie inside the "
                              f"{width}x{height} frame (with a positive size)")
        if region.name in seen:
            raise CamsimError(f"{where}: region name '{region.name}' is used twice: names must be unique")
        seen.add(region.name)


def region_weights(labels: np.ndarray, rect) -> tuple[np.ndarray, np.ndarray]:
    """The spectra inside a rectangle of a label map and their pixel counts: ``(indices (m,), counts (m,))``.

    ``indices`` are the distinct labels inside ``rect`` (x, y, width, height in pixels), ascending; ``counts`` how
    many of the rectangle's pixels carry each (they sum to width × height).
    """
    x, y, w, h = rect
    block = np.asarray(labels[y : y + h, x : x + w]).ravel()
    indices, counts = np.unique(block, return_counts=True)
    return indices.astype(np.int64), counts.astype(np.int64)


def weighted_rows(rows, indices: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """The pixel-weighted mean of rows ``indices`` of ``rows``: Σ counts_k rows_k / Σ counts_k.

    Parameters
    ----------
    rows : numpy.ndarray or camsim.light.rates.FactoredSpectra, shape (K, ...)
        Per-spectrum values (spectra (K, N), expected electrons (K, 3), …). Factored spectra are averaged on
        their coefficients, then taken through the basis once: (Σ w c_k) B, exact (the map is linear).
    indices, counts : numpy.ndarray, shape (m,)
        From :func:`region_weights`.

    Returns
    -------
    numpy.ndarray, shape rows.shape[1:]
        In the unit of ``rows``.
    """
    weights = counts.astype(np.float64) / float(np.sum(counts))
    if isinstance(rows, FactoredSpectra):
        coefficients = rows.coefficient_rows(indices)
        return (weights @ coefficients) @ rows.basis
    return np.tensordot(weights, np.asarray(rows[indices], dtype=np.float64), axes=1)
