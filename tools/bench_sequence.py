"""Benchmark: the rendering cost per frame of a sequence with camera shake against one static frame's (issue 29).

Renders, in one process and on the same scene (``--scene``, default the dead-leaves target, at ``--size``, Bayer), one
static frame as ``camsim render`` draws it (:func:`camsim.render.pipeline.scene_frame`, the scene lit beforehand)
and then ``--frames`` frames of a ``[sequence]`` with shake (:func:`camsim.render.sequence.render_sequence_frames`:
the per-pixel expectation along the path, the draw, the clean layer), and prints the seconds of each, the ratio
and where a sequence frame's time goes. No files are written (their cost is the same for both). The static frame is
the fastest of three (two before the sequence, one after: the load of a shared machine moves); each figure has its
CPU time (every thread's) beside the wall clock, and the machine's load average is printed. The warp
(:func:`camsim.render.warp.average_warp`) is compiled before the timings (its one-off compile time printed apart),
and one frame's expectation is timed on both of its paths, numpy and compiled, in the same run. The sequence's
table is :func:`sequence_options`'s (a new ``[sequence]`` option of the benchmark goes there). Usage::

    python tools/bench_sequence.py [--size 4000x3000] [--frames 16] [--shake-px 1] [--workers N]
        [--rolling-shutter-row-s 1e-5] [--flicker-hz 100 --flicker-depth 0.2]
"""

from __future__ import annotations

import argparse
import functools
import os
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
    parser.add_argument("--rolling-shutter-row-s", type=float, default=0.0)
    parser.add_argument("--flicker-hz", type=float, default=0.0)
    parser.add_argument("--flicker-depth", type=float, default=0.0)
    parser.add_argument("--workers", type=int, default=None)
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
    scene = scene.replace(sequence=SequenceParams(**sequence_options(args)))
    illuminant = scene.illuminants[0]
    lit = light_scene(scene, illuminant)
    sensor = frame_sensor(scene, lit, 1.0)

    def static_frame() -> tuple[float, float]:
        """(wall s, CPU s of every thread) of one static frame and its EXR's clean layer, as render makes them."""
        t0, c0 = time.perf_counter(), time.process_time()
        frame, _ = scene_frame(scene, illuminant, 1.0, lit=lit, workers=args.workers)
        frame.clean_dn()
        return time.perf_counter() - t0, time.process_time() - c0

    static = [static_frame() for _ in range(2)]  # the faster of two (the first pays one-off set-up) ...

    compile_s = _compile_warp()
    warp_s = _warp_paths(scene, lit, sensor, args.workers)

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
    t0, c0 = time.perf_counter(), time.process_time()
    subsamples, frame_s = [], []  # per frame: (wall s, CPU s)
    ref_s = None
    for index, f, extra in seqmod.render_sequence_frames(scene, lit, sensor, 1.0, workers=args.workers):
        t1, c1 = time.perf_counter(), time.process_time()
        if index == "ref":
            ref_s = t1 - t0
            for k in parts:
                parts[k] = 0.0
        else:
            subsamples.append(extra["blur_subsamples_used"])
            frame_s.append((t1 - t0, c1 - c0))
        del f
        t0, c0 = time.perf_counter(), time.process_time()
    for name, original in wrapped.items():
        setattr(seqmod, name, original)
    static.append(static_frame())  # ... and one after the sequence (the load of a shared machine moves)
    static_s, static_cpu = min(static)
    per_frame, per_frame_cpu = np.mean(frame_s, axis=0)
    median_frame = float(np.median([w for w, _ in frame_s]))
    load = os.getloadavg()
    print(f"{args.scene} {width}x{height} Bayer RGGB, shake {args.shake_px} px / {args.shake_deg} deg per interval, "
          f"rolling shutter {args.rolling_shutter_row_s:g} s/row, flicker {args.flicker_hz:g} Hz × "
          f"{args.flicker_depth:g}, T = {args.exposure} s, {args.frames} frames, sub-samples per exposure "
          f"{np.mean(subsamples):.1f} "
          f"(min {min(subsamples)}, max {max(subsamples)}); {os.cpu_count()} cores, workers "
          f"{args.workers or 'all'}, load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    print(f"static frame (scene_frame + clean layer, the fastest of three: two before the sequence, one after): "
          f"{static_s:.2f} s (CPU {static_cpu:.2f} s)")
    if warp_s is not None:
        samples, numpy_s, compiled_s = warp_s
        print(f"expectation of one frame ({samples} sub-samples, the faster of two): numpy warp {numpy_s:.2f} s "
              f"({numpy_s / samples:.3f} s per sub-sample), compiled {compiled_s:.2f} s "
              f"({compiled_s / samples:.3f} s per sub-sample): {numpy_s / compiled_s:.1f}x; compiling it "
              f"{compile_s:.2f} s once per process (not in the figures)")
    else:
        print("warp: numba cannot be imported, the numpy path only")
    print(f"sequence: reference {ref_s:.2f} s once; per frame {per_frame:.2f} s, median {median_frame:.2f} s, "
          f"CPU {per_frame_cpu:.2f} s (expectation along the path {parts['expectation'] / args.frames:.2f} s, draw "
          f"{parts['draw'] / args.frames:.2f} s, clean layer {parts['clean'] / args.frames:.2f} s)")
    print(f"ratio per frame / static: {per_frame / static_s:.2f} (median frame {median_frame / static_s:.2f}, "
          f"CPU {per_frame_cpu / static_cpu:.2f})")


