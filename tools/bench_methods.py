"""Speed against accuracy of the sampling methods (MODEL.md §5): one chart, every method, F from 1 down to
counts below one electron.

For each sensor (Table I with every stage on; the ideal sensor, whose counts fall below 1 e⁻ at low F), each F
and each method (spectral, poisson, table, gaussian, auto) it renders the ColorChecker under D65 (``pixel``
statistics, 2 worker threads) and measures:

* speed: pixels per second of ``render_frame`` (the fastest of the repeats, the figure least moved by other work
  on a shared machine; file writing excluded);
* error against the exact law, computed analytically (:func:`camsim.sensor.dn_law.dn_pmf`): per patch and channel, the
  total variation (TV) and Kolmogorov–Smirnov distances between the frame's digital numbers (Table I) or its
  values binned to whole electrons (the ideal sensor, unquantised) and their exact pmf, beside the noise floor of
  an exact sampler with as many pixels (E[TV], :func:`camsim.sensor.dn_law.expected_tv`: the mean over patches and
  channels of E[TV] is exactly what an exact sampler's mean TV is on average; the KS floor as the median over 16
  multinomial samples of the exact pmf) — at the chart's size and at a large size (default 4000 × 3000, where the
  floor is about 4 times lower; ``spectral`` only at the chart's size: its law under ``pixel`` statistics is
  ``poisson``'s), and a χ² test of each patch and channel against the exact pmf (bins of at least 5 expected
  counts): how many of the 72 reject at 1 % and the pooled p-value (log10);
* error against an exact frame, as before: an independent ``poisson`` frame of the same scene: mean and variance
  bias against the model's exact moments (in standard errors of the sample, median over patches and channels),
  the two-sample KS statistic of the pixel values before quantisation (largest and median over patches and
  channels; its own sampling noise, about 1.36 √(2/n) for n pixels a patch, hides smaller differences), and the
  downstream quantities of ``camsim analyze`` on the written frames (ellipse size, relative; ellipse angle,
  degrees; mean ΔE_ab), as differences from the exact frame's.

Writes CSV and a PNG chart (top: mean TV to the exact law in units of its floor, against speed, one curve per
method across F; bottom: mean TV against F at both sizes, with the exact sampler's floors).

    python tools/bench_methods.py [--size 1000x700] [--large 4000x3000] [--repeats 5] [--out outputs/bench_methods]
"""

from __future__ import annotations

import argparse
import csv
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
METHODS = ("spectral", "poisson", "table", "gaussian", "auto")
FACTORS = (1.0, 0.1, 0.01, 1e-3, 1e-4, 1e-5)
PRESETS = ("paper-table1", "ideal")


def frame_records(scene, lit, camera, sensor, factor, method, seed, workers, folder):
    """Render one frame, write it, analyse it from the files; returns (frame, analysis result, seconds)."""
    from camsim.analysis.analyze import analyse_paths
    from camsim.analysis.patches import AnalysisSettings
    from camsim.render.frame_files import frame_stem, write_frame
    from camsim.render.pipeline import make_frame, scene_frame_info

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


def patch_values(frame, rect, c, border=3):
    """A patch's integer values in channel ``c``: digital numbers, or (unquantised) floor of the DN value."""
    x, y, w, h = rect
    if frame.digital_dn is not None:
        return frame.digital_dn[c, y + border : y + h - border, x + border : x + w - border].ravel()
    return np.floor(frame.noisy_dn[c, y + border : y + h - border, x + border : x + w - border]).ravel()


def exact_law(frame, index, c):
    """The exact pmf (camsim.sensor.dn_law) of the values :func:`patch_values` returns for spectrum ``index``."""
    from camsim.sensor.dn_law import dn_pmf

    sensor, ex = frame.sensor, frame.expected
    return dn_pmf(ex.signal_e[index, c] + ex.dark_e[c], sensor.dn_per_electron,
                  sensor.read_noise_e if sensor.read_noise else 0.0,
                  sensor.full_well_e if sensor.saturation else None,
                  sensor.bits if frame.digital_dn is not None else None,
                  sensor.pedestal_dn if frame.digital_dn is not None else 0)


