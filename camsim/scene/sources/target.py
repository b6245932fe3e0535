"""Synthetic targets rendered spectrally (scene-file table ``[target]``): a dead-leaves chart and a slanted edge.

Both are a label map plus K spectra, like a chart, never a per-pixel spectrum:

* ``kind = "dead-leaves"``: the texture target of the texture-acutance literature (Cao, Guichard & Hornung 2010,
  IEEE / ISO): opaque disks dropped one over another until the frame is covered, radii with density ∝ r⁻³ on
  [``radius_min_px``, ``radius_max_px``], centres uniform, each disk's reflectance drawn uniformly from a reflectance
  set (plus optional flat greys). The label of a pixel is the spectrum of the topmost disk that covers its centre.
  It is drawn top-down (:func:`dead_leaves`): disks are drawn in order from the top, and each fills only the pixels
  still uncovered, until none is left — an exact sample of the dead-leaves model seen through the frame.
* ``kind = "slanted-edge"``: an ISO 12233 style straight edge through the frame centre (shifted by ``offset_px``
  along its normal), ``angle_deg`` from vertical, between a dark reflectance ``low`` and a bright one ``high``.
  Each pixel (a unit square) holds the exact area fraction a of itself on the bright side (:func:`edge_coverage`),
  rounded to one of ``levels`` values k / (levels − 1), so that K = ``levels`` spectra (1 − a)·low + a·high.
* ``kind = "flat"``: a uniform field of one ``reflectance`` (a flat grey in [0, 1], or a patch name of
  ``reflectances``) over the whole frame, one patch ``flat`` (K = 1): the flat field of a photon-transfer
  calibration; with ``reflectance = 0`` no photon reaches the sensor, a dark frame (the built-in ``flat`` and
  ``dark`` scenes).

Coordinates are pixels: x to the right, y down, the origin at the top-left corner of the top-left pixel, so that
pixel (row i, column j) is the square [j, j + 1] × [i, i + 1] and its centre is (j + ½, i + ½).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from camsim.core.errors import CamsimError
from camsim.core.schema import finite_float
from camsim.core.seeding import target_generator
from camsim.light.spectra import reflectance_set
from camsim.scene.sources.base import SceneSource, SourceSpectra, typed

TARGET_KINDS = ("dead-leaves", "slanted-edge", "flat")
_COMMON_KEYS = frozenset({"kind", "reflectances"})
_DEAD_LEAVES_KEYS = frozenset({"seed", "radius_min_px", "radius_max_px", "greys"})
_EDGE_KEYS = frozenset({"angle_deg", "offset_px", "low", "high", "levels"})
_FLAT_KEYS = frozenset({"reflectance"})
_KIND_KEYS = {"dead-leaves": _DEAD_LEAVES_KEYS, "slanted-edge": _EDGE_KEYS, "flat": _FLAT_KEYS}

#: The most disks a dead-leaves chart may need (its bound, see :func:`dead_leaves`); beyond it is an error.
MAX_DISKS = 200_000_000
#: Candidate pixels tested at once in :func:`dead_leaves` (memory ≈ 60 bytes × this).
_STAMP_BUDGET = 1 << 21
#: Side of the tiles by which :func:`dead_leaves` finds the uncovered pixels a disk may cover.
_TILE = 8
#: The smallest and the largest disk radius of a dead-leaves chart, pixels: a frame of 200 megapixels needs no
#: larger disk, and a smaller one only asks for more disks than :data:`MAX_DISKS` (beyond the range the disk count
#: and the radius law overflow float64).
RADIUS_RANGE_PX = (0.01, 1e6)
#: The largest number of coverage levels of a slanted edge.
MAX_LEVELS = 4096


# --------------------------------------------------------------------------------------------------- dead leaves
def _radii(u: np.ndarray, radius_min_px: float, radius_max_px: float) -> np.ndarray:
    """Radii (pixels) from uniform ``u`` in [0, 1) by inverting the CDF of the r⁻³ law on [r_min, r_max],
    F(r) = (r_min⁻² − r⁻²) / (r_min⁻² − r_max⁻²)."""
    inv_min, inv_max = radius_min_px ** -2, radius_max_px ** -2
    return (inv_min - u * (inv_min - inv_max)) ** -0.5


def mean_disk_area(radius_min_px: float, radius_max_px: float) -> float:
    """E[π r²] under the r⁻³ law, in px²: π · 2 ln(r_max / r_min) / (r_min⁻² − r_max⁻²) (π r² when equal)."""
    if radius_min_px == radius_max_px:
        return math.pi * radius_min_px ** 2
    return math.pi * 2 * math.log(radius_max_px / radius_min_px) / (radius_min_px ** -2 - radius_max_px ** -2)


def disk_bound(width: int, height: int, radius_min_px: float, radius_max_px: float) -> int:
    """The most disks :func:`dead_leaves` draws before it gives up: n = (ln(W·H) + 20) / q.

    Centres are uniform on the frame grown by r_max on every side (area A), so one disk covers a given pixel centre
    with probability q = E[π r²] / A, and after n disks some pixel is still uncovered with probability at most
    W·H·(1 − q)ⁿ ≤ e⁻²⁰ (about 2e-9). The expected number needed is about ln(W·H) / q.
    """
    area = (width + 2 * radius_max_px) * (height + 2 * radius_max_px)
    q = mean_disk_area(radius_min_px, radius_max_px) / area
    return math.ceil((math.log(width * height) + 20) / q)


def _reflectance_or_patch(table: dict, key: str, default: float, where: str) -> float | str:
    """A ``[target]`` key that is a flat reflectance in [0, 1] (an integer is taken as a number) or a patch name."""
    value = table.get(key, default)
    if isinstance(value, int) and not isinstance(value, bool):
        value = finite_float(value)
        if value is None:  # an integer beyond float64
            value = math.inf
    if isinstance(value, float):
        if not 0 <= value <= 1:
            raise CamsimError(f"{where}: [target] {key} must be a reflectance in [0, 1], got {value:g}")
    elif not isinstance(value, str):
        raise CamsimError(f"{where}: [target] {key} must be a reflectance in [0, 1] or a patch name, got {value!r}")
    return value


@dataclass(frozen=True)
class DeadLeaves:
    """A dead-leaves label map and what drew it.

    Attributes
    ----------
    labels : numpy.ndarray, shape (H, W), uint8 (uint16 for more than 256 spectra)
        The spectrum of the topmost disk over each pixel's centre.
    n_disks : int
        Disks drawn, from the top, until the frame was covered (including those that hid nothing or fell outside).
    disks : numpy.ndarray, shape (n_disks, 4), float64, or None
        With ``keep_disks``: per drawn disk, top first, its centre x, y (px), radius (px) and spectrum index.
    """

    labels: np.ndarray
    n_disks: int
    disks: np.ndarray | None = None


def dead_leaves(width: int, height: int, radius_min_px: float, radius_max_px: float, n_spectra: int, rng,
                *, keep_disks: bool = False) -> DeadLeaves:
    """Draw a dead-leaves label map, top-down, until every pixel is covered.

    Disks are drawn in order from the top: radius with density ∝ r⁻³ on [``radius_min_px``, ``radius_max_px``],
    centre uniform on the frame grown by ``radius_max_px`` on every side (every disk that can reach the frame),
    spectrum index uniform in [0, ``n_spectra``). A pixel is covered by a disk when its centre is inside it
    (distance ≤ r), and takes the spectrum of the first disk, in that order, that covers it: the visible leaf of
    the dead-leaves model (later disks lie beneath). Drawing stops when no pixel is left uncovered, or raises after
    :func:`disk_bound` disks. Disks are drawn in batches of about 1 / (2q) (q of :func:`disk_bound`), and a batch
    is tested only against the pixels still uncovered, found through the 8 × 8 px tiles its disks' boxes touch; the
    first disk of a batch to cover a pixel wins it.

    Parameters
    ----------
    width, height : int
        Frame size in pixels.
    radius_min_px, radius_max_px : float
        The radius range, pixels, 0 < r_min ≤ r_max.
    n_spectra : int
        Number of spectra K; labels are in [0, K).
    rng : numpy.random.Generator, numpy.random.SeedSequence or int
        The pattern's random stream (a scene draws it from :func:`camsim.core.seeding.target_generator`).
    keep_disks : bool, optional
        Also return every drawn disk (for tests and figures).

    Returns
    -------
    DeadLeaves

    Raises
    ------
    CamsimError
        If the frame would need more than :data:`MAX_DISKS` disks (r_min too small for the frame).
    """
    rng = np.random.default_rng(rng)
    if not (RADIUS_RANGE_PX[0] <= radius_min_px <= radius_max_px <= RADIUS_RANGE_PX[1]):
        raise CamsimError(f"dead leaves: need {RADIUS_RANGE_PX[0]:g} <= radius_min_px <= radius_max_px <= "
                          f"{RADIUS_RANGE_PX[1]:g}, got {radius_min_px}, {radius_max_px}")
    if not 1 <= n_spectra <= 65536:
        raise CamsimError(f"dead leaves: need 1 to 65536 spectra, got {n_spectra}")
    cap = disk_bound(width, height, radius_min_px, radius_max_px)
    if cap > MAX_DISKS:
        raise CamsimError(f"dead leaves: a {width}x{height} frame with radius_min_px = {radius_min_px:g} may need up "
                          f"to {cap:.3g} disks (more than {MAX_DISKS:.0e}): raise radius_min_px")
    top = np.full(width * height, -1, dtype=np.int32)
    tiles_x, tiles_y = -(-width // _TILE), -(-height // _TILE)
    # the uncovered pixels (flat indices), grouped by 8 × 8 tile: tile t's are rem[offsets[t]:offsets[t + 1]]
    ys = np.arange(tiles_y * _TILE)[:, None]
    xs = np.arange(tiles_x * _TILE)[None, :]
    tiled = np.where((ys < height) & (xs < width), ys * width + xs, -1)  # frame padded to whole tiles
    rem = tiled.reshape(tiles_y, _TILE, tiles_x, _TILE).transpose(0, 2, 1, 3).ravel()
    rem_tile = np.repeat(np.arange(tiles_x * tiles_y), _TILE * _TILE)[rem >= 0]
    rem = rem[rem >= 0]
    del tiled
    margin = radius_max_px
    # each batch of disks covers about 40 % of what is left (1 − e^(−1/2))
    chunk = int(np.clip(0.5 * (width + 2 * margin) * (height + 2 * margin)
                        / mean_disk_area(radius_min_px, radius_max_px), 256, 1 << 20))
    drawn, kept = 0, []
    while rem.size:
        if drawn >= cap:
            raise CamsimError(f"dead leaves: {rem.size} pixels still uncovered after {drawn} disks")
        m = min(chunk, cap - drawn)
        r = _radii(rng.random(m), radius_min_px, radius_max_px)
        cx = rng.uniform(-margin, width + margin, m)
        cy = rng.uniform(-margin, height + margin, m)
        spectrum = rng.integers(0, n_spectra, m)
        drawn += m
        if keep_disks:
            kept.append(np.column_stack([cx, cy, r, spectrum]))
        offsets = np.searchsorted(rem_tile, np.arange(tiles_x * tiles_y + 1))
        _cover(top, width, rem, offsets, tiles_x, cx, cy, r, spectrum)
        still = top[rem] < 0
        rem, rem_tile = rem[still], rem_tile[still]
    dtype = np.uint8 if n_spectra <= 256 else np.uint16
    labels = top.astype(dtype).reshape(height, width)
    disks = np.concatenate(kept)[:drawn] if keep_disks else None
    return DeadLeaves(labels, drawn, disks)


def _expand(counts: np.ndarray):
    """For a run of groups of ``counts[g]`` items: each item's group and its index within the group."""
    group = np.repeat(np.arange(counts.size), counts)
    return group, np.arange(group.size) - np.repeat(np.cumsum(counts) - counts, counts)


