"""Burst pairs per second against single pairs per second, in one run on the CPU (:mod:`camsim.pairs`, issue 29).

Five sources draw the same photographs, crops' sizes, cameras and F: single pairs (``burst_frames`` None), static
bursts of N frames (no motion: what N draws of noise and N + 1 expectations cost), bursts with shake and a pan
(the motion's warp, :func:`camsim.render.warp.average_warp`, over each exposure's sub-samples, on a crop with a margin),
the same with a rolling shutter (``--row-s``: each row's own sub-sample times, per-row inverses) and with a rolling
shutter and flicker (``--flicker-hz``, ``--flicker-depth``: each sub-sample weighted by the light's integral over its
part, and as many more sub-samples as the flicker's bound asks, :meth:`camsim.scene.sequence.Motion.subsample_count`).
The sources are timed in turn, round after round (``--repeats`` rounds of ``--batches`` batches each), each rate its
best round, after a warm-up round. Printed per source: items/s, frames/s (a single pair is one frame) and the cost
of a frame against a single pair's (single pairs/s ÷ burst frames/s); ``--profile`` splits one burst item of the
moving source into its stages (the warps, the draws with their expectations, the reference).

    python tools/bench_burst_pairs.py [--crop 256x256] [--batch-size 4] [--frames 8] [--batches 2] [--repeats 3]
                                      [--shake-px 0.5] [--shake-deg 0.1] [--pan 2,0] [--row-s S] [--flicker-hz 100]
                                      [--flicker-depth 0.5] [--domain dn] [--profile]
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def rates(sources: dict, batches: int, repeats: int) -> dict:
    """Seconds of each source's best round of batches 0 … batches − 1, the sources timed in turn in each round."""
    best = dict.fromkeys(sources, float("inf"))
    for _ in range(repeats):
        for name, source in sources.items():
            start = time.perf_counter()
            for index in range(batches):
                source.batch(index)
            best[name] = min(best[name], time.perf_counter() - start)
    return best


