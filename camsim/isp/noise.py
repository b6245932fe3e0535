"""Noise through the ISP, measured exactly: what each stage does to a frame's noise.

A camsim frame knows its noise: the clean layer (each pixel's expected value,
:meth:`camsim.render.frame.Frame.clean_dn`, or an EXR's ``clean`` layer) is developed through the same ISP, with
the same facts and settings, as the noisy frame, and the noise at stage s is the difference of the two images at
that stage::

    noise_s = develop_stages(noisy)[s] − develop_stages(clean)[s]

(:func:`camsim.isp.develop_stages`; stages ``raw``, ``normalised``, ``white_balanced``, ``demosaiced``,
``srgb_linear``, ``gained``, ``toned``; the difference in float64). Nothing is estimated from the image content:
the statistics below are of the exact noise of that frame, in the units of each stage.

:func:`noise_through_isp` gives, per region, stage, channel (and, for a Bayer frame, CFA site), the noise's mean,
standard deviation and the correlation between horizontal and vertical neighbours, and the noise power spectrum's
radial profile (relative to white noise of the same variance); :func:`write_noise_report` writes them as a CSV
table and a figure. ``camsim develop --noise-report`` calls both.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from camsim.core.errors import CamsimError
from camsim.io.atomic import undo_on_failure, write_text_atomic
from camsim.io.figures import new_figure, save_png
from camsim.sensor.cfa import cfa_sites

__all__ = ["NOISE_COLUMNS", "NPS_BINS", "NPS_WINDOW", "BAYER_MARGIN_PX", "clean_mosaic", "noise_layers",
           "noise_through_isp",
           "nps_frequencies", "noise_csv_text", "noise_figure", "write_noise_report"]

#: The radial bins of the noise power spectrum: equal widths from 0 to 0.5 cycles per pixel (Nyquist).
NPS_BINS = 8

#: The noise power spectrum is computed on a centred window of the region of at most this many pixels a side.
NPS_WINDOW = 512

#: The columns of ``STEM_noise_stages.csv``, in order (the NPS columns ``nps_f…`` follow them).
NOISE_COLUMNS = ("region", "stage", "domain", "channel", "site", "unit", "pixels", "signal", "mean", "std",
                 "corr_h", "corr_v", "clipped_fraction")

_CHANNELS = "RGB"

#: A toned value this close to 0 or 1 counts as clipped by the tone curve.
_CLIP_TOLERANCE = 1e-6

#: Margin left out at each edge of a region of a Bayer frame, where the demosaicing kernels reach past it. Unit: px.
BAYER_MARGIN_PX = 4


def nps_frequencies(bins: int = NPS_BINS) -> np.ndarray:
    """The centres of the NPS's radial bins, shape (bins,). Unit: cycles per pixel."""
    edges = np.linspace(0.0, 0.5, bins + 1)
    return (edges[:-1] + edges[1:]) / 2


def _nps_column(f: float) -> str:
    return f"nps_f{f:.3f}"


def clean_mosaic(clean_rgb, cfa_pattern: str) -> np.ndarray:
    """The clean layer of a Bayer frame as a mosaic: at each site its own colour's plane.

    A Bayer frame's clean layer (:meth:`camsim.render.frame.Frame.clean_dn`, an EXR's ``clean`` layer) holds the
    expected value of each colour at every pixel; the mosaic that goes with the noisy one keeps each site's own.

    Parameters
    ----------
    clean_rgb : numpy.ndarray, shape (3, H, W)
        The clean layer. Unit: DN.
    cfa_pattern : {"RGGB", "BGGR", "GRBG", "GBRG"}

    Returns
    -------
    numpy.ndarray, shape (H, W), the dtype of ``clean_rgb``
    """
    clean_rgb = np.asarray(clean_rgb)
    if clean_rgb.ndim != 3 or clean_rgb.shape[0] != 3:
        raise CamsimError(f"a clean layer is (3, H, W), got shape {clean_rgb.shape}")
    out = np.empty(clean_rgb.shape[1:], dtype=clean_rgb.dtype)
    for dy, dx, c in cfa_sites(cfa_pattern):
        out[dy::2, dx::2] = clean_rgb[c, dy::2, dx::2]
    return out


