"""The ``camsim`` command line. ``main(argv)`` does the work and returns an exit status; importing does nothing.

User errors (bad names, malformed files, bad values) print one line, ``camsim: error: ...``, and exit with 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from camsim.cli_types import non_negative_int, positive_float
from camsim.errors import CamsimError
from camsim.sensor import CFA_PATTERNS, PRESETS, STAGES

DEFAULT_OUT = Path("outputs")


class _UsageError(Exception):
    """A command-line usage error, reported on one line like any other user error."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # argparse would print the usage block and exit; camsim prints one line
        raise _UsageError(f"{message} (see '{self.prog} --help')")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="camsim",
        description=(
            "Physically grounded camera simulator: spectral scenes through the image-sensor model of "
            "'Image Sensor Modeling: Color Measurement at Low Light Levels' (2014) into 8-bit DNG raw, "
            "float EXR and JSON sidecar files."
        ),
        epilog="Run 'camsim render --help' for the rendering options.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    render = sub.add_parser(
        "render",
        help="render a scene file into DNG, EXR and JSON frames",
        description=(
            "Render SCENE.toml: one frame per illuminant and intensity factor. Each frame is written as NAME.dng "
            "(8-bit raw digital numbers), NAME.exr (float32 DN before quantisation, plus the expected 'clean' "
            "layer) and NAME.json (every parameter with its unit); OUT/manifest.json lists them all."
        ),
    )
    render.add_argument("scene", metavar="SCENE.toml", help="scene file (see scenes/macbeth_26.toml)")
    render.add_argument("--intensity", "-F", metavar="F", type=positive_float, nargs="+", action="extend",
                        help="intensity factor(s) F (unitless, > 0): the light is F × the scene radiance, "
                             "whose perfect white is 100 cd/m² at F = 1; F > 1 saturates. Default: the scene's list")
    render.add_argument("--illuminant", metavar="NAME", nargs="+", action="extend",
                        help="colour-science illuminant name(s), e.g. D65 FL2 'LED-B1'. Default: the scene's list")
    render.add_argument("--statistics", choices=("pixel", "paper"),
                        help="photon statistics: 'pixel' = exact Poisson electrons per pixel (default); "
                             "'paper' = Eq. 4 literally, Poisson photons per s·m²·sr, far smaller shot noise")
    render.add_argument("--method", choices=("poisson", "spectral", "gaussian", "auto"),
                        help="sampling: 'poisson' = one exact draw per pixel and channel (default); 'spectral' = "
                             "per-wavelength-bin draws (N× slower, the paper's literal method); 'gaussian' = one "
                             "moment-matched normal per pixel and channel (fast, wrong at low counts); 'auto' = "
                             "per spectrum and channel the Gaussian where its KS distance to the exact law is "
                             "within --tolerance, else poisson")
    render.add_argument("--tolerance", metavar="KS", type=positive_float,
                        help="auto's tolerance: the largest Kolmogorov–Smirnov distance (unitless, 0–1) between "
                             "a pixel value's exact law and its Gaussian replacement (default 0.01)")
    render.add_argument("--preset", choices=sorted(PRESETS),
                        help="sensor preset: paper-table1 (Table I, all stages on; default), paper-photon-dark "
                             "(photon + dark noise only), ideal (photon noise only, output in electrons)")
    render.add_argument("--disable", metavar="STAGE", choices=STAGES, nargs="+", action="extend", default=[],
                        help=f"switch sensor stage(s) off: {', '.join(STAGES)}")
    render.add_argument("--cfa", choices=CFA_PATTERNS,
                        help="a Bayer colour filter array (one channel per pixel; the DNG is then a CFA DNG) instead "
                             "of the default three-chip sensor (R, G and B at every pixel)")
    render.add_argument("--exposure", metavar="SECONDS", type=positive_float,
                        help="exposure time T in s (Table I: 1 s)")
    render.add_argument("--camera", metavar="NAME_OR_CSV",
                        help="colour-science camera name (default 'Nikon 5100 (NPL)') or a CSV of wavelength_nm, R, G, B")
    render.add_argument("--seed", type=non_negative_int, help="random seed (integer ≥ 0); same seed ⇒ identical files")
    render.add_argument("--size", metavar="WxH", help="frame size in pixels for chart scenes, e.g. 4000x3000")
    render.add_argument("--out", metavar="DIR", type=Path,
                        help="output directory (default: outputs/SCENE_NAME)")
    render.add_argument("--workers", metavar="N", type=int, help="threads per frame (default: all cores; "
                        "the output does not depend on it)")
    render.add_argument("--preview", action="store_true",
                        help="also write an sRGB PNG of each frame (camera RGB → XYZ → sRGB, white-balanced from the "
                             "illuminant; the perfect white at F = 1 is sRGB white, so low light looks dark)")
    render.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    analyze = sub.add_parser(
        "analyze",
        help="measure patches of rendered frames: statistics, chromaticity ellipses, ΔE, SNR",
        description=(
            "Measure every patch of every frame (DNG + sidecar, or EXR) in the given files and folders: per-channel "
            "mean, variance and standard deviation in DN and e⁻, the xy chromaticity ellipse (PCA, 1 σ), ΔE_ab by "
            "the paper's 5-step procedure against the same patch at F = 1, and SNR from the model and from the "
            "pixels. Writes OUT/analysis.csv (one row per frame × patch × channel) and OUT/analysis.json."
        ),
    )
    analyze.add_argument("paths", nargs="+", metavar="DIR_OR_FILES", help="frame files (.dng, .exr) or folders")
    analyze.add_argument("--subtract-black", action="store_true",
                         help="subtract the black level (the sidecar's mean dark level, in DN, or --dark's mean) "
                              "before measuring; the paper does not, which drags dark colours to the black point")
    analyze.add_argument("--dark", metavar="FILE", type=Path,
                         help="a dark frame (.dng or .exr) whose per-channel mean is the black level (DN); "
                              "implies --subtract-black")
    analyze.add_argument("--source", choices=("dng", "exr"), default="dng",
                         help="which file of a frame to measure: 'dng' = the quantised digital numbers (default), "
                              "'exr' = the signal before quantisation")
    analyze.add_argument("--matrix", choices=("paper", "paper-literal", "least-squares"), default="paper",
                         help="camera → XYZ matrix: 'paper' = Eq. 15 from the Qe (default), 'paper-literal' = Eq. 16 "
                              "as printed, 'least-squares' = fitted to the chart's patches")
    analyze.add_argument("--border", metavar="PIXELS", type=int, default=3,
                         help="pixels left out along each edge of a patch (default 3)")
    analyze.add_argument("--out", metavar="DIR", type=Path, help="output folder (default outputs/analysis)")
    analyze.add_argument("--quiet", "-q", action="store_true", help="no progress bar, no table")
    experiment = sub.add_parser(
        "experiment",
        help="reproduce the paper's experiments (scenarios I–III, SNR sensitivity) from rendered frames",
        description=(
            "Render the paper's 20 data points (13 on the convex hull of the Macbeth × illuminant chromaticities, "
            "7 inside) through the scenario's sensor at its intensity factors, under both photon statistics "
            "('paper' and 'pixel'), analyse the frames from their files, and write the numbers (CSV), the figures "
            "(PNG) and report.md, which says for each of the paper's findings whether it holds here."
        ),
    )
    experiment.add_argument("name", choices=("scenario1", "scenario2", "scenario3", "snr-sensitivity", "all"),
                            help="scenario1: ideal sensor, log10 F = 0 … −14; scenario2: photon + dark noise; "
                                 "scenario3: every stage (Table I); snr-sensitivity: ΔSNR for read +10 %%, "
                                 "dark +10 %%, quantisation off; all: each into OUT/NAME")
    experiment.add_argument("--out", metavar="DIR", type=Path,
                            help="output folder (default outputs/experiments/NAME)")
    experiment.add_argument("--size", metavar="WxH",
                            help="frame size in pixels (default 250x200 for the scenarios, about 1200 samples "
                                 "per data point; 500x400 for snr-sensitivity)")
    experiment.add_argument("--camera", metavar="NAME_OR_CSV",
                            help="camera (default the scene's, Nikon 5100 (NPL)); e.g. the paper's Sony DXC-930 "
                                 "CSV from the SFU data")
    experiment.add_argument("--seed", type=non_negative_int, default=0, help="random seed (default 0)")
    experiment.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    emva = sub.add_parser(
        "emva",
        help="simulate the EMVA 1288 measurement of the camera and analyse it with the reference implementation",
        description=(
            "Simulate the EMVA 1288 photon-transfer measurement of the configured camera (pairs of flat frames at "
            "a monochromatic 550 nm light from dark to beyond saturation, dark and bright stacks for DSNU / PRNU), "
            "analyse it with the emva1288 package and compare what the standard recovers (system gain K, temporal "
            "dark noise, quantum efficiency, saturation capacity, DSNU, PRNU) with the configuration. Writes "
            "OUT/report.md, OUT/emva.json and PNG plots."
        ),
    )
    emva.add_argument("--preset", choices=sorted(PRESETS),
                      help="sensor preset to measure (default emva-12bit: a 12-bit machine-vision-like sensor, "
                           "K = 0.4 DN/e⁻; paper-table1 shows the 8-bit, 35 e⁻/DN case, where quantisation "
                           "dominates the dark noise)")
    emva.add_argument("--out", metavar="DIR", type=Path, help="output folder (default outputs/emva)")
    emva.add_argument("--size", metavar="N", type=int, default=256,
                      help="side of the square region of interest in pixels, 16 to 4096 (default 256)")
    emva.add_argument("--seed", metavar="N", type=non_negative_int, default=0,
                      help="seed of the temporal noise (integer ≥ 0, default 0); the fixed pattern is the "
                           "sensor's own (its sensor_seed)")
    emva.add_argument("--quiet", "-q", action="store_true", help="no progress bar, no table")
    from camsim.dataset.cli import add_parser as add_dataset
    from camsim.denoise.cli import add_parser as add_denoise_eval

    add_dataset(sub)
    add_denoise_eval(sub)
    sub.add_parser("list", help="list the illuminants, cameras, reflectance sets and presets camsim knows")
    return parser


