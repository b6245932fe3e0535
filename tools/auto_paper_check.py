"""``auto`` and ``poisson`` against ``spectral`` (Eq. 4 literally) under ``paper`` statistics at low F: the figures
of the docs' benchmarks page (methods section).

For each F it renders the ColorChecker under D65 (ideal sensor, 360 × 240, 2304 pixels a patch) with ``auto``,
``poisson`` and ``spectral`` and prints, over the 72 patch-channels, the largest two-sample KS statistic of
``auto`` and of ``poisson`` against ``spectral``, the largest fraction of negative values in ``auto``'s frame,
the largest ``gaussian_ks`` recorded and how ``auto`` drew the channels; then the correlation between the
channels of ``spectral``'s white patch against Eq. 4's closed form.

    python tools/auto_paper_check.py [--size 360x240]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
FACTORS = (1e-13, 1e-14, 1e-15, 1e-16, 1e-17, 1e-18)


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from scipy import stats

    from camsim.methods.plan import KIND_NAMES
    from camsim.render.pipeline import light_scene, make_frame
    from camsim.scene.chart import parse_size
    from camsim.scene.scene_file import load_scene
    from camsim.sensor.camera import load_camera
    from camsim.sensor.params import PRESETS

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="360x240")
    args = parser.parse_args()
    width, height = parse_size(args.size)
    scene = load_scene(ROOT / "scenes" / "macbeth_26.toml").replace(width=width, height=height)
    lit = light_scene(scene, "D65", load_camera(scene.camera, scene.grid))
    sensor = PRESETS["ideal"]
    rects = lit.radiance.patch_rects

    def pixels(frame, rect, border=2):
        x, y, w, h = rect
        return frame.noisy_dn[:, y + border : y + h - border, x + border : x + w - border].reshape(3, -1)

    for factor in FACTORS:
        frames = {m: make_frame(lit, sensor, factor, statistics="paper", method=m, rng=seed)
                  for seed, m in enumerate(("auto", "spectral", "poisson"), start=1)}
        ks = {m: [] for m in ("auto", "poisson")}
        negative = []
        for rect in rects:
            exact = pixels(frames["spectral"], rect)
            for m in ks:
                drawn = pixels(frames[m], rect)
                ks[m] += [stats.ks_2samp(drawn[c], exact[c]).statistic for c in range(3)]
            negative += list(np.mean(pixels(frames["auto"], rect) < 0, axis=1))
        n, tests = pixels(frames["auto"], rects[0]).shape[1], 3 * len(rects)
        critical = np.sqrt(-np.log(1e-3 / (2 * tests)) / 2) * np.sqrt(2 / n)
        plan = frames["auto"].plan
        kinds = {KIND_NAMES[k]: int(np.sum(plan.kind[: len(rects)] == k)) for k in np.unique(plan.kind)}
        print(f"F={factor:g}: two-sample KS against spectral, largest of {tests}: auto {max(ks['auto']):.3f}, "
              f"poisson {max(ks['poisson']):.3f} ({n} pixels a patch; 0.1 % critical value over {tests} comparisons "
              f"{critical:.3f}); auto: negative values {max(negative):.3f}, largest gaussian_ks "
              f"{plan.predicted_ks[: len(rects)].max():.3f}, drawn {kinds}", flush=True)
    white = 18
    ex = frames["spectral"].expected
    w = sensor.exposure_s * ex.qe
    cov = (w * ex.photon_rate[white]) @ w.T
    theory = cov / np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    measured = np.corrcoef(pixels(frames["spectral"], rects[white]).astype(np.float64))
    for a, b in ((0, 1), (0, 2), (1, 2)):
        print(f"white patch, spectral, corr({'RGB'[a]}, {'RGB'[b]}): {measured[a, b]:.3f} (Eq. 4: {theory[a, b]:.3f})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
