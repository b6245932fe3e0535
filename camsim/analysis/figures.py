"""Figures of measured patches against the intensity factor F: the CIE 1931 xy diagram with each patch's samples
and 1 σ noise ellipse, and a patch value (ΔE, ellipse size, SNR …) against F; ``camsim analyze``'s figures of the
user's own frames (:func:`analysis_figures`).

The makers draw one panel per labelled series of frames (``{panel title: frames}``) and write PNG files into
``out_dir``. The experiments' figures (:mod:`camsim.experiments.figures`, the paper's Figs. 4–9) are drawn with
the same makers, which sit here, below both ``camsim analyze`` and the experiments. Undefined values (None) are
never plotted; each panel's legend says how many were left out. A data point keeps its colour (``tab20`` by point
number) throughout. The figures are drawn without pyplot (:mod:`camsim.io.figures`); matplotlib is imported when
the first is drawn.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from camsim.analysis.patches import AnalysisSettings, demosaiced_samples, frame_matrix, patch_samples
from camsim.colour.colorimetry import CHANNELS, chromaticity_xy, xyz_from_camera
from camsim.core.errors import CamsimError
from camsim.core.optional_numbers import finite_or_none as _num
from camsim.io.figures import new_figure, save_png
from camsim.io.output_folder import make_folder
from camsim.render.frame_files import load_frame

MAX_SAMPLES = 300
UNDEF = "undefined, not plotted"
_MARKERS = "os^D"
_STYLES = ("-", "--", "-.", ":")


def _halo():
    """Path effects of a line drawn with a white halo, so that it stays visible over the others."""
    import matplotlib.patheffects as pe

    return [pe.Stroke(linewidth=2.6, foreground="white"), pe.Normal()]


def _halo_text():
    """Path effects of a label drawn with a white halo."""
    import matplotlib.patheffects as pe

    return [pe.withStroke(linewidth=2.5, foreground="white")]


def _colormap(name: str):
    """A registered matplotlib colormap (``pyplot.get_cmap(name)`` without pyplot)."""
    import matplotlib

    return matplotlib.colormaps[name]


def _colour(number):
    """The colour of data point ``number``: tab20's ten dark shades first, then the ten light ones."""
    k = (int(number) - 1) % 20
    return _colormap("tab20")(2 * k if k < 10 else 2 * (k - 10) + 1)


def _save(fig, out_dir, name: str, tight: bool = True) -> str:
    """Write ``fig`` as ``out_dir/name``; ``tight=False`` for a figure whose layout engine already fits everything
    (no second drawing to measure it)."""
    make_folder(Path(out_dir))
    save_png(fig, Path(out_dir) / name, **({"bbox_inches": "tight"} if tight else {}))
    return name


def _entry(label: str, **style):
    """A legend entry; without style, a line of text (e.g. how many values were left out)."""
    from matplotlib.lines import Line2D

    return Line2D([], [], label=label, **({"linestyle": "none"} | style))


def _count(n: int, text: str) -> list:
    """A text legend entry "n text" if n > 0 (e.g. how many values were undefined and left out)."""
    return [_entry(f"{n} {text}")] if n else []


def _series(results) -> list:
    """The frames with a positive F, largest F first."""
    usable = [r for r in results or [] if (_num(r.get("intensity_factor")) or 0) > 0]
    return sorted(usable, key=lambda r: -float(r["intensity_factor"]))


def _patch(result, j):
    patches = result.get("patches") or []
    return patches[j] if j < len(patches) else {}


def _ellipse(patch, n: int = 121):
    """The 1 σ ellipse outline (x, y) of a patch record, or None where it is undefined."""
    values = [_num(patch.get(k)) for k in ("center_x", "center_y", "semi_major_xy", "semi_minor_xy", "angle_deg")]
    if patch.get("ellipse_status") != "ok" or None in values:
        return None
    cx, cy, a, b, angle = values
    t, theta = np.linspace(0.0, 2.0 * np.pi, n), np.radians(angle)
    u, v = a * np.cos(t), b * np.sin(t)
    return cx + u * np.cos(theta) - v * np.sin(theta), cy + u * np.sin(theta) + v * np.cos(theta)


def _centre(patch):
    x, y = _num(patch.get("center_x")), _num(patch.get("center_y"))
    return None if x is None or y is None else (x, y)