def sequence_options(args) -> dict:
    """The benchmark's ``[sequence]`` (SequenceParams' keyword arguments) from the command line: the one place a
    new option of the table goes."""
    return {"frames": args.frames, "frame_interval_s": args.interval, "shake_px": args.shake_px,
            "shake_deg": args.shake_deg, "rolling_shutter_row_s": args.rolling_shutter_row_s,
            "flicker_hz": args.flicker_hz, "flicker_depth": args.flicker_depth}


def _compile_warp() -> float:
    """Compile the warp kernel (where numba is there); its seconds."""
    import numpy as np

    from camsim.render.warp import average_warp, warp_kernels

    t0 = time.perf_counter()
    if warp_kernels() is not None:
        shift = np.eye(3)
        shift[0, 2] = 0.5
        average_warp(np.zeros((4, 4, 3), dtype=np.float32), shift[None, None], np.ones((1, 1)), compiled=True)
    return time.perf_counter() - t0


def _warp_paths(scene, lit, sensor, workers):
    """(sub-samples, numpy s, compiled s) of the second frame's expectation along the path
    (:func:`camsim.render.sequence.moving_expectation`, the faster of two on each path of its warp), or None
    without numba."""
    import camsim.render.warp as warp
    from camsim.render.raw_frame import static_signal_e
    from camsim.render.sequence import channels_last, moving_expectation
    from camsim.scene.sequence import Motion

    if warp.warp_kernels() is None:
        return None
    expected = lit.expected(sensor, 1.0, scene.statistics)
    static = static_signal_e(lit.labels, expected.signal_e)
    pixels = channels_last(static)
    height, width = lit.labels.shape
    motion = Motion.of(scene.sequence, width, height, scene.seed)
    frame = min(1, scene.sequence.frames - 1)
    original, seconds, samples = warp.average_warp, {}, []

    def average_warp(pixels, inverses, weights, *, _path, **options):
        samples.append(len(inverses))
        return original(pixels, inverses, weights, **{**options, "compiled": _path})

    try:
        for compiled in (False, True):
            warp.average_warp = functools.partial(average_warp, _path=compiled)
            runs = []
            for _ in range(2):
                t0 = time.perf_counter()
                moving_expectation(static, motion, frame, sensor.exposure_s, workers, pixels=pixels)
                runs.append(time.perf_counter() - t0)
            seconds[compiled] = min(runs)
    finally:
        warp.average_warp = original
    return samples[-1], seconds[False], seconds[True]


if __name__ == "__main__":
    main()
