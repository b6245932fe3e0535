"""GPU benchmark of camsim (issue 15): exact W1 frames on the device, training pairs per second, and the device's
Poisson draws against the exact pmf; with the CPU's figures of the same run beside them.

Workload W1 (as ``tools/bench_w1.py``): the chart of ``scenes/macbeth_26.toml`` under D65 at F = 1, 4000 × 3000 ×
3, the ``paper-table1`` sensor (shot and dark noise, 4 e⁻ read noise, full well, 8-bit ADC), ``pixel`` statistics.

Keys of the JSON line (seconds are medians of ``--repeats`` runs after a warm-up; GPU work is synchronised before
each clock reading):

* ``device`` — the GPU's name, or ``"none"`` (no CuPy, or no GPU: every GPU key is then null);
* ``w1_render_s`` — W1 drawn exactly on the device by the array path (:func:`camsim.render.backends.array_path
  .render_frame_xp`: its generator seeded, the means gathered, Poisson, full well, read noise, gain, ADC), the label
  map already on the device, excluding the copy to the host; ``w1_transfer_s`` — that copy (noisy float32 and
  digital uint8 planes);
* ``pairs_per_s_512`` — noisy/clean pairs of 512 × 512 (Bayer, virtual cameras of every camera with fits, crops of
  scikit-image's astronaut resized to 1024 × 1024, F log-uniform 1e-3 … 1) per second, in batches of
  ``--batch``, the clean target included (:mod:`camsim.pairs`);
* ``poisson_chi2_p_min`` — the smallest p of χ² tests of the device generator's Poisson draws (``--draws`` per λ)
  against the exact Poisson pmf, over λ on a log grid from 0.5 to 10 000 (``poisson_chi2_p`` has each); under
  1e-3 the sampler is suspect (the issue: ``torch.poisson`` on CUDA gives p = 0 at λ = 3000);
* CPU figures of the same run: ``cpu_w1_generic_s`` (the same array path with numpy, one thread),
  ``cpu_w1_fast_s`` (camsim's block renderer, method ``poisson``, every core), ``cpu_pairs_per_s_512`` and
  ``cpu_poisson_chi2_p_min`` (numpy's draws, the same test);
* ``targets`` and ``met`` (H100: W1 ≤ 0.010 s, ≥ 1000 pairs/s, p ≥ 1e-3; null where not measured).

Run:  python tools/bench_gpu.py [--quick] [--repeats N] [--batch B] [--draws N]
``--quick`` (the test suite's smoke run): a 1000 × 750 W1, 128 × 128 pairs, fewer draws; its keys keep their names.
Progress goes to stderr; the last stdout line is the JSON object. Exits 0 with or without a GPU.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
SCENE = ROOT / "scenes" / "macbeth_26.toml"
ILLUMINANT, FACTOR, SEED = "D65", 1.0, 0
LAMBDAS = tuple(float(v) for v in np.geomspace(0.5, 1e4, 13))
TARGETS = {"w1_render_s": 0.010, "pairs_per_s_512": 1000.0, "poisson_chi2_p_min": 1e-3}


def progress(message: str) -> None:
    print(f"[bench_gpu] {message}", file=sys.stderr, flush=True)


def timed(fn, xp, repeats: int) -> float:
    """Median wall time of ``fn()`` over ``repeats`` runs after one warm-up, the device synchronised."""
    from camsim.core.xp import synchronize

    fn()
    synchronize(xp)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        synchronize(xp)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def w1_setup(width: int, height: int) -> dict:
    from camsim.render.pipeline import light_scene
    from camsim.scene.scene_file import load_scene

    scene = load_scene(SCENE).replace(width=width, height=height, illuminants=(ILLUMINANT,),
                                      intensity_factors=(FACTOR,), preset_name="paper-table1", statistics="pixel")
    lit = light_scene(scene, ILLUMINANT)
    return {"scene": scene, "lit": lit, "expected": lit.expected(scene.sensor, FACTOR, "pixel")}


def w1_device(xp, w: dict, repeats: int) -> tuple[float, float]:
    """(render, transfer) seconds of W1 on ``xp``'s device."""
    from camsim.core.xp import to_host
    from camsim.render.backends.array_path import render_frame_xp

    labels = xp.asarray(w["lit"].labels)
    sensor = w["scene"].sensor
    seeds = iter(range(10**6))
    render = timed(lambda: render_frame_xp(xp, labels, w["expected"], sensor, rng=next(seeds)), xp, repeats)
    frame = render_frame_xp(xp, labels, w["expected"], sensor, rng=SEED)
    transfer = timed(lambda: (to_host(frame.noisy_dn), to_host(frame.digital_dn)), xp, repeats)
    return render, transfer


def w1_cpu_fast(w: dict, repeats: int) -> float:
    from camsim.render.pipeline import make_frame

    return timed(lambda: make_frame(w["lit"], w["scene"].sensor, FACTOR, rng=SEED), np, repeats)


def make_image(folder: Path, size: int) -> Path:
    """scikit-image's astronaut resized (bilinear) to ``size`` × ``size``, an 8-bit sRGB PNG in ``folder``."""
    import OpenImageIO as oiio
    import skimage.data
    import skimage.transform

    path = folder / "astronaut_big.png"
    big = skimage.transform.resize(skimage.data.astronaut(), (size, size), order=1, anti_aliasing=False,
                                   preserve_range=True)
    output = oiio.ImageOutput.create(str(path))
    output.open(str(path), oiio.ImageSpec(size, size, 3, oiio.UINT8))
    output.write_image(np.clip(np.rint(big), 0, 255).astype(np.uint8))
    output.close()
    return path