def noise_layers(path) -> tuple[np.ndarray, np.ndarray, object]:
    """A frame file's noisy and clean numbers, and the ISP's facts about them: what :func:`noise_through_isp` takes.

    The clean layer is in a frame's EXR, beside its DNG (same stem): the EXR's noisy and clean layers (the signal
    before the ADC, and its expected value) are read, with the facts of the EXR's numbers
    (:func:`camsim.isp.facts_of`: black level = the dark level before the ADC). A Bayer frame's clean layer becomes
    the mosaic that goes with its noisy one (:func:`clean_mosaic`).

    Parameters
    ----------
    path : str or pathlib.Path
        A camsim frame's ``.exr``, or its ``.dng`` (then the ``.exr`` beside it is read).

    Returns
    -------
    noisy : numpy.ndarray, float32, shape (3, H, W), or (H, W) for a Bayer frame
    clean : numpy.ndarray, float32, same shape
    facts : camsim.isp.IspFacts

    Raises
    ------
    CamsimError
        No EXR beside the DNG, an EXR without a clean layer, or what :func:`camsim.render.frame_files.load_frame`
        refuses.
    """
    from camsim.io.exr import read_exr_clean
    from camsim.isp.facts import facts_of
    from camsim.render.frame_files import load_frame

    path = Path(path)
    exr = path.with_suffix(".exr") if path.suffix.lower() == ".dng" else path
    if not exr.is_file():
        raise CamsimError(f"{path}: the noise report needs the frame's EXR ({exr.name}): its clean layer holds the "
                          "noise-free values")
    loaded = load_frame(exr)
    clean, _ = read_exr_clean(exr)
    if clean is None:
        raise CamsimError(f"{exr}: no clean layer (clean.R, clean.G, clean.B): the noise report needs one")
    noisy = loaded.pixels_dn
    if clean.shape[1:] != noisy.shape[1:]:
        raise CamsimError(f"{exr}: the clean layer is {clean.shape[2]}x{clean.shape[1]} but the frame "
                          f"{noisy.shape[2]}x{noisy.shape[1]}")
    if loaded.cfa_pattern is not None:
        return noisy[0], clean_mosaic(clean, loaded.cfa_pattern), facts_of(loaded)
    return noisy, clean, facts_of(loaded)


def _region_list(regions, height: int, width: int, margin: int) -> list[tuple[str, tuple[int, int, int, int]]]:
    """[(name, (y0, y1, x0, x1))] of the regions, each shrunk by ``margin`` pixels at every edge."""
    if regions is None:
        items = [("frame", (0, 0, width, height))]
    elif isinstance(regions, Mapping):
        items = list(regions.items())
    else:
        items = []
        for r in regions:
            if hasattr(r, "rect") and hasattr(r, "name"):
                items.append((r.name, r.rect))
            elif isinstance(r, (tuple, list)) and len(r) == 2:
                items.append(tuple(r))
            else:
                raise CamsimError(f"noise through the ISP: a region is (name, (x, y, width, height)) or has a name "
                                  f"and a rect, got {r!r}")
    out = []
    for name, rect in items:
        try:
            values = [v for v in rect]
            if len(values) != 4 or any(isinstance(v, bool) or int(v) != v for v in values):
                raise ValueError
            x, y, w, h = (int(v) for v in values)
        except (TypeError, ValueError, OverflowError):
            raise CamsimError(f"noise through the ISP: region {name!r} must be (x, y, width, height) in whole "
                              f"pixels, got {rect!r}") from None
        if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > width or y + h > height:
            raise CamsimError(f"noise through the ISP: region {name!r} {(x, y, w, h)} does not lie inside the "
                              f"{width}x{height} frame")
        y0, y1, x0, x1 = y + margin, y + h - margin, x + margin, x + w - margin
        if y1 - y0 < 4 or x1 - x0 < 4:
            raise CamsimError(f"noise through the ISP: region {name!r} {(x, y, w, h)} leaves fewer than 4 x 4 "
                              f"pixels inside its {margin}-pixel margin")
        if str(name) in {n for n, _ in out}:
            raise CamsimError(f"noise through the ISP: two regions are named {str(name)!r}")
        out.append((str(name), (y0, y1, x0, x1)))
    if not out:
        raise CamsimError("noise through the ISP: no regions given")
    return out