def _samples(cache: dict, result, n_points: int):
    """Per data point its xy samples (≤ 300, subsampled), re-read from the frame file once per call of a maker.

    The border is the result's ``border_px`` (the analysis's; default 3 px) and its ``black_dn`` is subtracted; a
    Bayer frame's patches are demosaiced as the analysis does. None if the frame cannot be read (e.g. moved or
    deleted).
    """
    path = str(result.get("frame_file"))
    if path in cache:
        return cache[path]
    cache[path] = None
    try:
        frame = load_frame(path)
        matrix = frame_matrix(frame, result.get("camera_to_xyz") or "paper")
    except (CamsimError, OSError, KeyError, TypeError, ValueError):
        return None
    black = np.asarray(result.get("black_dn") or np.zeros(3), dtype=np.float64)
    border = int(result.get("border_px", AnalysisSettings().border_px))
    rng, out = np.random.default_rng(0), []
    for meta in frame.meta["patches"][:n_points]:
        raw = (demosaiced_samples(frame, meta["rect_xywh"], border) if frame.cfa_pattern
               else patch_samples(frame.pixels_dn, meta["rect_xywh"], border))
        xy, _ = chromaticity_xy(xyz_from_camera(raw - black, matrix))
        out.append(xy[np.sort(rng.choice(len(xy), MAX_SAMPLES, replace=False))] if len(xy) > MAX_SAMPLES else xy)
    cache[path] = out
    return out


def _colour_science_diagram(ax) -> None:
    """colour-science's CIE 1931 chromaticity diagram (faded colours), drawn on ``ax`` and laid out in its figure.

    colour-science's plotting looks up pyplot's current figure and axes even when it is given its own, and so opens
    a blank pyplot figure when there is none: that one is closed again, leaving pyplot as it was.
    """
    import colour
    import matplotlib.pyplot as plt  # already imported: colour-science imports it

    open_before = set(plt.get_fignums())
    try:
        colour.plotting.plot_chromaticity_diagram_CIE1931(axes=ax, figure=ax.get_figure(), show=False, title=None,
                                                          diagram_opacity=0.3)
    finally:
        for number in set(plt.get_fignums()) - open_before:
            plt.close(number)


def _diagram(ax, colours: bool = True):
    """The CIE 1931 xy diagram (faded colours) or just its spectral locus."""
    import colour

    title = ax.get_title()
    if colours:
        try:
            _colour_science_diagram(ax)
        except Exception:  # the plotting API differs between colour versions: fall back to the locus
            colours = False
    if not colours:
        xyz = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"].values
        xy = xyz[:, :2] / xyz.sum(axis=1, keepdims=True)
        ax.plot(np.r_[xy[:, 0], xy[0, 0]], np.r_[xy[:, 1], xy[0, 1]], color="0.35", lw=1)
    ax.set(xlabel="CIE x", ylabel="CIE y", title=title)


def _zoom(ax, xs, ys, min_span: float = 0.05, pad: float = 0.08):
    """Square limits around the data (0.5–99.5 percentiles, so that a few strays do not rule), equal aspect."""
    if len(xs) == 0:
        return ax.set(xlim=(0, 0.8), ylim=(0, 0.9))
    (x0, x1), (y0, y1) = np.percentile(xs, [0.5, 99.5]), np.percentile(ys, [0.5, 99.5])
    half = max(x1 - x0, y1 - y0, min_span) * (0.5 + pad)
    ax.set(xlim=((x0 + x1) / 2 - half, (x0 + x1) / 2 + half), ylim=((y0 + y1) / 2 - half, (y0 + y1) / 2 + half))
    ax.set_aspect("equal", adjustable="box")


def _black(ax, black_xy, label, xs, ys) -> list:
    """Mark the camera black point of panel ``label`` (a star) if there is one; returns its legend entries."""
    point = (black_xy or {}).get(label)
    if point is None or None in (_num(point[0]), _num(point[1])):
        return []
    ax.plot(*point, marker="*", ms=15, color="k", mec="w", ls="none", zorder=8)  # above the labels
    xs.append(point[0]), ys.append(point[1])
    return [_entry("camera black point", marker="*", ms=12, color="k")]


