"""``camsim analyze``: measure frames from files into a tidy CSV, a JSON summary and a printed table."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tqdm import tqdm

from camsim.analysis.dark import DarkFrame, load_dark
from camsim.analysis.figures import analysis_figures
from camsim.analysis.frame_stats import FRAME_STAT_COLUMNS, frame_statistics
from camsim.analysis.grouping import group_key
from camsim.analysis.patches import AnalysisSettings, analyse_frame, frame_matrix
from camsim.core.errors import CamsimError
from camsim.core.optional_numbers import mean_of_defined
from camsim.io.atomic import write_json_atomic, write_text_atomic
from camsim.io.output_folder import make_folder
from camsim.render.frame_files import (
    LoadedFrame,
    load_frame,
    no_frames_message,
    read_frame_meta,
    search_frames,
    uncommitted_lines,
)

CSV_NAME = "analysis.csv"
FRAME_CSV_NAME = "frame_statistics.csv"
SUMMARY_NAME = "analysis.json"
#: The companion text of the CSVs: every column, SNR, ΔE and the flags explained (:mod:`camsim.analysis.columns`).
GUIDE_NAME = "README.txt"
FRAME_COLUMNS = ("frame_file", "source", "scene", "illuminant", "intensity_factor", "photon_statistics", "method",
                 "seed")
PATCH_COLUMNS = ("patch_index", "patch_name", "n_xy_valid", "n_xy_undefined", "ellipse_status", "center_x",
                 "center_y", "semi_major_xy", "semi_minor_xy", "angle_deg", "size_xy", "frac_in_2sigma",
                 "n_distinct_values", "delta_e_ab_mean", "delta_e_ab_std", "n_y_nonpositive", "delta_e_status")
CHANNEL_COLUMNS = ("channel", "n_pixels", "black_dn", "mean_dn", "var_dn2", "std_dn", "mean_e", "var_e2", "std_e",
                   "saturated_pixels", "constant", "snr_model", "snr_model_db", "snr_model_eq13", "snr_model_eq13_db",
                   "snr_empirical", "snr_empirical_db",
                   "snr_status")
@dataclass
class Analysis:
    """The outcome of :func:`analyse`.

    Attributes
    ----------
    results : list of dict
        One result per frame analysed (see :func:`analyse_paths`).
    skipped : list of dict
        The bad files, each ``{"file": path, "reason": why}``: unreadable, truncated or foreign files, missing
        or mismatched sidecars, frames that cannot be measured.
    uncommitted : list of str
        Frame files in the folders searched that no sidecar claims (frames being written, or left by an
        interrupted writer): not analysed.
    """

    results: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    uncommitted: list = field(default_factory=list)


def check_settings(path: Path, meta: dict, settings: AnalysisSettings, dark: DarkFrame | None) -> None:
    """Refuse settings that make no sense for the frame ``path`` (with metadata ``meta``).

    Raises
    ------
    CamsimError
        A border that leaves a patch empty (a Bayer patch needs a whole 2 × 2 cell left), or a dark frame of
        another size or CFA layout than the frame.
    """
    least = 2 if meta.get("cfa_pattern") else 1
    for index, patch in enumerate(meta["patches"]):
        _, _, w, h = patch["rect_xywh"]
        if min(w, h) - 2 * settings.border_px < least:
            raise CamsimError(f"a border of {settings.border_px} px (--border) leaves patch {index} "
                              f"'{patch['name']}' ({w}x{h} px) of {path} empty: it allows at most "
                              f"{max((min(w, h) - least) // 2, 0)} px")
    if settings.edge_region is not None:
        from camsim.analysis.mtf import check_region

        check_region(settings.edge_region, meta["width_px"], meta["height_px"], f"{path}: ")
    if dark is not None:
        layout = f"{meta.get('width_px')}x{meta.get('height_px')} {meta.get('cfa_pattern') or 'three-chip'}"
        if layout != dark.layout():
            raise CamsimError(f"--dark {dark.path} is {dark.layout()} but {path} is {layout}: a dark frame must "
                              "have the size and CFA layout of the frames analysed")


class _Report:
    """The bad and uncommitted files of an analysis: recorded, and told through ``warn`` (one line each).

    Lines are held back until the first frame has been analysed: when none can be, the analysis ends with one
    error that says why (:meth:`failure`) instead.
    """

    def __init__(self, warn, strict: bool):
        self.warn, self.strict = warn, strict
        self.skipped: list[dict] = []
        self.uncommitted: list[str] = []
        self.held: list[str] = []
        self.analysed = False

    def skip(self, path, message: str) -> None:
        """A bad file: recorded and told, or with ``strict`` the end of the analysis."""
        reason = message.removeprefix(f"{path}: ")
        if self.strict:
            raise CamsimError(f"{path}: {reason}")
        self.skipped.append({"file": str(path), "reason": reason})
        self._tell(f"skipped {path}: {reason}")

    def note(self, line: str) -> None:
        """Something a frame measured lacks (an unreadable EXR beside it): told on one line."""
        self._tell(line)

    def ignore(self, files) -> None:
        """Uncommitted frame files: recorded and told, one line per folder."""
        self.uncommitted += [str(p) for p in files]
        for line in uncommitted_lines(files):
            self._tell(line)

    def frame_done(self) -> None:
        if not self.analysed:
            self.analysed = True
            for line in self.held:
                self._tell(line)
            self.held.clear()

    def failure(self, paths) -> CamsimError:
        """The error when no frame was analysed."""
        if not self.skipped:
            return CamsimError(no_frames_message(paths, self.uncommitted))
        first = self.skipped[0]
        n = len(self.skipped)
        what = "skipped" if n == 1 else f"skipped {n} bad files, e.g."
        ignored = f"; ignored {len(self.uncommitted)} uncommitted frame file(s)" if self.uncommitted else ""
        return CamsimError(f"nothing analysed: {what} {first['file']}: {first['reason']}{ignored}")

    def _tell(self, line: str) -> None:
        if self.warn is None:
            return
        if self.analysed:
            self.warn(line)
        else:
            self.held.append(line)


def measure_frame(frame: LoadedFrame, settings: AnalysisSettings, black: np.ndarray, references: dict) -> dict:
    """The result of one frame (see :func:`analyse_paths`), its black level ``black`` (DN) subtracted.

    ``references`` maps a group key to the patches' reference Lab: the first F = 1 frame of a group enters it,
    the others of its group are measured against it.
    """
    meta = frame.meta
    key = group_key(meta)
    patches = []
    if meta["patches"]:  # (a frame without patches needs no matrix: least-squares fits one on the patches)
        matrix = frame_matrix(frame, settings.matrix)
        is_reference = meta["intensity_factor"] == 1.0 and key not in references
        patches, labs = analyse_frame(frame, settings, black, matrix,
                                      "self" if is_reference else references.get(key))
        if is_reference:
            references[key] = labs
    # the whole frame, black-level subtracted (the sidecar's level when the patches are measured without)
    frame_black = frame.expected_black_dn() if settings.black == "none" else black
    problems: list[str] = []
    statistics = frame_statistics(frame, frame_black, problems)
    mtf = _frame_mtf(frame, settings.edge_region)
    return {
        "frame_file": str(frame.path),
        "source": frame.source,
        **{k: meta.get(k) for k in FRAME_COLUMNS[2:]},
        "camera_to_xyz": settings.matrix,
        "cfa_pattern": frame.cfa_pattern,
        "demosaicing": "bilinear (colour-demosaicing), for xy, ellipses and ΔE only" if frame.cfa_pattern else None,
        "black_subtraction": settings.black,
        "border_px": settings.border_px,
        "black_dn": black.tolist(),
        "patches": patches,
        "frame_statistics": statistics,
        "unreadable_exr": problems[0] if problems else None,  # its EXR, there but unreadable: no residual
        **({"mtf": mtf} if mtf is not None else {}),
    }


def _frame_mtf(frame: LoadedFrame, edge_region) -> dict | None:
    """The e-SFR record of a frame (:func:`camsim.analysis.mtf.measure_frame_mtf`; an EXR's clean layer measured
    too), ``{"error": why}`` where it cannot be measured, None for a frame without an edge to measure."""
    from camsim.analysis.mtf import measure_frame_mtf, wants_mtf

    if not wants_mtf(frame.meta, edge_region):
        return None
    try:
        clean = None
        if frame.source == "exr":
            from camsim.io.exr import read_exr_clean

            clean, _ = read_exr_clean(frame.path)
        return measure_frame_mtf(frame.pixels_dn, frame.meta, edge_region, clean, str(frame.path),
                                 "dng" if frame.quantised else "noisy")
    except CamsimError as exc:
        return {"error": str(exc)}


def non_finite(value, where: str = "") -> str | None:
    """The place of the first NaN or infinity in ``value`` (nested dicts and lists of numbers), e.g.
    ``patches[0].channels[1].snr_model``; None when every number is finite (as ``analysis.json`` needs)."""
    if isinstance(value, dict):
        items = ((f"{where}.{key}" if where else str(key), v) for key, v in value.items())
    elif isinstance(value, (list, tuple)):
        items = ((f"{where}[{i}]", v) for i, v in enumerate(value))
    elif isinstance(value, (float, np.floating)):
        return None if np.isfinite(value) else where
    else:
        return None
    for place, item in items:
        found = non_finite(item, place)
        if found is not None:
            return found
    return None


def _black(frame: LoadedFrame, settings: AnalysisSettings, dark: DarkFrame | None) -> np.ndarray:
    if settings.black == "none":
        return np.zeros(3)
    if settings.black == "sidecar":
        return frame.expected_black_dn()
    return dark.black_dn


def _sorted_frames(files, settings: AnalysisSettings, dark: DarkFrame | None, report: _Report) -> list[Path]:
    """Pass 1: the frames' metadata only (sidecars, EXR headers), checked and sorted group by group, F = 1 first."""
    keys = []
    for path in files:
        try:
            meta = read_frame_meta(path)
        except CamsimError as exc:
            report.skip(path, str(exc))
            continue
        check_settings(path, meta, settings, dark)
        keys.append((group_key(meta), meta["intensity_factor"] != 1.0, str(path), path))
    return [key[-1] for key in sorted(keys)]


