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
    interval : tuple of float, optional
        The 95 % interval where it is not value ± 1.96 standard errors: that of a square root, taken from its
        square's (:func:`sqrt_estimate`), which stays right near 0.
    """

    value: float
    standard_error: float | None = None
    interval: tuple | None = None

    @property
    def ci95(self) -> tuple | None:
        """(low, high): :attr:`interval`, else value ± 1.96 standard errors; None without a standard error."""
        if self.interval is not None:
            return self.interval
        if self.standard_error is None:
            return None
        return (self.value - Z95 * self.standard_error, self.value + Z95 * self.standard_error)

    def scaled(self, factor: float) -> Estimate:
        """The estimate times a constant > 0 (a change of unit)."""
        se = None if self.standard_error is None else abs(factor) * self.standard_error
        interval = None if self.interval is None else tuple(factor * v for v in self.interval)
        return Estimate(self.value * factor, se, interval)

    def record(self, digits: int = 6) -> dict:
        """``{"value", "standard_error", "ci95"}`` for JSON, rounded to ``digits`` significant digits."""
        return {"value": _round(self.value, digits), "standard_error": _round(self.standard_error, digits),
                "ci95": None if self.ci95 is None else [_round(v, digits) for v in self.ci95]}


def _round(value, digits: int):
    if value is None or not math.isfinite(value):
        return None
    return float(f"{value:.{digits}g}")


def sqrt_estimate(square: Estimate) -> Estimate:
    """√ of an estimated square (a variance → a standard deviation): its error propagated (SE / (2 √v)) and its 95 %
    interval the square roots of the square's, clipped at 0 — which, unlike ±1.96 SE, includes 0 where the square
    does not differ from it. A negative square (below the estimator's noise) gives 0 with the error of √SE."""
    v, se = square.value, square.standard_error
    interval = None
    if se is not None:
        low, high = square.ci95
        interval = (math.sqrt(max(low, 0.0)), math.sqrt(max(high, 0.0)))
    if v <= 0:
        return Estimate(0.0, None if se is None else math.sqrt(se), interval)
    return Estimate(math.sqrt(v), None if se is None else se / (2 * math.sqrt(v)), interval)


def ratio(a: Estimate, b: Estimate) -> Estimate:
    """a / b of two independent estimates (a change of unit by a measured factor: DN → e⁻ by K), relative errors
    added in quadrature."""
    value = a.value / b.value
    if a.standard_error is None or b.standard_error is None:
        return Estimate(value, None)
    se = math.hypot(a.standard_error / b.value, value * b.standard_error / b.value)
    return Estimate(value, abs(se))
