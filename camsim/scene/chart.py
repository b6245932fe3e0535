"""Chart geometry: a grid of flat patches on a surround, as a label map (never a spectral cube)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError


@dataclass(frozen=True)
class ChartGeometry:
    """Layout of a patch chart within a frame.

    Attributes
    ----------
    columns, rows : int
        Patches across and down (a ColorChecker is 6 × 4).
    gap_fraction : float
        Gap between neighbouring patches, as a fraction of the patch pitch, in [0, 0.9].
    margin_fraction : float
        Surround left around the grid on each side, as a fraction of the frame width / height, in [0, 0.45).
    """

    columns: int = 6
    rows: int = 4
    gap_fraction: float = 0.15
    margin_fraction: float = 0.04

    def __post_init__(self):
        if not (isinstance(self.columns, int) and isinstance(self.rows, int) and self.columns > 0 and self.rows > 0):
            raise CamsimError(f"chart columns and rows must be positive integers, got {self.columns} × {self.rows}")
        if not 0 <= self.gap_fraction <= 0.9:
            raise CamsimError(f"chart gap_fraction must be in [0, 0.9], got {self.gap_fraction}")
        if not 0 <= self.margin_fraction < 0.45:
            raise CamsimError(f"chart margin_fraction must be in [0, 0.45), got {self.margin_fraction}")

    @property
    def n_patches(self) -> int:
        return self.columns * self.rows

    def rects(self, width: int, height: int) -> list[tuple[int, int, int, int]]:
        """Patch rectangles ``(x, y, w, h)`` in pixels, row-major from the top left.

        Raises CamsimError when the frame is too small to give every patch at least 2 × 2 pixels.
        """
        rects = []
        x_edges = _patch_edges(width, self.columns, self.margin_fraction, self.gap_fraction)
        y_edges = _patch_edges(height, self.rows, self.margin_fraction, self.gap_fraction)
        for y0, y1 in y_edges:
            for x0, x1 in x_edges:
                rects.append((x0, y0, x1 - x0, y1 - y0))
        if min(min(w, h) for _, _, w, h in rects) < 2:
            raise CamsimError(
                f"frame {width}×{height} is too small for a {self.columns}×{self.rows} chart "
                "(each patch needs at least 2×2 pixels)"
            )
        return rects

    def label_map(self, width: int, height: int) -> np.ndarray:
        """Label map of shape (height, width): patch i (row-major) has label i; the surround is ``n_patches``.

        Returns
        -------
        numpy.ndarray, shape (H, W), dtype uint8 (uint16 for more than 255 patches)
        """
        dtype = np.uint8 if self.n_patches < 255 else np.uint16
        labels = np.full((height, width), self.n_patches, dtype=dtype)
        for index, (x, y, w, h) in enumerate(self.rects(width, height)):
            labels[y : y + h, x : x + w] = index
        return labels


def _patch_edges(length: int, count: int, margin_fraction: float, gap_fraction: float):
    margin = length * margin_fraction
    pitch = (length - 2 * margin) / count
    gap = pitch * gap_fraction
    edges = []
    for i in range(count):
        start = int(round(margin + i * pitch + gap / 2))
        stop = int(round(margin + (i + 1) * pitch - gap / 2))
        edges.append((start, stop))
    return edges


def parse_size(text: str) -> tuple[int, int]:
    """Parse ``"WxH"`` into (width, height) in pixels."""
    parts = text.lower().replace("×", "x").split("x")
    try:
        width, height = (int(p) for p in parts)
    except ValueError:
        raise CamsimError(f"size must look like WIDTHxHEIGHT (e.g. 600x400), got {text!r}") from None
    if width <= 0 or height <= 0:
        raise CamsimError(f"size must be positive, got {text!r}")
    from camsim.core.pixel_limit import check_pixel_count

    return check_pixel_count(width, height, f"size {text}")
