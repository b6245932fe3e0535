"""Figures of ``camsim experiment``: the paper's Figs. 4–6 (per scenario), 4(c) and 7–9 (SNR sensitivity).

Every maker writes PNG files into ``out_dir`` and returns ``{figure_key: file name}``. The scenario figures draw one
panel per labelled series of frames, ``paper`` and ``pixel`` photon statistics side by side, with the makers of
:mod:`camsim.analysis.figures` (``camsim analyze`` draws the user's own frames with them). Undefined values (None)
are never plotted; each panel's legend says how many were left out. A data point keeps its colour (``tab20`` by
point number) throughout. The figures are drawn without pyplot (:mod:`camsim.io.figures`); matplotlib is imported
when the first is drawn.
"""

from __future__ import annotations

import math

import numpy as np

from camsim.analysis.figures import (
    UNDEF,
    _black,
    _centre,
    _colormap,
    _colour,
    _count,
    _diagram,
    _draw,
    _entry,
    _f_axes,
    _fig_lines,
    _fig_samples,
    _halo,
    _halo_text,
    _panels,
    _patch,
    _point_legend,
    _samples,
    _save,
    _series,
    _zoom,
)
from camsim.colour.colorimetry import CHANNELS
from camsim.core.optional_numbers import finite_or_none as _num
from camsim.io.figures import new_figure

STATISTICS = ("paper", "pixel")
SNR_VARIANTS = {"read+10%": "read", "dark+10%": "dark", "quantisation": "quantisation"}
SNR_PROTOCOLS = ("one-at-a-time", "all-on")


def _fig_centres(name, series, points, black_xy):
    fig, axes = _panels(f"{name}: ellipse centres as F falls (CIE 1931 xy)", series)
    for ax, (label, frames) in zip(axes, series.items()):
        _diagram(ax)
        xs, ys, undefined = [], [], 0
        top = frames[0]["intensity_factor"] if frames else None
        for j, point in enumerate(points):
            track = [(float(r["intensity_factor"]), _centre(_patch(r, j))) for r in frames]
            undefined += sum(xy is None for _, xy in track)
            track = [(f, xy) for f, xy in track if xy is not None]
            if not track:
                continue
            c, (x, y) = _colour(point.number), np.array([xy for _, xy in track]).T
            ax.plot(x, y, "-", marker=".", color=c, lw=1.4, ms=5, path_effects=_halo())
            if track[0][0] == top:
                ax.plot(x[0], y[0], "o", color=c, mec="k", ms=8, zorder=5)
            ax.text(x[0], y[0], f" {point.number}", fontsize=9, weight="bold", path_effects=_halo_text())
            xs.extend(x), ys.extend(y)
        handles = [_entry("centre path, F decreasing", color="0.3", marker=".", linestyle="-")]
        handles += [_entry(f"F = {top:g}", marker="o", color="0.5", mec="k")] if top is not None else []
        handles += _black(ax, black_xy, label, xs, ys) + _count(undefined, f"centres (point × F) {UNDEF}")
        _zoom(ax, xs, ys, min_span=0.05, pad=0.12)
        ax.legend(handles=handles, fontsize=8, loc="best")
    _point_legend(fig, points)
    return fig