def analyse(paths, settings: AnalysisSettings | None = None, source="dng", dark_frame=None, progress=True,
            strict=False, warn=None) -> Analysis:
    """Analyse every frame named by ``paths``, one at a time, skipping bad files.

    Parameters
    ----------
    paths, settings, source, dark_frame, progress
        As for :func:`analyse_paths`.
    strict : bool
        Stop at the first bad file (CamsimError) instead of skipping it.
    warn : callable, optional
        Called with one line (no prefix, no newline) per bad file and per folder with uncommitted frame files,
        once the first frame has been analysed; None says nothing (the :class:`Analysis` records them).

    Returns
    -------
    Analysis
        The results, the files skipped with their reasons and the uncommitted files left out.

    Raises
    ------
    CamsimError
        Settings that make no sense for the frames (:func:`check_settings`), an unusable or lit dark frame, a
        bad file with ``strict``, or no frame analysed (one message that says why).

    Notes
    -----
    Two passes, so that memory does not grow with the number of frames: the first reads each frame's metadata
    (its sidecar, or an EXR's header) to order the frames group by group (same measurement at different F),
    the F = 1 frame first, whose patches' mean Lab is the ΔE reference of the others; the second loads,
    measures and frees one frame at a time.
    """
    settings = AnalysisSettings() if settings is None else settings
    report = _Report(warn, strict)
    search = search_frames(paths, source)
    for path, reason in search.bad:
        report.skip(path, reason)
    report.ignore(search.uncommitted)
    dark = None
    if settings.black == "dark-frame":
        if dark_frame is None:
            raise CamsimError("black-level mode 'dark-frame' needs a dark frame (--dark FILE)")
        dark = load_dark(dark_frame)
    order = _sorted_frames(search.files, settings, dark, report)
    references: dict[str, list] = {}
    results = []
    for path in tqdm(order, desc="analysing", unit="frame", disable=not (progress and order)):
        try:
            frame = load_frame(path)
            with np.errstate(all="ignore"):  # a value out of range is told below, once, not as numpy warnings
                try:
                    result = measure_frame(frame, settings, _black(frame, settings, dark), references)
                except (OverflowError, ZeroDivisionError) as exc:  # Python floats' k**2, 1 / k**2 of extreme values
                    raise CamsimError(f"{path}: its sidecar's values give a measurement that is not finite "
                                      f"({type(exc).__name__}); values out of range?") from None
            where = non_finite(result)
            if where is not None:
                raise CamsimError(f"{path}: its sidecar's values give a measurement that is not finite ({where}); "
                                  "values out of range?")
            results.append(result)
            if result.get("mtf", {}).get("error"):
                report.note(f"no MTF: {result['mtf']['error']}")
            if result["unreadable_exr"]:
                report.note(f"measured {path} without its residual noisy − clean: {result['unreadable_exr']}")
        except CamsimError as exc:
            report.skip(path, str(exc))
            continue
        finally:
            frame = None  # free the pixels before the next frame is read
        report.frame_done()
    if not results:
        raise report.failure(paths)
    if settings.edge_region is not None and all("error" in r["mtf"] for r in results):
        raise CamsimError(f"no MTF measured: {results[0]['mtf']['error']}")
    return Analysis(results, report.skipped, report.uncommitted)


