"""Speed against accuracy of the sampling methods (MODEL.md §5): one chart, every method, F from 1 down to
counts below one electron.

For each sensor (Table I with every stage on; the ideal sensor, whose counts fall below 1 e⁻ at low F), each F
and each method (spectral, poisson, gaussian, auto) it renders the ColorChecker under D65 (``pixel``
statistics, 2 worker threads) and measures:

* speed: pixels per second of ``render_frame`` (median of repeats; file writing excluded);
* error against the exact method on the same work — an independent ``poisson`` frame of the same scene:
  mean and variance bias against the model's exact moments (in standard errors of the sample, median over
  patches and channels), the two-sample Kolmogorov–Smirnov statistic of the pixel values before quantisation
  (largest over patches and channels), and the downstream quantities of ``camsim analyze`` on the written frames
  (ellipse size, relative; ellipse angle, degrees; mean ΔE_ab), as differences from the exact frame's.

The ``poisson`` rows compare two independent exact frames: their KS statistic is the sampling-noise floor of the
comparison (about 1.36 √(2/n) for n pixels a patch). Writes CSV and a PNG chart (median KS against speed, one
curve per method across F).

    python tools/bench_methods.py [--size 1000x700] [--repeats 3] [--out outputs/bench_methods]
"""

from __future__ import annotations

import argparse
import csv
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
METHODS = ("spectral", "poisson", "gaussian", "auto")
FACTORS = (1.0, 0.1, 0.01, 1e-3, 1e-4, 1e-5)
PRESETS = ("paper-table1", "ideal")


def frame_records(scene, lit, camera, sensor, factor, method, seed, workers, folder):
    """Render one frame, write it, analyse it from the files; returns (frame, analysis result, seconds)."""
    from camsim.analysis.analyze import analyse_paths
    from camsim.analysis.patches import AnalysisSettings
    from camsim.frame_files import frame_stem, write_frame
    from camsim.pipeline import make_frame, scene_frame_info

    start = time.perf_counter()
    frame = make_frame(lit, sensor, factor, method=method, rng=seed, workers=workers)
    seconds = time.perf_counter() - start
    info = scene_frame_info(scene.replace(method=method, statistics="pixel"), lit, camera.name, factor, seed)
    folder.mkdir(parents=True, exist_ok=True)
    write_frame(folder, frame_stem(scene.name, f"{method}-{seed}", factor), frame, info)
    result = analyse_paths([folder], AnalysisSettings(), source="exr", progress=False)[0]
    return frame, result, seconds


def compare(frame, exact, rects, result, exact_result):
    """Errors of ``frame`` against the model and against the exact frame (see the module docstring)."""
    from scipy import stats

    ex = frame.expected
    k = frame.sensor.dn_per_electron
    read = frame.sensor.read_noise_e if frame.sensor.read_noise else 0.0
    mean_z, var_z, ks = [], [], []
    for index, (x, y, w, h) in enumerate(rects):
        for c in range(3):
            a = frame.noisy_dn[c, y + 3 : y + h - 3, x + 3 : x + w - 3].ravel().astype(np.float64)
            b = exact.noisy_dn[c, y + 3 : y + h - 3, x + 3 : x + w - 3].ravel()
            lam = ex.signal_e[index, c] + ex.dark_e[c]
            mean, var = k * min(lam, frame.sensor.full_well_e), k * k * (lam + read**2)
            if var <= 0 or lam + 10 * np.sqrt(lam) >= frame.sensor.full_well_e:
                continue  # saturated patches: the moments are not the model's simple ones
            mean_z.append(abs(a.mean() - mean) / np.sqrt(var / a.size))
            var_z.append(abs(a.var(ddof=1) - var) / (var * np.sqrt(2 / a.size + 1 / (max(lam, 1e-9) * a.size))))
            ks.append(stats.ks_2samp(a, b, method="asymp").statistic)
    out = {"mean_bias_se": float(np.median(mean_z)), "var_bias_se": float(np.median(var_z)),
           "ks_max": float(np.max(ks)), "ks_median": float(np.median(ks))}
    sizes, angles, des = [], [], []
    for p, q in zip(result["patches"], exact_result["patches"]):
        if p["size_xy"] and q["size_xy"] and p["ellipse_status"] == q["ellipse_status"] == "ok":
            sizes.append(abs(p["size_xy"] / q["size_xy"] - 1))
            d = abs(p["angle_deg"] - q["angle_deg"]) % 180
            angles.append(min(d, 180 - d))
        if p["delta_e_ab_mean"] is not None and q["delta_e_ab_mean"] is not None:
            des.append(abs(p["delta_e_ab_mean"] - q["delta_e_ab_mean"]))
    median = lambda v: float(np.median(v)) if v else None  # noqa: E731
    out.update(ellipse_size_rel_err=median(sizes), ellipse_angle_err_deg=median(angles), delta_e_err=median(des))
    return out


