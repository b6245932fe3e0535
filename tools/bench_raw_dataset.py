"""Frames per second of a ``[raws]`` dataset (crops of a folder of raw files) against an ``[images]`` dataset of the
same frame size, count and target sensor, in the same run, side by side with their ratio.

The datasets (both ``--frames`` frames of ``--crop`` × ``--crop`` pixels, 512 by default, the ``sony-a7s2`` sensor
at ISO 3200, 14-bit, every frame written as DNG + EXR + JSON and recorded with its SHA-256 in the manifest):

* ``images``: ``scenes/macbeth_26.toml``'s light and camera, crops of 2 sRGB pictures (2048 × 1536, a smooth random
  texture written here) under D65, method ``poisson``, F log-uniform over 1e-3 … 1;
* ``raws``: crops of 2 DNG files of a Sony A7S II (4256 × 2848, the SID sensor's size, 12.1 MP, written here by
  :func:`camsim.io.dng.write_dng_cfa` with the camera's Make/Model, ISO 100, 10 s, the same texture as a Bayer
  mosaic), flips on, photon law ``add``, ratio log-uniform over 100 … 300 (the SID convention).

Each configuration runs as a fresh ``camsim dataset`` process (as a user runs it) with ``--workers`` processes
(default 2), into its own folder; rounds alternate the two (``--rounds``, default 3) so that the machine's load hits
both alike, and the medians are reported. ``fps`` is camsim's own figure: frames / wall time of the rendering phase
(from the back-end's start, the process pool's start-up and, for raws, each worker's first reading of each raw file
included, to the last frame recorded; the imports and the spec's planning are not in it). The raw files'
reading is also timed alone (``read_s``: one :func:`camsim.io.raw_capture.read_raw_capture` of one file).

Run:  python tools/bench_raw_dataset.py [--frames N] [--crop PX] [--workers W] [--rounds R]
Progress goes to stderr; the last stdout line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
RAW_SIZE = (4256, 2848)  # (W, H): the Sony A7S II's raw, as in SID
IMAGE_SIZE = (2048, 1536)

IMAGES_SPEC = """
name = "bench_images"
scene = "{scene}"
seed = 0
[images]
folder = "images"
crop = [{crop}, {crop}]
flips = true
[fixed]
preset = "sony-a7s2"
iso = 3200
illuminant = "D65"
method = "poisson"
[random]
count = {count}
intensity_factor = {{ log_uniform = [1e-3, 1.0] }}
"""

RAWS_SPEC = """
name = "bench_raws"
seed = 0
[raws]
folder = "raws"
crop = [{crop}, {crop}]
flips = true
[fixed]
preset = "sony-a7s2"
iso = 3200
[random]
count = {count}
ratio = {{ log_uniform = [100.0, 300.0] }}
"""


def texture(width: int, height: int, seed: int) -> np.ndarray:
    """A smooth random texture in 0 … 1 (H, W): a few sines of random frequency and phase, and fine noise."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width].astype(np.float32)
    out = np.zeros((height, width), np.float32)
    for _ in range(6):
        fx, fy = rng.uniform(0.002, 0.05, 2)
        out += np.sin(fx * x + rng.uniform(0, 6.3)) * np.sin(fy * y + rng.uniform(0, 6.3))
    out = (out - out.min()) / (out.max() - out.min())
    return np.clip(0.05 + 0.9 * out + rng.normal(0, 0.01, out.shape).astype(np.float32), 0, 1)


def make_inputs(folder: Path, frames: int, crop: int) -> dict:
    """The pictures, the raw files and the two specs in ``folder``; the specs' paths by name."""
    import imageio.v3 as iio

    from camsim.io.dng import write_dng_cfa

    (folder / "images").mkdir(parents=True)
    (folder / "raws").mkdir()
    for i in range(2):
        grey = texture(*IMAGE_SIZE, seed=i)
        rgb = np.stack([grey, grey ** 1.1, grey ** 0.9], axis=-1)
        iio.imwrite(folder / "images" / f"p{i}.png", (rgb * 255 + 0.5).astype(np.uint8))
        mosaic = (512 + texture(*RAW_SIZE, seed=10 + i) * 12000).astype(np.uint16)
        write_dng_cfa(folder / "raws" / f"DSC0{i}.dng", mosaic, pattern="RGGB", black_level_dn=512.0,
                      white_level=16383, unique_camera_model="Sony ILCE-7SM2", make="SONY", model="ILCE-7SM2",
                      color_matrix1=[[0.6, -0.1, -0.05], [-0.4, 1.3, 0.1], [-0.08, 0.2, 0.6]],
                      as_shot_neutral=[0.5, 1.0, 0.7], iso=100, exposure_s=10.0)
    specs = {"images": folder / "images.toml", "raws": folder / "raws.toml"}
    specs["images"].write_text(IMAGES_SPEC.format(scene=(ROOT / "scenes" / "macbeth_26.toml").as_posix(), crop=crop,
                                                  count=frames))
    specs["raws"].write_text(RAWS_SPEC.format(crop=crop, count=frames))
    return specs


def run(spec: Path, out: Path, workers: int) -> float:
    """One fresh ``camsim dataset`` process; camsim's frames per second of its rendering phase."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    done = subprocess.run([sys.executable, "-m", "camsim", "dataset", str(spec), "--out", str(out), "--workers",
                           str(workers), "--quiet"], env=env, capture_output=True, text=True, check=False)
    if done.returncode:
        raise SystemExit(f"camsim dataset {spec} failed: {done.stderr.strip()}")
    match = re.search(r"rendered \d+ frames in [\d.]+ s: ([\d.]+) frames/s", done.stdout)
    if not match:
        raise SystemExit(f"no rate in camsim dataset's output: {done.stdout!r}")
    return float(match.group(1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=48)
    parser.add_argument("--crop", type=int, default=512)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    sys.path.insert(0, str(ROOT))
    from camsim.io.raw_capture import read_raw_capture

    with tempfile.TemporaryDirectory(prefix="bench-raw-dataset-") as tmp:
        tmp = Path(tmp)
        specs = make_inputs(tmp, args.frames, args.crop)
        start = time.perf_counter()
        read_raw_capture(tmp / "raws" / "DSC00.dng")
        read_s = time.perf_counter() - start
        rates: dict = {"images": [], "raws": []}
        for r in range(args.rounds):
            for name, spec in specs.items():
                fps = run(spec, tmp / f"out_{name}_{r}", args.workers)
                rates[name].append(fps)
                print(f"round {r}: {name} {fps:.2f} frames/s", file=sys.stderr)
    images, raws = (statistics.median(rates[n]) for n in ("images", "raws"))
    print(f"{args.frames} frames of {args.crop}x{args.crop}, {args.workers} worker(s), median of {args.rounds}: "
          f"images {images:.2f} frames/s | raws {raws:.2f} frames/s | raws/images {raws / images:.2f} "
          f"(one {RAW_SIZE[0]}x{RAW_SIZE[1]} DNG read: {read_s:.2f} s)")
    print(json.dumps({"frames": args.frames, "crop_px": args.crop, "workers": args.workers, "rounds": args.rounds,
                      "images_fps": rates["images"], "raws_fps": rates["raws"], "images_fps_median": images,
                      "raws_fps_median": raws, "ratio_raws_to_images": raws / images, "raw_read_s": read_s}))


if __name__ == "__main__":
    main()