def analyse_paths(paths, settings: AnalysisSettings | None = None, source="dng", dark_frame=None,
                  progress=True) -> list[dict]:
    """Analyse every frame named by ``paths``; returns one result per frame (metadata + patch records).

    Parameters
    ----------
    paths : iterable of str or Path
        Frame files (``.dng`` with its sidecar, ``.exr``) or folders searched recursively for committed frames
        (whose sidecar claims the file; :func:`camsim.render.frame_files.search_frames`).
    settings : AnalysisSettings, optional
        Border, black-level mode and camera → XYZ matrix (default ``AnalysisSettings()``: the paper's way).
    source : {'dng', 'exr'}
        Which file of a frame to measure when both exist: the digital numbers or the signal before quantisation.
    dark_frame : str or Path, optional
        A dark frame whose per-channel mean is the black level (with ``settings.black == 'dark-frame'``).
    progress : bool
        Show a progress bar.

    Returns
    -------
    list of dict
        Per frame: ``frame_file``, ``source``, the sidecar's scene, illuminant, F, statistics, method and seed,
        the black level used and ``patches`` (per patch and channel: mean, variance and SNR in DN and e⁻; the xy
        ellipse; ΔE_ab against the same patch at F = 1).

    Raises
    ------
    CamsimError
        Any bad file (this is :func:`analyse` with ``strict``), settings that make no sense, no frame found.

    Frames are taken group by group (same measurement at different F), the F = 1 frame first, so that its
    patches' mean Lab serves as the ΔE reference of the others; one frame's pixels are in memory at a time.
    """
    return analyse(paths, settings, source, dark_frame, progress, strict=True).results


