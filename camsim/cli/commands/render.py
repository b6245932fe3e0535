"""``camsim render``: render a scene file into DNG, EXR and JSON frames."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from camsim.cli.commands import DEFAULT_OUT, camera_argument, exr_compression_argument, preset_argument
from camsim.cli.types import (
    exposure_setting,
    optics_setting,
    positive_float,
    positive_int,
    schema_value,
    sensor_setting,
)
from camsim.core.errors import CamsimError
from camsim.methods import METHOD_NAMES, METHODS
from camsim.optics.params import OPTICS_PARAMS
from camsim.render.backends import DEVICES
from camsim.render.estimate import CONFIRM_BYTES, CONFIRM_FRAMES
from camsim.scene.scene_file import RENDER_PARAMS
from camsim.sensor.params import SENSOR_PARAMS, STAGES

_RENDER = {p.name: p for p in RENDER_PARAMS}
_SENSOR = {p.name: p for p in SENSOR_PARAMS}


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add ``render`` and its options to ``subparsers``; returns its parser."""
    parser = subparsers.add_parser(
        "render",
        help="render a scene file into DNG, EXR and JSON frames",
        description=(
            "Render SCENE.toml: one frame per illuminant and intensity factor. Each frame is written as NAME.dng "
            "(the raw digital numbers at the sensor's bit depth: 8-bit for paper-table1 and paper-photon-dark, 12 "
            "for emva-12bit, 10 to 16 for the camera presets (camsim list), or --sensor bits=N; no DNG when "
            "quantisation is off, e.g. --preset ideal), NAME.exr (float32 DN before "
            "quantisation, plus the expected 'clean' layer) and NAME.json (every parameter with its unit); "
            "OUT/manifest.json lists them all. A scene file with a [raw] table renders a real camera's raw file "
            "instead (its own light: one frame per intensity factor, NAME_as-shot_F…; the docs' guide 'Real raws "
            "in')."
        ),
    )
    parser.add_argument("scene", metavar="SCENE.toml", help="scene file (see scenes/macbeth_26.toml) or the name of "
                        "a built-in scene (camsim list), e.g. macbeth_26")
    parser.add_argument("--intensity", "-F", metavar="F", type=positive_float, nargs="+", action="extend",
                        help="intensity factor(s) F (unitless, > 0): the light is F × the scene radiance, "
                             "whose perfect white is 100 cd/m² at F = 1; F > 1 saturates. Default: the scene's list")
    parser.add_argument("--illuminant", metavar="NAME", nargs="+", action="extend",
                        help="colour-science illuminant name(s), e.g. D65 FL2 'LED-B1'. Default: the scene's list")
    parser.add_argument("--statistics", choices=_RENDER["statistics"].choices,
                        help=f"{_RENDER['statistics'].doc} (default pixel)")
    parser.add_argument("--method", choices=METHOD_NAMES,
                        help="sampling: " + "; ".join(f"'{m.name}' = {m.summary}" for m in METHODS.values()))
    parser.add_argument("--tolerance", metavar="KS", type=schema_value(_RENDER["tolerance"]),
                        help=f"{_RENDER['tolerance'].doc} (unitless, 0–1; default {_RENDER['tolerance'].default})")
    parser.add_argument("--preset", metavar="NAME|PATH.toml",
                        help="sensor preset: paper-table1 (Table I, all stages on; default), paper-photon-dark "
                             "(photon + dark noise only), ideal (photon noise only, output in electrons), "
                             "emva-12bit (a 12-bit machine-vision-like sensor); a real camera (camsim list: "
                             "sony-a7s2, nikon-d850, canon-eos-5d4, …, with --iso); or a camera preset file written "
                             "by camsim calibrate")
    parser.add_argument("--iso", metavar="ISO", type=positive_float,
                        help="ISO of a camera preset (default: ISO 100 where published); between published ISO "
                             "points the figures are interpolated (docs, guide "
                             "'Characterising and calibrating a camera')")
    parser.add_argument("--sensor", metavar="NAME=VALUE", type=sensor_setting, action="append", default=[],
                        help="set any sensor parameter, after the preset and the scene file (repeatable; VALUE as "
                             "in a scene file: 2.5, [1, 2, 3], true, RGGB, none): "
                             + "; ".join(p.help_text() for p in SENSOR_PARAMS).replace("%", "%%"))
    parser.add_argument("--optics", metavar="NAME=VALUE", type=optics_setting, action="append", default=[],
                        help="set a key of the scene's [optics] table, after the scene file (repeatable; the first "
                             "one adds an [optics] table with its defaults to a scene without one; VALUE as in a "
                             "scene file): " + "; ".join(p.help_text() for p in OPTICS_PARAMS).replace("%", "%%")
                             + "; relative_illumination: [[angle_deg, value], …] with vignetting = table")
    parser.add_argument("--disable", metavar="STAGE", choices=STAGES, nargs="+", action="extend", default=[],
                        help=f"switch sensor stage(s) off: {', '.join(STAGES)}")
    parser.add_argument("--cfa", choices=_SENSOR["cfa"].choices,
                        help="a Bayer colour filter array (one channel per pixel; the DNG is then a CFA DNG) instead "
                             "of the default three-chip sensor (R, G and B at every pixel)")
    parser.add_argument("--exposure", metavar="SECONDS|auto", type=exposure_setting(_SENSOR["exposure_s"]),
                        help="exposure time T in s for every frame (Table I: 1 s), or 'auto': each frame's T chosen "
                             "so that the perfect white under its illuminant, at its F, reaches --exposure-target "
                             "electrons in the strongest channel (dark current scales with T; the camera's Qe "
                             "never changes)")
    parser.add_argument("--exposure-target", metavar="E", type=schema_value(_RENDER["exposure_target_e"]),
                        help=f"{_RENDER['exposure_target_e'].doc} (e⁻; default "
                             f"{_RENDER['exposure_target_e'].default:g})")
    parser.add_argument("--exposure-max", metavar="SECONDS", type=schema_value(_RENDER["exposure_max_s"]),
                        help=f"{_RENDER['exposure_max_s'].doc} (s)")
    parser.add_argument("--camera", metavar="NAME_OR_CSV",
                        help="colour-science camera name (default 'Nikon 5100 (NPL)') or a CSV of "
                             "wavelength_nm, R, G, B")
    parser.add_argument("--seed", type=schema_value(_RENDER["seed"]), help="random seed (integer ≥ 0); same seed ⇒ "
                        "identical files")
    parser.add_argument("--size", metavar="WxH", help="frame size in pixels for chart scenes, e.g. 4000x3000")
    parser.add_argument("--out", metavar="DIR", type=Path,
                        help="output directory (default: outputs/SCENE_NAME)")
    parser.add_argument("--max-megapixels", metavar="MP", type=positive_float,
                        help="the largest frame to render, in megapixels (an image's or a cube's from its file's "
                             "header), whatever the memory free; default: what fits the memory free now (the "
                             "smaller of the free physical memory and the room under ulimit -v), at about 45 bytes a "
                             "pixel, and 185 more a distinct colour of an image; camsim's own limit of 200 "
                             "megapixels stays")
    parser.add_argument("--workers", metavar="N", type=positive_int, help="threads per frame (default: all cores; "
                        "the output does not depend on it)")
    parser.add_argument("--device", choices=DEVICES, default="cpu",
                        help="where frames are drawn: cpu (default; every method and statistics) or cuda (an NVIDIA "
                             "GPU through CuPy, the optional extra 'gpu': pip install '.[gpu]' in camsim's "
                             "folder); on "
                             "cuda every pixel is drawn from its exact law (poisson; table, gaussian and auto map to "
                             "it), pixel statistics only, and the sidecar records the device. The same seed, device "
                             "and library give the same files; CPU and GPU agree in distribution, not in bits")
    exr_compression_argument(parser)
    parser.add_argument("--format", choices=("files", "zarr"), default="files",
                        help="files (default): NAME.dng, .exr, .json per frame; zarr: a scene with a [sequence] "
                             "as one Zarr store per illuminant and F, OUT/NAME.zarr, with arrays noisy, clean, "
                             "digital (frame, channel, y, x), reference (channel, y, x), time_s, homography "
                             "(frame, 3, 3) and the sidecars as JSON, one chunk per frame per layer, renamed into "
                             "place when complete (docs, guide 'Rendering')")
    parser.add_argument("--preview", action="store_true",
                        help="also write an sRGB PNG of each frame (camera RGB → XYZ → sRGB, white-balanced from the "
                             "illuminant; the perfect white at F = 1 is sRGB white, so low light looks dark)")
    parser.add_argument("--yes", "-y", action="store_true",
                        help=f"render even when the scene asks for more than {CONFIRM_FRAMES} frames or "
                             f"{CONFIRM_BYTES / 1e9:g} GB, or more than the output folder's free space "
                             "(without it such a render is refused before it starts: the command says up front "
                             "how many frames and bytes it writes)")
    parser.add_argument("--quiet", "-q", action="store_true", help="no progress bar, no colour-science warnings")
    return parser


