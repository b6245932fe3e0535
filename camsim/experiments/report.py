"""An experiment's numbers (CSV) and its ``report.md``: each finding of the paper, whether it holds, and why."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camsim.experiments.findings import RESOLVED_SIZE, VISIBLE_XY, Verdict
from camsim.io.atomic import write_text_atomic


@dataclass(frozen=True)
class Finding:
    """A finding of the paper and its verdict under each photon statistics."""

    key: str
    text: str
    verdicts: dict = field(default_factory=dict)  # statistics -> Verdict
    figure: str = ""
    note: str = ""

    def holds(self, statistics: str) -> bool:
        return self.verdicts[statistics].holds


def write_csv(path: Path, rows: list[dict]) -> Path:
    """Write ``rows`` (dicts with the same keys) as a CSV file with a header; None is written as an empty cell."""
    buffer = io.StringIO()
    if rows:
        writer = csv.DictWriter(buffer, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        for row in rows:
            writer.writerow({k: "" if v is None else v for k, v in row.items()})
    write_text_atomic(path, buffer.getvalue())
    return path


def write_numbers(path: Path, results_by_stats: dict, black_xy: dict) -> Path:
    """One row per statistics × F × point: ellipse, centre, distance to the black point, ΔE, counts."""
    rows = []
    for statistics, results in results_by_stats.items():
        for result in sorted(results, key=lambda r: -r["intensity_factor"]):
            for p in result["patches"]:
                black = black_xy.get(statistics)
                distance = (None if black is None or p["center_x"] is None
                            else float(np.hypot(p["center_x"] - black[0], p["center_y"] - black[1])))
                rows.append({
                    "photon_statistics": statistics, "intensity_factor": result["intensity_factor"],
                    "point": p["index"] + 1, "point_label": p["name"], "n_xy_valid": p["n_xy_valid"],
                    "n_xy_undefined": p["n_xy_undefined"], "ellipse_status": p["ellipse_status"],
                    "center_x": p["center_x"], "center_y": p["center_y"], "semi_major_xy": p["semi_major_xy"],
                    "semi_minor_xy": p["semi_minor_xy"], "angle_deg": p["angle_deg"], "size_xy": p["size_xy"],
                    "frac_in_2sigma": p["frac_in_2sigma"], "distance_to_black_point_xy": distance,
                    "delta_e_ab_mean": p["delta_e_ab_mean"], "n_y_nonpositive": p["n_y_nonpositive"],
                    "n_distinct_values": p["n_distinct_values"],
                    "saturated_pixels_rgb": "/".join(str(ch["saturated_pixels"]) for ch in p["channels"]),
                    "frame_file": result["frame_file"],
                })
    return write_csv(path, rows)


def _mark(verdict: Verdict) -> str:
    return "**holds**" if verdict.holds else "**does not hold**"


def write_report(path: Path, title, setup, prep, sensor, factors, findings, figures: dict, numbers: Path,
                 preset: str, preamble=()) -> Path:
    """``report.md``: the set-up, then per finding its verdict in ``paper`` and ``pixel`` statistics.

    ``preamble``: lines of Markdown placed before the findings (e.g. the protocols of an experiment).
    """
    lines = [f"# {title}", "", "Reproduced by camsim from rendered frames (DNG/EXR + sidecars under `frames/`), "
             "analysed from those files. Both photon statistics are run on the same scene and F values: `paper` "
             "(Eq. 4 literally, per-bin Poisson photons per m²·sr, sampled per bin) and `pixel` (exact Poisson "
             "electrons per pixel; the docs' model page, Photon statistics).", "",
             "## Set-up", "",
             f"- Sensor preset `{preset}`: {', '.join(f'{k}={v}' for k, v in sensor.to_dict().items())}",
             f"- Camera: {prep.camera.name} ({prep.camera.sensitivity_basis} basis), anchored so that the perfect "
             "white under D65 at 100 cd/m² gives 8000 e⁻ in the strongest channel at F = 1, T = 1 s",
             f"- Intensity factors F: {', '.join(f'{f:g}' for f in factors)}",
             f"- Frames of {setup.width} × {setup.height} pixels; each data point is one patch of about "
             f"{_samples_per_patch(prep)} pixels (3-pixel border left out): that many samples per point and F "
             "(the paper took 200)",
             f"- Seed {setup.seed}; camera → XYZ by the paper's M (Eq. 15); no black-level subtraction (as in "
             "the paper) unless a finding says otherwise",
             f"- Ellipses below {RESOLVED_SIZE:g} in xy are below the float32 resolution of the EXR frames and are "
             f"not used to judge a finding; {VISIBLE_XY:g} in xy counts as visible on the diagram", "",
             "Data points (13 on the convex hull of the Macbeth × illuminant chromaticities, 7 inside; "
             "rule in `camsim/experiments/datapoints.py`):", "",
             "| # | patch | illuminant | x | y | hull |", "|---|---|---|---|---|---|"]
    lines += [f"| {p.number} | {p.patch} | {p.illuminant} | {p.x:.4f} | {p.y:.4f} | {'yes' if p.on_hull else ''} |"
              for p in prep.points]
    lines += ["", *preamble, "## Findings", "", "| finding | paper statistics | pixel statistics | figure |",
              "|---|---|---|---|"]
    for f in findings:
        fig = figures.get(f.figure, "")
        lines.append(f"| {f.key}: {f.text} | {_mark(f.verdicts['paper'])} | {_mark(f.verdicts['pixel'])} | "
                     f"{f'[{fig}]({fig})' if fig else ''} |")
    lines += ["", "## Evidence", ""]
    for f in findings:
        lines += [f"### {f.key}: {f.text}", ""]
        for statistics in ("paper", "pixel"):
            lines.append(f"- `{statistics}`: {_mark(f.verdicts[statistics])} — {f.verdicts[statistics].evidence}")
        if f.holds("paper") != f.holds("pixel"):
            lines.append(f"- It holds in `{'paper' if f.holds('paper') else 'pixel'}` statistics only. "
                         + (f.note or "The two differ in the shot noise: per m²·sr (paper) against per pixel."))
        elif f.note:
            lines.append(f"- {f.note}")
        if f.figure in figures:
            lines += ["", f"![{f.key}]({figures[f.figure]})"]
        lines.append("")
    lines += ["## Figures", ""] + [f"- `{key}`: [{name}]({name})" for key, name in figures.items()]
    lines += ["", f"Numbers: [{numbers.name}]({numbers.name}).", ""]
    write_text_atomic(path, "\n".join(lines))
    return path


def _samples_per_patch(prep) -> int:
    sizes = [(w - 6) * (h - 6) for _, _, w, h in prep.radiance.patch_rects]
    return int(np.median(sizes)) if sizes else 0
