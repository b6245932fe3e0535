"""Bayer colour filter arrays: the four 2 × 2 patterns and the sites of their cell (no other camsim import)."""

from __future__ import annotations

#: The Bayer patterns: colours of a 2 × 2 cell's top-left, top-right, bottom-left and bottom-right sites.
CFA_PATTERNS = ("RGGB", "BGGR", "GRBG", "GBRG")


def cfa_sites(pattern: str) -> list[tuple[int, int, int]]:
    """The 2 × 2 cell of a Bayer pattern as ``[(row offset, column offset, channel), ...]`` (channel 0 = R)."""
    return [(i // 2, i % 2, "RGB".index(colour)) for i, colour in enumerate(pattern)]
