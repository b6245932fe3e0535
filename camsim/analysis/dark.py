"""Dark frames for ``camsim analyze --dark``: the per-channel mean that serves as black level, and the checks that
refuse a lit frame."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camsim.colour.colorimetry import CHANNELS
from camsim.core.errors import CamsimError
from camsim.render.frame_files import LoadedFrame, load_frame

#: A dark frame whose sidecar expects more signal than this in any patch (or the surround) is lit. Unit: e⁻.
DARK_MAX_SIGNAL_E = 0.5
#: Without a chart in its sidecar, a dark frame is lit when a channel's mean exceeds its expected black level
#: by more than this many standard errors of that mean plus :data:`DARK_MARGIN_DN`.
DARK_MAX_SE = 5.0
#: See :data:`DARK_MAX_SE`. Unit: DN.
DARK_MARGIN_DN = 1.0


@dataclass(frozen=True)
class DarkFrame:
    """What the analysis keeps of a dark frame: its per-channel mean and what it must match.

    Attributes
    ----------
    path : Path
        The dark frame's file.
    black_dn : numpy.ndarray, shape (3,)
        Per-channel mean (of the channel's CFA sites for a Bayer frame). Unit: DN.
    width, height : int
        Unit: pixels.
    cfa_pattern : str or None
        The Bayer pattern, None for a three-chip frame.
    """

    path: Path
    black_dn: np.ndarray
    width: int
    height: int
    cfa_pattern: str | None

    def layout(self) -> str:
        return f"{self.width}x{self.height} {self.cfa_pattern or 'three-chip'}"


def channel_values(frame: LoadedFrame, channel: int) -> np.ndarray:
    """All values of one channel of a frame, shape (n,): a plane, or a Bayer frame's sites of that colour."""
    from camsim.sensor.cfa import cfa_sites

    if not frame.cfa_pattern:
        return frame.pixels_dn[channel].ravel()
    mosaic = frame.pixels_dn[0]
    return np.concatenate([mosaic[dy::2, dx::2].ravel() for dy, dx, c in cfa_sites(frame.cfa_pattern)
                           if c == channel])


def channel_means(frame: LoadedFrame) -> np.ndarray:
    """Per-channel mean of every pixel of a frame, shape (3,). Unit: DN."""
    if not frame.cfa_pattern:
        return frame.pixels_dn.reshape(3, -1).mean(axis=1)
    return np.array([channel_values(frame, c).mean(dtype=np.float64) for c in range(3)])


def lit_reason(frame: LoadedFrame, means: np.ndarray) -> str | None:
    """Why a would-be dark frame is lit, or None when it is dark.

    From its sidecar when it has a chart: lit when a patch (or the surround) expects more than
    :data:`DARK_MAX_SIGNAL_E` of signal. Otherwise from its pixels: lit when a channel's mean ``means`` (DN)
    exceeds the expected black level by more than :data:`DARK_MAX_SE` standard errors plus
    :data:`DARK_MARGIN_DN`.
    """
    meta = frame.meta
    regions = [(p["name"], p["signal_e"]) for p in meta["patches"]]
    if meta.get("surround"):
        regions.append(("surround", meta["surround"]["signal_e"]))
    if regions:
        name, signal = max(((n, float(np.max(s))) for n, s in regions), key=lambda r: r[1])
        if signal > DARK_MAX_SIGNAL_E:
            return (f"its sidecar expects up to {signal:.3g} e⁻ of signal per pixel ({name}, F = "
                    f"{meta['intensity_factor']:g}), more than {DARK_MAX_SIGNAL_E:g} e⁻")
        return None
    expected = frame.expected_black_dn()
    for c, name in enumerate(CHANNELS):
        values = channel_values(frame, c)
        se = float(np.std(values[:: max(1, values.size // 1_000_000)], dtype=np.float64)) / np.sqrt(values.size)
        if means[c] > expected[c] + DARK_MAX_SE * se + DARK_MARGIN_DN:
            return (f"its {name} mean {means[c]:.3f} DN exceeds the expected black level {expected[c]:.3f} DN by "
                    f"more than {DARK_MAX_SE:g} standard errors ({se:.2g} DN each) + {DARK_MARGIN_DN:g} DN")
    return None


def load_dark(path) -> DarkFrame:
    """Read a dark frame and keep its per-channel mean; its pixels are freed on return.

    Raises
    ------
    CamsimError
        An unreadable file, or a lit frame (:func:`lit_reason`).
    """
    try:
        frame = load_frame(path)
    except CamsimError as exc:
        raise CamsimError(f"--dark: {exc}") from None
    means = channel_means(frame)
    reason = lit_reason(frame, means)
    if reason is not None:
        raise CamsimError(f"--dark {frame.path} is not a dark frame: {reason}")
    _, height, width = frame.pixels_dn.shape
    return DarkFrame(frame.path, means, width, height, frame.cfa_pattern)
