"""Benchmark: W1 through the optics (diffraction and OLPF) against the same render without optics (issue 30).

W1 is :mod:`tools.bench_w1`'s workload: the chart of ``scenes/macbeth_26.toml`` under D65 at F = 1, 4000 × 3000
pixels, three channels, the ``paper-table1`` sensor (every noise stage on), ``pixel`` statistics, method
``poisson``. In one process the scene is lit once, then the two frames are made alternately ``--repeats`` times
as ``camsim render`` makes them (:func:`camsim.render.pipeline.scene_frame`, and the frame's EXR clean layer,
``frame.clean_dn()``, which render writes): without optics (the per-spectrum plans of
:func:`camsim.render.frame.render_frame`) and with ``[optics]`` f/4, 4 µm pixels, diffraction and the 4-spot OLPF
(:mod:`camsim.render.optics`: the per-pixel expectation, per channel the FFT convolutions of the mean OTF and of
each spectrum's components, the per-pixel draw). The medians of the same run give the ratio; where the optics
frame's time goes (the expectation's gather, the optics, the draw, the clean layer) is measured on its last repeat. Peak
memory: the peak RSS of a fresh child process that sets up and makes one frame of each kind (imports included). No files
are written (their cost is the same for both). Targets: time and peak memory ≤ 1.5× without optics.

On a device (``--device cuda``: an NVIDIA GPU through CuPy; ``numpy``: the same array code on the CPU) the two frames
are the array path's (:func:`camsim.render.backends.array_path.render_frame_xp`, the label map already on the device,
the expected signal made once, as ``tools/bench_gpu.py``'s W1) and :func:`camsim.render.optics.optics_frame_xp`
(everything a frame does: the OTFs' plan on the host, :func:`camsim.render.optics.optics_plan`; the gather, the
optics' FFTs and the per-pixel draw on the device), each synchronised, excluding the copy to the host. The repeats
are frames of one light, as a render's F values or a dataset's exposures: the plan and the device's OTF grids are
made for the first and reused (``on_cold_s``: one frame with both made anew). The parts (plan made anew, optics,
draw) and the memory pool's bytes after each kind (its blocks freed in between) are reported; no peak RSS.

Run:  python tools/bench_optics.py [--size 4000x3000] [--repeats 3] [--workers N] [--device cpu|cuda|numpy]
Progress goes to stderr; the last stdout line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OPTICS = {"f_number": 4.0, "pixel_pitch_um": 4.0, "diffraction": True, "olpf": True}


def progress(message: str) -> None:
    print(f"[bench_optics] {message}", file=sys.stderr, flush=True)


def scenes(width: int, height: int):
    """W1 without and with the optics."""
    from camsim.optics.params import parse_optics
    from camsim.scene.scene_file import load_scene

    base = load_scene(ROOT / "scenes" / "macbeth_26.toml").replace(
        width=width, height=height, illuminants=("D65",), intensity_factors=(1.0,), method="poisson",
        statistics="pixel")
    return base, base.replace(optics=parse_optics(OPTICS))


def make(scene, lit, camera, workers):
    from camsim.render.pipeline import scene_frame

    frame, _ = scene_frame(scene, "D65", 1.0, lit=lit, camera=camera, workers=workers)
    frame.clean_dn()
    return frame


def child(kind: str, width: int, height: int, workers) -> None:
    from camsim.render.pipeline import light_scene
    from camsim.sensor.camera import load_camera

    base, optics = scenes(width, height)
    camera = load_camera(base.camera, base.grid, base.sensitivity_basis, base.base_dir)
    lit = light_scene(base, "D65", camera)
    make(optics if kind == "on" else base, lit, camera, workers)
    print(json.dumps({"peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))


def synchronised(xp, fn):
    """Seconds of ``fn()`` on ``xp``'s device, the queued work finished before each clock reading."""
    from camsim.core.xp import synchronize

    synchronize(xp)
    t0 = time.perf_counter()
    fn()
    synchronize(xp)
    return time.perf_counter() - t0