def _fig_magnified(name, series, points, black_xy, cache, number):
    index = next((j for j, p in enumerate(points) if p.number == number), 0 if points else None)
    label = points[index].label if index is not None else "none"
    label += "" if any(p.number == number for p in points) else f" (point {number} is not among the data points)"
    fig, axes = _panels(f"{name}: data point {label}, samples and 1 σ ellipses at every F", series,
                        layout="constrained")
    logs = [math.log10(float(r["intensity_factor"])) for frames in series.values() for r in frames] or [0.0]
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    norm, cmap = Normalize(min(logs) - 0.5 * (min(logs) == max(logs)), max(logs)), _colormap("viridis")
    for ax, (panel, frames) in zip(axes, series.items()):
        _diagram(ax, colours=False)
        xs, ys, undefined, unread = [], [], 0, 0
        for result in frames if index is not None else []:
            c = cmap(norm(math.log10(float(result["intensity_factor"]))))
            samples = _samples(cache, result, len(points))
            unread += samples is None
            ellipse = _draw(ax, samples, index, _patch(result, index), c, xs, ys, lw=1.8)
            undefined += ellipse is None
            if ellipse is not None:
                xs.extend(ellipse[0]), ys.extend(ellipse[1])
        handles = [_entry("1 σ ellipse (colour: log₁₀ F)", color="0.3", lw=1.8, linestyle="-")]
        handles += _black(ax, black_xy, panel, xs, ys) + _count(undefined, f"ellipses (F) {UNDEF}")
        handles += _count(unread, "frame file(s) unreadable: samples not shown")
        _zoom(ax, xs, ys, min_span=0.01)
        ax.grid(alpha=0.3)
        ax.legend(handles=handles, fontsize=8, loc="best")
    fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=list(axes), label="log₁₀ F (intensity factor)",
                 shrink=0.8)
    return fig


def scenario_figures(name, results_by_stats, points, black_xy, out_dir, magnified_point=3) -> dict:
    """Write the figures of one scenario (the paper's Figs. 4–6), paper and pixel statistics side by side.

    Parameters
    ----------
    name : str
        Scenario name, the files' prefix (e.g. ``"scenario1"``).
    results_by_stats : dict of {str: list of dict}
        ``"paper"`` and ``"pixel"``: per frame (one per F) the analysis result, with ``frame_file``,
        ``intensity_factor`` and ``patches`` (one record per data point, in point order).
    points : list of DataPoint
        The data points, in the order of the patch records.
    black_xy : dict of {str: tuple of float or None}
        The camera black point's xy per statistics (None without dark current).
    out_dir : path-like
        Folder for the PNG files (created if missing).
    magnified_point : int, optional
        ``DataPoint.number`` of the point shown magnified (Fig. 4b).

    Returns
    -------
    dict of {str: str}
        Figure key → file name: ``samples``, ``centres``, ``magnified``, ``angle``, ``size``, ``delta_e``
        (files ``{name}_{key}.png``).
    """
    points = list(points)
    series = {f"{stat} statistics": _series((results_by_stats or {}).get(stat)) for stat in STATISTICS}
    black_xy = {f"{stat} statistics": (black_xy or {}).get(stat) for stat in STATISTICS}
    cache: dict = {}
    figures = {
        "samples": _fig_samples(name, series, points, black_xy, cache),
        "centres": _fig_centres(name, series, points, black_xy),
        "magnified": _fig_magnified(name, series, points, black_xy, cache, magnified_point),
        "angle": _fig_lines(name, series, points, "angle_deg", "inclination of the ellipses' major axis",
                            "angle of major axis to x axis (deg)"),
        "size": _fig_lines(name, series, points, "size_xy", "ellipse size √(a² + b²) (1 σ)",
                           "ellipse size (xy units)", logy=True),
        "delta_e": _fig_lines(name, series, points, "delta_e_ab_mean", "mean ΔE*ab of the samples to the F = 1 "
                              "colour", "ΔE*ab (CIELAB units)", logy=None, mean=True),
    }
    return {key: _save(fig, out_dir, f"{name}_{key}.png") for key, fig in figures.items()}