def apply_overrides(scene, args):
    """``scene`` with the command line's options applied (each given option replaces the scene file's value)."""
    from camsim.scene.chart import parse_size

    changes = {}
    if args.intensity:
        changes["intensity_factors"] = tuple(args.intensity)
    if args.illuminant:
        changes["illuminants"] = tuple(args.illuminant)
    for key in ("statistics", "method", "seed", "tolerance"):
        if getattr(args, key) is not None:
            changes[key] = getattr(args, key)
    if args.exposure is not None:
        changes["exposure"] = "auto" if args.exposure == "auto" else "fixed"
    if args.exposure_target is not None:
        changes["exposure_target_e"] = args.exposure_target
    if args.exposure_max is not None:
        changes["exposure_max_s"] = args.exposure_max
    if args.camera is not None:
        changes["camera"] = camera_argument(args.camera)
    if args.preset:
        changes["preset_name"] = preset_argument(args.preset)
    if args.iso is not None:
        changes["iso"] = args.iso
    if args.size:
        if scene.source.has_own_size:
            raise CamsimError("--size applies to chart and target scenes; a cube, image or raw scene has a size of its "
                              "own (an image's can be set with [image] size = [width, height], a raw's with [raw] "
                              "crop = [x, y, width, height])")
        changes["width"], changes["height"] = parse_size(args.size)
    if getattr(args, "optics", None):
        changes["optics"] = optics_overrides(scene.optics, args.optics)
    scene = scene.replace(**changes)
    overrides = sensor_overrides(args)
    return scene.with_sensor(**overrides) if overrides else scene


