"""``camsim analyze``: measure the patches of rendered frames (statistics, chromaticity ellipses, ΔE, SNR) and the
slanted-edge MTF."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from camsim.cli.commands import DEFAULT_OUT, writing_to
from camsim.cli.types import non_negative_int


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``analyze`` and its options to ``subparsers``; returns its parser."""
    parser = subparsers.add_parser(
        "analyze",
        help="measure patches of rendered frames: statistics, chromaticity ellipses, ΔE, SNR; slanted-edge MTF",
        description=(
            "Measure every patch of every frame (DNG + sidecar, or EXR) in the given files and folders: per-channel "
            "mean, variance and standard deviation in DN and e⁻, the xy chromaticity ellipse (PCA, 1 σ), ΔE_ab by "
            "the paper's 5-step procedure against the same patch at F = 1, and SNR from the model and from the "
            "pixels. For every frame, with or without patches: per channel the black-level-subtracted mean and σ, the "
            "fractions clipped at 0 and at the white level, and (with the EXR's clean layer) the residual noisy − "
            "clean, its bias and its variance against the model's. Writes OUT/analysis.csv (one row per frame × "
            "patch × channel), OUT/frame_statistics.csv (one row per frame × channel), OUT/analysis.json, "
            "OUT/README.txt (every column explained; SNR is signal² / variance, a power ratio) and PNG figures. "
            "Frames of one static scene and sensor that differ only in their noise (seed or frame_index: a "
            "sequence of N ≥ 2) also get their temporal and spatial noise separated (EMVA 1288: the pixels' variance "
            "over the frames, "
            "the mean image's variance less temporal / N), per patch and for the whole frame, against the model's: "
            "OUT/temporal.csv. "
            "Frames with a slanted edge (a slanted-edge target's sidecar, or --edge-region) also get their edge-SFR "
            "per channel (ISO 12233:2017 e-SFR; a Bayer colour on its own sites) beside the closed-form MTF of the "
            "sidecar's optics: OUT/mtf.csv (channel, frequency_cy_per_px, mtf_measured, mtf_model), MTF50 and MTF "
            "at Nyquist in analysis.json and the table, and OUT/mtf.png. "
            "Folders give their committed frames only (the sidecar, written last, names the file); other frame "
            "files there are ignored with one warning per folder, hidden files silently. A bad file (unreadable, "
            "truncated, foreign, a compressed DNG, a missing or mismatched sidecar, a sidecar value of the wrong "
            "type or range or not finite) is skipped with a warning and the rest analysed; "
            "the exit status is 2 only when no frame could be (or, with --strict, at the first bad file). Frames "
            "are read one at a time: memory does not grow with their number."
        ),
    )
    parser.add_argument("paths", nargs="+", metavar="DIR_OR_FILES", help="frame files (.dng, .exr) or folders")
    parser.add_argument("--subtract-black", action="store_true",
                        help="subtract the black level (the sidecar's mean DN of an unlit pixel, or --dark's mean) "
                             "before measuring; the paper does not, which drags dark colours to the black point")
    parser.add_argument("--dark", metavar="FILE", type=Path,
                        help="a dark frame (.dng or .exr) whose per-channel mean is the black level (DN); "
                             "implies --subtract-black. It must have the frames' size and CFA layout, and be "
                             "dark: refused when its sidecar expects more than 0.5 e⁻ of signal in any patch, or "
                             "(without a chart) when a channel's mean exceeds the expected black level by more "
                             "than 5 standard errors + 1 DN")
    parser.add_argument("--source", choices=("dng", "exr"), default="dng",
                        help="which file of a frame to measure: 'dng' = the quantised digital numbers (default), "
                             "'exr' = the signal before quantisation")
    parser.add_argument("--matrix", choices=("paper", "paper-literal", "least-squares"), default="paper",
                        help="camera → XYZ matrix: 'paper' = Eq. 15 from the Qe (default), 'paper-literal' = Eq. 16 "
                             "as printed, 'least-squares' = fitted to the chart's patches")
    parser.add_argument("--border", metavar="PIXELS", type=non_negative_int, default=3,
                        help="pixels left out along each edge of a patch (default 3); refused when it "
                             "leaves a patch empty")
    parser.add_argument("--edge-region", metavar="X,Y,W,H", type=_region,
                        help="measure the slanted-edge SFR (ISO 12233:2017 e-SFR) of every frame in this rectangle "
                             "(pixels: left, top, width, height), which must hold one straight edge slanted a few "
                             "degrees from vertical or horizontal; without it, frames whose sidecar records a "
                             "slanted-edge target are measured in the target's region. Writes OUT/mtf.csv (several "
                             "frames: OUT/mtf_<stem>.csv), MTF50 and MTF at Nyquist in analysis.json and a figure")
    parser.add_argument("--out", metavar="DIR", type=Path, help="output folder (default outputs/analysis)")
    parser.add_argument("--strict", action="store_true",
                        help="stop at the first bad file (exit status 2) instead of skipping it")
    parser.add_argument("--no-figures", action="store_true",
                        help="write no PNG figures (by default: per scene and light, the xy diagram with the noise "
                             "ellipses, the ellipse centres, and ellipse size, ΔE and SNR against F)")
    parser.add_argument("--quiet", "-q", action="store_true",
                        help="no progress bar, no table, no colour-science warnings")
    return parser