def _site_names(pattern: str) -> dict[tuple[int, int], tuple[str, int]]:
    """{(dy, dx): (site name, channel)}: R, G1 (the green on R's row), G2, B."""
    sites = cfa_sites(pattern)
    red_row = next(dy for dy, _, c in sites if c == 0)
    out = {}
    for dy, dx, c in sites:
        name = "G1" if c == 1 and dy == red_row else "G2" if c == 1 else _CHANNELS[c]
        out[(dy, dx)] = (name, c)
    return out


class _Moments:
    """Centred moments of a sample of values, or of pairs (a, b), combinable exactly (Chan et al.'s parallel
    formulas): ``n``, the means, and the centred sums of squares and products."""

    __slots__ = ("n", "mean_a", "mean_b", "caa", "cbb", "cab")

    def __init__(self, n=0, mean_a=0.0, mean_b=0.0, caa=0.0, cbb=0.0, cab=0.0):
        self.n, self.mean_a, self.mean_b, self.caa, self.cbb, self.cab = n, mean_a, mean_b, caa, cbb, cab

    @classmethod
    def of(cls, a: np.ndarray, b: np.ndarray | None = None) -> _Moments:
        """The moments of the values ``a`` (float64), or of the pairs (``a``, ``b``) (arrays of one shape)."""
        if a.size == 0:
            return cls()
        mean_a = float(a.mean())
        da = (a - mean_a).ravel()
        caa = float(da @ da)
        if b is None:
            return cls(a.size, mean_a, 0.0, caa)
        mean_b = float(b.mean())
        db = (b - mean_b).ravel()
        return cls(a.size, mean_a, mean_b, caa, float(db @ db), float(da @ db))

    @classmethod
    def combined(cls, parts: list[_Moments]) -> _Moments:
        parts = [p for p in parts if p.n]
        n = sum(p.n for p in parts)
        if not n:
            return cls()
        mean_a = sum(p.n * p.mean_a for p in parts) / n
        mean_b = sum(p.n * p.mean_b for p in parts) / n
        return cls(n, mean_a, mean_b,
                   sum(p.caa + p.n * (p.mean_a - mean_a) ** 2 for p in parts),
                   sum(p.cbb + p.n * (p.mean_b - mean_b) ** 2 for p in parts),
                   sum(p.cab + p.n * (p.mean_a - mean_a) * (p.mean_b - mean_b) for p in parts))

    def std(self) -> float | None:
        return math.sqrt(self.caa / (self.n - 1)) if self.n > 1 else None

    def correlation(self) -> float | None:
        """Pearson's correlation of the pairs; None where either side is constant or there are fewer than 3."""
        if self.n < 3:
            return None
        denominator = math.sqrt(self.caa * self.cbb)
        return self.cab / denominator if denominator > 0 else None


def _lattice(plane: np.ndarray, r: int, q: int) -> np.ndarray:
    """The pixels of ``plane`` on rows r, r + 2, … and columns q, q + 2, … (r, q ≥ 0; may be empty)."""
    return plane[r::2, q::2]


