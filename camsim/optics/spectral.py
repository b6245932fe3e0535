"""Per-spectrum OTFs in a few FFTs: the wavelength OTFs' deviation from a channel's mean OTF, decomposed.

Each spectrum k (a chart's patch, an image's recovered colour) gives channel c its own OTF,
OTF_{k,c}(ρ) = Σ_λ w_{k,c}(λ) OTF(ρ; λ) with w_{k,c}(λ) ∝ Qe_c(λ) g_k(λ) (each row summing to 1). Written as the
channel's mean OTF Ō_c (the frame's mean light: :func:`camsim.optics.stages.channel_wavelength_weights`) plus the
deviation D_c(λ, ρ) = OTF(ρ; λ) − Ō_c(ρ), the deviation over the grid's wavelengths is nearly low-rank:

    D_c(λ, ρ) ≈ Σ_{j<r} a_j(λ) B_j(ρ),

B_j the first r right singular vectors of diag(u_c) D_c (from its N × N Gram matrix), u_c(λ) = max_k w_{k,c}(λ)
(the wavelengths a channel's spectra weigh most are fitted best), a_j(λ) = Σ_ρ D_c(λ, ρ) B_j(ρ) (least squares:
the B_j are orthonormal over the samples). Then OTF_{k,c} ≈ Ō_c + Σ_j (Σ_λ w_{k,c}(λ) a_j(λ)) B_j, with the error at
every frequency at most

    ε_c(r) = max_k max_ρ |Σ_λ w_{k,c}(λ) (D_c(λ, ρ) − Σ_{j<r} a_j(λ) B_j(ρ))|

over the radial samples (computed so for up to :data:`EXACT_BOUND_SAMPLES` spectra × samples; beyond, the larger
max_k Σ_λ w_{k,c}(λ) max_ρ |…|) (the 2-D grid interpolates them linearly and multiplies by the OLPF and pixel-aperture
factors, each of magnitude ≤ 1: the bound holds there too). r is the least with ε_c(r) ≤ the tolerance. Every
OTF is 1 at ρ = 0, so D_c(λ, 0) = 0, B_j(0) = 0 and the energy is the mean OTF's: conserved. Where every spectrum
weighs the wavelengths alike (a grey chart) D's weighted part vanishes and r = 0: the mean OTF alone.
"""

from __future__ import annotations

import numpy as np

#: Spectra × radial samples up to which the error bound ε_c(r) is the exact maximum over the spectra (about 860
#: spectra: N times as many products per rank tried; beyond, the triangle inequality's larger bound, a few products
#: over the spectra; an image's factored colours are checked at their convex hull's vertices, a few).
EXACT_BOUND_SAMPLES = 5_000_000


def deviation_basis(table, mean_otf, envelope) -> tuple[np.ndarray, np.ndarray]:
    """The orthonormal radial components B_j and each wavelength's coefficients a_j(λ) of the deviation
    D(λ, ρ) = ``table`` − ``mean_otf`` (module docstring), all of them, most important first.

    Parameters
    ----------
    table : array_like, shape (N, M)
        OTF(ρ_m; λ_n) at the radial samples. Unitless.
    mean_otf : array_like, shape (M,)
        The channel's mean OTF Ō_c(ρ_m). Unitless.
    envelope : array_like, shape (N,)
        u_c(λ) ≥ 0: the largest weight any spectrum gives each wavelength (0: the wavelength is not fitted).

    Returns
    -------
    coefficients : numpy.ndarray, shape (N, R)
        a_j(λ). Unitless.
    components : numpy.ndarray, shape (R, M)
        B_j(ρ_m), orthonormal over the samples; R the rank of diag(u) D.
    """
    deviation = np.asarray(table, dtype=np.float64) - np.asarray(mean_otf, dtype=np.float64)[None]
    envelope = np.asarray(envelope, dtype=np.float64)
    # the SVD of X = diag(u) D (N × M, M ≫ N) from its Gram matrix X X^T = U S² U^T (a small symmetric eigenproblem;
    # a QR or SVD of the tall matrix costs 10-100× more): B_j = U_j^T X / s_j, the singular values above 1e-9 s_0
    # (the Gram resolves them to ~1e-8 s_0; a component's coefficients are least-squares projections and the error
    # bound is computed from the residual itself, so the bound holds whatever rounding the basis has)
    weighted = envelope[:, None] * deviation
    values, vectors = np.linalg.eigh(weighted @ weighted.T)
    order = np.argsort(values)[::-1]
    singular = np.sqrt(np.maximum(values[order], 0.0))
    rank = int(np.sum(singular > singular[0] * 1e-9)) if singular.size and singular[0] > 0 else 0
    components = (vectors[:, order[:rank]].T @ weighted) / singular[:rank, None]
    return deviation @ components.T, components


def residuals(table, mean_otf, coefficients, components):
    """Yield ``(r, E_r)`` for r = 0 … R: E_r(λ, ρ) = D(λ, ρ) − Σ_{j<r} a_j(λ) B_j(ρ), shape (N, M) (one array updated
    in place: use it before the next). Unitless."""
    residual = np.asarray(table, dtype=np.float64) - np.asarray(mean_otf, dtype=np.float64)[None]
    for r in range(components.shape[0] + 1):
        if r:
            residual -= np.outer(coefficients[:, r - 1], components[r - 1])
        yield r, residual