def tidy_rows(results) -> list[dict]:
    """One row per frame × patch × channel."""
    rows = []
    for result in results:
        for patch in result["patches"]:
            base = {k: result[k] for k in FRAME_COLUMNS}
            base.update({"patch_index": patch["index"], "patch_name": patch["name"]})
            base.update({k: patch[k] for k in PATCH_COLUMNS[2:]})
            for channel in patch["channels"]:
                rows.append({**base, **{k: channel[k] for k in CHANNEL_COLUMNS}})
    return rows


def frame_rows(results) -> list[dict]:
    """One row per frame × channel: the frame's columns and its whole-frame statistics."""
    return [{**{k: result[k] for k in FRAME_COLUMNS}, **channel} for result in results
            for channel in result["frame_statistics"]]


def csv_text(rows, columns=FRAME_COLUMNS + PATCH_COLUMNS + CHANNEL_COLUMNS) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if v is None else v) for k, v in row.items()})
    return buffer.getvalue()


def summary(results, settings: AnalysisSettings, skipped=(), uncommitted=()) -> dict:
    """The settings, the counts of undefined cases in total and per frame, the files left out (``skipped``: bad
    files with their reasons, ``uncommitted``: frame files no sidecar claims) and every frame's patch records."""
    totals = dict.fromkeys(("frames", "patches", "xy_undefined_samples", "y_nonpositive_samples",
                            "degenerate_ellipses", "saturated_patches", "constant_channels", "snr_undefined",
                            "frames_without_patches", "frames_without_residual", "unreadable_exr"), 0)
    frames = []
    for result in results:
        counts = dict.fromkeys(totals, 0)
        counts["frames"] = 1
        counts["frames_without_patches"] = int(not result["patches"])
        counts["frames_without_residual"] = int(any(ch["residual_status"] != "ok"
                                                    for ch in result["frame_statistics"]))
        counts["unreadable_exr"] = int(bool(result.get("unreadable_exr")))
        for patch in result["patches"]:
            counts["patches"] += 1
            counts["xy_undefined_samples"] += patch["n_xy_undefined"]
            counts["y_nonpositive_samples"] += patch["n_y_nonpositive"] or 0
            counts["degenerate_ellipses"] += patch["ellipse_status"] != "ok"
            counts["saturated_patches"] += any(ch["saturated_pixels"] for ch in patch["channels"])
            counts["constant_channels"] += sum(ch["constant"] for ch in patch["channels"])
            counts["snr_undefined"] += sum(ch["snr_status"] != "ok" for ch in patch["channels"])
        for key in totals:
            totals[key] += counts[key]
        if "mtf" in result:  # the curves are mtf.csv's; analysis.json holds the summary
            result = result | {"mtf": {k: v for k, v in result["mtf"].items() if k != "curves"}}
        frames.append(result | {"counts": counts})
    region = {"edge_region_xywh": list(settings.edge_region)} if settings.edge_region is not None else {}
    return {"settings": {"border_px": settings.border_px, "black_subtraction": settings.black,
                         "camera_to_xyz": settings.matrix, **region}, "totals": totals, "skipped": list(skipped),
            "uncommitted": list(uncommitted), "frames": frames}


