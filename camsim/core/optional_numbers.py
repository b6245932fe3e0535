"""Numbers that may be undefined: camsim's tables and JSON files hold None (an empty cell, ``null``) where a
value does not exist — an infinite SNR in dB, a chromaticity of a black sample — never NaN or infinity."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["finite_or_none", "mean_of_defined", "median_of_defined"]


def finite_or_none(value) -> float | None:
    """``value`` as a float if it is a finite number, else None.

    Parameters
    ----------
    value : object
        A number (Python or NumPy scalar), None, or anything else.

    Returns
    -------
    float or None
        None for None, NaN, ±infinity and values that are not numbers.
    """
    try:
        value = float(value)
    except (TypeError, ValueError):
        return None
    return value if math.isfinite(value) else None


def mean_of_defined(values) -> float | None:
    """The mean of the values that are not None, or None if there are none. Unit: that of the values."""
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def median_of_defined(values) -> float | None:
    """The median of the values that are not None, or None if there are none. Unit: that of the values."""
    values = [v for v in values if v is not None]
    return float(np.median(values)) if values else None
