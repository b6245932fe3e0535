"""Flicker: a light modulated in time (AC mains: 100 Hz or 120 Hz), integrated over an exposure.

The light's relative intensity at time t (s, from a sequence's first frame's start) is

    L(t) = 1 + m · cos(2π f t + φ),

f the modulation frequency (``flicker_hz``: twice the mains frequency for a lamp whose output follows the
power), m the depth (``flicker_depth``, 0 … 1) and φ the phase (``flicker_phase_deg``). Its mean over a period
is 1, so a flickering scene has the static scene's mean light. It multiplies the light only (the photo-electrons),
never the dark current. A pixel exposed over [a, b] collects the fraction

    (1/T) ∫ₐᵇ L(t) dt = (b − a)/T + (2m / (ωT)) · cos(ω (a + b)/2 + φ) · sin(ω (b − a)/2),   ω = 2π f

of the static scene's expectation per exposure time T (:func:`flicker_integral`; the product form of
sin(ωb + φ) − sin(ωa + φ), free of the difference's cancellation for a short interval).
"""

from __future__ import annotations

import math

import numpy as np


def flicker_integral(start_s, end_s, exposure_s: float, hz: float, depth: float, phase_deg: float = 0.0) -> np.ndarray:
    """(1/T) ∫ L(t) dt over [start_s, end_s] for the modulated light of the module docstring.

    Parameters
    ----------
    start_s, end_s : array_like
        Interval ends, broadcast together. Unit: s.
    exposure_s : float
        T, the normalisation. Unit: s.
    hz : float
        f, the modulation frequency (0: a steady light, L = 1). Unit: Hz.
    depth : float
        m, 0 … 1.
    phase_deg : float
        φ. Unit: degrees.

    Returns
    -------
    numpy.ndarray, float64
        The interval's share of the light, in units of the steady light's per T: (b − a)/T for a steady light.
    """
    a = np.asarray(start_s, dtype=np.float64)
    b = np.asarray(end_s, dtype=np.float64)
    out = (b - a) / exposure_s
    if hz and depth:
        omega = 2 * math.pi * hz
        out = out + (2 * depth / (omega * exposure_s)) * np.cos(omega * (a + b) / 2 + math.radians(phase_deg)) \
            * np.sin(omega * (b - a) / 2)
    return out