def table(results) -> str:
    """A short text table: one line per frame, each scene's frames by falling F (columns:
    :data:`camsim.analysis.columns.TABLE_COLUMNS`)."""
    lines = [f"{'frame':44s} {'F':>8s} {'stats':5s} {'ellipse size':>12s} {'mean ΔE':>8s} {'SNR G dB':>8s} flags"]
    first_seen: dict = {}
    for result in results:
        first_seen.setdefault((result["scene"], result["illuminant"], result["photon_statistics"]), len(first_seen))
    order = sorted(results, key=lambda r: (first_seen[(r["scene"], r["illuminant"], r["photon_statistics"])],
                                           -float(r["intensity_factor"])))
    for result in order:
        patches = result["patches"]
        size = mean_of_defined([p["size_xy"] for p in patches])
        de = mean_of_defined([p["delta_e_ab_mean"] for p in patches])
        snr = mean_of_defined([p["channels"][1]["snr_empirical_db"] for p in patches])
        flags = sum(p["ellipse_status"] != "ok" or p["n_xy_undefined"] > 0 for p in patches)
        fmt = lambda v, spec: "—" if v is None else format(v, spec)  # noqa: E731
        lines.append(f"{Path(result['frame_file']).name[:44]:44s} {result['intensity_factor']:>8g} "
                     f"{result['photon_statistics']:5s} {fmt(size, '12.3g')} {fmt(de, '8.2f')} {fmt(snr, '8.1f')} "
                     f"{flags}" + ("" if patches else "  (no patches: frame statistics below)"))
    return "\n".join(lines)


def frame_table(results) -> str:
    """A short text table of the whole-frame statistics: one line per frame × channel (mean and σ less the black
    level, clipped percentages, and the residual noisy − clean: bias ± its standard error, measured / predicted
    variance)."""
    fmt = lambda v, spec: "—" if v is None else format(v, spec)  # noqa: E731
    lines = [f"{'frame':44s} {'ch':2s} {'mean DN':>9s} {'σ DN':>8s} {'clip0 %':>7s} {'clipW %':>7s} "
             f"{'bias DN ± se':>18s} {'var/model':>9s}"]
    for result in results:
        for ch in result["frame_statistics"]:
            if ch["residual_status"] == "ok":
                bias = f"{ch['residual_mean_dn']:+.4f} ± {fmt(ch['residual_mean_se_dn'], '.4f')}"
                ratio = fmt(ch["residual_var_ratio"], "9.4f")
            else:
                bias, ratio = ch["residual_status"], ""
            lines.append(f"{Path(result['frame_file']).name[:44]:44s} {ch['channel']:2s} {ch['mean_dn']:9.3f} "
                         f"{fmt(ch['std_dn'], '8.3f')} {100 * ch['clip_low_fraction']:7.3f} "
                         f"{100 * ch['clip_high_fraction']:7.3f} {bias:>18s} {ratio:>9s}")
    return "\n".join(lines)


