"""Frames per second of ``camsim dataset`` for 1-megapixel frames, serial and on both cores.

The dataset: the ColorChecker of ``scenes/macbeth_26.toml`` at 1152 × 864 (0.995 MP), the ``emva-12bit`` sensor
(12-bit, DSNU and PRNU on; ``--preset`` to change), method ``poisson``, 3 illuminants × ``--frames / 3`` random draws of F (log-uniform 1e-3 … 1) and read
noise (uniform 1.5 … 6 e⁻); every frame written as DNG + EXR + JSON and recorded (SHA-256) in the manifest.

Configurations, each run as a fresh ``camsim dataset``-like process (as a user would run it), into its own folder:

* ``serial``: ``--workers 1`` (one process, one thread per frame: one core);
* ``threads2``: ``--workers 1 --threads 2`` (one process, each frame's noise draws and EXR compression on 2
  threads);
* ``processes2``: ``--workers 2`` (two processes, one frame each at a time).

For each: ``fps`` = frames / wall time of the rendering phase (from the back-end's start, including the process
pool's start-up, to the last frame recorded; not the imports and the spec's validation), and ``steady_fps`` =
frames per second between the first and the last completed frame of each worker (from the ``.done`` records'
times), i.e. without start-up. Runs are interleaved and repeated; medians are reported. The outputs of every
configuration are checked byte for byte against the serial one.

Run:  python tools/bench_dataset.py [--frames N] [--repeats R]
Progress goes to stderr; the last stdout line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WIDTH, HEIGHT = 1152, 864
CONFIGS = {"serial": (1, 1), "threads2": (1, 2), "processes2": (2, 1)}  # name: (workers, threads)

SPEC = """
name = "bench_1mp"
scene = "{scene}"
seed = 0

[frame]
width = {width}
height = {height}

[fixed]
preset = "{preset}"
method = "poisson"

[grid]
illuminants = ["D65", "A", "FL2"]

[random]
count = {count}
intensity_factor = {{ log_uniform = [1e-3, 1.0] }}
read_noise_e = {{ uniform = [1.5, 6.0] }}
"""


def child(args) -> None:
    """One run in this (fresh) process; prints its summary as JSON."""
    from camsim.dataset.manifest import DONE_SUFFIX, FRAMES_DIR
    from camsim.dataset.runner import run_dataset

    summary = run_dataset(args.spec, args.out, workers=args.workers, threads=args.threads, progress=False,
                          echo=None)
    times = sorted(p.stat().st_mtime_ns / 1e9 for p in (Path(args.out) / FRAMES_DIR).glob(f"*{DONE_SUFFIX}"))
    k = args.workers  # each worker's first frame carries its warm-up
    steady = (len(times) - k) / (times[-1] - times[k - 1]) if len(times) > k and times[-1] > times[k - 1] else None
    print(json.dumps(summary | {"steady_fps": steady}))


def tree(out: Path) -> dict:
    return {p.relative_to(out).as_posix(): p.read_bytes() for p in sorted(out.rglob("*"))
            if p.is_file() and not p.name.startswith(".camsim-dataset")}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--frames", type=int, default=24, help="frames per run, a multiple of 3 (default 24)")
    parser.add_argument("--repeats", type=int, default=3, help="runs of each configuration (default 3)")
    parser.add_argument("--preset", default="emva-12bit",
                        help="sensor preset (default emva-12bit, as in scenes/denoise_small.toml; paper-table1 is "
                             "the 8-bit sensor of the W1 benchmark, without DSNU / PRNU)")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--spec", help=argparse.SUPPRESS)
    parser.add_argument("--out", help=argparse.SUPPRESS)
    parser.add_argument("--workers", type=int, default=1, help=argparse.SUPPRESS)
    parser.add_argument("--threads", type=int, default=1, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        child(args)
        return
    if args.frames < 3 or args.frames % 3:
        parser.error("--frames must be a positive multiple of 3")

    results = {name: [] for name in CONFIGS}
    with tempfile.TemporaryDirectory(prefix="camsim-bench-dataset-") as tmp:
        tmp = Path(tmp)
        spec = tmp / "bench_1mp.toml"
        spec.write_text(SPEC.format(scene=(ROOT / "scenes" / "macbeth_26.toml").as_posix(), width=WIDTH,
                                    height=HEIGHT, count=args.frames // 3, preset=args.preset),
                        encoding="utf-8")
        reference = None
        for repeat in range(args.repeats):
            for name, (workers, threads) in CONFIGS.items():
                out = tmp / f"{name}-{repeat}"
                command = [sys.executable, __file__, "--child", "--spec", str(spec), "--out", str(out),
                           "--workers", str(workers), "--threads", str(threads)]
                done = subprocess.run(command, check=True, capture_output=True, text=True)
                summary = json.loads(done.stdout.strip().splitlines()[-1])
                results[name].append(summary)
                files = tree(out)
                if reference is None:
                    reference = files
                elif files != reference:
                    raise SystemExit(f"{name} run {repeat}: files differ from the serial run")
                print(f"run {repeat} {name:<10} {summary['rendered']} frames in {summary['seconds']:.2f} s: "
                      f"{summary['frames_per_second']:.2f} frames/s (steady {summary['steady_fps']:.2f})",
                      file=sys.stderr)
                for path in out.rglob("*"):  # keep the disk small: the bytes were compared
                    if path.is_file():
                        path.unlink()

    def median(name, key):
        return statistics.median(r[key] for r in results[name])

    mp = WIDTH * HEIGHT / 1e6
    print(f"camsim dataset, {args.frames} frames of {WIDTH}x{HEIGHT} ({mp:.3f} MP), preset {args.preset}, "
          f"DNG + EXR + JSON + manifest, median of {args.repeats} fresh-process runs:")
    for name, (workers, threads) in CONFIGS.items():
        print(f"  {name:<10} workers {workers}, threads {threads}: {median(name, 'frames_per_second'):6.2f} "
              f"frames/s ({median(name, 'megapixels_per_second'):5.2f} MP/s), steady state "
              f"{median(name, 'steady_fps'):6.2f} frames/s")
    speedup = median("processes2", "frames_per_second") / median("serial", "frames_per_second")
    print(f"  2 processes / serial: {speedup:.2f}x (steady state "
          f"{median('processes2', 'steady_fps') / median('serial', 'steady_fps'):.2f}x); "
          "every configuration's files are byte-identical to the serial run's")
    summary = {
        "width": WIDTH, "height": HEIGHT, "megapixels": mp, "frames": args.frames, "repeats": args.repeats,
        "preset": args.preset,
        "serial_fps": median("serial", "frames_per_second"),
        "threads2_fps": median("threads2", "frames_per_second"),
        "processes2_fps": median("processes2", "frames_per_second"),
        "serial_steady_fps": median("serial", "steady_fps"),
        "threads2_steady_fps": median("threads2", "steady_fps"),
        "processes2_steady_fps": median("processes2", "steady_fps"),
        "speedup_processes2": speedup,
        "identical": True,
    }
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
