"""The experiments' 20 data points: colour signals (ColorChecker patch × illuminant), chosen by a fixed rule.

The paper's RGB598 set is not public. Its 20 points are replaced by a documented, deterministic choice among
the 24 × 26 colour signals of ``scenes/macbeth_26.toml`` (reflectance × illuminant):

1. Points 1–13 lie on the convex hull of the signals' xy chromaticities. The hull's vertices are thinned to 13 by
   repeatedly dropping the vertex whose triangle with its two neighbours has the smallest area (the one that
   shapes the hull least); they are numbered counter-clockwise from the vertex of smallest x.
2. Points 14–20 lie inside: the signal nearest the centroid of all signals, then farthest-point sampling in xy
   among the other signals (each next point is the one farthest from all points chosen so far, hull points
   included), so that they spread over the interior rather than crowd the edges.

Each signal is then scaled to 100 cd/m² on its own, as in the paper.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull

from camsim.light.photons import scale_to_luminance
from camsim.light.spectra import WavelengthGrid, cmfs_on_grid, illuminant_spd, reflectance_set
from camsim.scene.chart import ChartGeometry
from camsim.scene.radiance import SceneRadiance

N_HULL, N_INSIDE = 13, 7


@dataclass(frozen=True)
class DataPoint:
    """One colour signal: a ColorChecker patch under an illuminant."""

    number: int
    patch: str
    illuminant: str
    on_hull: bool
    x: float
    y: float

    @property
    def label(self) -> str:
        return f"{self.number}: {self.patch} / {self.illuminant}"


def colour_signals(reflectances: str, illuminants, grid: WavelengthGrid):
    """All reflectance × illuminant signals: names (list of (patch, illuminant)), spectra (M, N), xy (M, 2)."""
    names, refl = reflectance_set(reflectances, grid)
    cmfs = cmfs_on_grid(grid)
    labels, spectra = [], []
    for illuminant in illuminants:
        spd = illuminant_spd(illuminant, grid)
        for name, row in zip(names, refl):
            labels.append((name, illuminant))
            spectra.append(row * spd)
    spectra = np.array(spectra)
    xyz = spectra @ cmfs.T
    return labels, spectra, xyz[:, :2] / xyz.sum(axis=1, keepdims=True)


def _thin_hull(xy: np.ndarray, vertices: list, keep: int) -> list:
    vertices = list(vertices)
    while len(vertices) > keep:
        areas = []
        for i, v in enumerate(vertices):
            a, b = xy[vertices[i - 1]], xy[vertices[(i + 1) % len(vertices)]]
            c = xy[v]
            areas.append(abs((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])) / 2)
        vertices.pop(int(np.argmin(areas)))
    return vertices


def select_points(xy: np.ndarray, n_hull: int = N_HULL, n_inside: int = N_INSIDE) -> tuple[list, list]:
    """Indices of the hull points (counter-clockwise from the smallest x) and of the inside points."""
    hull = list(ConvexHull(xy).vertices)  # counter-clockwise in 2-D
    if len(hull) < n_hull:
        raise ValueError(f"the signals' hull has {len(hull)} vertices, fewer than {n_hull}")
    hull = _thin_hull(xy, hull, n_hull)
    start = int(np.argmin([xy[v, 0] for v in hull]))
    hull = hull[start:] + hull[:start]
    taken = set(hull)
    candidates = [i for i in range(len(xy)) if i not in taken]
    centre = xy.mean(axis=0)
    inside = [min(candidates, key=lambda i: np.hypot(*(xy[i] - centre)))]
    while len(inside) < n_inside:
        chosen = xy[hull + inside]  # far from the hull points too, so that inside means inside
        distance = {i: np.min(np.hypot(*(chosen - xy[i]).T)) for i in candidates if i not in inside}
        inside.append(max(distance, key=lambda i: (distance[i], -i)))
    return hull, inside


def data_points(reflectances: str, illuminants, grid: WavelengthGrid):
    """The 20 data points and their spectra at 100 cd/m² each.

    Returns
    -------
    points : list of DataPoint
    radiance : numpy.ndarray, shape (20, N)
        Spectral radiance, each signal at 100 cd/m². Unit: W / (m² sr nm).
    """
    labels, spectra, xy = colour_signals(reflectances, illuminants, grid)
    hull, inside = select_points(xy)
    ybar = cmfs_on_grid(grid)[1]
    points, radiance = [], []
    for number, index in enumerate(hull + inside, start=1):
        patch, illuminant = labels[index]
        points.append(DataPoint(number, patch, illuminant, index in hull, float(xy[index, 0]), float(xy[index, 1])))
        radiance.append(scale_to_luminance(spectra[index], ybar, grid.step_nm, 100.0))
    return points, np.array(radiance)


def points_radiance(points, radiance, grid: WavelengthGrid, width: int, height: int, columns: int = 5):
    """A chart of the given points (a label map plus their spectra) on a black surround.

    The absolute scale's reference is the perfect white under D65 at 100 cd/m².
    """
    rows = -(-len(points) // columns)
    geometry = ChartGeometry(columns=columns, rows=rows, gap_fraction=0.15, margin_fraction=0.03)
    rects = geometry.rects(width, height)[: len(points)]
    labels = np.full((height, width), len(points), dtype=np.uint8)
    for index, (x, y, w, h) in enumerate(rects):
        labels[y : y + h, x : x + w] = index
    white = scale_to_luminance(illuminant_spd("D65", grid), cmfs_on_grid(grid)[1], grid.step_nm, 100.0)
    spectra = np.vstack([radiance, np.zeros((1, grid.size))])
    return SceneRadiance(labels, spectra, white, [p.label for p in points], rects, "experiment data points")


def incident_photons(photon_rate, luminance_cd_m2: float, factors, exposure_s: float = 1.0) -> list[dict]:
    """The paper's Fig. 4(c): how many photons of one data point arrive, at each intensity factor.

    Counted as Eq. 4 draws them, per m² and steradian (the paper's photons / (s m² sr) times the exposure): over the
    whole spectrum, and in the spectrum's largest bin (the largest Poisson mean of one draw).

    Parameters
    ----------
    photon_rate : numpy.ndarray, shape (N,)
        g(λi) of the point at F = 1 (Eq. 3). Unit: photons / (s m² sr) per bin.
    luminance_cd_m2 : float
        The point's luminance at F = 1. Unit: cd/m².
    factors : sequence of float
        Intensity factors F.
    exposure_s : float
        Exposure T. Unit: s.

    Returns
    -------
    list of dict
        Per F: ``intensity_factor``, ``luminance_cd_m2`` (F × the point's), ``photons_per_m2_sr`` (T F Σ g) and
        ``photons_per_m2_sr_peak_bin`` (T F max g), with their log10 (``log10_…``).
    """
    rate = np.asarray(photon_rate, dtype=np.float64)
    rows = []
    for factor in factors:
        total, peak = exposure_s * factor * rate.sum(), exposure_s * factor * rate.max()
        rows.append({"intensity_factor": float(factor), "luminance_cd_m2": float(factor * luminance_cd_m2),
                     "photons_per_m2_sr": float(total), "photons_per_m2_sr_peak_bin": float(peak),
                     "log10_photons_per_m2_sr": float(np.log10(total)),
                     "log10_photons_per_m2_sr_peak_bin": float(np.log10(peak))})
    return rows