def write_outputs(results, settings, out_dir: Path, skipped=(), uncommitted=(), figures: bool = False,
                  temporal=()):
    """Write ``out_dir/analysis.csv`` (per frame × patch × channel), ``out_dir/frame_statistics.csv`` (per frame ×
    channel, :func:`camsim.analysis.frame_stats.frame_statistics`), ``out_dir/analysis.json`` (:func:`summary`),
    ``out_dir/README.txt`` (every column, SNR, ΔE and the flags explained: :func:`camsim.analysis.columns.guide_text`)
    and, with ``figures``, the PNG figures (:func:`camsim.analysis.figures.analysis_figures`). With ``temporal``
    rows (:func:`camsim.analysis.temporal.analyse_sequences`), also ``out_dir/temporal.csv``, their records under
    ``temporal`` in ``analysis.json`` and their columns in ``README.txt``; without, every file is as before.
    Frames with an MTF record (a slanted edge: :mod:`camsim.analysis.mtf`) also get ``out_dir/mtf.csv`` (one frame;
    several: ``mtf_<frame stem>.csv`` each) and, with ``figures``, ``mtf.png`` (measured beside the model).

    Returns
    -------
    csv_path, json_path : pathlib.Path
        ``analysis.csv`` and ``analysis.json``.
    figure_files : list of str
        The figures' file names in ``out_dir`` (empty without ``figures``, or without patches and edges).
    """
    from camsim.analysis.columns import guide_text

    make_folder(out_dir)
    csv_path, json_path = out_dir / CSV_NAME, out_dir / SUMMARY_NAME
    write_text_atomic(csv_path, csv_text(tidy_rows(results)))
    write_text_atomic(out_dir / FRAME_CSV_NAME, csv_text(frame_rows(results), FRAME_COLUMNS + FRAME_STAT_COLUMNS))
    mtf_files = _write_mtf(results, out_dir, figures)
    document = summary(results, settings, skipped, uncommitted)
    if temporal:
        from camsim.analysis.temporal import TEMPORAL_COLUMNS, TEMPORAL_CSV_NAME

        write_text_atomic(out_dir / TEMPORAL_CSV_NAME, csv_text(temporal, TEMPORAL_COLUMNS))
        document["temporal"] = list(temporal)
    write_json_atomic(json_path, document)
    names = []
    if figures:
        names = list(analysis_figures(results, out_dir).values())
    write_text_atomic(out_dir / GUIDE_NAME, guide_text(names, temporal=bool(temporal), mtf=mtf_files))
    return csv_path, json_path, names + [name for name in mtf_files if name.endswith(".png")]


def mtf_file_stems(results) -> dict:
    """The file stem of each measured frame's MTF files, by result index: ``mtf`` for the only one, else
    ``mtf_<frame stem>`` (``_2``, ``_3`` … where stems repeat)."""
    measured = [i for i, r in enumerate(results) if "curves" in r.get("mtf", {})]
    if len(measured) == 1:
        return {measured[0]: "mtf"}
    stems, seen = {}, set()
    for i in measured:
        stem, n = f"mtf_{Path(results[i]['frame_file']).stem}", 1
        while (stem if n == 1 else f"{stem}_{n}") in seen:
            n += 1
        stems[i] = stem if n == 1 else f"{stem}_{n}"
        seen.add(stems[i])
    return stems


def _write_mtf(results, out_dir: Path, figures: bool) -> list[str]:
    """Each measured frame's ``mtf.csv`` (:data:`camsim.analysis.mtf.MTF_COLUMNS`) and, with ``figures``, its
    ``mtf.png``; the files' names go into the frame's ``mtf`` record. Returns the names written."""
    from camsim.analysis.mtf import MTF_COLUMNS, mtf_figure

    names = []
    for i, stem in mtf_file_stems(results).items():
        record = results[i]["mtf"]
        write_text_atomic(out_dir / f"{stem}.csv", csv_text(record["curves"], MTF_COLUMNS))
        record["csv"] = f"{stem}.csv"
        names.append(record["csv"])
        if figures:
            mtf_figure(record, out_dir / f"{stem}.png", Path(results[i]["frame_file"]).name)
            record["figure"] = f"{stem}.png"
            names.append(record["figure"])
    return names


def mtf_lines(results) -> list[str]:
    """The printed table of the slanted-edge SFRs: one line per frame × channel (MTF50 and MTF at Nyquist,
    measured and model) and the warnings."""
    lines = []
    fmt = lambda v, spec: "—" if v is None else format(v, spec)  # noqa: E731
    for result in results:
        record = result.get("mtf")
        if record is None or "channels" not in record:
            continue
        if not lines:
            lines.append(f"{'frame (slanted-edge SFR)':44s} {'ch':8s} {'angle °':>7s} {'MTF50 cy/px':>11s} "
                         f"{'model':>7s} {'MTF@Nyq':>8s} {'model':>7s}")
        for ch in record["channels"]:
            lines.append(f"{Path(result['frame_file']).name[:44]:44s} {ch['channel']:8s} {ch['angle_deg']:7.2f} "
                         f"{fmt(ch['mtf50_cy_per_px'], '11.4f')} {fmt(ch['model_mtf50_cy_per_px'], '7.4f')} "
                         f"{ch['mtf_nyquist']:8.4f} {fmt(ch['model_mtf_nyquist'], '7.4f')}")
            lines += [f"  warning: {w}" for w in ch["warnings"]]
    return lines