def _class_moments(plane: np.ndarray, r: int | None, q: int | None):
    """(values, right-neighbour pairs, lower-neighbour pairs) moments of the pixels of one site class of ``plane``
    (float64), the class starting at row r, column q with step 2 (None: every pixel)."""
    if r is None:
        return (_Moments.of(plane), _Moments.of(plane[:, :-1], plane[:, 1:]),
                _Moments.of(plane[:-1, :], plane[1:, :]))
    x = _lattice(plane, r, q)
    right = _lattice(plane, r, q + 1)
    below = _lattice(plane, r + 1, q)
    w = min(x.shape[1], right.shape[1])
    h = min(x.shape[0], below.shape[0])
    return (_Moments.of(x), _Moments.of(x[:, :w], right[:, :w]), _Moments.of(x[:h], below[:h]))


def _radial_nps(plane: np.ndarray, mask: np.ndarray | None, bins: int) -> list[float | None]:
    """The noise power spectrum's radial profile of ``plane`` relative to white noise of the same power.

    The mean is subtracted (over the pixels of ``mask``, the others set to 0), the power |DFT|² averaged in radial
    frequency bins of equal width from 0 to 0.5 cycles per pixel and divided by its mean over the whole frequency
    plane: 1 at every frequency for uncorrelated noise, whatever its variance (also with ``mask``: a channel's
    sites of a mosaic).
    """
    h, w = plane.shape
    wh, ww = min(h, NPS_WINDOW), min(w, NPS_WINDOW)
    y0, x0 = (h - wh) // 2, (w - ww) // 2
    window = plane[y0:y0 + wh, x0:x0 + ww]
    if mask is not None:
        m = mask[y0:y0 + wh, x0:x0 + ww]
        window = np.where(m, window - window[m].mean(), 0.0)
    else:
        window = window - window.mean()
    power = np.abs(np.fft.fft2(window)) ** 2
    total = power.mean()
    if not total > 0:
        return [None] * bins
    fy = np.fft.fftfreq(wh)[:, None]
    fx = np.fft.fftfreq(ww)[None, :]
    radius = np.hypot(fy, fx)
    index = np.floor(radius / 0.5 * bins).astype(np.int64)
    inside = index < bins
    sums = np.bincount(index[inside], weights=power[inside], minlength=bins)
    counts = np.bincount(index[inside], minlength=bins)
    return [float(s / c / total) if c else None for s, c in zip(sums, counts)]


def _unit(stage: str) -> str:
    return "DN" if stage == "raw" else "sRGB value" if stage == "toned" else "white level"