def profile(source) -> list[tuple[str, float]]:
    """Seconds of one burst item's stages (batch 0's first item, best of 3): its motion (homographies and
    sub-samples), the N warps, the N draws with their expectations, and the reference."""
    import dataclasses

    import numpy as np

    from camsim.render.backends import device_generator
    from camsim.render.warp import average_warp
    from camsim.scene.sequence import Motion

    batch = source.batch(0)
    p = batch.params[0]
    sensor = source._sensor(p["preset"], p["iso"], {})
    sensor = dataclasses.replace(sensor, exposure_s=p["exposure_s"])
    burst = p["burst"]
    width, height = source.crop
    seq = source._burst_sequence(p["exposure_s"])
    mx, my = burst["margin_px"]
    x, y = p["crop_x"], p["crop_y"]
    rgb = np.ascontiguousarray(source._rgb(p["image_index"])[y - my: y + height + my, x - mx: x + width + mx])
    shift, unshift = np.eye(3), np.eye(3)
    shift[:2, 2], unshift[:2, 2] = (mx, my), (-mx, -my)
    steps = []

    def timed(name, fn):
        best = float("inf")
        for _ in range(3):
            t = time.perf_counter()
            out = fn()
            best = min(best, time.perf_counter() - t)
        steps.append((name, best))
        return out

    def motion():
        m = Motion.of(seq, width, height, burst["motion_seed"])
        return [np.linalg.inv(m.homographies(m.subsample_times(j, p["exposure_s"]), j)) for j in range(seq.frames)]

    inverses = timed("motion (homographies, sub-samples)", motion)
    inside = (slice(my, my + height), slice(mx, mx + width))

    def warps():
        return [average_warp(rgb, (shift @ inv @ unshift)[:, None], np.full((len(inv), 1), 1 / len(inv)),
                             workers=1)[inside] for inv in inverses]

    moved = timed(f"{seq.frames} warps ({sum(len(i) for i in inverses)} sub-samples)", warps)
    rng = device_generator(np, 0)
    timed(f"{seq.frames} draws with their expectations (together)",
          lambda: source._draw_frames(np, rng, moved, [p] * len(moved), [sensor] * len(moved)))
    timed("the reference (expectation only)",
          lambda: source._draw_frames(np, rng, [np.ascontiguousarray(rgb[inside])], [p], [sensor], noise=False))
    return steps


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--crop", default="256x256", help="crop WxH (default 256x256)")
    parser.add_argument("--batch-size", type=int, default=4)
    parser.add_argument("--frames", type=int, default=8, help="frames per burst (default 8)")
    parser.add_argument("--batches", type=int, default=2, help="batches per timed round (default 2)")
    parser.add_argument("--repeats", type=int, default=3, help="timed rounds (default 3)")
    parser.add_argument("--shake-px", type=float, default=0.5)
    parser.add_argument("--shake-deg", type=float, default=0.1)
    parser.add_argument("--pan", default="2,0", help="pan vx,vy in px/s (default 2,0: 2 px of blur in T = 1 s)")
    parser.add_argument("--row-s", type=float, default=None,
                        help="rolling shutter's line time in s (default: 0.5 / crop height: half the frame interval)")
    parser.add_argument("--flicker-hz", type=float, default=100.0)
    parser.add_argument("--flicker-depth", type=float, default=0.5)
    parser.add_argument("--camera", default="sony-a7s2")
    parser.add_argument("--domain", default="dn", choices=("dn", "raw", "srgb"))
    parser.add_argument("--profile", action="store_true")
    args = parser.parse_args(argv)

    from camsim.pairs import PairSource

    width, height = (int(v) for v in args.crop.lower().split("x"))
    pan = tuple(float(v) for v in args.pan.split(","))
    base = dict(crop=(width, height), batch_size=args.batch_size, cameras=(args.camera,), intensity=(1e-2, 0.3),
                seed=0, domain=args.domain)
    images = ROOT / "scenes" / "images"
    row_s = 0.5 / height if args.row_s is None else args.row_s
    moving = dict(burst_frames=args.frames, shake_px=args.shake_px, shake_deg=args.shake_deg, pan_px_per_s=pan, **base)
    sources = {
        "single": PairSource.from_scene("macbeth_26", images, **base),
        "burst static": PairSource.from_scene("macbeth_26", images, burst_frames=args.frames, **base),
        "burst moving": PairSource.from_scene("macbeth_26", images, **moving),
        "+ rolling": PairSource.from_scene("macbeth_26", images, rolling_shutter_row_s=row_s, **moving),
        "+ rolling, flicker": PairSource.from_scene("macbeth_26", images, rolling_shutter_row_s=row_s,
                                                    flicker_hz=args.flicker_hz, flicker_depth=args.flicker_depth,
                                                    **moving),
    }
    start = time.perf_counter()
    rates(sources, 1, 1)
    warm = time.perf_counter() - start
    best = rates(sources, args.batches, args.repeats)
    items = args.batches * args.batch_size
    print(f"camsim burst pairs, {width}x{height} {args.camera} crops, domain {args.domain}, batches of "
          f"{args.batch_size}, {args.frames} frames per burst; motion: shake {args.shake_px} px / {args.shake_deg} deg "
          f"per frame interval, pan {pan} px/s (T = the scene's 1 s, frames back to back); rolling shutter "
          f"{row_s:.3g} s a row; flicker {args.flicker_hz:g} Hz, depth {args.flicker_depth:g}")
    print(f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}; best of {args.repeats} rounds of {args.batches} batches after a warm-up "
          f"({warm:.2f} s)")
    single = items / best["single"]
    print(f"{'source':<20} {'items/s':>9} {'frames/s':>9} {'frame cost / single pair':>26}")
    for name, seconds in best.items():
        frames = 1 if name == "single" else args.frames
        per_item = items / seconds
        print(f"{name:<20} {per_item:9.2f} {per_item * frames:9.2f} {single / (per_item * frames):26.2f}")
    for name in ("burst moving", "+ rolling", "+ rolling, flicker"):
        items = sources[name].batch(0).params
        print(f"{name} (batch 0): sub-samples per frame {items[0]['burst']['blur_subsamples_used']} (item 0); "
              f"reach {[round(p['burst']['reach_px'], 1) for p in items]} px; margins (x, y) "
              f"{[tuple(p['burst']['margin_px']) for p in items]} px; "
              f"clamped {sum(p['burst']['clamped'] for p in items)}")
    if args.profile:
        print("one moving burst item, stage by stage (best of 3):")
        for name, seconds in profile(sources["burst moving"]):
            print(f"  {name:<42} {seconds * 1e3:9.2f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
