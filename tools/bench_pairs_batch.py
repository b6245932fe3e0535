"""Training pairs per second and array calls per batch (:mod:`camsim.pairs`), this checkout against another one
(``--before``: e.g. a checkout of the code before a change), side by side in one run.

The pairs are those of ``tools/bench_gpu.py``'s ``pairs_per_s``: virtual cameras of every camera with fits (Bayer,
14 bits, Tukey read noise, row noise), crops of scikit-image's astronaut resized to 1024 × 1024, F log-uniform
1e-3 … 1, in batches of ``--batch``; here at several crop sizes (``--crops``, default 32, 128, 512). Each checkout
runs in its own process (its ``camsim`` imported first, from its folder); the checkouts take turns, ``--rounds``
rounds, each rate its best round (after a warm-up batch).

``calls`` is the number of array-library calls one batch makes on a device (the ``--count-crop`` crop, default 32:
the count does not depend on the size), counted by running the batch on :mod:`tests.support.fake_cupy` — numpy behind
CuPy's rules — as ``device="cuda"``: ``calls`` (what launches a kernel on a GPU: ufuncs, functions, reductions,
copies, gathers, random draws), ``views`` (Python only), ``to_device`` and ``to_host`` (transfers; ``to_host``
includes the synchronising ``bool``/``float`` of an array). Each CuPy call costs ~10–20 µs of launch and Python
whatever its size, which is what bounds small pairs on a GPU.

Run:  python tools/bench_pairs_batch.py [--before PATH] [--device cpu|cuda] [--crops 32,128,512] [--batch 16]
                                        [--rounds 2] [--seconds 3]
Prints a table (stderr: progress) and, last, one JSON line.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _worker(args) -> dict:
    """In a fresh process: ``camsim`` imported from ``args.checkout``; pairs/s per crop, and the call counts."""
    sys.path.insert(0, str(args.checkout))
    import camsim  # first: every camsim module comes from the checkout's package from now on

    assert Path(camsim.__file__).resolve().is_relative_to(Path(args.checkout).resolve()), camsim.__file__
    import importlib.util

    def load(name: str, path: Path):
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module

    from camsim.core.xp import synchronize
    from camsim.pairs import PairSource
    from camsim.scene.scene_file import load_scene
    from camsim.sensor.presets import CAMERA_PRESETS
    from camsim.sensor.presets.virtual import cameras_with_fits

    scene = load_scene(ROOT / "scenes" / "macbeth_26.toml").replace(illuminants=("D65",))
    cameras = cameras_with_fits(CAMERA_PRESETS, distinct=True)

    def source(crop: int, device: str):
        return PairSource(scene, (args.image,), crop=(crop, crop), batch_size=args.batch, intensity=(1e-3, 1.0),
                          cameras=cameras, cameras_mode="virtual", seed=1, device=device)

    out = {"rates": {}}
    if args.count:
        fake_cupy = load("fake_cupy", ROOT / "tests" / "support" / "fake_cupy.py")
        with fake_cupy.installed():
            counted = source(args.count_crop, "cuda")
            counted.batch(0)
            fake_cupy.reset()
            counted.batch(1)
            out["counts"] = {k: v for k, v in fake_cupy.COUNTS.items() if ":" not in k}
            out["top_calls"] = dict(sorted(((k.split(":", 1)[1], v) for k, v in fake_cupy.COUNTS.items()
                                            if k.startswith("calls:")), key=lambda kv: -kv[1])[:12])
    for crop in args.crops:
        src = source(crop, args.device)
        src.batch(0)  # warm-up: the photograph lit, the kernels compiled
        synchronize(src.xp)
        index, start = 1, time.perf_counter()
        while True:
            src.batch(index)
            index += 1
            synchronize(src.xp)
            elapsed = time.perf_counter() - start
            if elapsed >= args.seconds and index > 2:
                break
        out["rates"][str(crop)] = args.batch * (index - 1) / elapsed
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--before", type=Path, default=None, help="another checkout to compare with")
    parser.add_argument("--device", default="cpu", choices=("cpu", "cuda"))
    parser.add_argument("--crops", default="32,128,512")
    parser.add_argument("--batch", type=int, default=16)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=3.0, help="time per crop and round (at least 2 batches)")
    parser.add_argument("--count-crop", type=int, default=32)
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--checkout", type=Path, default=ROOT, help=argparse.SUPPRESS)
    parser.add_argument("--image", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--count", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    args.crops = [int(c) for c in str(args.crops).split(",")]
    if args.worker:
        print(json.dumps(_worker(args)))
        return
    checkouts = {"after": ROOT} | ({} if args.before is None else {"before": args.before.resolve()})
    results = {name: {"rates": {}, "counts": None} for name in checkouts}
    with tempfile.TemporaryDirectory() as tmp:
        sys.path.insert(0, str(ROOT))
        sys.path.insert(0, str(ROOT / "tools"))
        from bench_gpu import make_image

        image = make_image(Path(tmp), 1024)
        for r in range(args.rounds):
            for name, checkout in checkouts.items():
                print(f"[bench_pairs_batch] round {r + 1}: {name} ({checkout})", file=sys.stderr, flush=True)
                command = [sys.executable, __file__, "--worker", "--checkout", str(checkout), "--image", str(image),
                           "--device", args.device, "--crops", ",".join(map(str, args.crops)), "--batch",
                           str(args.batch), "--seconds", str(args.seconds), "--count-crop", str(args.count_crop)]
                if r == 0:
                    command.append("--count")
                done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT)
                if done.returncode:
                    sys.exit(f"worker for {name} failed:\n{done.stderr[-3000:]}")
                got = json.loads(done.stdout.strip().splitlines()[-1])
                for crop, rate in got["rates"].items():
                    results[name]["rates"][crop] = max(rate, results[name]["rates"].get(crop, 0.0))
                if "counts" in got:
                    results[name]["counts"], results[name]["top_calls"] = got["counts"], got["top_calls"]
    names = list(checkouts)
    print(f"pairs/s on {args.device}, batches of {args.batch} (best of {args.rounds} rounds)")
    print("crop   " + "".join(f"{n:>12}" for n in names) + ("      after/before" if "before" in names else ""))
    for crop in map(str, args.crops):
        rates = [results[n]["rates"][crop] for n in names]
        ratio = f"{rates[0] / rates[1]:>18.2f}" if len(rates) == 2 else ""
        print(f"{crop:>4}   " + "".join(f"{v:>12.1f}" for v in rates) + ratio)
    print(f"array calls per batch of {args.batch} (fake CuPy, crop {args.count_crop})")
    for key in ("calls", "views", "allocations", "to_device", "to_host"):
        print(f"{key:>11}" + "".join(f"{results[n]['counts'].get(key, 0):>12}" for n in names))
    print(json.dumps({"device": args.device, "batch": args.batch, "results": results}))


if __name__ == "__main__":
    main()