def optics_overrides(optics, settings):
    """The scene's ``[optics]`` (or, where it has none, the table's defaults) with the ``--optics NAME=VALUE``
    settings in order (a later one wins), checked as a scene file's table is."""
    import dataclasses

    from camsim.optics.params import OpticsParams, parse_optics

    base = optics if optics is not None else OpticsParams()
    table = {f.name: getattr(base, f.name) for f in dataclasses.fields(base)}
    if table["relative_illumination"] is None:
        del table["relative_illumination"]
    table["lateral_ca"] = list(table["lateral_ca"])
    given = dict(settings)
    if "relative_illumination" not in given and given.get("vignetting", table["vignetting"]) != "table":
        table.pop("relative_illumination", None)  # the scene's table, left behind by another vignetting
    return parse_optics(table | given)


def sensor_overrides(args) -> dict:
    """The sensor parameters set on the command line: ``--disable``, ``--exposure``, ``--cfa``, then every
    ``--sensor NAME=VALUE`` in order (a later setting wins)."""
    overrides = {stage: False for stage in args.disable}
    if args.exposure is not None and args.exposure != "auto":
        overrides["exposure_s"] = args.exposure
    if args.cfa is not None:
        overrides["cfa"] = args.cfa
    overrides.update(args.sensor)
    return overrides


def _warn_clear_of_the_bar(line: str) -> None:
    """One warning line on stderr, clear of the progress bar (an image's colours outside the recovery's gamut)."""
    from tqdm import tqdm

    tqdm.write(f"camsim: warning: {line}", file=sys.stderr)


