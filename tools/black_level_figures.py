"""The README's black-level figures: dark-frame means against the black level, and what raw readers' black-level
handling does to the neutral ColorChecker patches.

1. Dark frames (no light: every spectrum zero) of 2000 × 2000 pixels from :func:`camsim.pipeline.make_frame`, per
   channel: the old BlackLevel k · σ²_dark · T (now ``dark_level_dn``), the black level ``black_level_dn`` and the
   frame's mean DN ± one standard error (from the row means: rows are independent, pixels of a row are not when
   there is row noise), for Table I (three-chip and Bayer) and a 12-bit Bayer sensor with DSNU, row noise and
   Tukey λ read noise; with the time the black level takes to compute.
2. A Table I frame of ``macbeth_26`` at F = 1 under D65, written as a three-chip and a Bayer DNG, developed by
   LibRaw (rawpy, linear 16-bit, AsShotNeutral) with each reader's black-level handling imposed through
   ``user_black`` / ``user_cblack`` (darktable: none; dcraw: R's truncated value for all; RawTherapee's dcraw
   decoder: R's for R only): R/G and B/G of the neutral patches.

    python tools/black_level_figures.py [--size 2000] [--workdir DIR]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from camsim.cfa import cfa_sites
from camsim.pipeline import LitScene, make_frame
from camsim.sensor import PRESETS
from camsim.spectra import WavelengthGrid

NEUTRALS = ("white 9.5 (.05 D)", "neutral 5 (.70 D)", "neutral 3.5 (1.05 D)", "black 2 (1.5 D)")


def dark_means(sensor, size: int, seed: int = 1):
    """Per channel (mean DN, standard error) of a dark frame of ``sensor``."""
    grid = WavelengthGrid()
    n = grid.wavelengths_nm.size
    lit = LitScene(np.zeros((size, size), np.uint8), np.zeros((1, n)), np.full((3, n), 1e-20), grid)
    dn = make_frame(lit, sensor, 1.0, rng=seed).digital_dn
    out = []
    for c in range(3):
        if sensor.cfa is None:
            rows = dn[c].astype(np.float64).mean(axis=1)
        else:
            rows = np.concatenate([dn[0, dy::2, dx::2].astype(np.float64).mean(axis=1)
                                   for dy, dx, cc in cfa_sites(sensor.cfa) if cc == c])
        out.append((rows.mean(), rows.std(ddof=1) / np.sqrt(rows.size)))
    return out


def readers(workdir: Path):
    import rawpy

    for label, extra in (("three-chip", []), ("Bayer", ["--cfa", "RGGB"])):
        out = workdir / label
        subprocess.run([sys.executable, "-m", "camsim", "render", "macbeth_26", "--illuminant", "D65", "--intensity",
                        "1", "--size", "600x400", "--seed", "3", "--out", str(out), "-q", *extra], check=True,
                       stdout=subprocess.DEVNULL)
        meta = json.loads((out / "macbeth_26_D65_F1.json").read_text())
        rects = {p["name"]: p["rect_xywh"] for p in meta["patches"]}
        with rawpy.imread(str(out / "macbeth_26_D65_F1.dng")) as raw:
            libraw = [int(b) for b in raw.black_level_per_channel]
            r_black = libraw[0]
            variants = {f"LibRaw {libraw[:3]}": {}}
            if label == "three-chip":
                variants.update({"none (darktable)": dict(user_black=0, user_cblack=[0, 0, 0, 0]),
                                 f"R's {r_black} for all (dcraw)": dict(user_black=r_black, user_cblack=[0, 0, 0, 0]),
                                 f"R's {r_black} for R only (RawTherapee, dcraw decoder)":
                                     dict(user_black=0, user_cblack=[r_black, 0, 0, 0])})
            for name, kw in variants.items():
                rgb = raw.postprocess(gamma=(1, 1), no_auto_bright=True, output_bps=16, use_camera_wb=True,
                                      **kw).astype(np.float64)
                cells = []
                for patch in NEUTRALS:
                    x, y, w, h = rects[patch]
                    m = rgb[y + 4:y + h - 4, x + 4:x + w - 4].reshape(-1, 3).mean(axis=0)
                    cells.append(f"{m[0] / m[1]:.3f} / {m[2] / m[1]:.3f}")
                print(f"| {label}, {name} | " + " | ".join(cells) + " |")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=2000, help="dark frame side, pixels (default 2000)")
    parser.add_argument("--workdir", type=Path, help="where the DNGs go (default: a temporary folder)")
    args = parser.parse_args()
    cases = {
        "Table I, three-chip, 8 bits": PRESETS["paper-table1"],
        "Table I, Bayer RGGB, 8 bits": dataclasses.replace(PRESETS["paper-table1"], cfa="RGGB"),
        "emva-12bit, Bayer RGGB, DSNU 2 e-, row 1 e-, Tukey -0.1": dataclasses.replace(
            PRESETS["emva-12bit"], cfa="RGGB", row_noise_e=1.0, read_noise_model="tukey-lambda"),
    }
    print("| sensor | old BlackLevel k·σ²_dark·T | BlackLevel now | dark frame's mean DN | compute time |")
    for name, sensor in cases.items():
        t = time.perf_counter()
        black = sensor.black_level_dn
        ms = 1000 * (time.perf_counter() - t)
        means = dark_means(sensor, args.size)
        print(f"| {name} | {' / '.join(f'{v:.4f}' for v in sensor.dark_level_dn)} | "
              f"{' / '.join(f'{v:.4f}' for v in black)} | "
              f"{' / '.join(f'{m:.4f} ± {se:.4f}' for m, se in means)} | {ms:.1f} ms |")
    print("\n| black subtracted | " + " | ".join(NEUTRALS) + " |  (R/G / B/G)")
    if args.workdir is not None:
        args.workdir.mkdir(parents=True, exist_ok=True)
        readers(args.workdir)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            readers(Path(tmp))
    return 0


if __name__ == "__main__":
    sys.exit(main())
