"""The slanted-edge spatial frequency response (e-SFR of ISO 12233:2017), per channel of a frame.

No library at hand implements it (scikit-image and colour-science have none; the reference is Burns' ``sfrmat3``,
MATLAB, which the 2017 edition of the standard follows): this module writes the standard's steps out.

Steps (ISO 12233:2017, clause 6 and annex D; Burns, "Slanted-edge MTF for digital camera and scanner analysis",
PICS 2000), on one channel's sites in a region holding one near-vertical edge (a near-horizontal one is
transposed):

1. **Edge location per row**: the derivative along the row, [−½, +½] between neighbouring sites, and its
   centroid; a first-order (line) fit x = a + b·y of the centroids over the rows (the 2017 edition's polynomial
   order, 1). Then again, each row's derivative multiplied by a Hamming window centred on the fitted location, and
   the line refitted (as ``sfrmat3``).
2. **Rows kept**: an integer number of phase cycles (the largest count of rows over which the edge moves a whole
   number of site spacings), so that every sub-pixel phase is sampled alike.
3. **Projection**: every site's signed distance to the fitted edge along its normal, d = (x − a − b·y)·cos θ
   (θ = atan b), in sensor pixels, binned into bins of ¼ px (4× super-sampling). Each bin's mean value is placed at
   its samples' mean distance (not at the bin's centre, as the standard does: with a finite number of rows the
   phases fall unevenly in a bin, a jitter of up to ±0.05 px that lowered MTF50 by 1.3 % on 128 rows of an ideal
   edge) and the edge spread function (ESF) is interpolated linearly onto the bins' centres, which also fills empty
   bins (none in a good region). It is oriented dark → bright.
4. **ESF → LSF** by the derivative [−½, 0, +½], a **Hamming window** centred on the LSF's centroid, the **DFT**,
   its modulus normalised at zero frequency, and the **derivative's correction**: divided by the central
   difference's own transfer function, exactly sinc(2 f Δ) = sin(2π f Δ) / (2π f Δ) (Δ = ¼ px; the standard's
   correction, as ``sfrmat3``'s ``fir2fix``, which states it with its own frequency indexing), at most 10×.

Frequencies are cycles per sensor pixel along the edge normal; the SFR is reported up to 1 cy/px (twice Nyquist).
The ¼-px binning itself blurs the ESF by a box of ¼ px (samples anywhere in a bin count at its centre): an MTF
sinc(f/4), 0.974 at Nyquist and 0.963 at 0.6 cy/px, which the 2017 standard leaves in its SFR (it lowers the MTF50
of an ideal pixel by 2.3 %). This module divides it out as well (``bin_correction``, on by default; off leaves it in, as
the standard), so that the SFR measures the frame, not the method.

The **window's extent** is the region's (the standard leaves it to the user): a window of ±X px cuts the tails of
a blur's line spread function, and the Airy pattern's are long (energy beyond ±X as 1/X), which raises MTF50 by
about 0.36·(λN/p)/X. On a slanted-edge target's frame the region is therefore ±50·λN/p px (λ = 0.7 µm) about the
edge, at least ±24 px (:func:`window_margin_px`: at most +0.7 % on MTF50 from the window); the Hamming window
itself is the standard's.

For a **Bayer mosaic** each channel is measured on its own sites only, at their true positions on the sensor: red
and blue on every second row and column, green on the quincunx of both green sites. The projection onto the normal
puts them on the ¼-px bins of the sensor's pitch (a slanted edge samples every phase), so the SFR of every channel
is in cycles per sensor pixel, comparable with a three-chip frame's and with the model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from camsim.core.errors import CamsimError

#: Bins per pixel of the projected edge spread function (ISO 12233's 4× super-sampling).
SUPERSAMPLING = 4
#: The highest frequency reported, cy/px.
F_MAX_CY_PER_PX = 1.0
#: The largest factor of the derivative's correction (``sfrmat3``).
MAX_DERIVATIVE_CORRECTION = 10.0
#: The fewest rows (of a channel's sites) a region must hold.
MIN_ROWS = 8
#: The most empty ¼-px bins a measurement allows, as a fraction (more: the edge's angle does not sample the phases).
MAX_EMPTY_FRACTION = 0.1
#: Edge angles (degrees from the nearest axis) outside which a measurement warns: ISO 12233 asks for a slight slant
#: (about 5°); near 0° the phases are sampled by few rows, near 45° the edge's axis is ambiguous.
ANGLE_RANGE_DEG = (1.0, 30.0)
#: The least edge contrast, in standard deviations of the pixels' noise, that counts as an edge.
MIN_CONTRAST_SIGMA = 8.0


@dataclass(frozen=True)
class ChannelSites:
    """One channel's sites in a region: rows of values and their sensor coordinates.

    Attributes
    ----------
    values : numpy.ndarray, shape (R, C), float64
        The signal at the sites (any linear unit: DN, e⁻).
    x_px : numpy.ndarray, shape (R, C), float64
        Each site's centre x on the sensor (pixels; pixel j's centre is j + ½), increasing along a row.
    y_px : numpy.ndarray, shape (R,), float64
        Each row's centre y (pixels), increasing.
    """

    values: np.ndarray
    x_px: np.ndarray
    y_px: np.ndarray


@dataclass(frozen=True)
class EdgeSFR:
    """The e-SFR of one channel.

    Attributes
    ----------
    frequency_cy_per_px : numpy.ndarray, shape (n,)
        0 to :data:`F_MAX_CY_PER_PX`, cycles per sensor pixel along the edge normal.
    mtf : numpy.ndarray, shape (n,)
        The SFR, 1 at 0.
    mtf50_cy_per_px : float or None
        The first frequency where the SFR falls to 0.5 (linear interpolation); None if it stays above.
    mtf_nyquist : float
        The SFR at 0.5 cy/px (linear interpolation).
    angle_deg : float
        The fitted edge's angle from the vertical (from the horizontal for a transposed edge), degrees.
    normal_xy : tuple of float
        The edge's unit normal in the frame's coordinates (x right, y down), pointing dark → bright.
    transposed : bool
        Whether the edge was near-horizontal (measured with x and y exchanged).
    rows_used : int
        Rows of sites kept (an integer number of phase cycles).
    esf : numpy.ndarray
        The binned edge spread function (the values' unit), ¼ px bins.
    empty_bins : int
        Bins filled by interpolation.
    warnings : tuple of str
        What makes the measurement doubtful (edge angle outside :data:`ANGLE_RANGE_DEG`).
    """

    frequency_cy_per_px: np.ndarray
    mtf: np.ndarray
    mtf50_cy_per_px: float | None
    mtf_nyquist: float
    angle_deg: float
    normal_xy: tuple
    transposed: bool
    rows_used: int
    esf: np.ndarray
    empty_bins: int
    warnings: tuple = field(default=())


# --------------------------------------------------------------------------------------------------- the steps
def _row_derivative(values: np.ndarray, x_px: np.ndarray):
    """[−½, +½] derivative along each row (per pixel of x) at the midpoints between neighbouring sites."""
    d = np.diff(values, axis=1) / np.diff(x_px, axis=1)
    return d, 0.5 * (x_px[:, 1:] + x_px[:, :-1])


def _centroids(d: np.ndarray, xm: np.ndarray, window: np.ndarray | None = None) -> np.ndarray:
    """The centroid of each row's derivative (x, pixels), with an optional window per row; NaN for a row with none."""
    weight = d if window is None else d * window
    total = weight.sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(total != 0, (weight * xm).sum(axis=1) / total, np.nan)


def _hamming(n: int, centre: float) -> np.ndarray:
    """A Hamming window over samples 0 … n − 1 centred on ``centre`` (ISO 12233:2017's centred window): the
    symmetric window of half-width max(centre, n − 1 − centre)."""
    half = max(centre, n - 1 - centre, 1.0)
    i = np.arange(n)
    return 0.54 + 0.46 * np.cos(np.pi * (i - centre) / half)


def _fit_line(y: np.ndarray, x: np.ndarray) -> tuple[float, float]:
    """Least-squares x = a + b·y over the finite x; (a, b)."""
    ok = np.isfinite(x)
    if ok.sum() < 2:
        raise CamsimError("no edge in the region: fewer than 2 rows have a derivative to locate it")
    b, a = np.polyfit(y[ok], x[ok], 1)
    return float(a), float(b)


def locate_edge(sites: ChannelSites) -> tuple[float, float]:
    """The edge x = a + b·y fitted to the rows' derivative centroids, twice (the second time each row's derivative
    Hamming-windowed about the first fit), as ISO 12233:2017; returns (a, b) in pixels and pixels per pixel.

    Raises
    ------
    CamsimError
        Fewer than 2 rows with a derivative (no edge).
    """
    d, xm = _row_derivative(sites.values, sites.x_px)
    sign = np.sign(d.sum())
    d = d * (sign if sign != 0 else 1.0)
    a, b = _fit_line(sites.y_px, _centroids(d, xm))
    width = sites.x_px[:, -1] - sites.x_px[:, 0]
    mid = a + b * sites.y_px
    half = np.maximum(np.maximum(mid - sites.x_px[:, 0], sites.x_px[:, -1] - mid), width / 2)[:, None]
    window = 0.54 + 0.46 * np.cos(np.pi * np.clip((xm - mid[:, None]) / half, -1, 1))
    return _fit_line(sites.y_px, _centroids(d, xm, window))


def _noise_sigma(values: np.ndarray) -> float:
    """The pixels' noise σ from the row differences' median absolute deviation (robust to the edge's few)."""
    diff = np.diff(values, axis=1).ravel()
    mad = np.median(np.abs(diff - np.median(diff))) if diff.size else 0.0
    return float(1.4826 * mad / math.sqrt(2))


def esf_of(sites: ChannelSites, a: float, b: float):
    """The binned ESF: the sites projected on the edge's normal into ¼ px bins (step 3).

    Returns
    -------
    esf : numpy.ndarray, shape (n,)
        Mean value per bin, dark → bright, empty bins interpolated.
    empty : int
        Bins that were empty.
    flipped : bool
        Whether the distances were negated to make the ESF rise.
    rows : int
        Rows used.
    """
    values, x, y = sites.values, sites.x_px, sites.y_px
    theta = math.atan(b)
    spacing = float(np.median(np.diff(x, axis=1))) if x.shape[1] > 1 else 1.0
    dy = float(np.median(np.diff(y))) if y.size > 1 else 1.0
    # rows over a whole number of phase cycles: the edge moves by |b|·dy px per row, one cycle per site spacing
    cycles = math.floor(y.size * dy * abs(b) / spacing)
    rows = y.size if cycles < 1 else max(min(y.size, round(cycles * spacing / (abs(b) * dy))), MIN_ROWS)
    values, x, y = values[:rows], x[:rows], y[:rows]
    dist = (x - a - b * y[:, None]) * math.cos(theta)
    # the common range of every row: each bin holds samples of all phases and rows
    half = min(float(-dist[:, 0].max()), float(dist[:, -1].min()))
    step = 1.0 / SUPERSAMPLING
    n_half = int(math.floor(half / step))
    if n_half < 2 * SUPERSAMPLING:
        raise CamsimError(f"the edge lies within {max(half, 0):.1f} px of the region's side: the region must hold "
                          f"at least {2} px of both sides of the edge on every row")
    index = np.floor(dist / step).astype(np.int64) + n_half  # bin k covers [(k − n_half)·Δ, (k − n_half + 1)·Δ)
    inside = (index >= 0) & (index < 2 * n_half)
    counts = np.bincount(index[inside], minlength=2 * n_half).astype(np.float64)
    sums = np.bincount(index[inside], weights=values[inside], minlength=2 * n_half)
    filled = counts > 0
    empty = int((~filled).sum())
    if empty > MAX_EMPTY_FRACTION * counts.size:
        raise CamsimError(f"the edge's angle ({math.degrees(theta):.2f}° from the axis) leaves {empty} of "
                          f"{counts.size} quarter-pixel bins empty: the sites do not sample every phase (an angle "
                          "near 0° needs more rows; near 45° the sites fall on few phases); a slant of about 5° "
                          "is best")
    # each bin's mean value sits at its samples' mean distance, not exactly at its centre (the phases of a finite
    # number of rows fall unevenly in a bin): the ESF at the centres is interpolated from those mean positions
    at = np.bincount(index[inside], weights=dist[inside], minlength=2 * n_half)
    centres = (np.arange(counts.size) - n_half + 0.5) * step
    esf = np.interp(centres, at[filled] / counts[filled], sums[filled] / counts[filled])
    flipped = esf[-SUPERSAMPLING:].mean() < esf[:SUPERSAMPLING].mean()
    return (esf[::-1].copy() if flipped else esf), empty, bool(flipped), rows


def sfr_of_esf(esf: np.ndarray, bin_correction: bool = True):
    """ESF → LSF → windowed DFT → SFR (step 4).

    ``bin_correction`` also divides by the ¼ px bins' own box, sinc(f Δ) (beyond the 2017 standard: see the
    module's notes); False leaves it in, as the standard.

    Returns
    -------
    frequency : numpy.ndarray
        cy/px, up to :data:`F_MAX_CY_PER_PX`.
    sfr : numpy.ndarray
        Normalised at 0, divided by the derivative's transfer function.
    """
    step = 1.0 / SUPERSAMPLING
    lsf = np.empty_like(esf)
    lsf[1:-1] = 0.5 * (esf[2:] - esf[:-2])
    lsf[0], lsf[-1] = lsf[1], lsf[-2]
    weight = np.abs(lsf)
    centre = float((weight * np.arange(lsf.size)).sum() / weight.sum()) if weight.sum() > 0 else lsf.size / 2
    spectrum = np.abs(np.fft.rfft(lsf * _hamming(lsf.size, centre)))
    if spectrum[0] <= 0:
        raise CamsimError("no edge in the region: the edge spread function has no step")
    frequency = np.fft.rfftfreq(lsf.size, d=step)
    sfr = spectrum / spectrum[0]
    correction = np.minimum(1.0 / np.maximum(np.sinc(2 * frequency * step), 1e-12), MAX_DERIVATIVE_CORRECTION)
    if bin_correction:
        correction = correction / np.sinc(frequency * step)
    keep = frequency <= F_MAX_CY_PER_PX + 1e-12
    return frequency[keep], (sfr * correction)[keep]


def mtf50(frequency: np.ndarray, mtf: np.ndarray, level: float = 0.5) -> float | None:
    """The first frequency where ``mtf`` falls to ``level``, by linear interpolation; None if it never does."""
    below = np.flatnonzero(mtf <= level)
    if below.size == 0:
        return None
    k = int(below[0])
    if k == 0:
        return float(frequency[0])
    f0, f1, m0, m1 = frequency[k - 1], frequency[k], mtf[k - 1], mtf[k]
    return float(f0 + (m0 - level) * (f1 - f0) / (m0 - m1))


def edge_sfr(sites: ChannelSites, bin_correction: bool = True) -> EdgeSFR:
    """The e-SFR (ISO 12233:2017) of one channel's sites holding one slanted edge (the module's steps 1–4).

    Parameters
    ----------
    sites : ChannelSites
        One channel's values and sensor positions in the region, holding a near-vertical edge (a frame's
        near-horizontal edge is transposed before: :func:`measure_region`).
    bin_correction : bool
        Divide out the ¼ px bins' box (:func:`sfr_of_esf`).

    Returns
    -------
    EdgeSFR

    Raises
    ------
    CamsimError
        One line: a region too small, no edge in it (contrast under :data:`MIN_CONTRAST_SIGMA` noise σ, or no
        derivative), an edge too near the region's side, or an angle that leaves quarter-pixel bins empty.
    """
    values = np.asarray(sites.values, dtype=np.float64)
    if values.ndim != 2 or values.shape[0] < 2 or values.shape[1] < 4:
        raise CamsimError(f"the edge region holds {values.shape[::-1] if values.ndim == 2 else values.shape} sites "
                          "of a channel: too few to measure an edge")
    if not np.all(np.isfinite(values)):
        raise CamsimError("the edge region holds values that are not finite")
    sites = ChannelSites(values, np.asarray(sites.x_px, dtype=np.float64), np.asarray(sites.y_px, dtype=np.float64))
    if values.shape[0] < MIN_ROWS:
        raise CamsimError(f"the edge region holds {values.shape[0]} rows of a channel's sites along the edge: "
                          f"at least {MIN_ROWS} are needed")
    sigma = _noise_sigma(values)
    contrast = float(np.abs(np.median(values[:, -3:]) - np.median(values[:, :3])))
    if contrast <= MIN_CONTRAST_SIGMA * sigma or contrast == 0:
        raise CamsimError(f"no edge in the region: the two sides differ by {contrast:.3g} against a noise σ of "
                          f"{sigma:.3g} per site (need more than {MIN_CONTRAST_SIGMA:g} σ)")
    a, b = locate_edge(sites)
    esf, empty, flipped, rows = esf_of(sites, a, b)
    frequency, sfr = sfr_of_esf(esf, bin_correction)
    theta = math.atan(b)
    # the normal (cos θ, −sin θ) of x − a − b·y = 0 in the measured axes, made to point dark → bright
    normal = (-math.cos(theta), math.sin(theta)) if flipped else (math.cos(theta), -math.sin(theta))
    angle = math.degrees(theta)
    warnings = []
    if not ANGLE_RANGE_DEG[0] <= abs(angle) <= ANGLE_RANGE_DEG[1]:
        warnings.append(f"edge angle {angle:.2f}° from the axis is outside "
                        f"{ANGLE_RANGE_DEG[0]:g}–{ANGLE_RANGE_DEG[1]:g}°: the SFR is less reliable (about 5° is best)")
    nyquist = float(np.interp(0.5, frequency, sfr))
    return EdgeSFR(frequency, sfr, mtf50(frequency, sfr), nyquist, angle, normal, False, rows, esf, empty,
                   tuple(warnings))


# ---------------------------------------------------------------------------------------- the sites of a frame
def plane_sites(plane: np.ndarray, region_xywh) -> ChannelSites:
    """The sites of a full plane (a three-chip channel, an EXR layer) in ``region_xywh`` = (x, y, w, h) pixels."""
    x0, y0, w, h = region_xywh
    values = np.asarray(plane[y0:y0 + h, x0:x0 + w], dtype=np.float64)
    xs = np.arange(x0, x0 + w) + 0.5
    return ChannelSites(values, np.broadcast_to(xs, values.shape).copy(), np.arange(y0, y0 + h) + 0.5)


def mosaic_sites(mosaic: np.ndarray, cfa_pattern: str, channel: str, region_xywh) -> ChannelSites:
    """The sites of one colour of a Bayer mosaic in ``region_xywh``: its own sites only, at their sensor positions.

    Parameters
    ----------
    mosaic : numpy.ndarray, shape (H, W)
        One value per pixel.
    cfa_pattern : str
        The 2 × 2 cell's colours, row by row from the top-left pixel (e.g. ``"RGGB"``).
    channel : {'R', 'G', 'B'}
        The colour. Green takes both green sites of each cell (a quincunx: each row has its own x offsets).

    Returns
    -------
    ChannelSites
        The rows of the region holding the colour, each with its sites (as many per row: the fewest of any row).
    """
    x0, y0, w, h = region_xywh
    cell = np.array(list(cfa_pattern)).reshape(2, 2)
    rows, xs, ys = [], [], []
    for i in range(y0, y0 + h):
        cols = [j for j in (x0, x0 + 1) if cell[i % 2, j % 2] == channel]
        if not cols:
            continue
        j = np.arange(cols[0], x0 + w, 2)
        rows.append(np.asarray(mosaic[i, j], dtype=np.float64))
        xs.append(j + 0.5)
        ys.append(i + 0.5)
    if not rows:
        raise CamsimError(f"the edge region holds no {channel} site of the {cfa_pattern} mosaic")
    n = min(r.size for r in rows)
    return ChannelSites(np.stack([r[:n] for r in rows]), np.stack([x[:n] for x in xs]), np.asarray(ys))


#: The least margin of a target's region on each side of the edge, pixels (:func:`target_region`).
MIN_MARGIN_PX = 24
#: The margin per λ_max·N / p of a diffraction-limited lens (:func:`window_margin_px`).
MARGIN_PER_AIRY = 50.0


def window_margin_px(optics) -> int:
    """The margin of a target's region on each side of the edge: :data:`MIN_MARGIN_PX`, or wider where the sidecar's
    ``optics`` spreads the edge further.

    The Airy pattern's line spread function has long tails (its energy beyond ±X falls as 1/X): a window of ±X
    cuts them, which lowers the SFR's value at 0 more than elsewhere and raises the normalised SFR, by about
    0.36·(λN/p)/X on MTF50 (the bias of the method itself, measured on noiseless edges blurred by the closed-form
    OTF, 4 µm pixels, 640 rows: at f/5.6 in red +1.36 % at X = 24 px, +0.66 % at 48, +0.29 % at 96; at f/11 in red
    +2.86 %, +1.40 %, +0.68 %; it is the window: a flat-top window halves it, at more noise). The margin is
    at least 50·λN/p px (λ = 0.7 µm, the red end), which leaves at most +0.7 % (red), +0.6 % (green), +0.5 %
    (blue); defocus adds twice the geometric blur disk's diameter 8 N W020 / p. The SFR's noise grows with the
    window (as √X) and falls with the rows (as 1/√rows): a frame for this margin needs about 2·(50·0.7·N/p) px
    across the edge and many rows (ISO 12233's Hamming window is kept). An unusable record gives the least margin
    (the model reports it).
    """
    margin = float(MIN_MARGIN_PX)
    if isinstance(optics, dict):
        try:
            n, pitch = float(optics["f_number"]), float(optics["pixel_pitch_um"])
            w020_um = float(optics.get("defocus_waves") or 0.0) * 0.55 + \
                float(optics.get("defocus_um") or 0.0) / (8 * n * n)
            if optics.get("diffraction") is True:
                margin = max(margin, MARGIN_PER_AIRY * 0.7 * n / pitch)
            margin += 2 * 8 * n * abs(w020_um) / pitch
        except (KeyError, TypeError, ValueError, ZeroDivisionError, OverflowError):
            return MIN_MARGIN_PX
    return int(math.ceil(min(margin, 4096))) if math.isfinite(margin) else MIN_MARGIN_PX


def check_region(region_xywh, width: int, height: int, where: str = "") -> tuple:
    """``region_xywh`` as four ints if it lies inside a ``width`` × ``height`` frame and is large enough; else
    CamsimError (one line)."""
    x, y, w, h = (int(v) for v in region_xywh)
    if w < 8 or h < 8:
        raise CamsimError(f"{where}the edge region {x},{y},{w},{h} is too small: at least 8 x 8 px")
    if x < 0 or y < 0 or x + w > width or y + h > height:
        raise CamsimError(f"{where}the edge region {x},{y},{w},{h} (x, y, width, height) lies outside the "
                          f"{width}x{height} frame")
    return x, y, w, h


def target_region(target: dict, width: int, height: int, margin_px: int = MIN_MARGIN_PX) -> tuple:
    """The region of a slanted-edge target's frame (the sidecar's ``target`` record) to measure: the central 80 %
    of the rows (the target's edge is within ±45° of vertical) and the columns the edge crosses there, widened by
    ``margin_px`` on each side, within the frame. The margin sets the ESF's window (2 × 24 px by default): wide
    enough for a blur of a few pixels, narrow enough to keep the noise of the SFR down (it grows with the window).

    Returns
    -------
    tuple of int
        (x, y, w, h), pixels.
    """
    cx, cy = target["centre_xy"]
    nx, ny = target["normal_xy"]
    offset = target.get("offset_px", 0.0)
    y0, y1 = int(math.ceil(0.1 * height)), int(math.floor(0.9 * height))
    # the edge: (x − cx)·nx + (y − cy)·ny = offset, so x = cx + (offset − (y − cy)·ny) / nx
    xs = [cx + (offset - (y - cy) * ny) / nx for y in (y0, y1)]
    x0 = max(0, int(math.floor(min(xs))) - margin_px)
    x1 = min(width, int(math.ceil(max(xs))) + margin_px)
    return x0, y0, x1 - x0, y1 - y0


def edge_is_horizontal(pixels: np.ndarray, cfa_pattern: str | None, region_xywh) -> bool:
    """Whether the region's edge runs nearer the horizontal: the mean |difference| between same-colour neighbours
    (lag 2 on a mosaic, 1 otherwise) down the columns exceeds that along the rows. ``pixels`` (P, H, W)."""
    x0, y0, w, h = region_xywh
    lag = 2 if cfa_pattern else 1
    block = np.asarray(pixels[:, y0:y0 + h, x0:x0 + w], dtype=np.float64).sum(axis=0)
    along = np.abs(block[:, lag:] - block[:, :-lag]).mean()
    down = np.abs(block[lag:] - block[:-lag]).mean()
    return bool(down > along)


def _transpose_pattern(cfa_pattern: str) -> str:
    return "".join(np.array(list(cfa_pattern)).reshape(2, 2).T.ravel())


def measure_region(pixels: np.ndarray, cfa_pattern: str | None, region_xywh, channels=("R", "G", "B")) -> dict:
    """The e-SFR of every channel of a frame's region.

    Parameters
    ----------
    pixels : numpy.ndarray, shape (3, H, W) or (1, H, W)
        Three planes (three-chip, an EXR layer) or a Bayer mosaic (with ``cfa_pattern``). Linear values.
    cfa_pattern : str or None
        The mosaic's 2 × 2 pattern (e.g. ``"RGGB"``), None for three planes.
    region_xywh : tuple of int
        (x, y, w, h) pixels, inside the frame (:func:`check_region`).
    channels : sequence of str
        The planes' names (three planes) or the colours measured (a mosaic).

    Returns
    -------
    dict
        channel name -> :class:`EdgeSFR` (normals and angles in the frame's axes; ``transposed`` for a
        near-horizontal edge, measured with x and y exchanged).
    """
    import dataclasses

    horizontal = edge_is_horizontal(pixels, cfa_pattern, region_xywh)
    x0, y0, w, h = region_xywh
    if horizontal:
        pixels = np.swapaxes(pixels, 1, 2)
        cfa_pattern = _transpose_pattern(cfa_pattern) if cfa_pattern else None
        region_xywh = (y0, x0, h, w)
    out = {}
    for index, name in enumerate(channels):
        sites = (mosaic_sites(pixels[0], cfa_pattern, name, region_xywh) if cfa_pattern
                 else plane_sites(pixels[index], region_xywh))
        try:
            sfr = edge_sfr(sites)
        except CamsimError as exc:
            raise CamsimError(f"channel {name}: {exc}") from None
        if horizontal:
            sfr = dataclasses.replace(sfr, normal_xy=sfr.normal_xy[::-1], transposed=True)
        out[name] = sfr
    return out


# ------------------------------------------------------------------------------------------ a frame's measurement
#: The columns of ``mtf.csv``: one row per channel × frequency.
MTF_COLUMNS = ("channel", "frequency_cy_per_px", "mtf_measured", "mtf_model")
#: The summary's columns per channel (``analysis.json``'s ``mtf`` record and the printed table).
MTF_SUMMARY_KEYS = ("channel", "layer", "angle_deg", "rows_used", "mtf50_cy_per_px", "mtf_nyquist",
                    "model_mtf50_cy_per_px", "model_mtf_nyquist")


def _target_geometry(target, where: str) -> dict | None:
    """The slanted-edge geometry of a sidecar's ``target`` record, checked; None for another target or none."""
    if not isinstance(target, dict) or target.get("kind") != "slanted-edge":
        return None
    try:
        centre = [float(v) for v in target["centre_xy"]]
        normal = [float(v) for v in target["normal_xy"]]
        offset = float(target.get("offset_px", 0.0))
        if len(centre) != 2 or len(normal) != 2 or not all(map(math.isfinite, centre + normal + [offset])) \
                or abs(normal[0]) < 1e-6:
            raise ValueError
    except (KeyError, TypeError, ValueError):
        raise CamsimError(f"{where}: the sidecar's slanted-edge target record needs finite centre_xy, normal_xy "
                          "(x component not 0) and offset_px") from None
    return {"centre_xy": centre, "normal_xy": normal, "offset_px": offset}


def wants_mtf(meta: dict, edge_region) -> bool:
    """Whether a frame's SFR is measured: a region was given, or its sidecar records a slanted-edge target."""
    target = meta.get("target")
    return edge_region is not None or (isinstance(target, dict) and target.get("kind") == "slanted-edge")


def measure_frame_mtf(pixels: np.ndarray, meta: dict, edge_region=None, clean: np.ndarray | None = None,
                      where: str = "", source: str = "dng") -> dict:
    """The e-SFR of every channel of a frame beside the model of its sidecar's ``optics`` record.

    Parameters
    ----------
    pixels : numpy.ndarray, shape (3, H, W) or (1, H, W)
        The frame's values (a DNG's numbers or an EXR's noisy layer; a mosaic with the sidecar's ``cfa_pattern``).
    meta : dict
        The sidecar.
    edge_region : tuple of int, optional
        (x, y, w, h) px; default: the slanted-edge target's region (:func:`target_region`).
    clean : numpy.ndarray, shape (3, H, W), optional
        An EXR's clean layer, measured too (channels ``R_clean``, ``G_clean``, ``B_clean``).
    where : str
        The frame's file, for messages.
    source : str
        The layer name of ``pixels`` in the summary (``dng`` or ``noisy``).

    Returns
    -------
    dict
        ``region_xywh``, ``region_from``, ``model`` (the statement, or None without optics), ``optics_otf_model``
        (what the renderer wrote), ``source_sampling``, ``channels`` (per channel: :data:`MTF_SUMMARY_KEYS` and
        ``warnings``) and ``curves`` (rows of :data:`MTF_COLUMNS`).

    Raises
    ------
    CamsimError
        A region outside the frame, no edge in it, an unusable sidecar ``optics`` or ``target`` record.
    """
    from camsim.analysis.mtf_model import channel_mtf, check_optics_record

    width, height = int(meta["width_px"]), int(meta["height_px"])
    prefix = f"{where}: " if where else ""
    geometry = _target_geometry(meta.get("target"), where)
    if edge_region is not None:
        region, region_from = check_region(edge_region, width, height, prefix), "--edge-region"
    elif geometry is not None:
        margin = window_margin_px(meta.get("optics"))
        region = check_region(target_region(geometry, width, height, margin), width, height, prefix)
        region_from = f"the sidecar's slanted-edge target (± {margin} px about the edge)"
    else:
        raise CamsimError(f"{prefix}no edge to measure: the sidecar records no slanted-edge target; give a region "
                          "with --edge-region x,y,w,h")
    optics = meta.get("optics")
    record = None
    if optics is not None:
        try:
            record = check_optics_record(optics)
        except CamsimError as exc:
            raise CamsimError(f"{prefix}{exc}") from None
    cfa = meta.get("cfa_pattern") or None
    layers = [(pixels, cfa, source, "")]
    if clean is not None:
        layers.append((clean, None, "clean", "_clean"))
    channels, curves = [], []
    white = meta.get("white_level_dn")
    for values, pattern, layer, suffix in layers:
        try:
            sfrs = measure_region(values, pattern, region)
        except CamsimError as exc:
            raise CamsimError(f"{prefix}{layer} {exc}") from None
        x0, y0, w, h = region
        clipped = white is not None and layer == "dng" and bool(np.any(values[:, y0:y0 + h, x0:x0 + w] >= white))
        for index, (name, sfr) in enumerate(sfrs.items()):
            model = None
            if record is not None:
                model = channel_mtf(sfr.frequency_cy_per_px, sfr.normal_xy, record, index)
            warnings = list(sfr.warnings) + (["pixels at the white level in the region: a clipped edge's SFR is "
                                              "too high"] if clipped else [])
            channels.append({
                "channel": name + suffix, "layer": layer, "angle_deg": sfr.angle_deg, "rows_used": sfr.rows_used,
                "mtf50_cy_per_px": sfr.mtf50_cy_per_px, "mtf_nyquist": sfr.mtf_nyquist,
                "model_mtf50_cy_per_px": None if model is None else mtf50(sfr.frequency_cy_per_px, model),
                "model_mtf_nyquist": None if model is None else float(np.interp(0.5, sfr.frequency_cy_per_px, model)),
                "normal_xy": list(sfr.normal_xy), "transposed": sfr.transposed, "empty_bins": sfr.empty_bins,
                "warnings": warnings,
            })
            for k, f in enumerate(sfr.frequency_cy_per_px):
                curves.append({"channel": name + suffix, "frequency_cy_per_px": float(f),
                               "mtf_measured": float(sfr.mtf[k]),
                               "mtf_model": None if model is None else float(model[k])})
    from camsim.analysis.mtf_model import MODEL_STATEMENT

    return {
        "region_xywh": list(region), "region_from": region_from,
        "method": "ISO 12233:2017 e-SFR (line fit, 4x super-sampling, Hamming window, derivative correction; the "
                  "quarter-pixel bins' box divided out); frequencies in cycles per sensor pixel along the edge "
                  "normal" + ("; each CFA colour measured on its own sites" if cfa else ""),
        "model": MODEL_STATEMENT if record is not None else None,
        "optics_otf_model": optics.get("otf_model") if isinstance(optics, dict) else None,
        "source_sampling": ("the target's exact-area pixels: the full pixel's box, within the model's pixel factor "
                            "sinc(sqrt(ff) f nx) sinc(sqrt(ff) f ny)" if geometry is not None else
                            "not a slanted-edge target: the model takes the frame's pixels as full-pixel area samples "
                            "(camsim's sources are) within its pixel factor sinc(sqrt(ff) f nx) sinc(sqrt(ff) f ny); "
                            "the scene's own blur is not in it")
        if record is not None else None,
        "channels": channels, "curves": curves,
    }


def mtf_figure(record: dict, path, title: str = "") -> None:
    """A PNG of a frame's SFR per channel (solid) beside the model (dashed), with Nyquist marked: one panel per
    layer (the frame's values; an EXR's clean layer)."""
    from camsim.io.figures import new_figure, save_png

    colours = {"R": "tab:red", "G": "tab:green", "B": "tab:blue"}
    layers = list(dict.fromkeys(ch["layer"] for ch in record["channels"]))
    fig = new_figure(figsize=(5.2 * len(layers), 3.8), layout="constrained")
    axes = fig.subplots(1, len(layers), squeeze=False)[0]
    for ax, layer in zip(axes, layers):
        for ch in (c for c in record["channels"] if c["layer"] == layer):
            rows = [r for r in record["curves"] if r["channel"] == ch["channel"]]
            f = [r["frequency_cy_per_px"] for r in rows]
            colour = colours.get(ch["channel"][0], "k")
            m50 = ch["mtf50_cy_per_px"]
            ax.plot(f, [r["mtf_measured"] for r in rows], color=colour, lw=1.4,
                    label=f"{ch['channel']} measured" + (f" (MTF50 {m50:.3f})" if m50 is not None else ""))
            if rows and rows[0]["mtf_model"] is not None:
                ax.plot(f, [r["mtf_model"] for r in rows], color=colour, lw=1.0, ls="--",
                        label=f"{ch['channel']} model")
        ax.axvline(0.5, color="0.5", lw=0.8, ls=":")
        ax.axhline(0.5, color="0.8", lw=0.6)
        ax.set(xlim=(0, F_MAX_CY_PER_PX), ylim=(0, 1.1), xlabel="frequency (cycles / pixel)", ylabel="MTF",
               title=f"{title} ({layer})" if title else layer)
        ax.legend(fontsize=7, loc="upper right")
    save_png(fig, path)
