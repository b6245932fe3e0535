"""Training pairs per second in each domain of :mod:`camsim.pairs` on the CPU: ``dn`` (as rendered), ``raw``
(normalised, packed R, G1, G2, B) and ``srgb`` (developed through the ISP), side by side in one run, with the
ratio srgb / raw (issue 26's target: at least 0.8), and which path developed the srgb pairs (the ISP's compiled
kernel, :mod:`camsim.isp.fused`, or its numpy stages).

Every domain renders the same batches (the same seed: the same images, crops, cameras, F and noise), so the
difference is what the domain's conversion costs. The domains are timed in turn, round after round (``--repeats``
rounds of ``--batches`` batches each), and each rate is the domain's best round (the figure least moved by other
work on a shared machine, and the domains see the same changes of load), after a warm-up round (which pays for the
photographs' recovery, the lit scenes of every illuminant and colour-science's imports). ``--profile`` also times
the ISP's stages on one image of the batch, one by one, the pair through the numpy stages, one image through the
compiled kernel, and the pair as the srgb domain develops it (to see where the sRGB time goes). The warm-up round's
times are printed too: the srgb domain's includes numba's compilation of the kernel (once per process).

    python tools/bench_pair_domains.py [--crop 256x256] [--batch-size 8] [--batches 4] [--repeats 5]
                                       [--camera sony-a7s2] [--demosaic bilinear] [--profile]
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


def rates(sources: dict, batches: int, repeats: int, seconds: dict | None = None) -> dict:
    """Pairs per second of each source: its best of ``repeats`` rounds of batches 0 … batches − 1, the sources
    timed in turn in each round (``seconds``, if given, receives each source's best round in seconds)."""
    best = dict.fromkeys(sources, float("inf"))
    for _ in range(repeats):
        for name, source in sources.items():
            start = time.perf_counter()
            for index in range(batches):
                source.batch(index)
            best[name] = min(best[name], time.perf_counter() - start)
    if seconds is not None:
        seconds.update(best)
    return {name: batches * sources[name].batch_size / t for name, t in best.items()}


def profile(source_srgb) -> list[tuple[str, float]]:
    """Seconds of each ISP stage on one pair of batch 0 (the noisy frame), best of 5, as :func:`camsim.isp.develop`
    runs them: with a per-channel linear demosaicing (bilinear) the white balance, the matrix and the gain are one
    3 × 3 matrix after demosaicing; otherwise stage by stage."""
    import numpy as np

    from camsim.core.xp import to_host
    from camsim.isp import apply_gain, apply_matrix, apply_white_balance, demosaic, normalise, tone_curve
    from camsim.isp.develop import _develop_pair_into, _fused_matrix, _linear_after_demosaic, _plan

    settings = source_srgb.isp
    if settings is None:
        from camsim.pairs import pair_isp

        settings = pair_isp()
    dn = source_srgb.__class__(**{**{f: getattr(source_srgb, f) for f in (
        "scene", "images", "crop", "batch_size", "intensity", "cameras", "iso", "cameras_mode", "k_range", "flips",
        "seed", "device")}, "domain": "dn", "isp": None})
    batch = dn.batch(0)
    p = batch.params[0]
    from camsim.sensor.presets import sensor_preset

    sensor = sensor_preset(p["preset"], p["iso"])
    facts = dn._facts(p, sensor)
    raw = to_host(batch.noisy[0])
    raw = raw[0] if facts.cfa_pattern else raw
    clean = to_host(batch.clean[0])
    clean = clean[0] if facts.cfa_pattern else clean
    steps = []

    def timed(name, fn):
        best = float("inf")
        for _ in range(5):
            t = time.perf_counter()
            out = fn()
            best = min(best, time.perf_counter() - t)
        steps.append((name, best))
        return out

    plan = timed("plan (gains, matrix, record)", lambda: _plan(facts, settings))
    x = timed("normalise", lambda: normalise(raw, facts))
    fused = _linear_after_demosaic(facts, settings)
    if not fused:
        x = timed("white balance", lambda: apply_white_balance(x, plan.gains, facts.cfa_pattern))
    if facts.cfa_pattern:
        x = timed(f"demosaic ({settings.demosaic})", lambda: demosaic(x, facts.cfa_pattern, settings.demosaic))
    if fused:
        m = _fused_matrix(plan).astype(np.float32)
        x = timed("wb · matrix · gain (one 3 x 3)", lambda: np.matmul(m, x.reshape(3, -1)).reshape(x.shape))
    else:
        x = timed("matrix", lambda: apply_matrix(x, plan.matrix) if plan.matrix is not None else x)
        x = timed("gain", lambda: apply_gain(x, plan.gain))
    timed(f"tone ({settings.tone})", lambda: tone_curve(x, settings.tone))
    assert np.all(np.isfinite(x))
    shape = (3, *raw.shape[-2:])
    out_noisy, out_clean = np.empty(shape, dtype=np.float32), np.empty(shape, dtype=np.float32)
    timed("the pair (numpy stages)", lambda: _develop_pair_into(raw, clean, facts, settings, out_noisy, out_clean))
    from camsim.isp import fused

    if fused.fused_applies(facts, settings, raw.shape) and fused.fused_kernels() is not None:
        timed("one image (compiled kernel)", lambda: fused.develop_into(raw, facts, settings, plan, out_noisy))
    timed("the pair (as camsim.pairs)",
          lambda: fused.develop_pair_into(raw, clean, facts, settings, out_noisy, out_clean))
    return steps


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--crop", default="256x256", help="pair size WxH (default 256x256)")
    parser.add_argument("--batch-size", type=int, default=8)
    parser.add_argument("--batches", type=int, default=4, help="batches per timed run (default 4)")
    parser.add_argument("--repeats", type=int, default=5, help="timed rounds (default 5)")
    parser.add_argument("--camera", default="sony-a7s2", help="camera preset (default sony-a7s2, Bayer)")
    parser.add_argument("--demosaic", default=None, help="the srgb domain's demosaicing (default: pair_isp's)")
    parser.add_argument("--profile", action="store_true", help="also time the ISP's stages on one pair")
    args = parser.parse_args(argv)

    from camsim.isp import IspSettings
    from camsim.pairs import PAIR_DOMAINS, PairSource, pair_isp

    width, height = (int(v) for v in args.crop.lower().split("x"))
    isp = pair_isp() if args.demosaic is None else IspSettings(gain="auto", demosaic=args.demosaic)
    common = {"crop": (width, height), "batch_size": args.batch_size, "cameras": (args.camera,),
              "intensity": (1e-3, 0.1), "seed": 3, "device": "cpu"}
    images = ROOT / "camsim" / "scenes" / "images"
    sources = {domain: PairSource.from_scene("macbeth_26", images, domain=domain, **common,
                                             **({"isp": isp} if domain == "srgb" else {}))
               for domain in PAIR_DOMAINS}
    warm_up: dict = {}
    rates(sources, args.batches, 1, warm_up)  # warm-up: recovery, lit scenes (every illuminant), imports, numba
    measured = rates(sources, args.batches, args.repeats)
    path = sources["srgb"].batch(0).isp[0]["path"]
    print(f"camsim.pairs on the CPU ({platform.processor() or platform.machine()}, {os.cpu_count()} cores, load "
          f"{os.getloadavg()[0]:.1f}), camera {args.camera}, crop {width}x{height}, batch {args.batch_size}, best of "
          f"{args.repeats} rounds of {args.batches} batches; srgb: demosaic {isp.demosaic}, gain {isp.gain}, "
          f"tone {isp.tone}; one thread")
    print(f"{'domain':<10}{'pairs/s':>10}{'MP/s':>9}")
    for name, value in measured.items():
        print(f"{name:<10}{value:>10.2f}{value * width * height / 1e6:>9.2f}")
    print(f"srgb / raw = {measured['srgb'] / measured['raw']:.3f} (target >= 0.8); raw / dn = "
          f"{measured['raw'] / measured['dn']:.3f}")
    print(f"srgb path: {path}")
    print("warm-up round (first in this process; srgb's includes compiling the ISP kernel, once per process): "
          + ", ".join(f"{name} {value:.2f} s" for name, value in warm_up.items()))
    if args.profile:
        print("ISP stages on one image, one by one, and on the pair (best of 5):")
        for name, seconds in profile(sources["srgb"]):
            print(f"  {name:<30}{seconds * 1e3:>9.2f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