def run(args) -> int:
    """Carry out ``camsim render``; returns the exit status (0).

    Before anything is written, every frame is checked (:func:`camsim.render.run.scene_warnings`: a frame that cannot
    be drawn is a :class:`CamsimError`) and the warnings of valid but dark-saturated frames go to stderr, one line
    each, ``camsim: warning: ...``.
    """
    from camsim.render.run import check_scene, render_scene, scene_warnings
    from camsim.scene.scene_file import load_scene

    scene = apply_overrides(load_scene(args.scene), args)
    check_scene(scene)  # names and sizes (a DNG's 22 x 22 minimum, an image's own size too): before any work
    from camsim.render.frame_memory import check_scene_memory

    check_scene_memory(scene, getattr(args, "max_megapixels", None))  # from the header, before a pixel is decoded
    out = args.out if args.out is not None else DEFAULT_OUT / scene.name
    from camsim.render.estimate import check_render_size, estimate_render

    estimate = estimate_render(scene, preview=args.preview)  # before each frame is checked: there may be thousands
    check_render_size(estimate, out, confirmed=args.yes)
    device = getattr(args, "device", "cpu")
    if device != "cpu":  # one line and exit 2 before anything is written: no CuPy, no GPU, a method it cannot draw
        from camsim.render.backends import check_device, device_method

        drawn = device_method(scene.method, scene.statistics)
        check_device(device)
        if drawn != scene.method:
            print(f"camsim: warning: --device {device} draws every pixel from its exact law: method {scene.method} "
                  f"is rendered as {drawn} (the sidecar records method_requested)", file=sys.stderr)
    output = getattr(args, "format", "files")
    if output == "zarr":  # before any work: what a sequence store cannot hold
        if scene.sequence is None:
            raise CamsimError("--format zarr writes a sequence as one array: the scene needs a [sequence] table "
                              "(other scenes are written as files)")
        if args.preview or device != "cpu":
            raise CamsimError("a sequence's frames are drawn per pixel on the CPU and have no preview")
    for warning in scene_warnings(scene):
        print(f"camsim: warning: {warning}", file=sys.stderr)
    if not args.quiet:  # once the scene's checks are past, so that a refusal stays the one line printed
        print(f"camsim render: {estimate.text()}, to {out}/", file=sys.stderr)
    if output == "zarr":
        from camsim.dataset.sequence_store import render_sequence_store

        stores = render_sequence_store(scene, out, workers=args.workers, progress=not args.quiet)
        print(f"wrote {len(stores)} sequence store{'' if len(stores) == 1 else 's'} of "
              f"{_frames(scene.sequence.frames)} and a reference each to {out}/: "
              + ", ".join(p.name for p in stores))
        return 0
    manifest = render_scene(scene, out, workers=args.workers, progress=not args.quiet, preview=args.preview,
                            device=device, exr_compression=args.exr_compression,
                            warn=_warn_clear_of_the_bar)  # camsim's own warnings stay with -q
    print(written_summary(scene, manifest, out))
    return 0


#: The kinds of file a frame can have, in the order the summary names them.
FILE_KINDS = {"dng": "DNG", "xmp": "darktable XMP", "exr": "EXR", "json": "JSON", "png": "PNG", "mask": "mask PNG"}


def _frames(n: int) -> str:
    return f"{n} frame{'' if n == 1 else 's'}"


def written_summary(scene, manifest: dict, out: Path) -> str:
    """The line ``camsim render`` ends with: how many frames it wrote, which kinds of file (from the manifest:
    no DNG when quantisation is off), where, and how many frames of earlier runs the folder's index also lists.

    Parameters
    ----------
    scene : camsim.scene.scene_file.Scene
        The scene as rendered (its illuminants × intensity factors are this run's frames).
    manifest : dict
        :func:`camsim.render.run.render_scene`'s manifest of the folder (this run's frames and earlier ones).
    out : pathlib.Path
        The output folder.

    Returns
    -------
    str
        E.g. ``wrote 1 frame (EXR, JSON; no DNG: quantisation is off) to OUT/ — index: OUT/manifest.json``.
    """
    from camsim.render.frame_files import frame_stem

    stems = {frame_stem(scene.name, ill, f) for ill in scene.illuminants for f in scene.intensity_factors}
    if getattr(scene, "sequence", None) is not None:  # a sequence's frames STEM_fNNN (camsim.render.sequence)
        from camsim.render.sequence import frame_digits

        digits = frame_digits(scene.sequence.frames)
        refs = {f"{stem}_ref" for stem in stems}  # each illuminant × F's reference: listed, not counted as a frame
        stems = {f"{stem}_f{i:0{digits}d}" for stem in stems for i in range(scene.sequence.frames)}
    else:
        refs = set()
    kinds = set()
    for frame in manifest["frames"]:
        files = frame.get("files", {})
        if files.get("json") and Path(files["json"]).stem in stems:
            kinds.update(kind for kind, name in files.items() if name)
    names = [label for kind, label in FILE_KINDS.items() if kind in kinds]
    without_dng = "" if "dng" in kinds else "; no DNG: quantisation is off"
    earlier = len(manifest["frames"]) - len(stems) - len(refs)
    return (f"wrote {_frames(len(stems))} ({', '.join(names)}{without_dng}) to {out}/ — index: "
            f"{out / 'manifest.json'}" + (f" (with {_frames(earlier)} of earlier runs)" if earlier > 0 else ""))
