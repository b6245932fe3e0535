"""Frames per second of ``camsim dataset`` for 1-megapixel frames, serial and on both cores; with ``--baseline``,
against an earlier checkout in the same run; and the Zarr store's figures.

The dataset: the ColorChecker of ``scenes/macbeth_26.toml`` at 1152 × 864 (0.995 MP), the ``emva-12bit`` sensor
(12-bit, DSNU and PRNU on; ``--preset`` to change), method ``poisson``, 3 illuminants × ``--frames / 3`` random draws of
F (log-uniform 1e-3 … 1) and read noise (uniform 1.5 … 6 e⁻); every frame written as DNG + EXR + JSON and recorded
(SHA-256) in the manifest.

Configurations, each run as a fresh ``camsim dataset``-like process (as a user would run it), into its own folder:

* ``serial``: ``--workers 1`` (one process, one thread per frame: one core);
* ``threads2``: ``--workers 1 --threads 2`` (one process, each frame's noise draws and EXR compression on 2
  threads);
* ``processes2``: ``--workers 2`` (two processes, one frame each at a time);
* ``zarr2``: ``--workers 2 --format zarr`` (the same frames into one Zarr store: noisy, clean and digital
  arrays, sidecars, parameter table);
* with ``--baseline DIR`` (a checkout of an earlier camsim, e.g. ``git worktree add /tmp/base <commit>``):
  ``before_processes2``, ``--workers 2`` with that checkout's code (``PYTHONPATH=DIR``), its default EXR
  compression and all;
* with ``--compressions NAME ...``: ``processes2_NAME``, ``--workers 2 --exr-compression NAME`` (the dataset's
  frames per second and bytes by EXR compression);
* with ``--methods NAME ...``: ``processes2_method_NAME``, ``--workers 2`` with the spec's ``method = NAME``
  instead of ``poisson`` (e.g. ``table``, exact as well: the same laws, other draws, so other bytes).

For each: ``fps`` = frames / wall time of the rendering phase (from the back-end's start, including the process
pool's start-up, to the last frame recorded; not the imports and the spec's validation), and ``steady_fps`` =
frames per second between the first and the last completed frame of each worker (from the ``.done`` records'
times), i.e. without start-up; ``MB/frame``: the output's bytes per frame (frame files or store, records and
manifest). Runs are interleaved (every configuration once per round, rounds repeated) and medians are reported,
so that the machine's load hits every configuration alike. The outputs of every configuration of this checkout
are checked byte for byte against the serial one (the Zarr store, and each other EXR compression, against its own
first run).

Run:  python tools/bench_dataset.py [--frames N] [--repeats R] [--preset NAME] [--baseline DIR] [--methods NAME ...]
Progress goes to stderr; the last stdout line is one JSON object.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WIDTH, HEIGHT = 1152, 864
#: name: (workers, threads, format, code): code "after" is this checkout, "before" the --baseline one
CONFIGS = {"serial": (1, 1, "files", "after"), "threads2": (1, 2, "files", "after"),
           "processes2": (2, 1, "files", "after"), "zarr2": (2, 1, "zarr", "after"),
           "before_processes2": (2, 1, "files", "before")}

SPEC = """
name = "bench_1mp"
scene = "{scene}"
seed = 0

[frame]
width = {width}
height = {height}

[fixed]
preset = "{preset}"
method = "{method}"

[grid]
illuminants = ["D65", "A", "FL2"]