def noise_through_isp(noisy, clean, facts, settings=None, regions=None, *, margin: int | None = None,
                      nps_bins: int = NPS_BINS) -> list[dict]:
    """How the noise of a frame changes through each stage of the ISP, measured exactly.

    The noisy and the clean raw frame are developed with :func:`camsim.isp.develop_stages` (same facts, same
    settings) and their difference at each stage (in float64) is the noise. The statistics of a channel's pixels
    are those of its CFA site classes combined exactly.

    Parameters
    ----------
    noisy, clean : numpy.ndarray
        The raw frame and its clean layer (the expected value of every pixel), in the same units: a Bayer mosaic
        (H, W) or (1, H, W), each site its own colour's value (:func:`clean_mosaic`), or a three-chip image
        (3, H, W). Unit: DN. The clean layer is the expected signal before the ADC (``Frame.clean_dn()``, an EXR's
        ``clean`` layer), so the noisy frame that goes with it is the one before the ADC too (``Frame.noisy_dn``,
        an EXR's ``noisy`` layer), with ``facts`` for those numbers (black level: the dark level before the ADC).
    facts : camsim.isp.IspFacts
        What the ISP knows of the frame (:func:`camsim.isp.facts_of`, :func:`camsim.isp.facts_from_info`).
    settings : camsim.isp.IspSettings, optional
        The ISP's settings (default ``IspSettings()``).
    regions : mapping of str to (x, y, width, height), or sequence of regions, optional
        Rectangles to measure, in pixels (the sidecar's ``patch_rects`` convention; objects with ``name`` and
        ``rect`` such as :class:`camsim.scene.regions.Region` are taken too). Default: the whole frame, named
        ``frame``.
    margin : int, optional
        Pixels left out at every edge of each region. Default 4 for a Bayer frame (where the demosaicing kernels
        reach past the region's edge or the frame's), 0 for a three-chip frame.
    nps_bins : int
        The number of radial bins of the noise power spectrum, from 0 to 0.5 cycles per pixel.

    Returns
    -------
    list of dict
        One row per region, stage, channel and site, with the keys of :data:`NOISE_COLUMNS` and ``nps`` (list of
        ``nps_bins`` values, or None) and ``nps_frequency`` (tuple: the bins' centres, cycles per pixel):

        - ``domain``: ``mosaic`` for the stages before demosaicing of a Bayer frame, ``rgb`` otherwise;
        - ``channel``: ``R``, ``G``, ``B``; ``site``: ``all`` (every pixel of the channel: in a mosaic the sites of
          its colour, in an image every pixel), or, for a Bayer frame, one class of CFA site (``R``, ``G1`` — the
          green on the red row —, ``G2``, ``B``; in a mosaic only the sites of the channel's own colour);
        - ``pixels``: the pixels measured; ``signal``: the mean of the clean frame at the stage over them (for
          ``raw``, above the black level ``facts.black_dn``);
          ``mean``, ``std`` (ddof 1): of the noise, in ``unit`` (``DN`` for ``raw``, the white level = 1 for
          ``normalised`` … ``gained``, the sRGB value in [0, 1] for ``toned``);
        - ``corr_h``, ``corr_v``: Pearson's correlation between the noise of each pixel and that of its right
          (``h``) and lower (``v``) neighbour in the same plane (in a mosaic the neighbour is a site of another
          colour), both inside the region;
        - ``clipped_fraction``: for ``toned``, the fraction of the noisy pixels at 0 or 1 (within 10⁻⁶: where the
          tone curve's clipping changes the noise), else None;
        - ``nps``: for the ``all`` rows, the noise power spectrum's radial profile relative to white noise of the
          same power (1 at every frequency for uncorrelated noise; above 1 at low frequencies and below it at high
          ones for noise that demosaicing has smoothed),
          computed on a centred window of at most :data:`NPS_WINDOW` pixels a side; for a channel of a mosaic,
          on the mosaic with the other colours' sites set to 0. None for the site rows.

    Raises
    ------
    CamsimError
        The noisy and clean frames differ in shape, a region does not fit the frame (or leaves fewer than 4 × 4
        pixels inside its margin), a bad margin or number of NPS bins.
    """
    from camsim.isp import IspSettings, develop_stages

    noisy = np.asarray(noisy)
    clean = np.asarray(clean)
    if facts.cfa_pattern is not None:  # a LoadedFrame's (1, H, W) mosaic
        noisy = noisy[0] if noisy.ndim == 3 and noisy.shape[0] == 1 else noisy
        clean = clean[0] if clean.ndim == 3 and clean.shape[0] == 1 else clean
    if noisy.shape != clean.shape:
        raise CamsimError(f"noise through the ISP: the noisy frame has shape {noisy.shape} but the clean one "
                          f"{clean.shape}")
    if noisy.ndim not in (2, 3):
        raise CamsimError(f"noise through the ISP: a frame is a mosaic (H, W) or an image (3, H, W), got "
                          f"shape {noisy.shape}")
    settings = IspSettings() if settings is None else settings
    pattern = facts.cfa_pattern if noisy.ndim == 2 else None
    if noisy.ndim == 2 and pattern is None:
        raise CamsimError("noise through the ISP: a mosaic (H, W) needs facts with a CFA pattern")
    height, width = noisy.shape[-2:]
    margin = (BAYER_MARGIN_PX if pattern else 0) if margin is None else margin
    if isinstance(margin, bool) or not isinstance(margin, (int, np.integer)) or margin < 0:
        raise CamsimError(f"noise through the ISP: the margin must be a whole number of pixels ≥ 0, got {margin!r}")
    if isinstance(nps_bins, bool) or not isinstance(nps_bins, (int, np.integer)) or not 1 <= nps_bins <= 256:
        raise CamsimError(f"noise through the ISP: nps_bins must be a whole number from 1 to 256, got {nps_bins!r}")
    boxes = _region_list(regions, height, width, margin)
    noisy_stages = develop_stages(noisy, facts, settings)
    clean_stages = develop_stages(clean, facts, settings)
    sites = _site_names(pattern) if pattern else {}
    black = np.asarray(facts.black_dn, dtype=np.float64).reshape(3)
    frequencies = tuple(nps_frequencies(nps_bins).tolist())
    rows = []
    for region, (y0, y1, x0, x1) in boxes:
        for stage in noisy_stages:
            noisy_stage, clean_stage = np.asarray(noisy_stages[stage]), np.asarray(clean_stages[stage])
            if noisy_stage.shape != clean_stage.shape:
                raise CamsimError(f"noise through the ISP: stage {stage!r} has shape {noisy_stage.shape} for the "
                                  f"noisy frame but {clean_stage.shape} for the clean one")
            mosaic = noisy_stage.ndim == 2
            if mosaic:
                noisy_stage, clean_stage = noisy_stage[None], clean_stage[None]
            # the site classes, by the (row, column) of their first pixel inside the region
            starts = {key: ((key[0] - y0) % 2, (key[1] - x0) % 2) for key in sites}
            for p in range(noisy_stage.shape[0]):
                crop = np.s_[p, y0:y1, x0:x1]
                clean_plane = clean_stage[crop].astype(np.float64)
                plane = noisy_stage[crop].astype(np.float64) - clean_plane
                clipped = None
                if stage == "toned":
                    # at 0 or 1 within float32 rounding (the sRGB curve gives 1 − 6e-8 at 1)
                    clipped = (noisy_stage[crop] <= _CLIP_TOLERANCE) | (noisy_stage[crop] >= 1 - _CLIP_TOLERANCE)
                classes = {key: _class_moments(plane, *starts[key]) for key in sites} or {None: _class_moments(
                    plane, None, None)}
                for c in range(3) if mosaic else [p]:
                    own = [k for k in sites if sites[k][1] == c] if mosaic else list(classes)
                    groups = [("all", own)] + ([(sites[k][0], [k]) for k in own] if sites else [])
                    for site, keys in groups:
                        values = _Moments.combined([classes[k][0] for k in keys])
                        if keys == [None]:
                            signal = float(clean_plane.mean())
                            clipped_fraction = None if clipped is None else float(clipped.mean())
                        else:
                            lattices = [starts[k] for k in keys]
                            signal = sum(float(_lattice(clean_plane, *rq).sum()) for rq in lattices) / values.n
                            clipped_fraction = None if clipped is None else sum(
                                int(_lattice(clipped, *rq).sum()) for rq in lattices) / values.n
                        row = {"region": region, "stage": stage, "domain": "mosaic" if mosaic else "rgb",
                               "channel": _CHANNELS[c], "site": site, "unit": _unit(stage),
                               "pixels": int(values.n),
                               "signal": signal - (black[c] if stage == "raw" else 0.0),
                               "mean": values.mean_a, "std": values.std(),
                               "corr_h": _Moments.combined([classes[k][1] for k in keys]).correlation(),
                               "corr_v": _Moments.combined([classes[k][2] for k in keys]).correlation(),
                               "clipped_fraction": clipped_fraction,
                               "nps": None, "nps_frequency": frequencies}
                        if site == "all":
                            mask = None
                            if keys != [None]:
                                mask = np.zeros(plane.shape, dtype=bool)
                                for k in keys:
                                    mask[starts[k][0]::2, starts[k][1]::2] = True
                            row["nps"] = _radial_nps(plane, mask, nps_bins)
                        rows.append(row)
    # the rows region by region, then stage by stage (as they were made), channels in R, G, B order
    return rows


