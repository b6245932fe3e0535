"""Spectra given as linear combinations of a few basis spectra: K rows without a K × N array.

An sRGB image recovered with a linear method (Mallett 2019) has, per distinct colour k, the reflectance
ρ_k(λ) = Σ_j c_kj B_j(λ) over three basis spectra. Everything the model computes from a spectrum is linear in it
— radiance under a light, photon rate (Eq. 3), signal electrons T F Σ g Qe (Eqs. 5–6) and, under ``paper``
statistics, their variance T² F Σ g Qe² — so it is computed on the J basis spectra once and applied to the
coefficients: the expected electrons of every colour are its coefficients times one J × 3 matrix per camera and
light ("model no more than a scene needs"). :class:`FactoredSpectra` stands where a (K, N) array of
spectra stands (``@``, scaling by a number or per bin, row indexing), and gives dense rows only when indexed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np


@dataclass(frozen=True, eq=False)
class FactoredSpectra:
    """K spectra ``coefficients @ basis``, kept factored.

    Attributes
    ----------
    coefficients : numpy.ndarray, shape (K, J)
        Weights of the basis spectra per row. Unitless.
    basis : numpy.ndarray, shape (J, N)
        The basis spectra on the wavelength grid, in the unit of the rows (reflectance, radiance, photon rate).
    """

    coefficients: np.ndarray
    basis: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        """(K, N), as the dense array would have."""
        return self.coefficients.shape[0], self.basis.shape[1]

    def coefficient_rows(self, index) -> np.ndarray:
        """``coefficients[index]`` as float64 (an int, a slice or an index array), read from the file for a cube."""
        if isinstance(self.coefficients, np.ndarray):
            return np.asarray(self.coefficients[index], dtype=np.float64)
        return self.coefficients.rows(index)  # rows read from a file (a cube's pixels)

    def __getitem__(self, index) -> np.ndarray:
        """Dense rows: ``coefficients[index] @ basis`` (an int, a slice or an index array)."""
        return self.coefficient_rows(index) @ self.basis

    def __matmul__(self, other) -> np.ndarray:
        """``dense @ other`` computed as ``coefficients @ (basis @ other)``: (K, J) · (J, M). Exact: a sum reordered.

        Coefficients read from a file (:class:`CoefficientRows`) are taken block by block: memory for a block and
        the (K, M) result, never for the K × J coefficients as float64.
        """
        product = self.basis @ np.asarray(other, dtype=np.float64)
        if isinstance(self.coefficients, np.ndarray):
            return _tall_matmul(np.asarray(self.coefficients, dtype=np.float64), product)
        out = np.empty((self.shape[0],) + product.shape[1:])
        for start, block in self.coefficients.blocks():
            out[start:start + block.shape[0]] = _tall_matmul(block, product)
        return out

    def scaled(self, factor) -> FactoredSpectra:
        """Every row times ``factor``: a number or one value per bin, shape (N,) (applied to the basis)."""
        return FactoredSpectra(self.coefficients, self.basis * np.asarray(factor, dtype=np.float64))

    def __mul__(self, factor) -> FactoredSpectra:
        return self.scaled(factor)

    __rmul__ = __mul__

    def map_basis(self, function) -> FactoredSpectra:
        """Apply a per-bin linear map (e.g. radiance → photon rate, Eq. 3) to the basis."""
        return FactoredSpectra(self.coefficients, np.asarray(function(self.basis), dtype=np.float64))

    def all_finite(self) -> bool:
        """Whether the coefficients and the basis are finite (so is every row)."""
        finite = (np.all(np.isfinite(self.coefficients)) if isinstance(self.coefficients, np.ndarray)
                  else self.coefficients.all_finite())
        return bool(finite and np.all(np.isfinite(self.basis)))

    def __array__(self, dtype=None, copy=None):
        """The dense (K, N) rows: for small K, or paths that need every bin of every row."""
        dense = self[:]
        return dense if dtype is None else dense.astype(dtype)


class CoefficientRows(Protocol):
    """What :class:`FactoredSpectra` needs of coefficients that are not an array in memory (a cube file's pixels:
    :class:`camsim.io.cube_files.CubeRows`).

    Attributes
    ----------
    shape : (K, J)
    """

    shape: tuple[int, int]

    def blocks(self):
        """Yield ``(start, rows)``: consecutive rows as float64 arrays (n, J), covering all K."""

    def rows(self, index) -> np.ndarray:
        """Rows ``index`` (an int, a slice or an index array) as float64, shape (..., J)."""

    def all_finite(self) -> bool:
        """Whether every coefficient is finite."""


def _tall_matmul(tall: np.ndarray, small: np.ndarray) -> np.ndarray:
    """``tall @ small`` for a (K, J) array with a small J, C-contiguous: computed as ``(smallᵀ @ tallᵀ)ᵀ``, which
    numpy's BLAS takes as one long product (measured 20× faster than ``tall @ small`` for K = 777 000, J = M = 3:
    25 ms against 0.5 s, the same values)."""
    if small.ndim != 2:
        return tall @ small
    return np.ascontiguousarray((small.T @ tall.T).T)


def all_finite(spectra) -> bool:
    """Whether every value of dense or factored spectra is finite."""
    if isinstance(spectra, FactoredSpectra):
        return spectra.all_finite()
    return bool(np.all(np.isfinite(spectra)))
