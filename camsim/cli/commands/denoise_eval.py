"""``camsim denoise-eval``: score denoisers on rendered frames against the clean layer (PSNR, SSIM, colour bias,
noise ellipses, ΔE), per light level.

User errors raise :class:`camsim.core.errors.CamsimError` (printed on one line by ``camsim.cli.main``, exit 2).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import textwrap
from pathlib import Path

from camsim.cli.commands import DEFAULT_OUT, writing_to
from camsim.cli.types import non_negative_int, positive_float, positive_float_or
from camsim.core.errors import CamsimError

#: Longest default output folder name (the denoisers' names joined by '+'); beyond it, "comparison".
MAX_DIR_NAME = 80

DESCRIPTION = (
    "Run one or more denoisers on every noisy frame of a dataset — camsim EXR frames (layer noisy.R/G/B = the noisy "
    "DN, layer clean.R/G/B = their expected value, header camsim:metadata = the sidecar) found recursively in "
    "DATASET_DIR — and score each against the clean layer: PSNR and SSIM (scikit-image), and per patch the "
    "chromaticity bias of the patch mean, the chromaticity-noise ellipse before and after, and ΔE_ab (the paper's "
    "5-step procedure) against the same patch at F = 1; per intensity factor F. Every frame, chart or not, also "
    "gets a chart-free colour score: the mean CIEDE2000 of every pixel against the clean layer (CIELAB against the "
    "perfect white at the frame's F). Writes OUT/frames.csv, OUT/patches.csv, OUT/summary.csv, OUT/bands.csv, PNG "
    "plots (crops per band of F among them), OUT/summary.json and OUT/report.md, which states per half-decade band "
    "of F down to which light level each denoiser preserves detail (mean SSIM ≥ --min-ssim) and colour (mean ΔE00 ≤ "
    "--max-delta-e00), and, with a chart and an F = 1 frame, down to which it preserves the chart's colour "
    "(mean ΔE ≤ --max-delta-e and mean chromaticity bias ≤ --max-bias, no patch colour undefined). Bayer (CFA) "
    "frames (layer noisy.CFA, e.g. a dataset of the sony-a7s2 preset) are denoised as raw denoisers take them — the "
    "mosaic black-subtracted and normalised to the white level, packed R, G1, G2, B at half resolution (the SID/ELD "
    "convention; --bayer-input mosaic: unpacked) — and scored in the raw domain (PSNR and SSIM per packed plane and "
    "overall, data range 1) and after camsim's ISP (noisy, denoised and clean each developed alike: white balance as "
    "shot, the camera matrix, --isp-gain, sRGB; PSNR, SSIM and mean ΔE00 against the developed clean frame), which "
    "give their detail and colour verdicts; the chart's patch quantities are three-chip only."
)

EPILOG = """\
what a denoiser gets (and must return: an array of the same shape, finite numbers; float32 given):
  three-chip frame          a (H, W, 3) float32 array in DN (R, G, B last; the EXR's noisy values before
                            quantisation, black level included); sigma_dn: (3,) per channel, in DN
  Bayer frame, packed       a (H/2, W/2, 4) float32 array: the mosaic black-subtracted and divided by
  (default)                 white - black (0 = black, 1 = the white level; not clipped), planes
                            R, G1, G2, B last whatever the pattern (G1: the green on R's row);
                            sigma_dn: (4,) per plane, in that normalised unit
  Bayer frame, mosaic       (--bayer-input mosaic; your denoisers only) the same values as a (H, W) float32
                            mosaic in the frame's own pattern; sigma_dn: (4,) per plane R, G1, G2, B
  the built-ins always get the packed planes: identity, wavelet and tv work on each plane, nl-means on the
  four planes as channels of one image, bm3d on each plane (grey BM3D, its own sigma)

denoisers (--denoiser, repeatable; each gets the noisy frame as above and the noise sigma per channel
estimated blindly from the frame itself):
  identity                  the control: returns its input (scores = the noisy baseline)
  nl-means                  scikit-image non-local means (fast mode, h = 0.8 sigma)
  wavelet                   wavelet shrinkage (BayesShrink, soft, Haar), scikit-image's algorithm
  tv                        scikit-image total variation (Chambolle, weight = 1 sigma)
  bm3d                      BM3D (PyPI bm3d, bm3d_rgb, installed with camsim; free for non-commercial use),
                            given the sensor model's sigma per channel from the sidecar (it has no blind mode)
  MODULE:FUNCTION           your Python function, e.g. mypkg.filters:denoise or path/to/file.py:denoise
                            (the current directory is on sys.path); called as FUNCTION(image), or
                            FUNCTION(image, sigma_dn=...) if it has a parameter named sigma_dn; must return an
                            array of the same shape
  'cmd:PROGRAM ARGS...'     a program run once per frame (no shell; split like a POSIX shell would), in which
                            {input} is replaced by the path of an EXR holding the noisy frame (float32 channels
                            R, G, B in DN; a Bayer frame's R, G1, G2, B at half resolution, or with --bayer-input
                            mosaic one channel CFA, normalised; header camsim:denoise_sigma_dn = the estimated
                            sigma as JSON) and {output} by the path of the EXR it must write (the same channels,
                            same size); a non-zero exit status stops the run with the program's stderr

examples:
  camsim denoise-eval outputs/macbeth_26 --denoiser nl-means
  camsim denoise-eval outputs/a7s2 -d wavelet -d mypkg.raw:denoise_packed       # a Bayer dataset
  camsim denoise-eval frames/ -d identity -d nl-means -d wavelet -d tv --out outputs/denoise-eval/all
  camsim denoise-eval frames/ -d mypkg.filters:denoise
  camsim denoise-eval frames/ -d 'cmd:python my_denoiser.py --in {input} --out {output}'
"""


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``denoise-eval`` sub-parser to ``subparsers`` (from ``ArgumentParser.add_subparsers``)."""
    parser = subparsers.add_parser(
        "denoise-eval",
        help="score denoisers on rendered frames against the clean layer: PSNR, SSIM, colour bias, ellipses, ΔE",
        description=textwrap.fill(DESCRIPTION, width=110),  # pre-wrapped: the formatter keeps the epilog's layout
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("dataset", nargs="+", metavar="DATASET_DIR",
                        help="folder(s) searched recursively for camsim .exr frames (or .exr files)")
    parser.add_argument("--denoiser", "-d", metavar="NAME_OR_TARGET", action="append", required=True,
                        help="a built-in (identity, nl-means, wavelet, tv, bm3d), MODULE:FUNCTION or "
                             "'cmd:PROGRAM ARGS... {input} {output}' (see below); repeat to compare several")
    parser.add_argument("--out", metavar="DIR", type=Path,
                        help="output folder (default outputs/denoise-eval/NAME, NAME the denoiser's, or the "
                             "denoisers' joined by '+')")
    parser.add_argument("--border", metavar="PIXELS", type=non_negative_int, default=3,
                        help="pixels left out along each edge of a patch (default 3)")
    parser.add_argument("--keep-black", action="store_true",
                        help="do not subtract the sidecar's black level (mean DN of an unlit pixel) before the colour "
                             "quantities, as the paper; by default it is subtracted, so that they measure the "
                             "denoiser and not the dark current's drag toward the camera black point (three-chip "
                             "frames; a Bayer frame is always black-subtracted and normalised)")
    parser.add_argument("--max-delta-e", metavar="DE", type=positive_float, default=3.0,
                        help="criterion: largest mean ΔE_ab at which colour counts as preserved (default 3)")
    parser.add_argument("--max-bias", metavar="DXY", type=positive_float, default=0.005,
                        help="criterion: largest mean chromaticity bias |Δxy| of patch means at which colour counts "
                             "as preserved (default 0.005)")
    parser.add_argument("--min-ssim", metavar="SSIM", type=positive_float, default=0.8,
                        help="criterion: smallest mean SSIM against the clean layer at which detail counts as "
                             "preserved in a band of F (default 0.8)")
    parser.add_argument("--max-delta-e00", metavar="DE00", type=positive_float, default=5.0,
                        help="criterion: largest mean ΔE00 against the clean layer (chart-free, every pixel) at "
                             "which colour counts as preserved in a band of F (default 5)")
    parser.add_argument("--bayer-input", choices=("packed", "mosaic"), default="packed",
                        help="what your denoisers (MODULE:FUNCTION, cmd:) get for a Bayer frame: 'packed' (default) "
                             "the normalised planes R, G1, G2, B as a (H/2, W/2, 4) array, 'mosaic' the normalised "
                             "(H, W) mosaic; the built-ins always get the packed planes")
    parser.add_argument("--isp-gain", metavar="white|auto|X", default="white",
                        type=positive_float_or(("white", "auto"), "expected white, auto or a positive number"),
                        help="the gain with which Bayer frames are developed for the scores after the ISP: 'white' "
                             "(default) maps the perfect white under the frame's light at its F to 1 (exposed for "
                             "its light), 'auto' is 1/F (as at F = 1: clips wherever F = 1 would pass the white "
                             "level), a number a fixed gain")
    parser.add_argument("--timeout", metavar="SECONDS", type=positive_float,
                        help="time limit per frame for a 'cmd:' denoiser (default none)")
    parser.add_argument("--quiet", "-q", action="store_true", help="no progress bar, no colour-science warnings")
    return parser


def _unique_names(denoisers):
    seen, out = {}, []
    targets = [d.target for d in denoisers]
    for target in targets:
        if targets.count(target) > 1:
            raise CamsimError(f"denoiser {target!r} is given more than once")
    for d in denoisers:
        n = seen.get(d.name, 0) + 1
        seen[d.name] = n
        out.append(d if n == 1 else dataclasses.replace(d, name=f"{d.name}-{n}"))
    return out


def default_out(denoisers) -> Path:
    """``outputs/denoise-eval/NAME``, NAME the denoisers' names joined by '+' (or "comparison" if too long)."""
    name = "+".join(d.name for d in denoisers)
    return DEFAULT_OUT / "denoise-eval" / (name if len(name) <= MAX_DIR_NAME else "comparison")


def run(args) -> int:
    """Handle ``camsim denoise-eval``; returns the exit status (0). User errors raise CamsimError."""
    from camsim.denoise.denoisers import resolve_denoiser
    from camsim.denoise.evaluate import EvalSettings, evaluate
    from camsim.denoise.report import band_verdict_sentence, verdict_sentence, write_outputs
    from camsim.denoise.summary import NOISY, Criterion

    denoisers = _unique_names([resolve_denoiser(t, timeout_s=args.timeout) for t in args.denoiser])
    settings = EvalSettings(border_px=args.border, subtract_black=not args.keep_black, bayer_input=args.bayer_input,
                            isp_gain=args.isp_gain,
                            criterion=Criterion(args.max_delta_e, args.max_bias, args.min_ssim,
                                                args.max_delta_e00))
    out = args.out if args.out is not None else default_out(denoisers)
    with writing_to(out):
        evaluation = evaluate(args.dataset, denoisers, settings, progress=not args.quiet)
        paths = write_outputs(evaluation, out)
    n = len(evaluation.dataset.frames)
    print(f"scored {len(denoisers)} denoiser(s) on {n} frame(s); criterion: {settings.criterion.band_text()}")
    for name in [*(d.name for d in denoisers), NOISY]:
        for aspect in ("detail", "colour"):
            print(f"  {band_verdict_sentence(evaluation, name, aspect).replace('**', '')}")
        if name != NOISY:
            print(f"    [{evaluation.seconds.get(name, 0.0):.1f} s, "
                  f"{evaluation.seconds.get(name, 0.0) / n:.3g} s/frame]")
    if any(v["status"] != "undetermined" for v in evaluation.verdicts.values()) and evaluation.patch_rows:
        print(f"chart (criterion: {settings.criterion.text()}):")
        for name in [*(d.name for d in denoisers), NOISY]:
            print(f"  {verdict_sentence(evaluation, name).replace('**', '')}")
    from camsim.denoise.frames import UNCOMMITTED

    uncommitted = [s["file"] for s in evaluation.dataset.skipped if s["reason"] == UNCOMMITTED]
    if uncommitted:
        shown = ", ".join(uncommitted[:5]) + (" …" if len(uncommitted) > 5 else "")
        print(f"camsim: warning: ignored {len(uncommitted)} uncommitted frame file(s) (no sidecar claims them): "
              f"{shown}", file=sys.stderr)
    if evaluation.dataset.skipped:
        print(f"skipped {len(evaluation.dataset.skipped)} file(s): listed, with the reason, in {paths['report']}")
    print(f"wrote {paths['report']}, {paths['summary']}, {paths['frames']}, {paths['patches']} and plots to {out}/")
    return 0