def pairs_per_s(device: str, image: Path, crop: int, batch: int, batches: int) -> float:
    from camsim.core.xp import synchronize
    from camsim.pairs import PairSource
    from camsim.scene.scene_file import load_scene
    from camsim.sensor.presets import CAMERA_PRESETS
    from camsim.sensor.presets.virtual import cameras_with_fits

    scene = load_scene(SCENE).replace(illuminants=(ILLUMINANT,))
    source = PairSource(scene, (str(image),), crop=(crop, crop), batch_size=batch, intensity=(1e-3, 1.0),
                        cameras=cameras_with_fits(CAMERA_PRESETS, distinct=True), cameras_mode="virtual", seed=1,
                        device=device)
    source.batch(0)  # warm-up: the photograph lit, the device's kernels compiled
    synchronize(source.xp)
    start = time.perf_counter()
    for index in range(1, batches + 1):
        source.batch(index)
    synchronize(source.xp)
    return batch * batches / (time.perf_counter() - start)


def poisson_chi2(xp, draws: int) -> dict:
    """χ² p of ``draws`` Poisson draws per λ of :data:`LAMBDAS` on ``xp``'s generator against the exact pmf."""
    from scipy import stats

    from camsim.core.xp import to_host
    from camsim.render.backends import device_generator
    from camsim.sensor.kernels import poisson
    from tests.support.helpers import chi2_p_counts  # the tests' χ² (ROOT is on the path)

    rng = device_generator(xp, np.random.SeedSequence(SEED, spawn_key=(0xC412,)))
    out = {}
    for lam in LAMBDAS:
        values = to_host(poisson(rng, xp.full(draws, lam))).astype(np.int64)
        lo, hi = max(0, int(lam - 13 * np.sqrt(lam) - 20)), int(lam + 13 * np.sqrt(lam) + 20)
        if values.min() < lo or values.max() > hi:
            out[f"{lam:.4g}"] = 0.0
            continue
        observed = np.bincount(values - lo, minlength=hi - lo + 1).astype(float)
        expected = stats.poisson.pmf(np.arange(lo, hi + 1), lam) * draws
        out[f"{lam:.4g}"] = chi2_p_counts(observed, expected)  # bins pooled until each expects ≥ 5
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="small sizes: a smoke run")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--batch", type=int, default=16, help="pairs per batch (default 16)")
    parser.add_argument("--draws", type=int, default=None, help="Poisson draws per λ (default 1e6, quick 1e5)")
    args = parser.parse_args()
    width, height = (1000, 750) if args.quick else (4000, 3000)
    crop, batches = (128, 2) if args.quick else (512, 20)
    repeats = 1 if args.quick else args.repeats
    draws = args.draws or (100_000 if args.quick else 1_000_000)

    from camsim.core.errors import CamsimError
    from camsim.render.backends import cuda_module, device_name

    result = {"device": device_name(), "w1_size": [width, height], "pair_size": crop, "batch": args.batch}
    try:
        cupy = cuda_module()
    except CamsimError as exc:
        progress(f"no GPU ({exc}); CPU figures only")
        cupy = None
    w = w1_setup(width, height)
    with tempfile.TemporaryDirectory() as tmp:
        image = make_image(Path(tmp), max(2 * crop, 256))
        if cupy is not None:
            progress("W1 on the GPU")
            result["w1_render_s"], result["w1_transfer_s"] = w1_device(cupy, w, repeats)
            progress("pairs on the GPU")
            result["pairs_per_s_512"] = pairs_per_s("cuda", image, crop, args.batch, 5 * batches)
            progress("Poisson draws on the GPU")
            result["poisson_chi2_p"] = poisson_chi2(cupy, draws)
            result["poisson_chi2_p_min"] = min(result["poisson_chi2_p"].values())
        else:
            result.update(w1_render_s=None, w1_transfer_s=None, pairs_per_s_512=None, poisson_chi2_p=None,
                          poisson_chi2_p_min=None)
        progress("W1 on the CPU: the array path with numpy, then the block renderer")
        result["cpu_w1_generic_s"], _ = w1_device(np, w, repeats)
        result["cpu_w1_fast_s"] = w1_cpu_fast(w, repeats)
        progress("pairs on the CPU")
        result["cpu_pairs_per_s_512"] = pairs_per_s("cpu", image, crop, args.batch, batches)
        progress("Poisson draws on the CPU")
        cpu_p = poisson_chi2(np, draws)
        result["cpu_poisson_chi2_p_min"] = min(cpu_p.values())
    result["targets"] = TARGETS
    result["met"] = {
        "w1_render_s": None if result["w1_render_s"] is None else result["w1_render_s"] <= TARGETS["w1_render_s"],
        "pairs_per_s_512": None if result["pairs_per_s_512"] is None
        else result["pairs_per_s_512"] >= TARGETS["pairs_per_s_512"],
        "poisson_chi2_p_min": None if result["poisson_chi2_p_min"] is None
        else result["poisson_chi2_p_min"] >= TARGETS["poisson_chi2_p_min"],
    }
    print(json.dumps(result))


if __name__ == "__main__":
    main()