# --- the report ---------------------------------------------------------------------------------------------


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return "" if not math.isfinite(value) else f"{value:.6g}"
    return str(value)


def noise_csv_text(rows: list[dict]) -> str:
    """The CSV text of :func:`noise_through_isp`'s rows: the columns of :data:`NOISE_COLUMNS`, then one column
    per NPS bin named by its centre frequency (``nps_f0.031``: cycles per pixel). Empty cells are undefined."""
    frequencies = rows[0]["nps_frequency"] if rows else nps_frequencies().tolist()
    nps_columns = [_nps_column(f) for f in frequencies]
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(list(NOISE_COLUMNS) + nps_columns)
    for row in rows:
        nps = row.get("nps") or [None] * len(nps_columns)
        writer.writerow([_cell(row.get(k)) for k in NOISE_COLUMNS] + [_cell(v) for v in nps])
    return buffer.getvalue()


def _stage_order(rows: list[dict]) -> list[str]:
    order = []
    for row in rows:
        if row["stage"] not in order:
            order.append(row["stage"])
    return order


_COLOURS = {"R": "tab:red", "G": "tab:green", "B": "tab:blue"}


def _series(rows: list[dict], stages: list[str], key: str) -> np.ndarray:
    by_stage = {r["stage"]: r.get(key) for r in rows}
    return np.array([np.nan if by_stage.get(s) is None else by_stage[s] for s in stages], dtype=float)


