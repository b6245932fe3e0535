"""``camsim analyze``: measure frames from files into a tidy CSV, a JSON summary and a printed table."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
from tqdm import tqdm

from camsim.frame_files import find_frames, load_frame
from camsim.analysis.patches import AnalysisSettings, analyse_frame, frame_matrix
from camsim.errors import CamsimError
from camsim.io.atomic import write_json_atomic, write_text_atomic
from camsim.optional_numbers import mean_of_defined
from camsim.sensor import SensorParams
from camsim.io.output_folder import make_folder

CSV_NAME = "analysis.csv"
SUMMARY_NAME = "analysis.json"
FRAME_COLUMNS = ("frame_file", "source", "scene", "illuminant", "intensity_factor", "photon_statistics", "method",
                 "seed")
PATCH_COLUMNS = ("patch_index", "patch_name", "n_xy_valid", "n_xy_undefined", "ellipse_status", "center_x",
                 "center_y", "semi_major_xy", "semi_minor_xy", "angle_deg", "size_xy", "frac_in_2sigma", "n_distinct_values", "delta_e_ab_mean",
                 "delta_e_ab_std", "n_y_nonpositive", "delta_e_status")
CHANNEL_COLUMNS = ("channel", "n_pixels", "black_dn", "mean_dn", "var_dn2", "std_dn", "mean_e", "var_e2", "std_e",
                   "saturated_pixels", "constant", "snr_model", "snr_model_db", "snr_model_eq13", "snr_model_eq13_db",
                   "snr_empirical", "snr_empirical_db",
                   "snr_status")
#: Sidecar values that must agree for two frames to be the same measurement at different F (ΔE reference): the
#: scene, light, camera and render settings, and every sensor key the schema writes (so a new sensor parameter
#: joins the grouping by itself).
GROUP_KEYS = ("scene", "illuminant", "photon_statistics", "method", "auto_tolerance_ks", "camera",
              "sensitivity_basis", "reflectances", "luminance_cd_m2", "normalisation", "scale", "width_px",
              "height_px", "wavelengths_nm", *SensorParams().sidecar_record())


def group_key(meta: dict) -> str:
    return json.dumps([meta.get(key) for key in GROUP_KEYS], sort_keys=True)


def analyse_paths(paths, settings: AnalysisSettings | None = None, source="dng", dark_frame=None,
                  progress=True) -> list[dict]:
    """Analyse every frame named by ``paths``; returns one result per frame (metadata + patch records).

    Parameters
    ----------
    paths : iterable of str or Path
        Frame files (``.dng`` with its sidecar, ``.exr``) or folders searched recursively.
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

    Frames are taken group by group (same measurement at different F), the F = 1 frame first, so that its
    patches' mean Lab serves as the ΔE reference of the others.
    """
    settings = AnalysisSettings() if settings is None else settings
    files = find_frames(paths, source)
    dark_black = None
    if settings.black == "dark-frame":
        if dark_frame is None:
            raise CamsimError("black-level mode 'dark-frame' needs a dark frame (--dark FILE)")
        dark = load_frame(dark_frame)
        dark_black = dark.pixels_dn.reshape(3, -1).mean(axis=1)
    frames = [load_frame(path) for path in files]
    order = sorted(range(len(frames)), key=lambda i: (group_key(frames[i].meta),
                                                      frames[i].meta["intensity_factor"] != 1.0, str(files[i])))
    references: dict[str, list] = {}
    results = []
    for i in tqdm(order, desc="analysing", unit="frame", disable=not progress):
        frame = frames[i]
        frames[i] = None  # free the pixels once measured
        if settings.black == "none":
            black = np.zeros(3)
        elif settings.black == "sidecar":
            black = frame.expected_black_dn()
        else:
            black = dark_black
        matrix = frame_matrix(frame, settings.matrix)
        key = group_key(frame.meta)
        is_reference = frame.meta["intensity_factor"] == 1.0 and key not in references
        patches, labs = analyse_frame(frame, settings, black, matrix, "self" if is_reference else references.get(key))
        if is_reference:
            references[key] = labs
        meta = frame.meta
        results.append({
            "frame_file": str(frame.path),
            "source": frame.source,
            **{k: meta.get(k) for k in FRAME_COLUMNS[2:]},
            "camera_to_xyz": settings.matrix,
            "cfa_pattern": frame.cfa_pattern,
            "demosaicing": "bilinear (colour-demosaicing), for xy, ellipses and ΔE only" if frame.cfa_pattern else None,
            "black_subtraction": settings.black,
            "black_dn": black.tolist(),
            "patches": patches,
        })
    return results


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


def csv_text(rows) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=FRAME_COLUMNS + PATCH_COLUMNS + CHANNEL_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: ("" if v is None else v) for k, v in row.items()})
    return buffer.getvalue()


def summary(results, settings: AnalysisSettings) -> dict:
    """The settings, the counts of undefined cases in total and per frame, and every frame's patch records."""
    totals = dict.fromkeys(("frames", "patches", "xy_undefined_samples", "y_nonpositive_samples",
                            "degenerate_ellipses", "saturated_patches", "constant_channels", "snr_undefined"), 0)
    frames = []
    for result in results:
        counts = dict.fromkeys(totals, 0)
        counts["frames"] = 1
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
        frames.append(result | {"counts": counts})
    return {"settings": {"border_px": settings.border_px, "black_subtraction": settings.black,
                         "camera_to_xyz": settings.matrix}, "totals": totals, "frames": frames}


def table(results) -> str:
    """A short text table: one line per frame."""
    lines = [f"{'frame':44s} {'F':>8s} {'stats':5s} {'ellipse size':>12s} {'mean ΔE':>8s} {'SNR G dB':>8s} flags"]
    for result in results:
        patches = result["patches"]
        size = mean_of_defined([p["size_xy"] for p in patches])
        de = mean_of_defined([p["delta_e_ab_mean"] for p in patches])
        snr = mean_of_defined([p["channels"][1]["snr_empirical_db"] for p in patches])
        flags = sum(p["ellipse_status"] != "ok" or p["n_xy_undefined"] > 0 for p in patches)
        fmt = lambda v, spec: "—" if v is None else format(v, spec)  # noqa: E731
        lines.append(f"{Path(result['frame_file']).name[:44]:44s} {result['intensity_factor']:>8g} "
                     f"{result['photon_statistics']:5s} {fmt(size, '12.3g')} {fmt(de, '8.2f')} {fmt(snr, '8.1f')} "
                     f"{flags}")
    return "\n".join(lines)


def write_outputs(results, settings, out_dir: Path) -> tuple[Path, Path]:
    make_folder(out_dir)
    csv_path, json_path = out_dir / CSV_NAME, out_dir / SUMMARY_NAME
    write_text_atomic(csv_path, csv_text(tidy_rows(results)))
    write_json_atomic(json_path, summary(results, settings))
    return csv_path, json_path
