"""Packing a Bayer mosaic into four half-resolution planes R, G1, G2, B (the SID/ELD convention of raw denoisers)."""

from __future__ import annotations

import numpy as np

from camsim.core.errors import CamsimError
from camsim.sensor.cfa import CFA_PATTERNS

__all__ = ["PACKED_PLANES", "pack_rggb", "unpack_rggb", "packed_sites"]

#: The packed planes, in order: G1 is the green on red's row, G2 the green on blue's row.
PACKED_PLANES = ("R", "G1", "G2", "B")


def packed_sites(cfa_pattern: str) -> list[tuple[int, int]]:
    """The (row, column) offsets in the 2 × 2 cell of R, G1 (the green on R's row), G2 and B for a pattern."""
    if cfa_pattern not in CFA_PATTERNS:
        raise CamsimError(f"unknown CFA pattern {cfa_pattern!r}; patterns: {', '.join(CFA_PATTERNS)}")
    r = cfa_pattern.index("R")
    ry, rx = divmod(r, 2)
    return [(ry, rx), (ry, 1 - rx), (1 - ry, rx), (1 - ry, 1 - rx)]


def pack_rggb(mosaic, cfa_pattern: str) -> np.ndarray:
    """Pack an (H, W) Bayer mosaic into (4, H/2, W/2) planes R, G1, G2, B whatever the native pattern.

    Parameters
    ----------
    mosaic : array_like, shape (H, W) or (1, H, W), H and W even
        Values as :func:`camsim.isp.normalise` gives them (0 = black, 1 = white level) for a raw denoiser; any
        values are packed as they are (same dtype).
    cfa_pattern : {"RGGB", "BGGR", "GRBG", "GBRG"}

    Returns
    -------
    numpy.ndarray, shape (4, H/2, W/2)
        ``planes[k][i, j] = mosaic[2 i + dy_k, 2 j + dx_k]`` for the sites of :func:`packed_sites`.
    """
    mosaic = np.asarray(mosaic)
    if mosaic.ndim == 3 and mosaic.shape[0] == 1:
        mosaic = mosaic[0]
    if mosaic.ndim != 2:
        raise CamsimError(f"a Bayer mosaic must be (H, W), got shape {mosaic.shape}")
    height, width = mosaic.shape
    if height % 2 or width % 2 or height == 0 or width == 0:
        raise CamsimError(f"packing needs an even, non-zero height and width, got {width}x{height}")
    return np.stack([mosaic[dy::2, dx::2] for dy, dx in packed_sites(cfa_pattern)])


def unpack_rggb(planes, cfa_pattern: str) -> np.ndarray:
    """The exact inverse of :func:`pack_rggb`: (4, h, w) planes R, G1, G2, B → the (2h, 2w) mosaic of
    ``cfa_pattern``."""
    planes = np.asarray(planes)
    if planes.ndim != 3 or planes.shape[0] != 4 or planes.shape[1] == 0 or planes.shape[2] == 0:
        raise CamsimError(f"packed planes must be (4, h, w), got shape {planes.shape}")
    _, h, w = planes.shape
    mosaic = np.empty((2 * h, 2 * w), dtype=planes.dtype)
    for plane, (dy, dx) in zip(planes, packed_sites(cfa_pattern)):
        mosaic[dy::2, dx::2] = plane
    return mosaic