def _region(text: str) -> tuple:
    """``X,Y,W,H``: four integers, X, Y ≥ 0 and W, H ≥ 8 (pixels)."""
    parts = text.split(",")
    try:
        values = tuple(int(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 4 or min(values[:2]) < 0 or min(values[2:]) < 8:
        raise argparse.ArgumentTypeError(f"expected X,Y,W,H in pixels (X, Y >= 0; W, H >= 8), got {text!r}")
    return values


def _warn(line: str) -> None:
    """One warning line on stderr, clear of the progress bar."""
    from tqdm import tqdm

    tqdm.write(f"camsim: warning: {line}", file=sys.stderr)


def run(args) -> int:
    """Carry out ``camsim analyze``; returns the exit status (0)."""
    from camsim.analysis.analyze import (
        FRAME_CSV_NAME,
        GUIDE_NAME,
        analyse,
        frame_table,
        mtf_lines,
        table,
        write_outputs,
    )
    from camsim.analysis.patches import AnalysisSettings
    from camsim.analysis.temporal import TEMPORAL_CSV_NAME, analyse_sequences, summary_lines

    black = "dark-frame" if args.dark is not None else ("sidecar" if args.subtract_black else "none")
    settings = AnalysisSettings(border_px=args.border, black=black, matrix=args.matrix, edge_region=args.edge_region)
    out = args.out if args.out is not None else DEFAULT_OUT / "analysis"
    with writing_to(out):
        analysis = analyse(args.paths, settings, source=args.source, dark_frame=args.dark,
                           progress=not args.quiet, strict=args.strict, warn=_warn)
        results = analysis.results
        temporal = analyse_sequences([r["frame_file"] for r in results], args.source, args.border, warn=_warn)
        csv_path, json_path, figures = write_outputs(results, settings, out, analysis.skipped, analysis.uncommitted,
                                                     figures=not args.no_figures, temporal=temporal)
    if not args.quiet:
        from camsim.analysis.columns import legend_text

        print(table(results))
        print(frame_table(results))
        print(legend_text())
        for line in summary_lines(temporal):
            print(line)
        for line in mtf_lines(results):
            print(line)
    ignored = f", ignored {len(analysis.uncommitted)} uncommitted file(s)" if analysis.uncommitted else ""
    print(f"analysed {len(results)} frames, skipped {len(analysis.skipped)} bad file(s){ignored}: {csv_path} "
          f"(one row per frame × patch × channel), {out / FRAME_CSV_NAME} (one row per frame × channel), {json_path}"
          f", {len(figures)} figure(s); columns explained in {out / GUIDE_NAME}")
    if temporal:
        sequences = len({row["sequence"] for row in temporal})
        print(f"temporal and spatial noise of {sequences} sequence(s) (EMVA 1288): {out / TEMPORAL_CSV_NAME} (one row "
              "per sequence × region × channel)")
    mtf_csvs = [r["mtf"]["csv"] for r in results if "csv" in r.get("mtf", {})]
    if mtf_csvs:
        print(f"slanted-edge SFR (ISO 12233:2017) of {len(mtf_csvs)} frame(s): {out / mtf_csvs[0]}"
              + (f" … ({len(mtf_csvs)} files)" if len(mtf_csvs) > 1 else "") + " (one row per channel × frequency)")
    return 0
