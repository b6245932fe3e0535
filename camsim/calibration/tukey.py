"""The shape λ of the read noise by the probability-plot correlation coefficient (PPCC), as the ELD noise model does.

ELD (Wei et al., CVPR 2020, Sec. 3.2) fits the read noise of bias frames with a Tukey-λ law: over a grid of λ the
sorted samples are correlated with the Tukey-λ quantiles at the plotting positions, and the λ of the largest
correlation is the shape; the slope of that probability plot is the scale. :func:`ppcc` and :func:`fit_tukey`
do that, with the standard quantile function (:func:`tukey_quantiles`, the closed form of
``scipy.stats.tukeylambda.ppf``) — the *plain* PPCC.

The samples a calibration has are not draws of the read noise itself. A dark pixel reads floor(a T + m) with T
the standard Tukey variable, a its scale and m the pixel's fixed level (black, DSNU), and the fixed level is only
known through the mean of the n dark frames. The sample of frame i is then

    r = Y_i − Ȳ = (1 − 1/n) (Y_i − Ȳ_others),        Y = a T + U (U: the ADC's error, uniform of width 1 DN),

and Ȳ_others, a mean of n − 1 frames, is close to N(0, σ_Y² / (n − 1)) (plus the row means the samples lose,
σ_Y² / W per row). So r is a scaled a T + U + G, G Gaussian: the law of the read noise blurred by a box and a
Gaussian whose widths are known (1 DN and √(σ_Y²/(n−1) + ...)). Its tails are lighter than the read noise's,
and the plain PPCC pulls λ towards the Gaussian-like 0.14: by 0.02–0.04 for λ = −0.15 and 8–16 frames. The
*matched* PPCC (:func:`blurred_tukey_quantiles`) correlates the samples with the quantiles of that blurred law
instead, computed exactly by quadrature for each λ (the scale a for that λ from the measured variance), which
removes the bias; the box also stands for the quantisation, which is why the samples need no dithering of their
own: the pixels' fixed levels m spread over the DN lattice (the ADC error is then uniform and independent of the
noise to within exp(−2π² σ²), :func:`camsim.calibration.dark.sheppard_read_variance_dn2`).

Every function here is pure; units are those of the samples (DN) unless named.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import optimize, special

from camsim.sensor.kernels import tukey_lambda_variance

#: The plain grid of λ (ELD's range): −0.5 < λ ≤ 0.5, step 0.01 (λ = −0.5 itself has no variance).
LAMBDA_GRID = np.round(np.arange(-0.49, 0.5001, 0.01), 2)
#: The matched PPCC's coarse grid before its refinement (each point costs a quadrature).
MATCHED_GRID = np.round(np.arange(-0.45, 0.5001, 0.05), 2)
#: The λ of the Tukey law closest to the Gaussian (Joiner & Rosenblatt 1971).
GAUSSIAN_LAMBDA = 0.1349
#: Order statistics kept for the correlation: at most this many, evenly spaced in rank (the full sort is kept
#: for the extremes: the first and the last are always among them).
KEEP_ORDER_STATISTICS = 50_000
#: The quadrature of the blurred law: nodes of the standard Tukey variable in logit(u), from logit(p_min) − margin
#: up to 0; nodes of the blur's density.
_Z_NODES, _Z_MARGIN, _BLUR_NODES = 2000, 12.0, 121


def plotting_positions(n: int) -> np.ndarray:
    """Filliben's plotting positions of n order statistics (the medians of the uniform order statistics),
    as ``scipy.stats.probplot`` and ``ppcc_max`` use them: m₁ = 1 − 0.5^(1/n), mₙ = 0.5^(1/n),
    mᵢ = (i − 0.3175) / (n + 0.365) between. Unitless, shape (n,)."""
    i = np.arange(1, n + 1, dtype=np.float64)
    m = (i - 0.3175) / (n + 0.365)
    m[-1] = 0.5 ** (1.0 / n)
    m[0] = 1.0 - m[-1]
    return m


def tukey_quantiles(lam: float, p: np.ndarray, logs: tuple | None = None) -> np.ndarray:
    """Quantiles of the standard Tukey-λ law, Q(p) = (p^λ − (1 − p)^λ) / λ (λ = 0: the logistic, log(p/(1 − p))):
    ``scipy.stats.tukeylambda.ppf``. ``logs``: (log p, log(1 − p)) if already computed. Unitless."""
    lp, lq = logs if logs is not None else (np.log(p), np.log1p(-np.asarray(p, dtype=np.float64)))
    if abs(lam) < 1e-9:
        return lp - lq
    return (np.exp(lam * lp) - np.exp(lam * lq)) / lam


def blurred_tukey_quantiles(lam: float, p: np.ndarray, box_width: float, gauss_sd: float) -> np.ndarray:
    """Quantiles of T + U + G: T standard Tukey-λ, U uniform of width ``box_width``, G ~ N(0, ``gauss_sd``²), all
    independent and in the units of T.

    F(x) = E[F_T(x − U − G)] by quadrature: F_T through a table of T at nodes in logit(u) (a monotone
    interpolation, exact at the nodes), the blur's density (box ∗ Gaussian, a difference of normal CDFs) on
    :data:`_BLUR_NODES` nodes over ±(w/2 + 7 s). The law is symmetric: the lower half is computed and mirrored.
    Quantiles are read from F by interpolation in logit(F), so that the tails keep their relative precision.
    Both widths 0 give :func:`tukey_quantiles`.

    Parameters
    ----------
    lam : float
        Tukey shape λ.
    p : numpy.ndarray
        Probabilities in (0, 1).
    box_width, gauss_sd : float
        w and s, ≥ 0. Unit: that of T.

    Returns
    -------
    numpy.ndarray
        The quantiles, shaped like ``p``. Unit: that of T.
    """
    p = np.asarray(p, dtype=np.float64)
    if box_width <= 0 and gauss_sd <= 0:
        return tukey_quantiles(lam, p)
    half = box_width / 2
    reach = half + 7.0 * gauss_sd
    # the blur's nodes and weights: box * Gaussian (a box alone, or a Gaussian alone, at the limits)
    y = np.linspace(-reach, reach, _BLUR_NODES)
    if gauss_sd <= 0:
        y = (np.arange(_BLUR_NODES) + 0.5) / _BLUR_NODES * box_width - half
        w = np.full(_BLUR_NODES, 1.0 / _BLUR_NODES)
    else:
        if box_width > 0:
            w = special.ndtr((y + half) / gauss_sd) - special.ndtr((y - half) / gauss_sd)
        else:
            w = np.exp(-0.5 * (y / gauss_sd) ** 2)
        w /= w.sum()
    # the table of T's lower half in s = logit(u): T increases with s
    p_low = float(np.min(np.minimum(p, 1 - p)))
    s = np.linspace(special.logit(max(p_low, 1e-300)) - _Z_MARGIN, 0.0, _Z_NODES)
    t = tukey_quantiles(lam, special.expit(s))
    keep = np.concatenate(([True], np.diff(t) > 0))  # bounded support (λ > 0): the far nodes pile up at −1/λ
    s, t = s[keep], t[keep]

    def cdf(v):
        """F_T(v) for any v, through the lower-half table and the symmetry F_T(−v) = 1 − F_T(v)."""
        inner = np.interp(-np.abs(v), t, s, left=-np.inf)
        return special.expit(np.where(v > 0, -inner, inner))

    # F of the blurred law on the lower half: at the table's T (and below its least, by the blur's reach)
    x = np.concatenate((t[0] - reach * np.linspace(1, 0, 40, endpoint=False), t))
    x = x[x <= 0]
    F = np.einsum("ij,j->i", cdf(x[:, None] - y[None, :]), w)
    ok = F > 0
    x, F = x[ok], F[ok]
    order = np.concatenate(([True], np.diff(F) > 0))
    x, F = x[order], F[order]
    low = np.minimum(p, 1 - p)
    q = np.interp(special.logit(low), special.logit(F), x)
    return np.where(p > 0.5, -q, q)


@dataclass(frozen=True)
class TukeyFit:
    """The PPCC fit of a Tukey-λ law to read-noise samples.

    Attributes
    ----------
    lam : float
        λ of the largest correlation.
    ppcc : float
        That correlation.
    scale_dn : float
        The Tukey scale a: the probability plot's slope (divided by the samples' shrink factor). Unit: DN.
    std_dn : float
        a · √Var(T_λ): the standard deviation that scale gives. Unit: DN.
    lambda_grid : numpy.ndarray
        The λ at which the correlation was evaluated (grid and refinement), ascending.
    ppcc_curve : numpy.ndarray
        The correlation at each of them.
    samples : int
        Samples fitted.
    """

    lam: float
    ppcc: float
    scale_dn: float
    std_dn: float
    lambda_grid: np.ndarray
    ppcc_curve: np.ndarray
    samples: int


def order_statistics(samples: np.ndarray, keep: int = KEEP_ORDER_STATISTICS) -> tuple[np.ndarray, np.ndarray]:
    """The sorted samples and their plotting positions, thinned to at most ``keep`` evenly spaced ranks (the first
    and the last always kept). Returns (values in the samples' unit, probabilities)."""
    x = np.sort(np.ravel(samples).astype(np.float64))
    p = plotting_positions(x.size)
    if x.size > keep:
        idx = np.unique(np.round(np.linspace(0, x.size - 1, keep)).astype(np.int64))
        x, p = x[idx], p[idx]
    return x, p


def _correlation(xc: np.ndarray, xx: float, q: np.ndarray) -> tuple[float, float]:
    """(correlation, slope) of the centred sorted samples ``xc`` (Σ xc² = ``xx``) against the quantiles ``q``."""
    qc = q - q.mean()  # (einsum, not BLAS: no thread pool to wake for 10⁵ products)
    qq = float(np.einsum("i,i->", qc, qc))
    xq = float(np.einsum("i,i->", xc, qc))
    return xq / np.sqrt(xx * qq), xq / qq


def ppcc(samples: np.ndarray, lambdas=LAMBDA_GRID, quantiles=None, keep: int = KEEP_ORDER_STATISTICS) -> np.ndarray:
    """The probability-plot correlation coefficient of ``samples`` against a law of shape λ, for each λ.

    Parameters
    ----------
    samples : numpy.ndarray
        Any shape (flattened).
    lambdas : sequence of float
    quantiles : callable, optional
        ``quantiles(lam, p)``: the law's quantiles at the plotting positions p; default :func:`tukey_quantiles`.
    keep : int
        Order statistics used (:func:`order_statistics`).

    Returns
    -------
    numpy.ndarray
        Correlations, shape (len(lambdas),). Unitless, at most 1.
    """
    quantiles = quantiles or tukey_quantiles
    x, p = order_statistics(samples, keep)
    xc = x - x.mean()
    xx = float(np.einsum("i,i->", xc, xc))
    return np.array([_correlation(xc, xx, quantiles(float(lam), p))[0] for lam in lambdas])


def fit_tukey(samples: np.ndarray | None = None, *, variance_dn2: float | None = None, frames: int | None = None,
              row_pixels: int | None = None, box_width_dn: float = 1.0, keep: int = KEEP_ORDER_STATISTICS,
              order: tuple | None = None) -> TukeyFit:
    """Fit λ and the scale of a Tukey-λ read noise to its samples by the PPCC: a grid of λ, then Brent's method
    between the grid's neighbours of its best point.

    Without ``frames`` the samples are taken as draws of the noise itself (the plain PPCC of ELD: standard
    Tukey quantiles, grid :data:`LAMBDA_GRID`). With ``frames`` they are dark-frame residuals about each pixel's
    mean over ``frames`` frames, less their row's mean over ``row_pixels`` pixels (see the module's docstring),
    and the law they are correlated with is the read noise blurred by the ADC's box (``box_width_dn``; 0 for
    values that were never quantised) and by the Gaussian of the mean and the row mean (the matched PPCC, grid
    :data:`MATCHED_GRID`); its scale at each λ comes from ``variance_dn2``.

    Parameters
    ----------
    samples : numpy.ndarray
        Unit: DN.
    variance_dn2 : float, optional
        σ_Y², the temporal variance of one pixel's values (read noise and quantisation; no row noise, no fixed
        pattern). Needed with ``frames``. Unit: DN².
    frames : int, optional
        n ≥ 2, the frames whose mean was subtracted.
    row_pixels : int, optional
        W, the pixels whose mean was subtracted per row and frame (None: no row means were subtracted).
    box_width_dn : float
        The quantiser's step. Unit: DN.
    keep : int
        Order statistics used.
    order : tuple, optional
        (values, probabilities, samples) from :func:`order_statistics` and the number of samples, instead of
        ``samples`` (one sort for several fits).

    Returns
    -------
    TukeyFit
    """
    if order is None:
        x, p = order_statistics(samples, keep)
        count = int(np.size(samples))
    else:
        x, p, count = order
    xc = x - x.mean()
    xx = float(np.einsum("i,i->", xc, xc))
    logs = (np.log(p), np.log1p(-p))
    if frames is None:
        shrink = 1.0

        def law(lam):
            return tukey_quantiles(lam, p, logs)

        grid = LAMBDA_GRID
    else:
        if frames < 2 or variance_dn2 is None or not variance_dn2 > box_width_dn**2 / 12:
            raise ValueError("the matched PPCC needs ≥ 2 frames and a variance above the quantiser's")
        shrink = (1.0 - 1.0 / frames) * (1.0 - 1.0 / row_pixels if row_pixels else 1.0)
        read_var = variance_dn2 - box_width_dn**2 / 12  # Sheppard
        gauss_var = variance_dn2 / (frames - 1)
        if row_pixels:
            gauss_var += variance_dn2 * frames / ((frames - 1) * row_pixels)

        def law(lam):
            a = np.sqrt(read_var / tukey_lambda_variance(lam))  # the scale at this λ, in DN
            return blurred_tukey_quantiles(lam, p, box_width_dn / a, np.sqrt(gauss_var) / a)

        grid = MATCHED_GRID
    seen: dict[float, tuple[float, float]] = {}  # λ: (correlation, slope of the samples on the law's quantiles)

    def score(lam: float) -> float:
        lam = float(lam)
        if lam not in seen:
            seen[lam] = _correlation(xc, xx, law(lam))
        return seen[lam][0]

    curve = [score(lam) for lam in grid]
    best = int(np.argmax(curve))
    lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, len(grid) - 1)]
    if hi > lo:
        optimize.minimize_scalar(lambda lam: -score(lam), bounds=(lo, hi), method="bounded",
                                 options={"xatol": 1e-4})
    lams = np.array(sorted(seen))
    values = np.array([seen[lam][0] for lam in lams])
    lam = float(lams[int(np.argmax(values))])
    r, slope = seen[lam]
    scale = slope / shrink
    return TukeyFit(lam=lam, ppcc=float(r), scale_dn=float(scale),
                    std_dn=float(scale * np.sqrt(tukey_lambda_variance(lam))), lambda_grid=lams, ppcc_curve=values,
                    samples=count)