#: The average curves drawn in each SNR panel: (CSV column, quantisation term, label, line style). The first is the
#: form the verdicts judge; each other changes one thing.
SNR_CURVES = (
    ("delta_snr_eq13_pct", "mean-square", "Eqs. 13–14 as printed, σ²_ADC = 1/3 DN²", dict(color="k", lw=2.8)),
    ("delta_snr_eq13_pct", "variance", "as printed, σ²_ADC = 1/12 DN²", dict(color="k", lw=2.0, ls="--")),
    ("delta_snr_eq13_unquantised_numerator_pct", "mean-square", "numerator k S (not [k S]_nb)",
     dict(color="tab:blue", lw=2.0, ls="-.")),
    ("delta_snr_statistics_variance_pct", "mean-square", "the statistics' own Var S (not S)",
     dict(color="tab:orange", lw=2.0, ls=":")),
    ("delta_snr_eq13_unquantised_numerator_pct", "variance", "numerator k S and σ²_ADC = 1/12 DN² (what the pixels "
     "measure)", dict(color="0.45", lw=2.2, ls="-")),
)


def _snr_panel(ax, rows):
    """ΔSNR against F for one statistics × channel: thin lines and empirical circles per point, average curves.

    The y-axis spans the model values: empirical values beyond them (the measured SNR₁ is near 0 where the signal is
    near the black level, and the ratio explodes) are counted in the legend, not drawn.
    """
    rows = [r for r in rows if (_num(r.get("intensity_factor")) or 0) > 0 and r.get("point") is not None]
    if not rows:
        ax.set(xscale="log", xlim=(1e-3, 1e-1), ylim=(0, 1))  # an empty log axis would tick a huge default range
        return ax.text(0.5, 0.5, "no data", transform=ax.transAxes, ha="center", va="center", color="0.4")
    printed = [r for r in rows if r.get("quantisation_term") == "mean-square"]
    model = [v for r in rows for column, *_ in SNR_CURVES if (v := _num(r.get(column))) is not None]
    low, high = min(model + [0.0]), max(model + [0.0])
    pad = max(0.08 * (high - low), 0.05)
    low, high = low - pad, high + pad
    notes = []
    for column, kind, style in (("delta_snr_eq13_pct", "as printed", dict(ls="-", lw=0.9)),
                                ("delta_snr_empirical_pct", "empirical",
                                 dict(ls="none", marker="o", ms=4, mfc="none"))):
        values = [(int(r["point"]), float(r["intensity_factor"]), _num(r.get(column))) for r in printed]
        notes += _count(sum(v is None for *_, v in values), f"{kind} values {UNDEF}")
        good = sorted(x for x in values if x[2] is not None)
        if kind == "empirical":
            notes += _count(sum(not low <= v <= high for *_, v in good), "empirical values beyond the axes")
            good = [x for x in good if low <= x[2] <= high]
        for number in sorted({n for n, _, _ in good}):
            ax.plot(*np.array([(f, v) for n, f, v in good if n == number]).T, color=_colour(number), alpha=0.7,
                    **style)
    for rank, (column, term, _, style) in enumerate(SNR_CURVES):  # the verdicts' form (the first) on top
        good = [(float(r["intensity_factor"]), _num(r.get(column))) for r in rows
                if r.get("quantisation_term") == term]
        good = [(f, v) for f, v in good if v is not None]
        fs = sorted({f for f, _ in good})
        if fs:
            ax.plot(fs, [np.mean([v for g, v in good if g == f]) for f in fs], zorder=10 - rank, **style)
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.set_ylim(low, high)
    if notes:
        ax.legend(handles=notes, fontsize=7, loc="best")