def chi_square(law, values, minimum=5.0):
    """χ² statistic and degrees of freedom of integer ``values`` against ``law``: adjacent levels merged until each
    bin expects at least ``minimum`` counts; values outside the law's window go to its end bins."""
    n = values.size
    index = np.clip(values.astype(np.int64) - law.first, 0, law.pmf.size - 1)
    observed = np.bincount(index, minlength=law.pmf.size)
    expected = n * law.pmf
    bins_o, bins_e, acc_o, acc_e = [], [], 0, 0.0
    for o, e in zip(observed, expected):
        acc_o, acc_e = acc_o + o, acc_e + e
        if acc_e >= minimum:
            bins_o.append(acc_o), bins_e.append(acc_e)
            acc_o, acc_e = 0, 0.0
    if not bins_o:
        return 0.0, 0
    bins_o[-1] += acc_o
    bins_e[-1] += acc_e
    o, e = np.array(bins_o, dtype=np.float64), np.array(bins_e)
    return float(np.sum((o - e) ** 2 / e)), o.size - 1


def log10_chi2_sf(statistic, dof):
    """log10 of the χ² p-value, also where it underflows float64: there Q(a, x) = Γ(a, x) / Γ(a), a = dof / 2,
    x = χ² / 2 ≫ a, from Γ(a, x) ≈ x^(a−1) e^(−x) / (1 − (a − 1) / x)."""
    from scipy import special, stats

    value = stats.chi2.logsf(statistic, dof)
    if np.isfinite(value):
        return float(value / np.log(10))
    a, x = dof / 2, statistic / 2
    return float(((a - 1) * np.log(x) - x - special.gammaln(a) - np.log1p(-(a - 1) / x)) / np.log(10))


def law_errors(frame, rects, seed, chi2=False, floor_samples=16):
    """Distances of ``frame`` to the exact law per patch and channel (see the module docstring): medians and
    largest of TV and KS, their exact-sampler floors, and with ``chi2`` the χ² rejections and pooled p-value."""
    from scipy import stats

    from camsim.sensor.dn_law import expected_tv, sample_distances

    rng = np.random.default_rng(seed)
    tv, ks, tv_floor, ks_floor, chis, dofs, rejects = [], [], [], [], [], [], 0
    for index, rect in enumerate(rects):
        for c in range(3):
            values = patch_values(frame, rect, c)
            law = exact_law(frame, index, c)
            d_tv, d_ks = sample_distances(law, values)
            tv.append(d_tv)
            ks.append(d_ks)
            tv_floor.append(expected_tv(law, values.size))
            cdf = np.cumsum(law.pmf)
            ks_floor.append(float(np.median([np.max(np.abs(np.cumsum(rng.multinomial(values.size, law.pmf))
                                                            / values.size - cdf))
                                             for _ in range(floor_samples)])))
            if chi2:
                statistic, dof = chi_square(law, values)
                if dof > 0:
                    chis.append(statistic)
                    dofs.append(dof)
                    rejects += bool(stats.chi2.sf(statistic, dof) < 0.01)
    # the mean over patches × channels of E[TV] is exactly the expected mean TV of an exact sampler
    out = {"law_tv_mean": float(np.mean(tv)), "law_tv_floor_mean": float(np.mean(tv_floor)),
           "law_tv_ratio": float(np.mean(tv) / np.mean(tv_floor)),
           "law_tv_median": float(np.median(tv)), "law_tv_max": float(np.max(tv)),
           "law_tv_floor_median": float(np.median(tv_floor)), "law_ks_median": float(np.median(ks)),
           "law_ks_max": float(np.max(ks)), "law_ks_floor_median": float(np.median(ks_floor)),
           "pixels_per_patch": int(np.median([patch_values(frame, r, 0).size for r in rects]))}
    if chi2:
        out.update(chi2_tests=len(chis), chi2_rejects_1pct=rejects,
                   chi2_pooled_log10_p=log10_chi2_sf(np.sum(chis), np.sum(dofs)) if chis else None)
    return out


COLOURS = {"spectral": "tab:purple", "poisson": "tab:blue", "table": "tab:orange", "gaussian": "tab:red",
           "auto": "tab:green"}