[random]
count = {count}
intensity_factor = {{ log_uniform = [1e-3, 1.0] }}
read_noise_e = {{ uniform = [1.5, 6.0] }}
"""


def child(args) -> None:
    """One run in this (fresh) process, as ``camsim dataset`` runs it (the pool's fork server is started first, so
    that it imports camsim while this process does); prints its summary as JSON."""
    from camsim.dataset._pool import start_fork_server

    if args.workers > 1:
        start_fork_server(**({"zarr": True} if args.format == "zarr" else {}))
    from camsim.dataset.manifest import DONE_SUFFIX, FRAMES_DIR
    from camsim.dataset.runner import run_dataset

    options = {"output": "zarr"} if args.format == "zarr" else {}  # a baseline has no output option
    if args.exr_compression:
        options["exr_compression"] = args.exr_compression
    summary = run_dataset(args.spec, args.out, workers=args.workers, threads=args.threads, progress=False,
                          echo=None, **options)
    records = Path(args.out) / ("records" if args.format == "zarr" else FRAMES_DIR)
    times = sorted(p.stat().st_mtime_ns / 1e9 for p in records.glob(f"*{DONE_SUFFIX}"))
    k = args.workers  # each worker's first frame carries its warm-up
    steady = (len(times) - k) / (times[-1] - times[k - 1]) if len(times) > k and times[-1] > times[k - 1] else None
    size = sum(p.stat().st_size for p in Path(args.out).rglob("*") if p.is_file())
    print(json.dumps(summary | {"steady_fps": steady, "bytes": size}))


def tree(out: Path) -> dict:
    """SHA-256 of every file of a run's output (but the lock), by relative path."""
    return {p.relative_to(out).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(out.rglob("*"))
            if p.is_file() and not p.name.startswith(".camsim-dataset")}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=24, help="frames per run, a multiple of 3 (default 24)")
    parser.add_argument("--repeats", type=int, default=3, help="runs of each configuration (default 3)")
    parser.add_argument("--preset", default="emva-12bit",
                        help="sensor preset (default emva-12bit, as in scenes/denoise_small.toml; paper-table1 is "
                             "the 8-bit sensor of the W1 benchmark, without DSNU / PRNU)")
    parser.add_argument("--baseline", type=Path,
                        help="a checkout of an earlier camsim (e.g. made by git worktree add): its code runs the "
                             "before_processes2 configuration, in the same rounds")
    parser.add_argument("--configs", nargs="+", choices=list(CONFIGS),
                        help="run only these configurations (default: all; before_* need --baseline)")
    parser.add_argument("--compressions", nargs="+", default=[], metavar="NAME",
                        help="also processes2 with each of these EXR compressions (processes2_NAME)")
    parser.add_argument("--methods", nargs="+", default=[], metavar="NAME",
                        help="also processes2 with each of these sampling methods (processes2_method_NAME)")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--spec", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    parser.add_argument("--workers", type=int, default=1, help=argparse.SUPPRESS)
    parser.add_argument("--threads", type=int, default=1, help=argparse.SUPPRESS)
    parser.add_argument("--format", default="files", help=argparse.SUPPRESS)
    parser.add_argument("--exr-compression", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args)
        return
    if args.frames < 3 or args.frames % 3:
        parser.error("--frames must be a positive multiple of 3")
    if args.baseline is not None and not (args.baseline / "camsim" / "__init__.py").is_file():
        parser.error(f"--baseline {args.baseline}: no camsim checkout there")
    # name: (workers, threads, format, code, EXR compression or None for the default, method)
    configs = {name: (*config, None, "poisson") for name, config in CONFIGS.items()
               if (args.configs is None or name in args.configs) and (config[3] == "after" or args.baseline)}
    configs.update({f"processes2_{name}": (2, 1, "files", "after", name, "poisson") for name in args.compressions})
    configs.update({f"processes2_method_{name}": (2, 1, "files", "after", None, name) for name in args.methods})

    results = {name: [] for name in configs}
    with tempfile.TemporaryDirectory(prefix="camsim-bench-dataset-") as tmp:
        tmp = Path(tmp)
        specs = {}  # method -> its spec file
        for method in {config[5] for config in configs.values()}:
            specs[method] = tmp / f"bench_1mp_{method}.toml"
            specs[method].write_text(SPEC.format(scene=(ROOT / "scenes" / "macbeth_26.toml").as_posix(), width=WIDTH,
                                                 height=HEIGHT, count=args.frames // 3, preset=args.preset,
                                                 method=method), encoding="utf-8")
        references = {}  # format -> the first run's files (this checkout's)
        for repeat in range(args.repeats):
            for name, (workers, threads, output, code, compression, method) in configs.items():
                out = tmp / f"{name}-{repeat}"
                command = [sys.executable, __file__, "--child", "--spec", str(specs[method]), "--out", str(out),
                           "--workers", str(workers), "--threads", str(threads), "--format", output,
                           *(["--exr-compression", compression] if compression else [])]
                path = str(ROOT if code == "after" else args.baseline.resolve())
                env = os.environ | {"PYTHONPATH": os.pathsep.join(filter(None, [path, os.environ.get("PYTHONPATH")]))}
                # cwd: a folder without camsim, so that the code is PYTHONPATH's (the pool's fork server, started
                # with python -c, has the working directory first on its path)
                done = subprocess.run(command, check=True, capture_output=True, text=True, env=env, cwd=tmp)
                summary = json.loads(done.stdout.strip().splitlines()[-1])
                results[name].append(summary)
                if code == "after":
                    files = tree(out)
                    reference = references.setdefault((output, compression, method), files)
                    if files != reference:
                        raise SystemExit(f"{name} run {repeat}: files differ from the first {output} run")
                print(f"run {repeat} {name:<17} {summary['rendered']} frames in {summary['seconds']:.2f} s: "
                      f"{summary['frames_per_second']:.2f} frames/s (steady {summary['steady_fps']:.2f}), "
                      f"{summary['bytes'] / 1e6 / summary['rendered']:.1f} MB/frame", file=sys.stderr)
                for path in out.rglob("*"):  # keep the disk small: the bytes were compared
                    if path.is_file():
                        path.unlink()

    def median(name, key):
        return statistics.median(r[key] for r in results[name])

    def mb_per_frame(name):
        return statistics.median(r["bytes"] / r["rendered"] for r in results[name]) / 1e6

    mp = WIDTH * HEIGHT / 1e6
    print(f"camsim dataset, {args.frames} frames of {WIDTH}x{HEIGHT} ({mp:.3f} MP), preset {args.preset}, "
          f"DNG + EXR + JSON + manifest (zarr2: one Zarr store), median of {args.repeats} fresh-process runs, "
          "interleaved:")
    for name, (workers, threads, *_) in configs.items():
        print(f"  {name:<17} workers {workers}, threads {threads}: {median(name, 'frames_per_second'):6.2f} "
              f"frames/s ({median(name, 'megapixels_per_second'):5.2f} MP/s), steady state "
              f"{median(name, 'steady_fps'):6.2f} frames/s, {mb_per_frame(name):5.1f} MB/frame")
    summary = {
        "width": WIDTH, "height": HEIGHT, "megapixels": mp, "frames": args.frames, "repeats": args.repeats,
        "preset": args.preset,
    }
    for name in configs:
        summary[f"{name}_fps"] = median(name, "frames_per_second")
        summary[f"{name}_steady_fps"] = median(name, "steady_fps")
        summary[f"{name}_mb_per_frame"] = mb_per_frame(name)
    if "serial" in configs and "processes2" in configs:
        speedup = median("processes2", "frames_per_second") / median("serial", "frames_per_second")
        print(f"  2 processes / serial: {speedup:.2f}x (steady state "
              f"{median('processes2', 'steady_fps') / median('serial', 'steady_fps'):.2f}x)")
        summary["speedup_processes2"] = speedup
    if "before_processes2" in configs:
        for name in ("processes2", "zarr2", *(n for n in configs if n.startswith("processes2_method_"))):
            if name in configs:
                ratio = median(name, "frames_per_second") / median("before_processes2", "frames_per_second")
                steady = median(name, "steady_fps") / median("before_processes2", "steady_fps")
                print(f"  {name} / before_processes2 ({args.baseline}): {ratio:.2f}x (steady state {steady:.2f}x)")
                summary[f"speedup_{name}_vs_before"] = ratio
                summary[f"steady_speedup_{name}_vs_before"] = steady
    print("  every configuration's output is byte-identical to its first run (this checkout)")
    summary["identical"] = True
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