def device_run(device: str, width: int, height: int, repeats: int) -> dict:
    """W1 with and without the optics on ``device``'s array path (module docstring)."""
    from camsim.render.backends import array_module, device_name
    from camsim.render.backends.array_path import render_frame_xp
    from camsim.render.optics import apply_optics, optics_frame_xp, optics_plan
    from camsim.render.pipeline import frame_sensor, light_scene
    from camsim.render.raw_frame import static_signal_e

    xp = array_module(device)
    base, optics = scenes(width, height)
    lit = light_scene(optics, "D65")
    sensor = frame_sensor(optics, lit, 1.0)
    expected = lit.expected(sensor, 1.0, "pixel")
    labels = xp.asarray(lit.labels)
    seeds = iter(range(10**6))
    kinds = {"off": lambda: render_frame_xp(xp, labels, expected, sensor, rng=next(seeds)),
             "on": lambda: optics_frame_xp(xp, lit, expected, sensor, optics.optics, rng=next(seeds), labels=labels)}
    pool = None if xp is np else xp.get_default_memory_pool()
    held = {}
    for kind, fn in kinds.items():  # warm-up (the device's kernels compiled, the maps copied) and the pool's bytes
        if pool is not None:
            pool.free_all_blocks()
        synchronised(xp, fn)
        held[kind] = None if pool is None else pool.total_bytes() / 2**20
    times = {"off": [], "on": []}
    for r in range(repeats):
        for kind, fn in kinds.items():
            progress(f"repeat {r + 1}/{repeats}: optics {kind} on {device}")
            times[kind].append(synchronised(xp, fn))
    import camsim.render.optics as optics_module

    optics_module._PLANS.clear()  # a frame of a light not seen before: its plan and OTF grids made anew
    optics_module._DEVICE_GRIDS.clear()
    cold = synchronised(xp, kinds["on"])
    parts = {}
    optics_module._PLANS.clear()
    t0 = time.perf_counter()
    weights, spectral = optics_plan(lit, expected.signal_e, optics.optics, labels)
    parts["plan"] = time.perf_counter() - t0
    import dataclasses

    spectral = dataclasses.replace(spectral, labels=labels)
    box = {}
    parts["optics"] = synchronised(xp, lambda: box.update(signal=apply_optics(
        static_signal_e(labels, expected.signal_e), optics.optics, lit.grid.wavelengths_nm, weights,
        spectral=spectral)))
    parts["draw"] = synchronised(xp, lambda: render_frame_xp(xp, labels, expected, sensor, rng=1,
                                                             signal_e=box["signal"]))
    off, on = statistics.median(times["off"]), statistics.median(times["on"])
    return {"size": f"{width}x{height}", "optics": OPTICS, "device": device,
            "device_name": device_name() if device == "cuda" else "numpy", "repeats": repeats,
            "off_s": times["off"], "on_s": times["on"], "median_off_s": off, "median_on_s": on,
            "ratio_time": on / off, "ratio_time_plan_reused": (parts["optics"] + parts["draw"]) / off,
            "on_cold_s": cold, "ratio_time_cold": cold / off,
            "pool_mb_off": held["off"], "pool_mb_on": held["on"], "on_parts_s": parts}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="4000x3000")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--device", choices=("cpu", "cuda", "numpy"), default="cpu",
                        help="cpu: camsim render's frames (default); cuda, numpy: the array path's (module docstring)")
    parser.add_argument("--child", choices=("on", "off"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))
    if args.child:
        return child(args.child, width, height, args.workers)
    if args.device != "cpu":
        result = device_run(args.device, width, height, args.repeats)
        print(f"W1 {result['size']} on {result['device_name']}: without optics median "
              f"{result['median_off_s'] * 1e3:.1f} ms, with diffraction + OLPF {result['median_on_s'] * 1e3:.1f} ms "
              f"(ratio {result['ratio_time']:.2f}; a light's first frame {result['on_cold_s'] * 1e3:.1f} ms, ratio "
              f"{result['ratio_time_cold']:.2f}); parts "
              + ", ".join(
                  f"{k} {v * 1e3:.1f} ms" for k, v in result["on_parts_s"].items()))
        print(json.dumps(result))
        return None

    peaks = {}
    for kind in ("off", "on"):
        progress(f"peak RSS, optics {kind}: a fresh process")
        cmd = [sys.executable, str(Path(__file__).resolve()), "--child", kind, "--size", args.size]
        if args.workers:
            cmd += ["--workers", str(args.workers)]
        out = subprocess.run(cmd, check=True, stdout=subprocess.PIPE, text=True).stdout
        peaks[kind] = json.loads(out.strip().splitlines()[-1])["peak_rss_mb"]

    import camsim.render.optics as optics_module
    import camsim.render.raw_frame as raw_frame
    from camsim.render.pipeline import light_scene
    from camsim.sensor.camera import load_camera

    base, optics = scenes(width, height)
    camera = load_camera(base.camera, base.grid, base.sensitivity_basis, base.base_dir)
    lit = light_scene(base, "D65", camera)
    make(base, lit, camera, args.workers)  # warm-up: first calls' set-up
    times = {"off": [], "on": []}
    for r in range(args.repeats):
        for kind, scene in (("off", base), ("on", optics)):
            progress(f"repeat {r + 1}/{args.repeats}: optics {kind}")
            t0 = time.perf_counter()
            frame = make(scene, lit, camera, args.workers)
            times[kind].append(time.perf_counter() - t0)
            del frame

    parts = {"apply_optics": 0.0, "render_expectation_frame": 0.0, "expectation_clean_dn": 0.0}
    originals = {}
    for module, name in ((optics_module, "apply_optics"), (raw_frame, "render_expectation_frame"),
                         (raw_frame, "expectation_clean_dn")):
        original = getattr(module, name)

        def timed(*a, _f=original, _n=name, **k):
            s = time.perf_counter()
            out = _f(*a, **k)
            parts[_n] += time.perf_counter() - s
            return out

        originals[(module, name)] = original
        setattr(module, name, timed)
    t0 = time.perf_counter()
    make(optics, lit, camera, args.workers)
    total = time.perf_counter() - t0
    for (module, name), original in originals.items():
        setattr(module, name, original)

    off, on = statistics.median(times["off"]), statistics.median(times["on"])
    result = {"size": f"{width}x{height}", "optics": OPTICS, "repeats": args.repeats, "workers": args.workers,
              "off_s": times["off"], "on_s": times["on"], "median_off_s": off, "median_on_s": on,
              "ratio_time": on / off, "peak_rss_mb_off": peaks["off"], "peak_rss_mb_on": peaks["on"],
              "ratio_memory": peaks["on"] / peaks["off"],
              "on_parts_s": {**parts, "rest": total - sum(parts.values()), "total": total}}
    print(f"W1 {width}x{height}: without optics median {off:.2f} s, with diffraction + OLPF {on:.2f} s "
          f"(ratio {on / off:.2f}); peak RSS {peaks['off']:.0f} MB vs {peaks['on']:.0f} MB "
          f"(ratio {peaks['on'] / peaks['off']:.2f})")
    print("optics frame's parts: " + ", ".join(f"{k} {v:.2f} s" for k, v in result["on_parts_s"].items()))
    print(json.dumps(result))


if __name__ == "__main__":
    main()