def chart(rows, path: Path) -> None:
    """Top: error in units of the exact sampler's noise floor (mean over patches × channels of TV / E[TV]) against
    speed, at the large size (spectral: the chart's size). Bottom: mean TV against F at both sizes, with the
    floors."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    sizes = sorted({r["size"] for r in rows}, key=lambda z: -np.prod([int(v) for v in z.split("x")]))
    large, small = sizes[0], sizes[-1]
    styles = dict(zip(sizes, ("-", "--")))
    fig, axes = plt.subplots(2, len(PRESETS), figsize=(18, 11))
    for column, preset in enumerate(PRESETS):
        ax = axes[0, column]
        speed = {(r["method"], r["intensity_factor"]): r["mpix_per_s"]
                 for r in rows if r["preset"] == preset and r["size"] == small}
        for method in METHODS:
            size = large if any(r["method"] == method and r["size"] == large for r in rows) else small
            mine = sorted((r for r in rows if r["preset"] == preset and r["method"] == method and r["size"] == size),
                          key=lambda r: -r["intensity_factor"])
            xs = [r["law_tv_ratio"] for r in mine]
            ys = [speed[(method, r["intensity_factor"])] for r in mine]
            ax.plot(xs, ys, "-", color=COLOURS[method], lw=2.5 if method == "auto" else 1.2,
                    alpha=0.6 if method == "auto" else 1.0, label=f"{method} ({size})")
            ax.scatter(xs, ys, s=[8 + 14 * (np.log10(r["intensity_factor"]) + 5) for r in mine],
                       color=COLOURS[method], zorder=3)
        ax.axvline(1.0, color="0.4", lw=4, alpha=0.3, label="an exact sampler (TV = its floor E[TV])")
        ax.plot([], [], "o", color="0.5", ms=2, label="marker size: F, from 1e-5 (small) to 1 (large)")
        ax.set(xscale="log", yscale="log", title=f"{preset}: error against speed",
               xlabel="error: mean over patches × channels of TV to the exact law / its floor E[TV] at that size",
               ylabel=f"speed: megapixels per second ({small}, 2 threads)")
        ax.grid(alpha=0.3, which="both")
        # outside the axes, so that no label covers a curve or another label
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
        ax = axes[1, column]
        for method in METHODS:
            for size in sizes:
                mine = sorted((r for r in rows if r["preset"] == preset and r["method"] == method
                               and r["size"] == size), key=lambda r: r["intensity_factor"])
                if mine:
                    ax.plot([r["intensity_factor"] for r in mine], [r["law_tv_mean"] for r in mine], styles[size],
                            marker="o", ms=3, color=COLOURS[method],
                            lw=3 if method == "auto" else 1.2, alpha=0.6 if method == "auto" else 1.0)
        for size in sizes:
            mine = sorted((r for r in rows if r["preset"] == preset and r["method"] == "poisson" and r["size"] == size),
                          key=lambda r: r["intensity_factor"])
            ax.plot([r["intensity_factor"] for r in mine], [r["law_tv_floor_mean"] for r in mine], styles[size],
                    color="0.3", lw=6, alpha=0.25)
        same = [r["law_tv_mean"] for r in rows if r["preset"] == preset and r["method"] == "auto"] == \
            [r["law_tv_mean"] for r in rows if r["preset"] == preset and r["method"] == "gaussian"]
        if same:
            ax.text(0.02, 0.28, "auto draws the Gaussian everywhere here: its curves are gaussian's",
                    transform=ax.transAxes, fontsize=8, color=COLOURS["auto"])
        ax.set(xscale="log", yscale="log", xlabel="intensity factor F",
               ylabel="mean over patches × channels of TV to the exact law",
               title=f"{preset}: error against F at two frame sizes")
        ax.grid(alpha=0.3, which="both")
    handles = [Line2D([], [], color=COLOURS[m], lw=2, label=m) for m in METHODS]
    handles += [Line2D([], [], color="0.2", ls=styles[z], label=f"{z} pixels") for z in sizes]
    handles += [Line2D([], [], color="0.3", lw=6, alpha=0.25, label="exact sampler's floor E[TV]")]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.suptitle("Sampling methods against the exact law (camsim.sensor.dn_law) of the digital numbers (Table I) or of "
                 "the electrons binned to 1 e⁻ (ideal)\nColorChecker under D65, pixel statistics")
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> int:
    sys.path.insert(0, str(ROOT))
    from camsim.render.pipeline import light_scene, make_frame
    from camsim.scene.chart import parse_size
    from camsim.scene.scene_file import load_scene
    from camsim.sensor.camera import load_camera
    from camsim.sensor.params import PRESETS as SENSORS

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="1000x700")
    parser.add_argument("--large", default="4000x3000", help="the large frames' size, or 'none'")
    parser.add_argument("--repeats", type=int, default=5)
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
                    times = []
                    for r in range(0 if method == "spectral" else args.repeats - 1):  # timed only
                        start = time.perf_counter()
                        make_frame(lit, sensor, factor, method=method, rng=100 + r, workers=2)
                        times.append(time.perf_counter() - start)
                    frame, result, seconds = frame_records(scene, lit, camera, sensor, factor, method, 2, 2,
                                                           Path(tmp) / f"{preset}-{factor}-{method}")
                    times.append(seconds)
                    row = {"preset": preset, "size": f"{width}x{height}", "intensity_factor": factor,
                           "method": method,
                           "mean_charge_e": float(np.median(frame.expected.signal_e + frame.expected.dark_e)),
                           "mpix_per_s": width * height / 1e6 / min(times),
                           **compare(frame, exact, lit.radiance.patch_rects, result, exact_result),
                           **law_errors(frame, lit.radiance.patch_rects, seed=11, chi2=True)}
                    if frame.plan is not None and method == "auto":
                        row["auto_gaussian_fraction"] = float(np.mean(frame.plan.kind == 1))
                    rows.append(row)
                    print(f"{preset:13s} F={factor:<7g} {method:9s} {row['mpix_per_s']:8.2f} MP/s  "
                          f"KS median {row['ks_median']:.4f} max {row['ks_max']:.4f}  TV to the law mean "
                          f"{row['law_tv_mean']:.4f} (floor {row['law_tv_floor_mean']:.4f})  mean bias "
                          f"{row['mean_bias_se']:.2f} SE  var bias {row['var_bias_se']:.2f} SE", flush=True)
    if args.large != "none":
        rows += large_frames(scene, camera, parse_size(args.large), make_frame, light_scene, SENSORS)
    args.out.mkdir(parents=True, exist_ok=True)
    fields = list(dict.fromkeys(key for row in rows for key in row))
    with open(args.out / "methods.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    chart(rows, args.out / "methods_chart.png")
    print(f"wrote {args.out / 'methods.csv'} and {args.out / 'methods_chart.png'}")
    return 0


def large_frames(scene, camera, size, make_frame, light_scene, sensors):
    """Rows of the large frames: poisson, table, gaussian and auto, their errors against the exact law and χ² tests."""
    width, height = size
    lit = light_scene(scene.replace(width=width, height=height), "D65", camera)
    rows = []
    for preset in PRESETS:
        for factor in FACTORS:
            for method in ("poisson", "table", "gaussian", "auto"):
                start = time.perf_counter()
                frame = make_frame(lit, sensors[preset], factor, method=method, rng=21, workers=2)
                seconds = time.perf_counter() - start
                row = {"preset": preset, "size": f"{width}x{height}", "intensity_factor": factor, "method": method,
                       "mean_charge_e": float(np.median(frame.expected.signal_e + frame.expected.dark_e)),
                       "mpix_per_s": width * height / 1e6 / seconds,
                       **law_errors(frame, lit.radiance.patch_rects, seed=12, chi2=True)}
                rows.append(row)
                print(f"{preset:13s} F={factor:<7g} {method:9s} {width}x{height}  TV to the law mean "
                      f"{row['law_tv_mean']:.4f} max {row['law_tv_max']:.4f} (floor {row['law_tv_floor_mean']:.4f})"
                      f"  KS median {row['law_ks_median']:.4f} (floor {row['law_ks_floor_median']:.4f})  χ² rejects "
                      f"{row['chi2_rejects_1pct']} of {row['chi2_tests']}, pooled log10 p "
                      f"{row['chi2_pooled_log10_p']:.1f}", flush=True)
                del frame
    return rows


if __name__ == "__main__":
    sys.exit(main())