def _panels(title: str, labels, layout=None):
    """A figure of one panel per label (side by side, each titled with its label); returns (figure, axes)."""
    labels = list(labels)
    fig = new_figure(figsize=(7 * len(labels), 6.5) if len(labels) > 1 else (9, 7.5), layout=layout)
    axes = np.atleast_1d(fig.subplots(1, len(labels)))
    fig.suptitle(title, fontsize=13 if len(labels) > 1 else 11)
    for ax, label in zip(axes, labels):
        ax.set_title(label, fontsize=12 if len(labels) > 1 else 10)
    return fig, axes


def _point_legend(fig, points):
    if points:
        fig.legend(handles=[_entry(p.label, color=_colour(p.number), lw=2, linestyle="-") for p in points],
                   loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=8, title="data point")


def _f_axes(ax, ylabel: str):
    ax.set_xscale("log")
    ax.set(xlabel="intensity factor F", ylabel=ylabel)
    ax.grid(alpha=0.3, which="both")


def _draw(ax, samples, j, patch, colour, xs, ys, marker="o", **line):
    """Point ``j``'s samples (dots) and 1 σ ellipse of ``patch``; returns the ellipse, None if undefined."""
    if samples is not None and j < len(samples) and len(samples[j]):
        ax.scatter(*samples[j].T, s=5, color=colour, alpha=0.45, marker=marker, linewidths=0)
        xs.extend(samples[j][:, 0]), ys.extend(samples[j][:, 1])
    ellipse = _ellipse(patch)
    if ellipse is not None:
        ax.plot(*ellipse, color=colour, path_effects=_halo(), zorder=4, **line)
    return ellipse


#: Frames whose median ellipse size exceeds this (in xy) are left out of the samples figure: their clouds cover
#: the whole diagram and hide everything else (the size and ΔE figures show them).
READABLE_SIZE = 0.05


def _readable(result, n_points: int) -> bool:
    sizes = [_num(_patch(result, j).get("size_xy")) for j in range(n_points) if _ellipse(_patch(result, j))]
    sizes = [v for v in sizes if v is not None]
    return bool(sizes) and float(np.median(sizes)) <= READABLE_SIZE


def _fig_samples(name, series, points, black_xy, cache, sizes_in="the size figure"):
    fig, axes = _panels(f"{name}: samples and 1 σ ellipses at representative F (CIE 1931 xy; F with median "
                        f"ellipse size ≤ {READABLE_SIZE:g} — larger clouds fill the diagram, see {sizes_in})",
                        series)
    for ax, (label, frames) in zip(axes, series.items()):
        _diagram(ax)
        valid = [i for i, r in enumerate(frames) if _readable(r, len(points))]
        last = valid[-1] if valid else len(frames) - 1
        chosen = [frames[i] for i in sorted({0, last, round(last / 3), round(2 * last / 3)})] if frames else []
        xs, ys, handles, undefined, excluded, unread = [], [], [], 0, 0, 0
        for k, result in enumerate(chosen):
            samples = _samples(cache, result, len(points))
            unread += samples is None
            for j, point in enumerate(points):
                patch = _patch(result, j)
                excluded += int(_num(patch.get("n_xy_undefined")) or 0)
                if _draw(ax, samples, j, patch, _colour(point.number), xs, ys, _MARKERS[k], ls=_STYLES[k], lw=1.4):
                    ax.text(*_centre(patch), str(point.number), fontsize=9 if k == 0 else 7, weight="bold",
                            ha="center", va="center", zorder=7, path_effects=_halo_text())
                else:
                    undefined += 1
            handles.append(_entry(f"F = {float(result['intensity_factor']):g}", color="k", linestyle=_STYLES[k],
                                  marker=_MARKERS[k], ms=4))
        handles += _black(ax, black_xy, label, xs, ys) + _count(undefined, f"ellipses (point × F) {UNDEF}")
        handles += _count(excluded, "samples with X+Y+Z ≤ 0 excluded")
        handles += _count(unread, "frame file(s) unreadable: samples not shown")
        _zoom(ax, xs, ys, min_span=0.1)
        if handles:
            ax.legend(handles=handles, fontsize=8, loc="best")
    return fig


