"""The exact law of one pixel's digital number under ``pixel`` statistics (the docs' model page), computed: its pmf.

    I = clip(floor(k · (min(N, c) + R)), 0, 2^nb − 1),   N ~ Poisson(λ),   R ~ N(0, σ²),

with λ = S̄ + D̄ the mean charge (signal and dark electrons: one Poisson count under ``pixel`` statistics), c the
full well, σ the read noise and k = G · G_Ve⁻ the gain in DN per electron (Eqs. 6–11). :func:`dn_pmf` gives
P(I = j) on the levels that carry probability; it is what a frame's digital numbers of one spectrum and channel
are drawn from, so it serves as the reference law of the methods' accuracy (``tools/bench_methods.py``) and as
the table of an exact sampler.

It is computed in exact (float64) arithmetic. Without read noise, a charge n whose k · n lies within float32
rounding of a level's edge may be one level off in a rendered frame (the renderer multiplies in float32); with
read noise, edges carry no probability.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special

from camsim.sensor.stages import adc_offset_dn

#: Charges further than this many √λ (plus 20) from the mean carry less than 1e-36 of the Poisson law.
_POISSON_HALF_WIDTH = 13.0
#: Read noise beyond this many σ is neglected (Φ(−10) = 7.6e-24).
_READ_NOISE_SIGMAS = 10.0


@dataclass(frozen=True)
class DnPmf:
    """The pmf of a digital number on a window of levels.

    Attributes
    ----------
    first : int
        The level of ``pmf[0]``. Unit: DN.
    pmf : numpy.ndarray, float64
        P(I = first + j); the levels outside the window have probability below 1e-20 together.
    """

    first: int
    pmf: np.ndarray

    @property
    def levels(self) -> np.ndarray:
        """The levels of :attr:`pmf`. Unit: DN."""
        return self.first + np.arange(self.pmf.size)

    @property
    def mean(self) -> float:
        """E[I]. Unit: DN."""
        return float(self.pmf @ self.levels)

    def dense(self, levels: int) -> np.ndarray:
        """P(I = j) for j = 0 … ``levels`` − 1 (the window must lie inside)."""
        if self.first < 0 or self.first + self.pmf.size > levels:
            raise ValueError(f"levels {self.first}…{self.first + self.pmf.size - 1} do not fit in 0…{levels - 1}")
        out = np.zeros(levels)
        out[self.first : self.first + self.pmf.size] = self.pmf
        return out


def charge_support(mean_e, full_well_e: float | None = None):
    """The integer charges :func:`charge_pmf` holds below the full well, as bounds (lo, hi) broadcast over
    ``mean_e``: λ ± (13 √λ + 20), clipped at 0 and at ⌈c⌉ − 1 (hi < lo: none, far above the well). λ ≤ 0: (0, 0).
    Unit: e⁻."""
    lam = np.asarray(mean_e, dtype=np.float64)
    with np.errstate(invalid="ignore"):
        half = _POISSON_HALF_WIDTH * np.sqrt(np.maximum(lam, 0.0)) + 20.0
    lo = np.maximum(0.0, np.floor(lam - half))
    hi = np.ceil(lam + half)
    if full_well_e is not None:
        hi = np.minimum(hi, np.ceil(full_well_e) - 1)
    return np.where(lam > 0, lo, 0.0), np.where(lam > 0, hi, 0.0)


def charge_pmf(mean_e: float, full_well_e: float | None = None):
    """The law of min(N, c), N ~ Poisson(λ): (charges, probabilities), charges ascending. Unit: e⁻.

    The charges are the integers within λ ± (13 √λ + 20), and the full well c itself, which carries
    P(N ≥ ⌈c⌉) (the integers from ⌈c⌉ on are dropped). λ = 0: the charge is 0.
    """
    lam = float(mean_e)
    if lam <= 0:
        return np.zeros(1), np.ones(1)
    lo, hi = (int(v) for v in charge_support(lam, full_well_e))
    n = np.arange(min(lo, hi + 1), hi + 1, dtype=np.float64)  # empty far above the full well
    # differences of the CDF below the mean and of the survival function above it: absolute errors of order 1e-16
    # (scipy's pmf has relative errors of order λ · 1e-16: 3e-12 at 9000 e⁻, 5e-10 in its sum at 1e6)
    edges = np.append(n[:1] - 1, n)
    cdf = np.where(edges < 0, 0.0, special.pdtr(np.maximum(edges, 0), lam))
    sf = np.where(edges < 0, 1.0, special.pdtrc(np.maximum(edges, 0), lam))
    p = np.where(n < lam, np.diff(cdf), -np.diff(sf))
    if full_well_e is not None:
        n = np.append(n, float(full_well_e))
        p = np.append(p, special.pdtrc(np.ceil(full_well_e) - 1, lam))
    return n, np.maximum(p, 0.0)


def dn_pmf(mean_e: float, dn_per_electron: float, read_noise_e: float = 0.0, full_well_e: float | None = None,
           bits: int | None = None, pedestal_dn: int = 0) -> DnPmf:
    """The pmf of I = clip(floor(k (min(N, c) + R) + h) + P, 0, 2^nb − 1), N ~ Poisson(λ), R ~ N(0, σ²), P the
    pedestal and h = ½ with a pedestal, 0 without (:func:`camsim.sensor.stages.quantise_dn`,
    :func:`camsim.sensor.stages.adc_offset_dn`).

    Parameters
    ----------
    mean_e : float
        λ = S̄ + D̄, the mean charge before saturation. Unit: e⁻.
    dn_per_electron : float
        k = G · G_Ve⁻. Unit: DN / e⁻.
    read_noise_e : float
        σ (0: none). Unit: e⁻.
    full_well_e : float, optional
        c; None: no saturation. Unit: e⁻.
    bits : int, optional
        nb: the levels are clipped to 0 … 2^nb − 1; None: not clipped (floor(k · value) on its own, which may
        be negative with read noise).
    pedestal_dn : int
        P, the ADC's black-level pedestal (0: none): the ADC adds P + ½ before its floor. Unit: DN.

    Returns
    -------
    DnPmf
        Its probabilities sum to 1 within float64 rounding.
    """
    k = float(dn_per_electron)
    if not k > 0:
        raise ValueError(f"dn_per_electron must be positive, got {dn_per_electron!r}")
    if pedestal_dn != int(pedestal_dn):
        raise ValueError(f"pedestal_dn must be an integer, got {pedestal_dn!r}")
    charges, p = charge_pmf(mean_e, full_well_e)
    half = adc_offset_dn(int(pedestal_dn)) - int(pedestal_dn)  # ½ with a pedestal, else 0
    sigma = float(read_noise_e)
    if sigma > 0:
        reach = _READ_NOISE_SIGMAS * sigma
        first = int(np.floor(k * (charges[0] - reach) + half))
        last = int(np.floor(k * (charges[-1] + reach) + half))
        # P(I ≤ j) = P(charge + R < (j + 1 − h) / k), j = first … last − 1; banded: only charges within 10 σ of an
        # edge
        edges = (np.arange(first, last) + 1 - half) / k
        below = np.concatenate([[0.0], np.cumsum(p)])
        cdf = np.empty(edges.size)
        # edges in chunks of m, each against the (m / k + 2 · 10 σ) charges in its reach: at most ~2M values of Φ
        chunk = int(max(1, min(np.sqrt(2**21 * k), 2**21 / (2 * reach + 1))))
        for i in range(0, edges.size, chunk):
            part = edges[i : i + chunk]
            lo = np.searchsorted(charges, part[0] - reach)
            hi = np.searchsorted(charges, part[-1] + reach, side="right")
            cdf[i : i + part.size] = below[lo] + p[lo:hi] @ special.ndtr((part[None, :] - charges[lo:hi, None])
                                                                         / sigma)
        pmf = np.diff(np.concatenate([[0.0], cdf, [below[-1]]]))
    else:
        level = np.floor(k * charges + half).astype(np.int64)
        first = int(level[0])
        pmf = np.bincount(level - first, weights=p)
    first += int(pedestal_dn)
    if bits is not None:
        top = 2**bits - 1
        levels = first + np.arange(pmf.size)
        clipped = np.clip(levels, 0, top)
        lo_level, hi_level = int(clipped[0]), int(clipped[-1])
        pmf = np.bincount(clipped - lo_level, weights=pmf, minlength=hi_level - lo_level + 1)
        first = lo_level
    return DnPmf(first, np.maximum(pmf, 0.0))


def sample_distances(law: DnPmf, values) -> tuple[float, float]:
    """Total variation and Kolmogorov–Smirnov distances between the empirical law of integer ``values`` (digital
    numbers, or values binned to levels) and ``law``: ½ Σ |n_j / n − p_j| (values outside the window count in
    full) and max_j |F̂(j) − F(j)| over the levels."""
    values = np.asarray(values).ravel().astype(np.int64)
    n = values.size
    inside = (values >= law.first) & (values < law.first + law.pmf.size)
    counts = np.bincount(values[inside] - law.first, minlength=law.pmf.size) / n
    below = np.count_nonzero(values < law.first) / n
    tv = 0.5 * (np.abs(counts - law.pmf).sum() + (n - np.count_nonzero(inside)) / n)
    ks = np.max(np.abs(below + np.cumsum(counts) - np.cumsum(law.pmf)), initial=below)
    return float(tv), float(ks)


def expected_tv(law: DnPmf, n: int) -> float:
    """E[TV] between ``law`` and the empirical law of n independent draws from it: the noise floor of
    :func:`sample_distances`' TV for an exact sampler, which falls as 1/√n.

    E[TV] = (1 / 2n) Σ_j E|X_j − n p_j|, X_j ~ Binomial(n, p_j), each by de Moivre's closed form
    E|X − np| = 2 ν C(n, ν) p^ν (1 − p)^{n−ν+1}, ν = ⌊np⌋ + 1.
    """
    p = law.pmf[(law.pmf > 0) & (law.pmf < 1)]
    nu = np.floor(n * p) + 1
    log_term = (special.gammaln(n + 1) - special.gammaln(nu + 1) - special.gammaln(n - nu + 1)
                + nu * np.log(p) + (n - nu + 1) * np.log1p(-p))
    return float(np.sum(2 * nu * np.exp(log_term)) / (2 * n))


__all__ = ["DnPmf", "charge_pmf", "dn_pmf", "expected_tv", "sample_distances"]