def _apply_overrides(scene, args):
    from camsim.chart import parse_size

    changes = {}
    if args.intensity:
        changes["intensity_factors"] = tuple(args.intensity)
    if args.illuminant:
        changes["illuminants"] = tuple(args.illuminant)
    for key in ("statistics", "method", "seed", "tolerance"):
        if getattr(args, key) is not None:
            changes[key] = getattr(args, key)
    if args.camera is not None:  # a CSV named on the command line is relative to the working directory
        is_csv = args.camera.lower().endswith(".csv")
        changes["camera"] = str(Path(args.camera).resolve()) if is_csv else args.camera
    if args.preset:
        changes["preset_name"] = args.preset
    if args.size:
        if scene.source.has_own_size:
            raise CamsimError("--size applies to chart scenes; a cube scene has the size of its cube")
        changes["width"], changes["height"] = parse_size(args.size)
    scene = scene.replace(**changes)
    overrides = {stage: False for stage in args.disable}
    if args.exposure is not None:
        overrides["exposure_s"] = args.exposure
    if args.cfa is not None:
        overrides["cfa"] = args.cfa
    return scene.with_sensor(**overrides) if overrides else scene


def _cmd_render(args) -> int:
    from camsim.run import render_scene
    from camsim.scene import load_scene

    scene = _apply_overrides(load_scene(args.scene), args)
    out = args.out if args.out is not None else DEFAULT_OUT / scene.name
    if args.workers is not None and args.workers < 1:
        raise CamsimError(f"--workers must be ≥ 1, got {args.workers}")
    manifest = render_scene(scene, out, workers=args.workers, progress=not args.quiet, preview=args.preview)
    print(f"wrote {len(manifest['frames'])} frames (DNG, EXR, JSON) to {out}/ — index: {out / 'manifest.json'}")
    return 0