def _fig_lines(name, series, points, key, title, ylabel, logy=False, mean=False):
    """One line per data point of a patch value against F; with ``mean``, faint lines and their mean in black.

    ``key`` names the patch record's value, or is a function ``(panel label, patch record) → value`` (e.g. one
    channel's SNR per panel). ``logy=None`` chooses a log y-axis when the positive values span more than a factor
    100.
    """
    value = key if callable(key) else (lambda _, patch: patch.get(key))
    fig, axes = _panels(f"{name}: {title}", series)
    for ax, (label, frames) in zip(axes, series.items()):
        table = [[(float(r["intensity_factor"]), _num(value(label, _patch(r, j)))) for r in frames]
                 for j in range(len(points))]
        positive = [v for row in table for _, v in row if v is not None and v > 0]
        log = (len(positive) > 1 and max(positive) > 100 * min(positive)) if logy is None else logy
        undefined, by_f = 0, {}
        for point, row in zip(points, table):
            good = [(f, v) for f, v in row if v is not None and (v > 0 or not log)]
            undefined += len(row) - len(good)
            for f, v in good:
                by_f.setdefault(f, []).append(v)
            if good:
                ax.plot(*np.array(good).T, "-o", color=_colour(point.number), ms=3, lw=1.0 if mean else 1.4,
                        alpha=0.5 if mean else 1.0)
        handles = [_entry("per data point", color="0.5", alpha=0.5, linestyle="-")] if mean else []
        if mean and by_f:
            ax.plot(sorted(by_f), [np.mean(by_f[f]) for f in sorted(by_f)], "-o", color="k", lw=2.8, ms=5)
            handles.append(_entry("mean over data points", color="k", lw=2.8, marker="o", linestyle="-"))
        _f_axes(ax, ylabel)
        if log:
            ax.set_yscale("log")
        elif key == "angle_deg":
            ax.set_ylim(-92, 92)
        handles += _count(undefined, f"values (point × F) {UNDEF}")
        if handles:
            ax.legend(handles=handles, fontsize=8, loc="best")
    _point_legend(fig, points)
    return fig


# ------------------------------------------------------------------------------------ camsim analyze's figures


@dataclass(frozen=True)
class PatchPoint:
    """A patch of the user's frames as a data point of the figures: its number (1-based, the colour) and name."""

    number: int
    name: str

    @property
    def label(self) -> str:
        return f"{self.number}: {self.name}"


#: The figures :func:`analysis_figures` writes per measurement, each ``{prefix}_{key}.png``.
ANALYSIS_FIGURES = ("xy", "delta_e", "snr")


def _slug(text: str) -> str:
    """``text`` (from a sidecar: input) as a file-name prefix: letters, digits, ``-`` and ``.`` kept, the rest ``_``;
    no leading ``.`` (a hidden file) and at most 100 characters, so that the figure's name is a safe file name
    (:mod:`camsim.core.names`)."""
    slug = "".join(ch if ch.isalnum() or ch in "-." else "_" for ch in text).strip("_").lstrip(".")
    return slug[:100] or "frames"


def _channel_value(patch, channel: str, key: str):
    """``key`` of one channel's record of a patch (None where the patch or the channel is missing)."""
    return next((ch.get(key) for ch in patch.get("channels") or [] if ch.get("channel") == channel), None)


def _analysis_black_xy(meta: dict, result: dict):
    """xy of the camera black point of a frame (its expected black level through the frame's camera → XYZ
    matrix), where the analysis subtracted no black level; None otherwise, or where it is undefined."""
    from camsim.colour.colorimetry import camera_to_xyz_matrix

    method = result.get("camera_to_xyz") or "paper"
    if result.get("black_subtraction") != "none" or method == "least-squares":
        return None  # with the black level subtracted there is no black point to drift to
    black = meta.get("black_level_dn") if result.get("source") == "dng" else meta.get("dark_level_dn",
                                                                                       meta.get("black_level_dn"))
    try:
        matrix = camera_to_xyz_matrix(np.asarray(meta["qe_e_m2_sr_per_photon"]), np.asarray(meta["wavelengths_nm"]),
                                      meta["dn_per_electron"], method=method)
        xyz = matrix @ np.asarray(black, dtype=np.float64)
    except (KeyError, TypeError, ValueError):
        return None
    total = float(xyz.sum())
    return (float(xyz[0] / total), float(xyz[1] / total)) if np.isfinite(total) and total > 0 else None


