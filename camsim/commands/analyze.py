"""``camsim analyze``: measure the patches of rendered frames (statistics, chromaticity ellipses, ΔE, SNR)."""

from __future__ import annotations

import argparse
from pathlib import Path

from camsim.cli_types import non_negative_int
from camsim.commands import DEFAULT_OUT, writing_to


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``analyze`` and its options to ``subparsers``; returns its parser."""
    parser = subparsers.add_parser(
        "analyze",
        help="measure patches of rendered frames: statistics, chromaticity ellipses, ΔE, SNR",
        description=(
            "Measure every patch of every frame (DNG + sidecar, or EXR) in the given files and folders: per-channel "
            "mean, variance and standard deviation in DN and e⁻, the xy chromaticity ellipse (PCA, 1 σ), ΔE_ab by "
            "the paper's 5-step procedure against the same patch at F = 1, and SNR from the model and from the "
            "pixels. Writes OUT/analysis.csv (one row per frame × patch × channel) and OUT/analysis.json."
        ),
    )
    parser.add_argument("paths", nargs="+", metavar="DIR_OR_FILES", help="frame files (.dng, .exr) or folders")
    parser.add_argument("--subtract-black", action="store_true",
                        help="subtract the black level (the sidecar's mean dark level, in DN, or --dark's mean) "
                             "before measuring; the paper does not, which drags dark colours to the black point")
    parser.add_argument("--dark", metavar="FILE", type=Path,
                        help="a dark frame (.dng or .exr) whose per-channel mean is the black level (DN); "
                             "implies --subtract-black")
    parser.add_argument("--source", choices=("dng", "exr"), default="dng",
                        help="which file of a frame to measure: 'dng' = the quantised digital numbers (default), "
                             "'exr' = the signal before quantisation")
    parser.add_argument("--matrix", choices=("paper", "paper-literal", "least-squares"), default="paper",
                        help="camera → XYZ matrix: 'paper' = Eq. 15 from the Qe (default), 'paper-literal' = Eq. 16 "
                             "as printed, 'least-squares' = fitted to the chart's patches")
    parser.add_argument("--border", metavar="PIXELS", type=non_negative_int, default=3,
                        help="pixels left out along each edge of a patch (default 3)")
    parser.add_argument("--out", metavar="DIR", type=Path, help="output folder (default outputs/analysis)")
    parser.add_argument("--quiet", "-q", action="store_true", help="no progress bar, no table")
    return parser


def run(args) -> int:
    """Carry out ``camsim analyze``; returns the exit status (0)."""
    from camsim.analysis.analyze import analyse_paths, table, write_outputs
    from camsim.analysis.patches import AnalysisSettings

    black = "dark-frame" if args.dark is not None else ("sidecar" if args.subtract_black else "none")
    settings = AnalysisSettings(border_px=args.border, black=black, matrix=args.matrix)
    out = args.out if args.out is not None else DEFAULT_OUT / "analysis"
    with writing_to(out):
        results = analyse_paths(args.paths, settings, source=args.source, dark_frame=args.dark,
                                progress=not args.quiet)
        csv_path, json_path = write_outputs(results, settings, out)
    if not args.quiet:
        print(table(results))
    print(f"analysed {len(results)} frames: {csv_path} (one row per frame × patch × channel), {json_path}")
    return 0
