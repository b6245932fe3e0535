"""``camsim calibrate``: estimate a camera's noise parameters from its raw dark frames and flat pairs; write a
preset."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from camsim.cli.commands import DEFAULT_OUT, writing_to
from camsim.cli.types import file_name, positive_float


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``calibrate`` and its options to ``subparsers``; returns its parser."""
    parser = subparsers.add_parser(
        "calibrate",
        help="estimate a real camera's noise parameters from its raw dark and flat frames; write a preset",
        description=(
            "Measure a camera's noise from raw files (DNG or any raw LibRaw reads): the black level, the system "
            "gain K (DN/e⁻) by the photon transfer method, the read noise (its σ and its Tukey λ by the "
            "probability-plot correlation, as the ELD noise model), row noise, DSNU and PRNU, per colour plane. "
            "Shoot at least 2 (better 8–16) dark frames with the lens capped and pairs of flat frames of equal "
            "exposure at 3 or more levels (better 5–8, from about 5 % to 70 % of the white level), all at one "
            "ISO. Writes OUT/preset.toml (for --preset PATH.toml), OUT/calibration.json (every estimate with its "
            "standard error), OUT/report.md, the plots ptc.png, probability_plot.png and row_spectrum.png, and the "
            "dark fixed pattern's maps dark_shading.npy (e⁻) and hot_pixels.npy (e⁻/s), which preset.toml names "
            "where they hold a pattern (--no-maps: never)."
        ),
    )
    parser.add_argument("--dark", metavar="FILE", nargs="+", action="extend", required=True,
                        help="dark frames (at least 2; lens capped, same exposure and ISO as the flats)")
    parser.add_argument("--flat", metavar="FILE", nargs="+", action="extend", required=True,
                        help="flat frames: pairs of equal exposure at 3 or more levels, in any order (paired by "
                             "their mean level); none may saturate")
    parser.add_argument("--out", metavar="DIR", type=Path, help="output folder (default outputs/calibration)")
    parser.add_argument("--iso", metavar="N", type=positive_float,
                        help="the ISO the preset's values are for (default: the files' ISO, else 100)")
    parser.add_argument("--name", metavar="NAME", type=file_name("NAME"),
                        help="the preset's name (default: the camera model in the files, else 'calibrated'): a "
                             "safe file name, as every name camsim reads (no / or \\, no leading '.', printable, at "
                             "most 128 bytes)")
    parser.add_argument("--no-maps", dest="maps", action="store_false",
                        help="write dark_shading.npy and hot_pixels.npy but do not name them in preset.toml: a "
                             "preset that names them renders frames of the calibrated size only; without them it "
                             "renders the DSNU and column FPN as drawn patterns of the measured σ, and no hot pixels")
    parser.add_argument("--quiet", "-q", action="store_true",
                        help="no progress bars, no summary, no colour-science warnings")
    return parser


def run(args) -> int:
    """Carry out ``camsim calibrate``; returns the exit status (0)."""
    from camsim.calibration import calibrate, write_outputs

    out = args.out if args.out is not None else DEFAULT_OUT / "calibration"
    with writing_to(out):
        cal = calibrate(args.dark, args.flat, iso=args.iso, name=args.name, progress=not args.quiet)
        paths = write_outputs(cal, out, maps=args.maps)
    for warning in cal.warnings:
        print(f"camsim: warning: {warning}", file=sys.stderr)
    if not args.quiet:
        k, read = cal.k_dn_per_e, cal.read_dn
        print(f"  K            {k.value:.5g} ± {k.standard_error:.2g} DN/e⁻")
        print(f"  black level  {cal.black_dn.value:.4f} DN (pedestal {cal.pedestal_dn})")
        print(f"  read noise   {read.value:.4g} DN = {cal.read_e.value:.4g} e⁻, Tukey λ {cal.tukey_lambda.value:+.3f} "
              f"({cal.read_noise_model})")
        print(f"  row noise    {cal.row_dn.value:.4g} DN   DSNU {cal.dsnu_dn.value:.4g} DN   "
              f"PRNU {cal.prnu_percent.value:.3g} %")
        fx = cal.effects
        if fx is not None:
            print(f"  dark shading {fx.shading_rms_e.value:.4g} e⁻ RMS   hot pixels {fx.hot_count}   column FPN "
                  f"{fx.column_fpn_dn.value:.3g} DN   black-level error {fx.black_level_error_dn.value:.3g} DN")
    print(f"calibrated {cal.name} at ISO {cal.iso:g}: {paths['preset']}, {paths['report']}")
    return 0