def _relative(rows: list[dict], stages: list[str]) -> np.ndarray:
    std, signal = _series(rows, stages, "std"), _series(rows, stages, "signal")
    with np.errstate(invalid="ignore", divide="ignore"):
        return 100 * np.where(signal > 0, std / signal, np.nan)


#: The figure draws one line per region (green channel) for up to this many regions, and names them up to 12.
_MAX_REGION_LINES = 30


def noise_figure(rows: list[dict], title: str = ""):
    """The figure of :func:`write_noise_report`: per stage, the noise's standard deviation relative to the clean
    signal and the correlation between neighbours — per channel for one region, for the green channel of each
    region (up to 30) when there are several — and the radial NPS of the first region's noise, normalised raw vs
    developed."""
    regions = list(dict.fromkeys(r["region"] for r in rows))
    first_region = regions[0]
    all_rows = [r for r in rows if r["site"] == "all"]
    mine = [r for r in all_rows if r["region"] == first_region]
    stages = _stage_order(mine)
    x = np.arange(len(stages))
    fig = new_figure(figsize=(15, 4.6), layout="constrained")
    ax_std, ax_corr, ax_nps = fig.subplots(1, 3)
    if len(regions) == 1:
        for channel, colour in _COLOURS.items():
            picked = [r for r in mine if r["channel"] == channel]
            ax_std.plot(x, _relative(picked, stages), "o-", color=colour, label=channel)
            ax_corr.plot(x, _series(picked, stages, "corr_h"), "o-", color=colour, label=f"{channel}, horizontal")
            ax_corr.plot(x, _series(picked, stages, "corr_v"), "s--", color=colour, mfc="none",
                         label=f"{channel}, vertical")
        scope = f"region {first_region!r}"
    else:
        shown = regions[:_MAX_REGION_LINES]
        from matplotlib import colormaps

        colours = colormaps["viridis"](np.linspace(0, 0.9, len(shown)))
        for region, colour in zip(shown, colours):
            picked = [r for r in all_rows if r["region"] == region and r["channel"] == "G"]
            label = region if len(shown) <= 12 else None
            ax_std.plot(x, _relative(picked, stages), "o-", color=colour, ms=3, lw=1)  # named on the right
            ax_corr.plot(x, _series(picked, stages, "corr_h"), "o-", color=colour, ms=3, lw=1,
                         label=None if label is None else f"{region}, horizontal")
        scope = (f"green channel of {len(shown)} regions" + (f" (of {len(regions)})" if len(shown) < len(regions)
                                                              else ""))
    for ax in (ax_std, ax_corr):
        ax.set_xticks(x, stages, rotation=30, ha="right")
        ax.grid(alpha=0.3)
    ax_std.set(yscale="log", ylabel="noise std / clean signal (%)",
               title="Noise relative to the clean signal\n(raw: above black)")
    from matplotlib.ticker import LogLocator, NullFormatter, ScalarFormatter

    ax_std.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    ax_std.yaxis.set_major_formatter(ScalarFormatter())
    ax_std.yaxis.set_minor_formatter(NullFormatter())
    ax_corr.axhline(0, color="0.3", lw=0.8)
    pixels = min(r["pixels"] for r in all_rows)
    band = 2 / math.sqrt(pixels)  # two standard errors of a zero correlation
    ax_corr.axhspan(-band, band, color="0.85", zorder=0, label=f"±2/√n: no correlation (n = {pixels})")
    measured = [v for r in all_rows for v in (r["corr_h"], r["corr_v"]) if v is not None]
    ax_corr.set_ylim(min([-0.2] + [v - 0.05 for v in measured]), max([1.0] + [v + 0.05 for v in measured]))
    ax_corr.set(ylabel="correlation with the neighbour", title="Correlation between neighbours\nper stage")
    if ax_std.get_legend_handles_labels()[1]:
        ax_std.legend(fontsize=7, loc="best")
    ax_corr.legend(fontsize=7, ncol=2, loc="upper left")
    first = "normalised" if "normalised" in stages else stages[0]
    last = stages[-1]
    for stage, style in ((first, ":"), (last, "-")):
        for channel, colour in _COLOURS.items():
            row = next((r for r in mine if r["stage"] == stage and r["channel"] == channel), None)
            if row is None or row.get("nps") is None:
                continue
            nps = np.array([np.nan if v is None else v for v in row["nps"]], dtype=float)
            ax_nps.plot(row["nps_frequency"], nps, style, marker="o", ms=3, color=colour,
                        label=f"{channel}, {stage}")
    ax_nps.axhline(1, color="0.3", lw=0.8)
    ax_nps.set(xlabel="radial frequency (cycles per pixel)", ylabel="NPS / white noise of the same variance",
               title=f"Noise power spectrum: {first} vs {last}\nregion {first_region!r}", xlim=(0, 0.5),
               ylim=(0, None))
    ax_nps.grid(alpha=0.3)
    ax_nps.legend(fontsize=7, ncol=2)
    fig.suptitle((title + ": " if title else "") + f"noise through the ISP, {scope} "
                 "(noise = developed noisy − developed clean)")
    return fig


def write_noise_report(rows: list[dict], out_dir, stem: str) -> list[Path]:
    """Write ``STEM_noise_stages.csv`` (:func:`noise_csv_text`) and ``STEM_noise_stages.png``
    (:func:`noise_figure`) into ``out_dir``, atomically and both or neither.

    Parameters
    ----------
    rows : list of dict
        :func:`noise_through_isp`'s rows.
    out_dir : str or pathlib.Path
        An existing folder.
    stem : str
        The files' stem (the frame's).

    Returns
    -------
    list of pathlib.Path
        The CSV and the PNG.
    """
    if not rows:
        raise CamsimError("noise report: no rows to write")
    out_dir = Path(out_dir)
    csv_path = out_dir / f"{stem}_noise_stages.csv"
    png_path = out_dir / f"{stem}_noise_stages.png"
    fig = noise_figure(rows, stem)
    with undo_on_failure():
        write_text_atomic(csv_path, noise_csv_text(rows))
        save_png(fig, png_path)
    return [csv_path, png_path]