def chart(rows, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(PRESETS), figsize=(13, 5.5), sharey=True)
    colours = {"spectral": "tab:purple", "poisson": "tab:blue", "gaussian": "tab:red", "auto": "tab:green"}
    for ax, preset in zip(axes, PRESETS):
        floor = [r["ks_median"] for r in rows if r["preset"] == preset and r["method"] == "poisson"]
        for method in METHODS:
            mine = sorted((r for r in rows if r["preset"] == preset and r["method"] == method),
                          key=lambda r: -r["intensity_factor"])
            xs, ys = [r["ks_median"] for r in mine], [r["mpix_per_s"] for r in mine]
            ax.plot(xs, ys, "o-", color=colours[method], label=method)
            for r in mine:
                ax.annotate(f"{r['intensity_factor']:g}", (r["ks_median"], r["mpix_per_s"]), fontsize=7,
                            xytext=(3, 3), textcoords="offset points", color=colours[method])
        if floor:
            ax.axvspan(1e-4, max(floor), color="0.85",
                       label="sampling noise (poisson vs poisson)")
        ax.set(xscale="log", yscale="log", xlabel="error: median two-sample KS against an exact frame",
               title=f"{preset} (labels: F)")
        ax.grid(alpha=0.3, which="both")
    axes[0].set_ylabel("speed: megapixels per second (2 threads)")
    axes[0].legend(fontsize=8)
    fig.suptitle("Sampling methods: error against speed, ColorChecker under D65, pixel statistics")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from camsim.camera import load_camera
    from camsim.chart import parse_size
    from camsim.pipeline import light_scene
    from camsim.scene import load_scene
    from camsim.sensor import PRESETS as SENSORS

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="1000x700")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--out", type=Path, default=ROOT / "outputs" / "bench_methods")
    args = parser.parse_args()
    width, height = parse_size(args.size)
    scene = load_scene(ROOT / "scenes" / "macbeth_26.toml").replace(width=width, height=height)
    camera = load_camera(scene.camera, scene.grid)
    lit = light_scene(scene, "D65", camera)
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_methods_") as tmp:
        for preset in PRESETS:
            sensor = SENSORS[preset]
            for method in ("gaussian", "auto"):  # warm-up, untimed: they tabulate their KS distances once
                frame_records(scene, lit, camera, sensor, 1.0, method, 0, 2, Path(tmp) / f"{preset}-warm")
            for factor in FACTORS:
                exact, exact_result, _ = frame_records(scene, lit, camera, sensor, factor, "poisson", 1, 2,
                                                       Path(tmp) / f"{preset}-{factor}-exact")
                for method in METHODS:
                    times, frame, result = [], None, None
                    for r in range(1 if method == "spectral" else args.repeats):
                        frame, result, seconds = frame_records(scene, lit, camera, sensor, factor, method, 2 + r,
                                                               2, Path(tmp) / f"{preset}-{factor}-{method}-{r}")
                        times.append(seconds)
                    row = {"preset": preset, "intensity_factor": factor, "method": method,
                           "mean_charge_e": float(np.median(frame.expected.signal_e + frame.expected.dark_e)),
                           "mpix_per_s": width * height / 1e6 / statistics.median(times),
                           **compare(frame, exact, lit.radiance.patch_rects, result, exact_result)}
                    if frame.plan is not None and method == "auto":
                        row["auto_gaussian_fraction"] = float(np.mean(frame.plan.kind == 1))
                    rows.append(row)
                    print(f"{preset:13s} F={factor:<7g} {method:18s} {row['mpix_per_s']:8.2f} MP/s  "
                          f"KS median {row['ks_median']:.4f} max {row['ks_max']:.4f}  mean bias {row['mean_bias_se']:.2f} SE  "
                          f"var bias {row['var_bias_se']:.2f} SE", flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    fields = sorted({key for row in rows for key in row}, key=lambda k: list(rows[0]).index(k) if k in rows[0] else 99)
    with open(args.out / "methods.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    chart(rows, args.out / "methods_chart.png")
    print(f"wrote {args.out / 'methods.csv'} and {args.out / 'methods_chart.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
