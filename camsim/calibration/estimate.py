"""A measured value with its standard error, and its 95 % interval."""

from __future__ import annotations

import math
from dataclasses import dataclass

#: The normal quantile of a two-sided 95 % interval.
Z95 = 1.959963984540054


@dataclass(frozen=True)
class Estimate:
    """A value and its standard error (both in the unit the owner names; None: unknown).

    Attributes
    ----------
    value : float
    standard_error : float or None
    """

    value: float
    standard_error: float | None = None

    @property
    def ci95(self) -> tuple | None:
        """(low, high): value ± 1.96 standard errors, or None without a standard error."""
        if self.standard_error is None:
            return None
        return (self.value - Z95 * self.standard_error, self.value + Z95 * self.standard_error)

    def scaled(self, factor: float) -> Estimate:
        """The estimate times a constant (a change of unit)."""
        se = None if self.standard_error is None else abs(factor) * self.standard_error
        return Estimate(self.value * factor, se)

    def record(self, digits: int = 6) -> dict:
        """``{"value", "standard_error", "ci95"}`` for JSON, rounded to ``digits`` significant digits."""
        return {"value": _round(self.value, digits), "standard_error": _round(self.standard_error, digits),
                "ci95": None if self.ci95 is None else [_round(v, digits) for v in self.ci95]}


def _round(value, digits: int):
    if value is None or not math.isfinite(value):
        return None
    return float(f"{value:.{digits}g}")


def sqrt_estimate(square: Estimate) -> Estimate:
    """√ of an estimated square (a variance → a standard deviation), its error propagated (SE / (2 √v)); a
    negative square (below the estimator's noise) gives 0 with the error of √SE."""
    v, se = square.value, square.standard_error
    if v <= 0:
        return Estimate(0.0, None if se is None else math.sqrt(se))
    return Estimate(math.sqrt(v), None if se is None else se / (2 * math.sqrt(v)))


def ratio(a: Estimate, b: Estimate) -> Estimate:
    """a / b of two independent estimates (a change of unit by a measured factor: DN → e⁻ by K), relative errors
    added in quadrature."""
    value = a.value / b.value
    if a.standard_error is None or b.standard_error is None:
        return Estimate(value, None)
    se = math.hypot(a.standard_error / b.value, value * b.standard_error / b.value)
    return Estimate(value, abs(se))
