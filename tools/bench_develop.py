"""``camsim develop`` of a 12 MP Bayer frame against colour-demosaicing's own demosaicing call on the same mosaic
(issue 26, "Speed": the whole pipeline with Malvar 2004 within 2× the time of colour-demosaicing's Malvar call).

The frame: the built-in ``macbeth_26`` chart at 4000 × 3000 pixels through the ``sony-a7s2`` preset (14-bit RGGB),
F = 1 under D65, rendered once into ``--frames DIR`` (default a temporary folder; an existing frame there is
reused). Per demosaicing method (Malvar 2004, bilinear, Menon 2007) and round, in one process:

* ``colour-demosaicing``: ``demosaicing_CFA_Bayer_<method>(mosaic, "RGGB")`` on the DNG's mosaic as float64 (the
  library's own dtype), already in memory;
* ``camsim develop``: ``camsim develop FRAME.dng --out DIR --demosaic <method>`` run in this process
  (``camsim.cli.main``): reading the DNG and its sidecar, the ISP (black level, white balance, demosaicing,
  colour matrix, gain, sRGB tone curve) and writing the 8-bit PNG and the JSON record.

The methods are interleaved round by round (``--repeats``, default 3; Menon 2007 once unless ``--menon-repeats``)
and each figure is the best (smallest) wall time, the least disturbed by other work on the machine. Printed side by
side with the ratio develop / colour-demosaicing. Then where the time of a Malvar development goes: each step of
``camsim develop`` timed on its own (reading the frame, each ISP stage, the 8-bit encoding, the PNG's compression),
best of ``--repeats``. The last stdout line is all of it as JSON.

Run:  python tools/bench_develop.py [--repeats N] [--menon-repeats N] [--frames DIR]
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SIZE = "4000x3000"
FRAME = "macbeth_26_D65_F1.dng"
FUNCTIONS = {"malvar2004": "demosaicing_CFA_Bayer_Malvar2004", "bilinear": "demosaicing_CFA_Bayer_bilinear",
             "menon2007": "demosaicing_CFA_Bayer_Menon2007"}
TARGET = 2.0


def render(folder: Path) -> Path:
    """The 12 MP frame in ``folder``, rendered if it is not there yet."""
    from camsim.cli import main

    path = folder / FRAME
    if not path.exists():
        status = main(["render", "macbeth_26", "--preset", "sony-a7s2", "--size", SIZE, "-F", "1", "--illuminant",
                       "D65", "--out", str(folder), "-q"])
        if status != 0:
            raise SystemExit(f"render failed with status {status}")
    return path


def timed(call) -> float:
    start = time.perf_counter()
    call()
    return time.perf_counter() - start


def stage_times(path: Path, repeats: int) -> dict[str, float]:
    """Each step of a Malvar 2004 development of ``path``, timed alone: best wall time of ``repeats``. Unit: s."""
    import camsim.isp as isp
    from camsim.isp.files import read_frame_to_develop
    from camsim.isp.writers import PNG_COMPRESS_LEVEL, _png_bytes, encode_image

    best: dict[str, float] = {}

    def step(name, call):
        start = time.perf_counter()
        value = call()
        best[name] = min(best.get(name, float("inf")), time.perf_counter() - start)
        return value

    for _ in range(repeats):
        frame = step("read DNG and sidecar", lambda: read_frame_to_develop(path))
        facts = frame.facts
        gains, matrix = step("white-balance gains, matrix",
                             lambda: (isp.white_balance_gains(facts, "as-shot"), isp.srgb_matrix(facts)))
        x = step("black and white level", lambda: isp.normalise(frame.raw, facts))
        x = step("white balance", lambda: isp.apply_white_balance(x, gains, facts.cfa_pattern))
        x = step("demosaic (malvar2004)", lambda: isp.demosaic(x, facts.cfa_pattern, "malvar2004"))
        x = step("colour matrix", lambda: isp.apply_matrix(x, matrix))
        x = step("sRGB tone curve", lambda: isp.tone_curve(x, "srgb"))
        pixels = step("8-bit encoding", lambda: encode_image(x, 8))
        step(f"PNG (zlib level {PNG_COMPRESS_LEVEL})", lambda: _png_bytes(pixels, "{}", PNG_COMPRESS_LEVEL))
    return best


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--menon-repeats", type=int, default=1)
    parser.add_argument("--frames", type=Path, help="folder for the rendered frame (default: a temporary one)")
    args = parser.parse_args()

    import colour_demosaicing
    import numpy as np

    from camsim.cli import main as camsim_main
    from camsim.io.dng import read_dng

    with tempfile.TemporaryDirectory() as tmp:
        frames = args.frames or Path(tmp) / "frames"
        frames.mkdir(parents=True, exist_ok=True)
        path = render(frames)
        mosaic = read_dng(path)[0][0].astype(np.float64)
        out = Path(tmp) / "developed"
        best: dict[str, dict[str, float]] = {m: {"colour-demosaicing": float("inf"), "camsim develop": float("inf")}
                                             for m in FUNCTIONS}
        rounds = max(args.repeats, args.menon_repeats)
        for round_ in range(rounds):
            for method, function in FUNCTIONS.items():
                if round_ >= (args.menon_repeats if method == "menon2007" else args.repeats):
                    continue
                call = getattr(colour_demosaicing, function)
                t_lib = timed(lambda: call(mosaic, "RGGB"))
                with contextlib.redirect_stdout(io.StringIO()):
                    t_dev = timed(lambda: camsim_main(["develop", str(path), "--out", str(out), "--demosaic", method,
                                                       "-q"]))
                best[method]["colour-demosaicing"] = min(best[method]["colour-demosaicing"], t_lib)
                best[method]["camsim develop"] = min(best[method]["camsim develop"], t_dev)
        png = (out / FRAME.replace(".dng", ".png")).stat().st_size
        steps = stage_times(path, args.repeats)
    print(f"12 MP Bayer frame ({SIZE}, sony-a7s2 14-bit RGGB), best of {args.repeats} "
          f"(Menon 2007: {args.menon_repeats}); 8-bit PNG of {png / 1e6:.1f} MB")
    print(f"{'method':<12} {'colour-demosaicing s':>21} {'camsim develop s':>17} {'ratio':>7}")
    result = {"size": SIZE, "repeats": args.repeats, "menon_repeats": args.menon_repeats, "target_ratio": TARGET,
              "methods": {}}
    for method, times in best.items():
        ratio = times["camsim develop"] / times["colour-demosaicing"]
        print(f"{method:<12} {times['colour-demosaicing']:>21.2f} {times['camsim develop']:>17.2f} {ratio:>7.2f}")
        result["methods"][method] = {**times, "ratio": ratio}
    result["met"] = result["methods"]["malvar2004"]["ratio"] <= TARGET
    print(f"where a Malvar 2004 development's time goes (best of {args.repeats}):")
    for step, seconds in steps.items():
        print(f"  {step:<28} {seconds:>6.2f} s")
    result["steps_s"] = steps
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
