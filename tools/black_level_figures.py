"""The black-level figures of the docs (benchmarks page): dark-frame means against the black level.

1. Dark frames (no light: every spectrum zero) of 2000 × 2000 pixels from :func:`camsim.render.pipeline.make_frame`, per
   channel: the old BlackLevel k · σ²_dark · T (now ``dark_level_dn``), the black level ``black_level_dn`` and the
   frame's mean DN ± one standard error (from the row means: rows are independent, pixels of a row are not when
   there is row noise), for Table I (three-chip and Bayer) and a 12-bit Bayer sensor with DSNU, row noise and
   Tukey λ read noise; with the time the black level takes to compute.

What the raw readers themselves make of the DNGs' black level is measured by running them:
``tools/raw_readers.py``.

    python tools/black_level_figures.py [--size 2000]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time

import numpy as np

from camsim.light.spectra import WavelengthGrid
from camsim.render.pipeline import LitScene, make_frame
from camsim.sensor.cfa import cfa_sites
from camsim.sensor.params import PRESETS


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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=2000, help="dark frame side, pixels (default 2000)")
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
    return 0


if __name__ == "__main__":
    sys.exit(main())