def _cmd_analyze(args) -> int:
    from camsim.analysis.analyze import analyse_paths, table, write_outputs
    from camsim.analysis.patches import AnalysisSettings

    black = "dark-frame" if args.dark is not None else ("sidecar" if args.subtract_black else "none")
    settings = AnalysisSettings(border_px=args.border, black=black, matrix=args.matrix)
    results = analyse_paths(args.paths, settings, source=args.source, dark_frame=args.dark, progress=not args.quiet)
    out = args.out if args.out is not None else DEFAULT_OUT / "analysis"
    csv_path, json_path = write_outputs(results, settings, out)
    if not args.quiet:
        print(table(results))
    print(f"analysed {len(results)} frames: {csv_path} (one row per frame × patch × channel), {json_path}")
    return 0


def _cmd_experiment(args) -> int:
    from camsim.chart import parse_size
    from camsim.experiments.runner import Setup
    from camsim.experiments.scenarios import DEFAULT_SCENE, run_experiment

    width, height = parse_size(args.size) if args.size else (None, None)
    camera = str(Path(args.camera).resolve()) if args.camera and args.camera.lower().endswith(".csv") else args.camera
    setup = Setup(DEFAULT_SCENE, width, height, seed=args.seed, camera=camera)
    out = args.out if args.out is not None else DEFAULT_OUT / "experiments" / args.name
    done = run_experiment(args.name, out, setup, progress=not args.quiet)
    for name, findings in done.items():
        report = out / name / "report.md" if args.name == "all" else out / "report.md"
        print(f"{name}: {report}")
        for f in findings:
            marks = ", ".join(f"{s} {'holds' if v.holds else 'does not hold'}" for s, v in f.verdicts.items())
            print(f"  {f.key} {f.text}: {marks}")
    return 0


