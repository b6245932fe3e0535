"""``camsim render``: render a scene file into DNG, EXR and JSON frames."""

from __future__ import annotations

import argparse
from pathlib import Path

from camsim.cli_types import non_negative_int, positive_float, positive_int
from camsim.commands import DEFAULT_OUT, camera_argument
from camsim.errors import CamsimError
from camsim.sensor import CFA_PATTERNS, PRESETS, STAGES


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``render`` and its options to ``subparsers``; returns its parser."""
    parser = subparsers.add_parser(
        "render",
        help="render a scene file into DNG, EXR and JSON frames",
        description=(
            "Render SCENE.toml: one frame per illuminant and intensity factor. Each frame is written as NAME.dng "
            "(8-bit raw digital numbers), NAME.exr (float32 DN before quantisation, plus the expected 'clean' "
            "layer) and NAME.json (every parameter with its unit); OUT/manifest.json lists them all."
        ),
    )
    parser.add_argument("scene", metavar="SCENE.toml", help="scene file (see scenes/macbeth_26.toml)")
    parser.add_argument("--intensity", "-F", metavar="F", type=positive_float, nargs="+", action="extend",
                        help="intensity factor(s) F (unitless, > 0): the light is F × the scene radiance, "
                             "whose perfect white is 100 cd/m² at F = 1; F > 1 saturates. Default: the scene's list")
    parser.add_argument("--illuminant", metavar="NAME", nargs="+", action="extend",
                        help="colour-science illuminant name(s), e.g. D65 FL2 'LED-B1'. Default: the scene's list")
    parser.add_argument("--statistics", choices=("pixel", "paper"),
                        help="photon statistics: 'pixel' = exact Poisson electrons per pixel (default); "
                             "'paper' = Eq. 4 literally, Poisson photons per s·m²·sr, far smaller shot noise")
    parser.add_argument("--method", choices=("poisson", "spectral", "gaussian", "auto"),
                        help="sampling: 'poisson' = one exact draw per pixel and channel (default); 'spectral' = "
                             "per-wavelength-bin draws (N× slower, the paper's literal method); 'gaussian' = one "
                             "moment-matched normal per pixel and channel (fast, wrong at low counts); 'auto' = "
                             "per spectrum and channel the Gaussian where its KS distance to the exact law is "
                             "within --tolerance, else poisson")
    parser.add_argument("--tolerance", metavar="KS", type=positive_float,
                        help="auto's tolerance: the largest Kolmogorov–Smirnov distance (unitless, 0–1) between "
                             "a pixel value's exact law and its Gaussian replacement (default 0.01)")
    parser.add_argument("--preset", choices=sorted(PRESETS),
                        help="sensor preset: paper-table1 (Table I, all stages on; default), paper-photon-dark "
                             "(photon + dark noise only), ideal (photon noise only, output in electrons)")
    parser.add_argument("--disable", metavar="STAGE", choices=STAGES, nargs="+", action="extend", default=[],
                        help=f"switch sensor stage(s) off: {', '.join(STAGES)}")
    parser.add_argument("--cfa", choices=CFA_PATTERNS,
                        help="a Bayer colour filter array (one channel per pixel; the DNG is then a CFA DNG) instead "
                             "of the default three-chip sensor (R, G and B at every pixel)")
    parser.add_argument("--exposure", metavar="SECONDS", type=positive_float,
                        help="exposure time T in s (Table I: 1 s)")
    parser.add_argument("--camera", metavar="NAME_OR_CSV",
                        help="colour-science camera name (default 'Nikon 5100 (NPL)') or a CSV of wavelength_nm, R, G, B")
    parser.add_argument("--seed", type=non_negative_int, help="random seed (integer ≥ 0); same seed ⇒ identical files")
    parser.add_argument("--size", metavar="WxH", help="frame size in pixels for chart scenes, e.g. 4000x3000")
    parser.add_argument("--out", metavar="DIR", type=Path,
                        help="output directory (default: outputs/SCENE_NAME)")
    parser.add_argument("--workers", metavar="N", type=positive_int, help="threads per frame (default: all cores; "
                        "the output does not depend on it)")
    parser.add_argument("--preview", action="store_true",
                        help="also write an sRGB PNG of each frame (camera RGB → XYZ → sRGB, white-balanced from the "
                             "illuminant; the perfect white at F = 1 is sRGB white, so low light looks dark)")
    parser.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    return parser


def apply_overrides(scene, args):
    """``scene`` with the command line's options applied (each given option replaces the scene file's value)."""
    from camsim.chart import parse_size

    changes = {}
    if args.intensity:
        changes["intensity_factors"] = tuple(args.intensity)
    if args.illuminant:
        changes["illuminants"] = tuple(args.illuminant)
    for key in ("statistics", "method", "seed", "tolerance"):
        if getattr(args, key) is not None:
            changes[key] = getattr(args, key)
    if args.camera is not None:
        changes["camera"] = camera_argument(args.camera)
    if args.preset:
        changes["preset_name"] = args.preset
    if args.size:
        if scene.cube is not None:
            raise CamsimError("--size applies to chart scenes; a cube scene has the size of its cube")
        changes["width"], changes["height"] = parse_size(args.size)
    scene = scene.replace(**changes)
    overrides = {stage: False for stage in args.disable}
    if args.exposure is not None:
        overrides["exposure_s"] = args.exposure
    if args.cfa is not None:
        overrides["cfa"] = args.cfa
    return scene.with_sensor(**overrides) if overrides else scene


def run(args) -> int:
    """Carry out ``camsim render``; returns the exit status (0)."""
    from camsim.run import render_scene
    from camsim.scene import load_scene

    scene = apply_overrides(load_scene(args.scene), args)
    out = args.out if args.out is not None else DEFAULT_OUT / scene.name
    manifest = render_scene(scene, out, workers=args.workers, progress=not args.quiet, preview=args.preview)
    print(f"wrote {len(manifest['frames'])} frames (DNG, EXR, JSON) to {out}/ — index: {out / 'manifest.json'}")
    return 0