def _analysis_groups(results) -> list:
    """The frames with patches, by measurement (:func:`camsim.analysis.grouping.group_key`): per group its file
    prefix, panel title, frames (largest F first) and camera black point (of its lowest-F frame)."""
    from camsim.analysis.grouping import group_key
    from camsim.render.frame_files import read_frame_meta

    groups: dict = {}
    for result in results or []:
        if not result.get("patches"):
            continue
        try:
            meta = read_frame_meta(Path(result["frame_file"]))
        except (CamsimError, OSError, KeyError):
            continue
        key = (group_key(meta), result.get("source"), result.get("black_subtraction"), result.get("camera_to_xyz"))
        groups.setdefault(key, (meta, []))[1].append(result)
    out, used = [], set()
    for meta, frames in groups.values():
        frames = _series(frames)
        if not frames:
            continue
        first = frames[0]
        prefix = base = _slug(f"{first.get('scene')}_{first.get('illuminant')}_{first.get('photon_statistics')}")
        n = 1
        while prefix in used:
            n += 1
            prefix = f"{base}_{n}"
        used.add(prefix)
        title = (f"{first.get('scene')} under {first.get('illuminant')}, {first.get('photon_statistics')} statistics, "
                 f"camera {meta.get('camera')}, {meta.get('bits')}-bit, black level subtracted: "
                 f"{first.get('black_subtraction')} ({first.get('source')} values)")
        out.append((prefix, title, frames, _analysis_black_xy(meta, frames[-1])))
    return out


def analysis_figures(results, out_dir) -> dict:
    """Write the figures of ``camsim analyze`` for the user's own frames: per measurement (frames of one scene,
    light and camera at several F) the xy diagram with samples and 1 σ noise ellipses at representative F, and
    ΔE and the measured SNR against F.

    Parameters
    ----------
    results : list of dict
        :func:`camsim.analysis.analyze.analyse` results (``frame_file``, ``source``, ``intensity_factor``,
        ``black_subtraction``, ``camera_to_xyz``, ``border_px``, ``patches``). Frames without patches are left out;
        frames are grouped as the analysis groups them for ΔE (their sidecars are re-read for it).
    out_dir : path-like
        Folder for the PNG files (created if missing).

    Returns
    -------
    dict of {str: str}
        ``{prefix}_{key}`` → file name ``{prefix}_{key}.png``, ``key`` one of :data:`ANALYSIS_FIGURES`, ``prefix``
        ``{scene}_{illuminant}_{statistics}`` (``_2``, ``_3``, … for further measurements of the same). The SNR
        figure has one panel per channel: SNR = (mean − black level)² / variance of the patch's pixels, a power
        ratio, drawn in dB (10 log₁₀); the camera black point (a star; frames measured without black
        subtraction) is where the chromaticities go as F falls.
    """
    figures = {}
    for prefix, title, frames, black in _analysis_groups(results):
        points = [PatchPoint(j + 1, str(p.get("name"))) for j, p in enumerate(frames[0]["patches"])]
        series, black_xy = {title: frames}, {title: black}
        cache: dict = {}
        xy = _fig_samples(prefix, series, points, black_xy, cache, sizes_in="size_xy in analysis.csv")
        _point_legend(xy, points)
        made = {
            "xy": xy,
            "delta_e": _fig_lines(prefix, series, points, "delta_e_ab_mean",
                                  "mean ΔE*ab of the samples to the patch's F = 1 colour (each sample scaled to "
                                  "Y = 100: chromaticity only, unbounded where the signal nears 0)",
                                  "ΔE*ab (CIELAB units)", logy=None, mean=True),
            "snr": _fig_lines(prefix, {f"channel {c}": frames for c in CHANNELS}, points,
                              lambda label, patch: _channel_value(patch, label[-1], "snr_empirical_db"),
                              "measured SNR = (mean − black level)² / variance (power ratio) in dB",
                              "SNR (dB) = 10 log₁₀(signal² / variance)", mean=True),
        }
        figures.update({f"{prefix}_{key}": _save(fig, out_dir, f"{prefix}_{key}.png") for key, fig in made.items()})
    return figures