def _cmd_emva(args) -> int:
    from camsim.emva import EmvaSetup, run, write_outputs

    result = run(args.preset, EmvaSetup(size=args.size, seed=args.seed), progress=not args.quiet)
    out = args.out if args.out is not None else DEFAULT_OUT / "emva"
    paths = write_outputs(result, out)
    if not args.quiet:
        for key, row in result.comparison().items():
            ok = result.within_target(key)
            mark = "" if ok is None else ("  ok" if ok else "  outside target")
            rel = "" if row["relative_error"] is None else f"  {100 * row['relative_error']:+.2f} %"
            recovered = "—" if row["recovered"] is None else f"{row['recovered']:.5g}"
            print(f"  {key:<14} configured {row['configured']:<10.5g} recovered {recovered:<10}{rel}{mark}")
    print(f"EMVA 1288 of preset {result.measurement.preset_name}: {paths['report']}, {paths['json']}")
    return 0


def _cmd_list(args) -> int:
    from camsim.spectra import camera_names, illuminant_names, reflectance_set_names

    print("illuminants:", ", ".join(illuminant_names()))
    print("cameras:", ", ".join(camera_names()))
    print("reflectance sets:", ", ".join(reflectance_set_names()))
    print("presets:", ", ".join(PRESETS))
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit status (0 ok, 2 user error)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except _UsageError as exc:
        print(f"camsim: error: {exc}", file=sys.stderr)
        return 2
    if args.command is None:
        parser.print_help()
        return 2
    try:
        from camsim.dataset.cli import run as dataset
        from camsim.denoise.cli import run as denoise_eval

        commands = {"render": _cmd_render, "analyze": _cmd_analyze, "experiment": _cmd_experiment,
                    "dataset": dataset, "denoise-eval": denoise_eval,
                    "emva": _cmd_emva, "list": _cmd_list}
        return commands[args.command](args)
    except CamsimError as exc:
        print(f"camsim: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("camsim: interrupted; completed frames are kept, no partial file is left", file=sys.stderr)
        return 130


def main_entry() -> None:
    """Console-script entry point."""
    sys.exit(main())
