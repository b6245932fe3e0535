"""The ``table`` method's sampler: the collected charge of a spectrum and channel drawn from its exact law by an
alias table (the docs' model page, Sampling methods; issue 14).

Under ``pixel`` statistics a pixel of a spectrum collects min(N, c) electrons, N ~ Poisson(S̄ + D̄), c the full well
(where saturation can act): one law per spectrum and channel, :func:`camsim.sensor.dn_law.charge_pmf` (its support
λ ± (13 √λ + 20) and the full-well atom; the tails beyond hold < 1e-36). :func:`charge_table` turns it into a
:class:`camsim.sensor.kernels.AliasTable` (cached by mean and well), and every pixel of a rectangle of that spectrum
draws its charge with one 64-bit word (:func:`camsim.sensor.kernels.alias_draw`, about 9 ns against numpy's Poisson's
50); the read noise, row noise, gain and ADC then follow as for ``poisson`` (:mod:`camsim.methods.fused`), so the EXR's
noisy layer and the digital numbers keep their exact laws.

Where a pixel's law is its own — PRNU, dark-current DSNU or an offset DSNU (every pixel a different mean or
offset), an image's or a cube's pixels (no rectangles of one spectrum), ``paper`` statistics (a scaled Poisson
plus a Poisson), no photon noise — the pixel is drawn as ``poisson`` draws it (exact as well).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from camsim.sensor.dn_law import charge_pmf, charge_support
from camsim.sensor.kernels import AliasTable, alias_table

#: Largest support (values of the charge) a table is made for; wider laws are drawn by numpy's Poisson sampler.
MAX_TABLE_VALUES = 2**16
#: Charges must be integers exact in float32 (the pixel values' type).
MAX_TABLE_CHARGE = 2.0**24


@lru_cache(maxsize=4096)
def charge_table(mean_e: float, full_well_e: float | None) -> AliasTable | None:
    """The alias table of min(N, c), N ~ Poisson(``mean_e``), c = ``full_well_e`` (None: no well); None where the
    law is too wide (:data:`MAX_TABLE_VALUES`) or its charges not exact in float32. Unit: e⁻."""
    charges, p = charge_pmf(mean_e, full_well_e)
    if charges.size > MAX_TABLE_VALUES or charges[-1] >= MAX_TABLE_CHARGE or not p.sum() > 0:
        return None
    return alias_table(charges, p)


def table_eligible(sensor, statistics: str) -> bool:
    """Whether the frame's spectra can be drawn by tables: ``pixel`` statistics with photon noise, and no
    fixed-pattern map (each would give every pixel its own law)."""
    return statistics == "pixel" and sensor.photon_noise and not sensor.fixed_pattern


def charge_tables_fit(expected, sensor) -> np.ndarray:
    """(K, 3) bool: whether each spectrum and channel's charge law fits a table (:func:`charge_table` not None),
    judged from the support's size alone (no table is built)."""
    lam = expected.signal_e + expected.dark_e
    well = sensor.full_well_e if sensor.saturation else None
    lo, hi = charge_support(lam, well)  # the charges charge_pmf holds, and the well's atom
    values = np.maximum(hi - lo + 1, 0) + (well is not None)
    top = hi if well is None else np.full(lam.shape, float(well))
    return (values <= MAX_TABLE_VALUES) & (top < MAX_TABLE_CHARGE) & np.isfinite(lam)


