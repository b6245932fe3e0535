"""``camsim develop``: develop camsim frames (DNG or EXR) into sRGB pictures through the camera ISP
(:mod:`camsim.isp`).

User errors raise :class:`camsim.core.errors.CamsimError` (printed on one line by ``camsim.cli.main``, exit 2).
"""

from __future__ import annotations

import argparse
import textwrap
from pathlib import Path

from camsim.cli.commands import DEFAULT_OUT, writing_to
from camsim.cli.types import positive_float_or

DESCRIPTION = (
    "Develop camsim frames into sRGB pictures through a camera ISP: black level off and normalised to the white "
    "level, white balance (the frame's as-shot neutral, none, or a named illuminant), demosaicing of Bayer frames "
    "(colour-demosaicing's bilinear, Malvar 2004 or Menon 2007), camera → linear sRGB colour matrix (from the "
    "camera's spectral sensitivities in the sidecar, von Kries/Bradford adaptation of the white-balance white to "
    "D65), a digital gain, and a tone curve (sRGB transfer function, a filmic curve, or linear). FRAMES are .dng "
    "files (with their .json sidecar beside them; a DNG without one is developed from its own tags: BlackLevel, "
    "WhiteLevel, CFAPattern, AsShotNeutral, ColorMatrix1), .exr files (the float values before quantisation), or "
    "folders searched recursively for committed frames (the DNG where there is one). Each frame gives OUT/STEM.png "
    "(8 or 16 bits, the record of every stage in its 'camsim:develop' text chunk, no timestamp: the same frame "
    "gives the same bytes), OUT/STEM.json (the same record), with --jpeg-quality OUT/STEM.jpg, and with "
    "--noise-report how the noise changes through each stage (OUT/STEM_noise_stages.csv and .png)."
)

EPILOG = """\
examples:
  camsim develop outputs/macbeth_26 --out outputs/developed
  camsim develop frame.dng --out developed --gain auto --bits 16
  camsim develop frames/ --out developed --demosaic menon2007 --tone filmic --jpeg-quality 92
  camsim develop outputs/macbeth_26/macbeth_26_D65_F0.01.dng --out developed --gain white --noise-report
"""


def _quality(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"JPEG quality must be an integer from 1 to 95, got {text!r}") from None
    if not 1 <= value <= 95:
        raise argparse.ArgumentTypeError(f"JPEG quality must be an integer from 1 to 95, got {text!r}")
    return value


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``develop`` sub-parser to ``subparsers`` (from ``ArgumentParser.add_subparsers``)."""
    from camsim.isp.stages import DEMOSAIC_METHODS, MATRICES, TONE_CURVES

    parser = subparsers.add_parser(
        "develop",
        help="develop frames (DNG, EXR) into sRGB PNG/JPEG through a camera ISP, every stage recorded",
        description=textwrap.fill(DESCRIPTION, width=110),
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("frames", nargs="+", metavar="FRAMES",
                        help=".dng or .exr frame files, or folders searched recursively for committed frames")
    parser.add_argument("--out", metavar="DIR", type=Path,
                        help=f"output folder (default {DEFAULT_OUT / 'developed'})")
    parser.add_argument("--white-balance", metavar="NAME", default="as-shot",
                        help="'as-shot' (default: the frame's AsShotNeutral, the perfect white under its "
                             "illuminant), 'none', or a colour-science illuminant name (e.g. D65, A, FL2)")
    parser.add_argument("--demosaic", metavar="NAME", default="malvar2004", choices=list(DEMOSAIC_METHODS),
                        help=f"demosaicing of Bayer frames: {', '.join(DEMOSAIC_METHODS)} (default malvar2004)")
    parser.add_argument("--matrix", metavar="NAME", default="camera", choices=list(MATRICES),
                        help="'camera' (default: camera → linear sRGB from the camera's spectral sensitivities and "
                             "the white-balance illuminant), 'dng' (from the DNG's ColorMatrix1, as raw converters "
                             "do) or 'none'")
    parser.add_argument("--gain", metavar="X|auto|white", default=1.0,
                        type=positive_float_or(("auto", "white"),
                                               "gain must be a positive number, 'auto' or 'white'"),
                        help="digital gain on the linear values (default 1: the white level is 1), 'auto' = 1 / F, "
                             "F the frame's intensity factor (the SID/ELD exposure ratio), or 'white': the perfect "
                             "white under the frame's light at its F is 1")
    parser.add_argument("--tone", metavar="NAME", default="srgb", choices=list(TONE_CURVES),
                        help="tone curve: srgb (default, IEC 61966-2-1), filmic (Narkowicz 2015's ACES fit, then "
                             "sRGB's), linear")
    parser.add_argument("--bits", type=int, choices=(8, 16), default=8, help="PNG bit depth (default 8)")
    parser.add_argument("--jpeg-quality", metavar="Q", type=_quality,
                        help="also write STEM.jpg at this quality (1–95; 4:4:4, no chroma subsampling)")
    parser.add_argument("--no-black", action="store_true",
                        help="do not subtract the black level (only divide by the white level)")
    parser.add_argument("--noise-report", action="store_true",
                        help="also write OUT/STEM_noise_stages.csv and .png: the noise (developed noisy minus "
                             "developed clean, same settings) after each stage — std, neighbour correlation, noise "
                             "power spectrum; needs the frame's EXR (its clean layer), beside a DNG or given")
    parser.add_argument("--quiet", "-q", action="store_true", help="no line per frame")
    return parser


def run(args) -> int:
    """Carry out ``camsim develop``; returns the exit status (0)."""
    from camsim.isp.develop import IspSettings
    from camsim.isp.files import develop_file, output_names, read_frame_to_develop
    from camsim.isp.noise import noise_layers, noise_through_isp, write_noise_report
    from camsim.render.frame_files import find_frames

    settings = IspSettings(black=not args.no_black, white_balance=args.white_balance, demosaic=args.demosaic,
                           matrix=args.matrix, gain=args.gain, tone=args.tone)
    paths = find_frames(args.frames, source="dng")
    stems = output_names(paths)
    out = args.out if args.out is not None else DEFAULT_OUT / "developed"
    frames = [read_frame_to_develop(p) for p in paths] if len(paths) == 1 else None
    with writing_to(out):
        for index, (path, stem) in enumerate(zip(paths, stems)):
            frame = frames[0] if frames is not None else read_frame_to_develop(path)
            if args.noise_report:  # read first: a frame without its clean layer fails before anything is written
                noisy, clean, facts = noise_layers(path)
            record = develop_file(frame, out, stem, settings, bits=args.bits, jpeg_quality=args.jpeg_quality)
            if args.noise_report:
                write_noise_report(noise_through_isp(noisy, clean, facts, settings), out, stem)
            if not args.quiet:
                print(f"{path} -> {out / record['files']['png']}")
    print(f"developed {len(paths)} frame(s) into {out}/")
    return 0
