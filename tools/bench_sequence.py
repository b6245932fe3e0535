"""Benchmark: the rendering cost per frame of a sequence with camera shake against one static frame's (issue 29).

Renders, in one process and on the same scene (``--scene``, default the dead-leaves target, at ``--size``, Bayer), one
static frame as ``camsim render`` draws it (:func:`camsim.render.pipeline.scene_frame`, the scene lit beforehand)
and then ``--frames`` frames of a ``[sequence]`` with shake (:func:`camsim.render.sequence.render_sequence_frames`:
the per-pixel expectation along the path, the draw, the clean layer), and prints the seconds of each, the ratio
and where a sequence frame's time goes. No files are written (their cost is the same for both). Usage::

    python tools/bench_sequence.py [--size 4000x3000] [--frames 16] [--shake-px 1] [--workers N]
        [--rolling-shutter-row-s 1e-5] [--flicker-hz 100 --flicker-depth 0.2]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="4000x3000")
    parser.add_argument("--frames", type=int, default=16)
    parser.add_argument("--shake-px", type=float, default=1.0)
    parser.add_argument("--shake-deg", type=float, default=0.05)
    parser.add_argument("--exposure", type=float, default=0.01)
    parser.add_argument("--interval", type=float, default=1 / 30)
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--rolling-shutter-row-s", type=float, default=0.0, help="a rolling shutter's line time "
                        "(s; 0: a global shutter)")
    parser.add_argument("--flicker-hz", type=float, default=0.0)
    parser.add_argument("--flicker-depth", type=float, default=0.0)
    parser.add_argument("--scene", default="dead_leaves", help="a built-in scene (camsim/scenes/NAME.toml): a "
                        "chart or a target (their size is --size)")
    args = parser.parse_args(argv)

    import numpy as np

    import camsim.render.sequence as seqmod
    from camsim.render.pipeline import frame_sensor, light_scene, scene_frame
    from camsim.scene.scene_file import load_scene
    from camsim.scene.sequence import SequenceParams

    width, height = (int(v) for v in args.size.lower().split("x"))
    scene = load_scene(ROOT / "camsim" / "scenes" / f"{args.scene}.toml")
    scene = scene.replace(width=width, height=height, intensity_factors=(1.0,)).with_sensor(
        cfa="RGGB", exposure_s=args.exposure)
    scene = scene.replace(sequence=SequenceParams(frames=args.frames, frame_interval_s=args.interval,
                                                  shake_px=args.shake_px, shake_deg=args.shake_deg,
                                                  rolling_shutter_row_s=args.rolling_shutter_row_s,
                                                  flicker_hz=args.flicker_hz, flicker_depth=args.flicker_depth))
    illuminant = scene.illuminants[0]
    lit = light_scene(scene, illuminant)
    sensor = frame_sensor(scene, lit, 1.0)

    static_s = []
    for _ in range(2):  # the faster of two (the first pays one-off set-up)
        t0 = time.perf_counter()
        frame, _ = scene_frame(scene, illuminant, 1.0, lit=lit, workers=args.workers)
        frame.clean_dn()  # its EXR's clean layer, as render writes it
        static_s.append(time.perf_counter() - t0)
        del frame
    static_s = min(static_s)

    parts = {"expectation": 0.0, "draw": 0.0, "clean": 0.0}
    wrapped = {}
    for name, part in (("moving_expectation", "expectation"), ("render_expectation_frame", "draw"),
                       ("expectation_clean_dn", "clean")):
        original = getattr(seqmod, name)

        def timed(*a, _f=original, _p=part, **k):
            s = time.perf_counter()
            out = _f(*a, **k)
            parts[_p] += time.perf_counter() - s
            return out

        wrapped[name] = original
        setattr(seqmod, name, timed)
    t0 = time.perf_counter()
    subsamples = []
    ref_s = None
    for index, f, extra in seqmod.render_sequence_frames(scene, lit, sensor, 1.0, workers=args.workers):
        if index == "ref":
            ref_s = time.perf_counter() - t0
            for k in parts:
                parts[k] = 0.0
            t0 = time.perf_counter()
        else:
            subsamples.append(extra["blur_subsamples_used"])
    frames_s = time.perf_counter() - t0
    for name, original in wrapped.items():
        setattr(seqmod, name, original)
    per_frame = frames_s / args.frames
    print(f"{args.scene} {width}x{height} Bayer RGGB, shake {args.shake_px} px / {args.shake_deg} deg per interval, "
          f"rolling shutter {args.rolling_shutter_row_s:g} s/row, flicker {args.flicker_hz:g} Hz × "
          f"{args.flicker_depth:g}, T = {args.exposure} s, {args.frames} frames, sub-samples per exposure "
          f"{np.mean(subsamples):.1f} (min {min(subsamples)}, max {max(subsamples)})")
    print(f"static frame (scene_frame + clean layer, the faster of two): {static_s:.2f} s")
    print(f"sequence: reference {ref_s:.2f} s once; per frame {per_frame:.2f} s "
          f"(expectation along the path {parts['expectation'] / args.frames:.2f} s, draw "
          f"{parts['draw'] / args.frames:.2f} s, clean layer {parts['clean'] / args.frames:.2f} s)")
    print(f"ratio per frame / static: {per_frame / static_s:.2f}")


if __name__ == "__main__":
    main()
