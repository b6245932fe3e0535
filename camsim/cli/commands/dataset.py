"""``camsim dataset``: render a dataset of frames (grid or random draws of parameters) with a manifest, resumably.

``run`` raises :class:`camsim.core.errors.CamsimError` for user errors, which ``camsim.cli.main`` reports on one line.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from camsim.cli.commands import DEFAULT_OUT, exr_compression_argument
from camsim.cli.types import positive_int


def add_parser(subparsers) -> argparse.ArgumentParser:
    """Add the ``dataset`` sub-command to an argparse sub-parsers object; returns its parser."""
    parser = subparsers.add_parser(
        "dataset",
        help="render a dataset of frames (grid or random draws of parameters) with a manifest, resumably",
        description=(
            "Render every frame of SPEC.toml (see scenes/denoise_small.toml): scenes (or random crops of a folder "
            "of images) × illuminants × intensity factors × exposure and sensor parameters, over a grid and/or "
            "random draws, each frame as "
            "OUT/frames/ID.dng, ID.exr (noisy R, G, B and the clean.R/G/B layer) and ID.json, and "
            "OUT/manifest.jsonl with one line per frame (every parameter, the seed, each file's size and SHA-256). "
            "A re-run renders only the frames that are not complete and verified. Frames run in parallel on "
            "this machine's cores, or on a Dask cluster with --scheduler; the files do not depend on which. "
            "With --format zarr, the frames go to one Zarr store instead, OUT/dataset.zarr: one chunked array per "
            "layer (noisy, clean, digital), the sidecars and the parameter table, for xarray and Dask. A spec's "
            "burst_frames makes each item a burst with camera motion: ID_fNNN.dng/.exr/.json per frame and the "
            "clean reference ID_ref.exr/.json."
        ),
    )
    parser.add_argument("spec", metavar="SPEC.toml", type=Path, help="dataset spec file, or the name of a built-in "
                        "spec (camsim list), e.g. denoise_small; a spec's scene can be a built-in scene's name")
    parser.add_argument("--out", metavar="DIR", type=Path, help="output folder (default outputs/SPEC_NAME)")
    parser.add_argument("--workers", metavar="N", type=positive_int,
                        help="local processes rendering frames in parallel (default: all cores; 1 = in this "
                             "process)")
    parser.add_argument("--threads", metavar="N", type=positive_int, default=1,
                        help="threads per frame, for the noise draws and the EXR compression (default 1: one "
                             "core per frame; the files do not depend on it)")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help="address of a dask.distributed scheduler, e.g. tcp://10.0.0.5:8786: one task per "
                             "frame on the cluster, whose workers need camsim installed (not a shared disk: "
                             "they send the files back)")
    parser.add_argument("--format", choices=("files", "zarr"), default="files",
                        help="files (default): OUT/frames/ID.dng, .exr, .json per frame; zarr: one Zarr store, "
                             "OUT/dataset.zarr, with arrays noisy, clean (float32) and digital (uint8/uint16) of "
                             "shape (frame, channel, y, x) (bursts: (frame, burst_frame, channel, y, x) with the "
                             "reference, homographies and start times), one chunk per frame, plus the sidecars, done "
                             "flags and the parameters (docs, guide 'Datasets for denoisers'); every frame must have "
                             "the same size")
    exr_compression_argument(parser, spec_key=True)
    parser.add_argument("--srgb", choices=("none", "png", "png16"),
                        help="also each frame's noisy and clean layers developed through one camera ISP (the same "
                             "white balance, colour matrix, gain 1/F (1 with auto exposure) and sRGB curve for "
                             "both): png = 8-bit, png16 = 16-bit, as OUT/frames/ID_srgb_noisy.png and "
                             "ID_srgb_clean.png, or the arrays srgb_noisy and srgb_clean of a Zarr store; a burst's "
                             "frames all with its reference's development, as ID_fNNN_srgb_noisy.png, "
                             "ID_fNNN_srgb_clean.png and ID_ref_srgb_clean.png (a store: srgb_reference; not bursts "
                             "of [raws] crops yet) (default: the spec's srgb, else a store's own, else none)")
    parser.add_argument("--verify", choices=("sha256", "size"), default="sha256",
                        help="how a re-run checks the files of complete frames: size and SHA-256 (default) or "
                             "size only")
    parser.add_argument("--dry-run", action="store_true",
                        help="validate the spec and list its frames (id and parameters) without rendering")
    parser.add_argument("--quiet", "-q", action="store_true", help="no progress bar, no colour-science warnings")
    return parser


def run(args) -> int:
    """Carry out ``camsim dataset``; returns the exit status (0)."""
    from camsim.dataset._pool import start_fork_server

    if args.scheduler is None and args.workers != 1 and not args.dry_run:
        start_fork_server(zarr=args.format == "zarr")  # the pool's fork server imports camsim meanwhile

    from camsim.dataset.runner import check_output_of, check_settings, run_dataset
    from camsim.dataset.spec import load_spec, plan_spec

    if args.dry_run:  # what the run checks before its first frame: the settings, then the spec and every frame
        check_settings(workers=args.workers, threads=args.threads, scheduler=args.scheduler, verify=args.verify,
                       exr_compression=args.exr_compression, output=args.format, srgb=args.srgb)
        plan = plan_spec(args.spec)
        check_output_of(plan, args.format, args.srgb or plan.srgb)
        print_plan(plan)
        return 0
    spec = load_spec(args.spec)
    if spec.axes.get("raw_file") == "raws" and "burst_frames" in spec.axes:  # bursts of real raws: their noise
        import sys

        from camsim.dataset.raws import raw_burst_warnings

        for line in raw_burst_warnings(spec.frames):
            print(f"camsim: warning: {line}", file=sys.stderr)
    out = args.out if args.out is not None else DEFAULT_OUT / spec.name
    run_dataset(spec, out, workers=args.workers, threads=args.threads, scheduler=args.scheduler,
                verify=args.verify, progress=not args.quiet, exr_compression=args.exr_compression,
                output=args.format, srgb=args.srgb)
    return 0


def print_plan(plan, write=None, chunk: int = 1000) -> None:
    """``--dry-run``: a header line, then one JSON line per frame (id, scene, repeat, the varied parameters,
    seed), written as the frames are made (``chunk`` lines at a time), so that a long spec streams.

    ``write`` defaults to ``sys.stdout.write``.
    """
    import json
    import sys

    write = write or sys.stdout.write
    varied = [name for name, how in plan.axes.items() if how != "fixed"]
    items = "bursts" if "burst_frames" in plan.axes else "frames"  # a burst spec's items (burst_frames: each's)
    write(f"dataset {plan.name}: {len(plan)} {items} of {plan.size_text}; "
          f"varied: {', '.join(f'{n} ({plan.axes[n]})' for n in varied)}\n")
    keys = [(n, "photon_statistics" if n == "statistics" else n) for n in varied]
    encode = json.JSONEncoder(ensure_ascii=False).encode
    lines = []
    for frame in plan.frames():
        shown = {"id": frame.id, "scene": frame.get("scene"), "repeat": frame.get("repeat"),
                 **{n: _value(frame, key) for n, key in keys}, "seed": frame.seed}
        lines.append(encode(shown) + "\n")
        if len(lines) == chunk:
            write("".join(lines))
            lines = []
    write("".join(lines))


def _value(frame, key: str):
    """The frame's ``key``, or None where its record has none (``burst_frames`` of a scene without a burst)."""
    try:
        return frame.get(key)
    except KeyError:
        return None