def snr_figures(rows, out_dir) -> dict:
    """Write the SNR sensitivity figures (the paper's Figs. 7–9), one per noise and protocol.

    Parameters
    ----------
    rows : list of dict
        Keys ``statistics`` ('paper'/'pixel'), ``protocol`` ('one-at-a-time'/'all-on'), ``variant`` ('read+10%',
        'dark+10%', 'quantisation'), ``quantisation_term`` ('mean-square'/'variance'), ``intensity_factor``,
        ``point`` (int), ``channel`` ('R'/'G'/'B') and the ΔSNR columns of :data:`SNR_CURVES` and
        ``delta_snr_empirical_pct`` (float or None; unit: %).
    out_dir : path-like
        Folder for the PNG files (created if missing).

    Returns
    -------
    dict of {str: str}
        ``snr_<noise>_<protocol>`` (noise ``read``, ``dark``, ``quantisation``; protocol ``one_at_a_time``,
        ``all_on``) → file name ``<key>.png``. Known noises and protocols without rows still get a figure, marked
        "no data".
    """
    rows = list(rows or [])
    variants = dict(SNR_VARIANTS)
    protocols = list(SNR_PROTOCOLS)
    for row in rows:
        variant = str(row.get("variant"))
        variants.setdefault(variant, "".join(ch if ch.isalnum() else "_" for ch in variant).strip("_"))
        if str(row.get("protocol")) not in protocols:
            protocols.append(str(row.get("protocol")))
    figures = {}
    for variant, slug in variants.items():
        for protocol in protocols:
            key = f"snr_{slug}_{protocol.replace('-', '_')}"
            fig = new_figure(figsize=(16, 8.5), layout="constrained")
            axes = fig.subplots(2, 3, squeeze=False)
            fig.suptitle(f"SNR change ΔSNR = 100 (SNR₁ − SNR₂) / SNR₁ for {variant}, protocol {protocol}",
                         fontsize=13)
            subset = [r for r in rows if str(r.get("variant")) == variant and r.get("protocol") == protocol]
            for a, stat in enumerate(STATISTICS):
                for b, channel in enumerate(CHANNELS):
                    ax = axes[a][b]
                    _snr_panel(ax, [r for r in subset if r.get("statistics") == stat and r.get("channel") == channel])
                    ax.set_title(f"{stat} statistics, channel {channel}", fontsize=11)
                    _f_axes(ax, "ΔSNR (%)")
            numbers = sorted({int(r["point"]) for r in subset if r.get("point") is not None})
            handles = [_entry("as printed (1/3 DN²), per point", color="0.4", lw=0.9, linestyle="-"),
                       _entry("empirical, per point", color="0.4", marker="o", mfc="none")]
            handles += [_entry(f"mean over points: {label}", linestyle=style.get("ls", "-"),
                               **{k: v for k, v in style.items() if k != "ls"}) for _, _, label, style in SNR_CURVES]
            handles += [_entry(f"point {n}", color=_colour(n), lw=2, linestyle="-") for n in numbers]
            fig.legend(handles=handles, loc="outside right center", fontsize=8)
            figures[key] = _save(fig, out_dir, f"{key}.png", tight=False)
    return figures


def _fig_photons(name, rows, label):
    """Fig. 4(c): log10 of the incident photons per m²·sr against luminance (log axis)."""
    fig = new_figure(figsize=(8, 5.5), layout="constrained")
    ax = fig.subplots()
    rows = [r for r in rows if (_num(r.get("luminance_cd_m2")) or 0) > 0]
    luminance = [float(r["luminance_cd_m2"]) for r in rows]
    ax.plot(luminance, [r["log10_photons_per_m2_sr"] for r in rows], "-o", color="k",
            label="over the spectrum, Σᵢ F g(λᵢ) T")
    ax.plot(luminance, [r["log10_photons_per_m2_sr_peak_bin"] for r in rows], "--s", color="tab:red", ms=4,
            label="in the largest wavelength bin (one Poisson draw of Eq. 4)")
    ax.axhline(2.0, color="0.5", lw=1, ls=":", label="100 photons (the paper: photon noise noticeable below)")
    ax.set_xscale("log")
    ax.set(xlabel="luminance (cd/m²)", ylabel="log₁₀ incident photons per m²·sr in T",
           title=f"{name}: incident photons, data point {label}")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8, loc="best")
    return fig


def photon_figure(name, rows, label, out_dir) -> dict:
    """Write the paper's Fig. 4(c), ``{name}_photons.png``; returns ``{"photons": file name}``.

    ``rows`` come from :func:`camsim.experiments.datapoints.incident_photons`; ``label`` names the data point.
    """
    return {"photons": _save(_fig_photons(name, rows, label), out_dir, f"{name}_photons.png")}