def _cover(top, width, rem, offsets, tiles_x, cx, cy, r, spectrum) -> None:
    """Give each still-uncovered pixel inside disks (cx, cy, r) (in top-down order) the spectrum of the first disk
    that covers it. Candidates are the uncovered pixels (``rem``, grouped by tile by ``offsets``) of the tiles that
    each disk's box touches, handled in batches of about :data:`_STAMP_BUDGET`."""
    height = top.size // width
    # the pixel columns j whose centre j + 1/2 lies within [cx − r, cx + r], clipped to the frame; rows alike
    x0 = np.maximum(np.ceil(cx - r - 0.5), 0).astype(np.int64)
    x1 = np.minimum(np.floor(cx + r - 0.5), width - 1).astype(np.int64)
    y0 = np.maximum(np.ceil(cy - r - 0.5), 0).astype(np.int64)
    y1 = np.minimum(np.floor(cy + r - 0.5), height - 1).astype(np.int64)
    live = np.flatnonzero((x0 <= x1) & (y0 <= y1))
    tx0, ty0 = x0[live] // _TILE, y0[live] // _TILE
    tw = x1[live] // _TILE - tx0 + 1
    # (disk, tile) pairs, disk-major (so top-down), kept where the tile has uncovered pixels
    pair_disk, k = _expand(tw * (y1[live] // _TILE - ty0 + 1))
    tile = (ty0[pair_disk] + k // tw[pair_disk]) * tiles_x + tx0[pair_disk] + k % tw[pair_disk]
    first_px, counts = offsets[tile], offsets[tile + 1] - offsets[tile]
    busy = counts > 0
    pair_disk, first_px, counts = live[pair_disk[busy]], first_px[busy], counts[busy]
    ends = np.cumsum(counts)
    start = 0
    while start < counts.size:  # batches of at most _STAMP_BUDGET candidates (at least one pair), in order
        base = ends[start - 1] if start else 0
        stop = max(int(np.searchsorted(ends, base + _STAMP_BUDGET, side="right")), start + 1)
        pair, j = _expand(counts[start:stop])
        flat = rem[first_px[start:stop][pair] + j]
        disk = pair_disk[start:stop][pair]
        py, px = np.divmod(flat, width)
        inside = (px + 0.5 - cx[disk]) ** 2 + (py + 0.5 - cy[disk]) ** 2 <= r[disk] ** 2
        inside &= top[flat] < 0  # not taken by an earlier batch
        flat, disk = flat[inside], disk[inside]
        # candidates are in disk order: a pixel's first occurrence (np.unique's return_index) is its top disk
        flat, first = np.unique(flat, return_index=True)
        top[flat] = spectrum[disk[first]]
        start = stop


@functools.lru_cache(maxsize=4)
def _dead_leaves_cached(width, height, radius_min_px, radius_max_px, n_spectra, seed) -> DeadLeaves:
    """The scene's dead-leaves map, kept between the illuminants of a run (read-only)."""
    result = dead_leaves(width, height, radius_min_px, radius_max_px, n_spectra, target_generator(seed))
    result.labels.flags.writeable = False
    return result


# ------------------------------------------------------------------------------------------------- slanted edge
def edge_coverage(width: int, height: int, angle_deg: float, offset_px: float = 0.0) -> np.ndarray:
    """The exact area fraction of each pixel on the bright side of a straight edge.

    The edge passes through the frame centre (W/2, H/2) shifted by ``offset_px`` along its normal, at
    ``angle_deg`` θ from vertical (|θ| ≤ 45°). A point (x, y) is at signed distance
    d = (x − W/2)·cos θ − (y − H/2)·sin θ − offset_px from it and on the bright side where d > 0 (the right side for
    θ = 0; a positive θ leans the edge's lower end to the right, x growing with y).

    Over pixel (i, j), d = d₀ + u·cos θ − v·sin θ with (u, v) uniform on the unit square and d₀ its top-left
    corner's distance; the fraction is P(d > 0), a piecewise quadratic (the CDF of a sum of two uniforms).

    Returns
    -------
    numpy.ndarray, shape (H, W), float64
        Coverage in [0, 1].
    """
    theta = math.radians(angle_deg)
    cos, sin = math.cos(theta), math.sin(theta)
    d0 = ((np.arange(width) - width / 2) * cos)[None, :] - ((np.arange(height) - height / 2) * sin)[:, None] - offset_px
    # d = d0 + min(−sin, 0) + X with X = cos·U + |sin|·V' (U, V' uniform); fraction = 1 − P(X ≤ t), t = −d0 − min
    t = -(d0 + min(-sin, 0.0))
    alpha, beta = max(abs(cos), abs(sin)), min(abs(cos), abs(sin))
    return 1.0 - _uniform_sum_cdf(t, alpha, beta)


def _uniform_sum_cdf(t: np.ndarray, alpha: float, beta: float) -> np.ndarray:
    """P(α U + β V ≤ t) for independent U, V uniform on [0, 1], α ≥ β ≥ 0 (β = 0 allowed)."""
    t = np.clip(t, 0.0, alpha + beta)
    safe = max(2 * alpha * beta, np.finfo(float).tiny)
    low = t * t / safe
    mid = (t - beta / 2) / alpha
    high = 1.0 - (alpha + beta - t) ** 2 / safe
    return np.where(t <= beta, low, np.where(t <= alpha, mid, high)) if beta > 0 else t / alpha


def quantise_coverage(coverage: np.ndarray, levels: int) -> np.ndarray:
    """The coverage level k = round(a · (levels − 1)) of each pixel (0: all dark, levels − 1: all bright)."""
    return np.rint(coverage * (levels - 1)).astype(np.int64)


def _flat_rects(level: np.ndarray, levels: int) -> list:
    """Two flat rectangles (x, y, w, h) away from the edge: all-dark pixels left of it, all-bright right of it,
    over the middle half of the rows, 2 px from the edge's pixels and W/16 from the frame's sides; empty when
    either would be under 4 × 4 px."""
    height, width = level.shape
    y0, y1 = height // 4, height - height // 4
    rows = level[y0:y1]
    if y1 - y0 < 4:
        return []
    margin, gap = max(2, width // 16), 2
    not_dark = rows > 0
    not_bright = rows < levels - 1
    first_not_dark = int(np.where(not_dark.any(1), not_dark.argmax(1), width).min())
    last_not_bright = int(np.where(not_bright.any(1), width - 1 - not_bright[:, ::-1].argmax(1), -1).max())
    dark = (margin, y0, first_not_dark - gap - margin, y1 - y0)
    bright_x = last_not_bright + 1 + gap
    bright = (bright_x, y0, width - margin - bright_x, y1 - y0)
    if dark[2] < 4 or bright[2] < 4:
        return []
    return [dark, bright]


# ------------------------------------------------------------------------------------------------------ sources
@dataclass(frozen=True)
class TargetSource(SceneSource):
    """A synthetic target (scene-file table ``[target]``); :meth:`from_table` gives a :class:`DeadLeavesTarget`, a
    :class:`SlantedEdgeTarget` or a :class:`FlatTarget` by the table's ``kind``."""

    table = "target"
    keys = _COMMON_KEYS | _DEAD_LEAVES_KEYS | _EDGE_KEYS | _FLAT_KEYS

    @classmethod
    def from_table(cls, table: dict, base_dir, where: str) -> TargetSource:
        kind = typed(table, "kind", str, None, where)
        if kind not in TARGET_KINDS:
            raise CamsimError(f"{where}: [target] kind must be one of {', '.join(TARGET_KINDS)}, got {kind!r}")
        own = _KIND_KEYS[kind]
        stray = sorted(set(table) - own - _COMMON_KEYS)
        if stray:
            raise CamsimError(f"{where}: [target] key(s) {', '.join(stray)} do not apply to kind = {kind!r} "
                              f"(its keys: {', '.join(sorted(own | {'reflectances'}))})")
        if kind == "dead-leaves":
            return DeadLeavesTarget._from_table(table, base_dir, where)
        if kind == "flat":
            return FlatTarget._from_table(table, base_dir, where)
        return SlantedEdgeTarget._from_table(table, base_dir, where)


def _radius(table, key, default, where) -> float:
    value = typed(table, key, float, default, where)
    if not RADIUS_RANGE_PX[0] <= value <= RADIUS_RANGE_PX[1]:
        raise CamsimError(f"{where}: [target] {key} must be {RADIUS_RANGE_PX[0]:g} to {RADIUS_RANGE_PX[1]:g} "
                          f"pixels, got {value:g}")
    return value


@dataclass(frozen=True)
class DeadLeavesTarget(TargetSource):
    """A dead-leaves chart (``[target]`` with ``kind = "dead-leaves"``).

    Attributes
    ----------
    reflectances : str
        A colour-science ``SDS_COLOURCHECKERS`` name or a CSV of reflectances: the disks' spectra.
    greys : tuple of float
        Flat reflectances (unitless, in [0, 1]) added to the set.
    radius_min_px, radius_max_px : float
        The radius range, pixels (density ∝ r⁻³ on it).
    seed : int
        The pattern's seed (:func:`camsim.core.seeding.target_generator`), apart from the frames' noise seed.
    base_dir : pathlib.Path or None
        Where a reflectance CSV is looked for.
    """

    reflectances: str = "ColorChecker N Ohta"
    greys: tuple = ()
    radius_min_px: float = 2.0
    radius_max_px: float = 100.0
    seed: int = 0
    base_dir: object = None

    @classmethod
    def _from_table(cls, table, base_dir, where) -> DeadLeavesTarget:
        r_min = _radius(table, "radius_min_px", 2.0, where)
        r_max = _radius(table, "radius_max_px", 100.0, where)
        if r_min > r_max:
            raise CamsimError(f"{where}: [target] radius_min_px ({r_min:g}) must not exceed radius_max_px ({r_max:g})")
        seed = typed(table, "seed", int, 0, where)
        if seed < 0:
            raise CamsimError(f"{where}: [target] seed must be a non-negative integer, got {seed}")
        greys = typed(table, "greys", list, [], where)
        for grey in greys:
            if isinstance(grey, bool) or not isinstance(grey, (int, float)) or not 0 <= grey <= 1:
                raise CamsimError(f"{where}: [target] greys must be reflectances in [0, 1], got {grey!r}")
        return cls(reflectances=typed(table, "reflectances", str, "ColorChecker N Ohta", where),
                   greys=tuple(float(g) for g in greys), radius_min_px=r_min, radius_max_px=r_max, seed=seed,
                   base_dir=base_dir)

    def spectra(self, grid, width: int, height: int) -> SourceSpectra:
        """The set's reflectances plus the greys (K of them) and the dead-leaves label map; no patches."""
        names, refl = reflectance_set(self.reflectances, grid, self.base_dir)
        if self.greys:
            refl = np.vstack([refl, np.repeat(np.array(self.greys)[:, None], grid.size, axis=1)])
        leaves = _dead_leaves_cached(width, height, self.radius_min_px, self.radius_max_px, len(refl), self.seed)
        record = {
            "kind": "dead-leaves", "seed": self.seed, "radius_min_px": self.radius_min_px,
            "radius_max_px": self.radius_max_px, "radius_law": "density proportional to r^-3 on [min, max]",
            "reflectances": self.reflectances, "greys": list(self.greys), "spectra": len(refl),
            "spectrum_names": [*names, *(f"grey {g:g}" for g in self.greys)], "disks_drawn": leaves.n_disks,
            "rule": "disks drawn top-down, centres uniform on the frame grown by radius_max_px, spectrum uniform; "
                    "a pixel shows the topmost disk containing its centre",
        }
        name = self.reflectances + (f" + {len(self.greys)} greys" if self.greys else "")
        return SourceSpectra(leaves.labels, refl, "reflectance", [], [], name, surround=False, target=record)


@dataclass(frozen=True)
class SlantedEdgeTarget(TargetSource):
    """A slanted edge (``[target]`` with ``kind = "slanted-edge"``).

    Attributes
    ----------
    angle_deg : float
        The edge's angle from vertical, degrees, in [−45, 45].
    offset_px : float
        The edge's shift from the frame centre along its normal (towards the bright side), pixels.
    low, high : float or str
        The dark and bright sides: a flat reflectance in [0, 1] (low < high) or a patch name of ``reflectances``.
    levels : int
        Coverage levels, 2 to :data:`MAX_LEVELS`: K = levels spectra.
    reflectances : str
        Where named ``low`` / ``high`` patches come from.
    """

    angle_deg: float = 5.0
    offset_px: float = 0.0
    low: float | str = 0.1
    high: float | str = 0.8
    levels: int = 64
    reflectances: str = "ColorChecker N Ohta"
    base_dir: object = None

    @classmethod
    def _from_table(cls, table, base_dir, where) -> SlantedEdgeTarget:
        angle = typed(table, "angle_deg", float, 5.0, where)
        if not -45 <= angle <= 45:
            raise CamsimError(f"{where}: [target] angle_deg must be in [-45, 45] degrees from vertical, got {angle:g}")
        offset = typed(table, "offset_px", float, 0.0, where)
        if not math.isfinite(offset):
            raise CamsimError(f"{where}: [target] offset_px must be finite, got {offset}")
        levels = typed(table, "levels", int, 64, where)
        if not 2 <= levels <= MAX_LEVELS:
            raise CamsimError(f"{where}: [target] levels must be an integer in [2, {MAX_LEVELS}], got {levels}")
        sides = [_reflectance_or_patch(table, key, default, where) for key, default in (("low", 0.1), ("high", 0.8))]
        if all(isinstance(v, float) for v in sides) and not sides[0] < sides[1]:
            raise CamsimError(f"{where}: [target] low ({sides[0]:g}) must be below high ({sides[1]:g})")
        return cls(angle_deg=angle, offset_px=offset, low=sides[0], high=sides[1], levels=levels,
                   reflectances=typed(table, "reflectances", str, "ColorChecker N Ohta", where), base_dir=base_dir)

    def _side(self, value, grid) -> np.ndarray:
        if isinstance(value, float):
            return np.full(grid.size, value)
        names, refl = reflectance_set(self.reflectances, grid, self.base_dir)
        if value not in names:
            raise CamsimError(f"slanted edge: no patch {value!r} in {self.reflectances!r} (its patches: "
                              f"{', '.join(names)})")
        return refl[names.index(value)]

    def spectra(self, grid, width: int, height: int) -> SourceSpectra:
        """K = levels mixtures (1 − a)·low + a·high, a = k / (levels − 1); spectra 0 and 1 are the all-dark and
        all-bright ones (the patches ``dark`` and ``bright``, when the frame leaves room for them), then
        k = 1 … levels − 2."""
        low, high = self._side(self.low, grid), self._side(self.high, grid)
        top = self.levels - 1
        order = np.array([0, top, *range(1, top)])  # spectrum index -> level
        a = order / top
        refl = (1 - a)[:, None] * low + a[:, None] * high
        index_of_level = np.empty(self.levels, dtype=np.int64)
        index_of_level[order] = np.arange(self.levels)
        level = quantise_coverage(edge_coverage(width, height, self.angle_deg, self.offset_px), self.levels)
        labels = index_of_level[level].astype(np.uint8 if self.levels <= 256 else np.uint16)
        rects = _flat_rects(level, self.levels)
        theta = math.radians(self.angle_deg)
        record = {
            "kind": "slanted-edge", "angle_deg": self.angle_deg, "offset_px": self.offset_px,
            "centre_xy": [width / 2, height / 2], "normal_xy": [math.cos(theta), -math.sin(theta)],
            "signed_distance": "d(x, y) = (x - cx) * nx + (y - cy) * ny - offset_px, bright where d > 0; x right, "
                               "y down, pixels, origin at the top-left corner of the top-left pixel",
            "levels": self.levels, "low": self.low, "high": self.high,
            "coverage": "exact area fraction of each pixel square on the bright side, rounded to k / (levels - 1)",
            "spectrum_levels": order.tolist(),
        }
        names = ["dark", "bright"] if rects else []
        named = any(isinstance(v, str) for v in (self.low, self.high))
        name = self.reflectances if named else f"flat greys {self.low:g} / {self.high:g}"
        return SourceSpectra(labels, refl, "reflectance", names, rects, name, surround=False, target=record)


@dataclass(frozen=True)
class FlatTarget(TargetSource):
    """A uniform field (``[target]`` with ``kind = "flat"``): one reflectance over the whole frame.

    The flat field of a photon-transfer calibration (``camsim calibrate``'s flats; the built-in scene ``flat``) and,
    with ``reflectance = 0``, a dark frame (the built-in scene ``dark``): the spectrum is zero at every wavelength,
    so the expected photo-electrons are exactly 0 and the Poisson draws are 0 — the frame holds only the sensor's
    own signal (dark current, its DSNU, read and row noise, the pedestal and the ADC), as with the lens capped.

    Attributes
    ----------
    reflectance : float or str
        A flat reflectance in [0, 1] (unitless, 1 = the perfect white) or a patch name of ``reflectances``.
    reflectances : str
        Where a named ``reflectance`` comes from (a colour-science ``SDS_COLOURCHECKERS`` name or a CSV).
    base_dir : pathlib.Path or None
        Where a reflectance CSV is looked for.
    """

    reflectance: float | str = 1.0
    reflectances: str = "ColorChecker N Ohta"
    base_dir: object = None

    @classmethod
    def _from_table(cls, table, base_dir, where) -> FlatTarget:
        value = _reflectance_or_patch(table, "reflectance", 1.0, where)
        return cls(reflectance=value, reflectances=typed(table, "reflectances", str, "ColorChecker N Ohta", where),
                   base_dir=base_dir)

    def spectra(self, grid, width: int, height: int) -> SourceSpectra:
        """One spectrum (K = 1) at every pixel, and one patch, ``flat``, the whole frame."""
        if isinstance(self.reflectance, float):
            refl, name = np.full((1, grid.size), self.reflectance), f"flat grey {self.reflectance:g}"
        else:
            names, spectra = reflectance_set(self.reflectances, grid, self.base_dir)
            if self.reflectance not in names:
                raise CamsimError(f"flat target: no patch {self.reflectance!r} in {self.reflectances!r} (its "
                                  f"patches: {', '.join(names)})")
            refl, name = spectra[[names.index(self.reflectance)]], self.reflectances
        record = {"kind": "flat", "reflectance": self.reflectance}
        labels = np.zeros((height, width), dtype=np.uint8)
        return SourceSpectra(labels, refl, "reflectance", ["flat"], [(0, 0, width, height)], name, surround=False,
                             target=record)
