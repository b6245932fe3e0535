"""Bayer colour filter arrays: the four 2 × 2 patterns and the sites of their cell (no other camsim import)."""

from __future__ import annotations

#: The Bayer patterns: colours of a 2 × 2 cell's top-left, top-right, bottom-left and bottom-right sites.
CFA_PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")


def cfa_sites(pattern: str) -> list[tuple[int, int, int]]:
    """The 2 × 2 cell of a Bayer pattern as ``[(row offset, column offset, channel), ...]`` (channel 0 = R)."""
    return [(i // 2, i % 2, "RGB".index(colour)) for i, colour in enumerate(pattern)]


def mosaic_of(planes, pattern: str):
    """The Bayer mosaic (H, W) of per-channel planes (3, H, W): each site of the 2 × 2 cell takes its channel's
    plane, in the planes' array type and dtype (numpy or CuPy)."""
    out = planes[0].copy()
    for dy, dx, channel in cfa_sites(pattern):
        out[dy::2, dx::2] = planes[channel][dy::2, dx::2]
    return out
