"""The paper's findings, each checked on analysis results (one check per statistics), with its evidence.

Every check returns a :class:`Verdict`: whether the finding holds, and the figures that decide it. The thresholds
are fixed here, before any run, and stated in the evidence.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

#: The EXR frames hold float32: an ellipse smaller than this in xy is below float32 resolution (the ``paper``
#: statistics' shot noise at F ≳ 1e-7 is ~1e-9 of the signal, so its clouds there are float32 rounding).
RESOLVED_SIZE = 1e-6
#: An ellipse or a shift of at least this in xy is visible on the chromaticity diagram.
VISIBLE_XY = 1e-3
GAUSSIAN_2SIGMA = 1 - np.exp(-2.0)  # 0.865: fraction of a bivariate normal inside its 2 σ ellipse


@dataclass(frozen=True)
class Verdict:
    holds: bool
    evidence: str


def _by_point(results):
    """{point index: [(F, patch record), ...]} sorted by decreasing F."""
    table = {}
    for result in sorted(results, key=lambda r: -r["intensity_factor"]):
        for patch in result["patches"]:
            table.setdefault(patch["index"], []).append((result["intensity_factor"], patch))
    return table


def _resolved(patch) -> bool:
    return (patch["ellipse_status"] == "ok" and patch["n_xy_undefined"] == 0 and patch["size_xy"] is not None
            and patch["size_xy"] > RESOLVED_SIZE)


def ellipses_are_gaussian(results) -> Verdict:
    """I.1: the samples form elliptical (bivariate-Gaussian-like) clouds: ~86.5 % inside the 2 σ ellipse."""
    fractions = [p["frac_in_2sigma"] for r in results for p in r["patches"] if _resolved(p)]
    if not fractions:
        return Verdict(False, "no resolved ellipse")
    mean = float(np.mean(fractions))
    holds = abs(mean - GAUSSIAN_2SIGMA) < 0.04
    return Verdict(holds, f"{len(fractions)} resolved clouds hold on average {100 * mean:.1f} % of their samples "
                          f"inside the 2 σ ellipse (Gaussian: {100 * GAUSSIAN_2SIGMA:.1f} %; criterion ± 4 points)")


def _axial_spread(angles) -> float:
    """Largest difference between inclination angles (axial data, period 180°), in degrees."""
    a = np.asarray(angles)
    diff = np.abs(a[:, None] - a[None, :]) % 180.0
    return float(np.max(np.minimum(diff, 180.0 - diff)))


def inclination_constant(results, max_spread_deg=10.0) -> Verdict:
    """I.2: the inclination of each point's ellipse stays nearly constant across F."""
    spreads = []
    for series in _by_point(results).values():
        angles = [p["angle_deg"] for _, p in series if _resolved(p) and p["n_xy_valid"] >= 30]
        if len(angles) >= 3:
            spreads.append(_axial_spread(angles))
    if not spreads:
        return Verdict(False, "fewer than 3 resolved ellipses per point")
    median = float(np.median(spreads))
    return Verdict(median <= max_spread_deg,
                   f"over the F values with resolved ellipses, each point's angle spans a median {median:.1f}° "
                   f"(max {max(spreads):.1f}°, {len(spreads)} points; criterion: median ≤ {max_spread_deg:g}°)")


def size_grows(results) -> Verdict:
    """I.3: the ellipses grow as F falls, as F^(-1/2) (shot noise)."""
    slopes = []
    for series in _by_point(results).values():
        pts = [(np.log10(f), np.log10(p["size_xy"])) for f, p in series if _resolved(p) and p["n_xy_valid"] >= 30]
        if len(pts) >= 3:
            x, y = np.array(pts).T
            slopes.append(float(np.polyfit(x, y, 1)[0]))
    if not slopes:
        return Verdict(False, "fewer than 3 resolved ellipses per point")
    median = float(np.median(slopes))
    holds = max(slopes) < 0 and -0.6 <= median <= -0.4
    return Verdict(holds, f"slope of log size against log F: median {median:.2f}, range {min(slopes):.2f} to "
                          f"{max(slopes):.2f} over {len(slopes)} points (shot noise: −0.5; criterion: all < 0, "
                          "median in [−0.6, −0.4])")


def largest_visible_factor(results) -> float | None:
    """Largest F at which the median ellipse size reaches :data:`VISIBLE_XY`."""
    visible = []
    for result in results:
        sizes = [p["size_xy"] for p in result["patches"] if p["size_xy"] is not None and p["n_xy_undefined"] == 0]
        if sizes and np.median(sizes) >= VISIBLE_XY:
            visible.append(result["intensity_factor"])
    return max(visible) if visible else None


def size_visible_below(results, factor_max) -> Verdict:
    """I.4 (paper statistics): the ellipses become visible only at F ≲ ``factor_max``."""
    f = largest_visible_factor(results)
    holds = f is not None and f <= factor_max
    where = "never" if f is None else f"from F = {f:g} down"
    return Verdict(holds, f"median ellipse size ≥ {VISIBLE_XY:g} in xy {where} (criterion: only at F ≤ {factor_max:g})")


def size_visible_above(results, factor_min) -> Verdict:
    """I.4 (pixel statistics): the ellipses are visible already at F ≥ ``factor_min``."""
    f = largest_visible_factor(results)
    holds = f is not None and f >= factor_min
    where = "never" if f is None else f"from F = {f:g} down"
    return Verdict(holds, f"median ellipse size ≥ {VISIBLE_XY:g} in xy {where} (criterion: already at F ≥ "
                          f"{factor_min:g})")


def _mean_delta_e(result):
    values = [p["delta_e_ab_mean"] for p in result["patches"] if p["delta_e_ab_mean"] is not None]
    return float(np.mean(values)) if values else None


def delta_e_grows_until_failure(results, fail_delta_e=10.0) -> Verdict:
    """I.5: mean ΔE grows as F falls, and in the dark colour cannot be measured, even by an ideal sensor."""
    series = sorted((r["intensity_factor"], _mean_delta_e(r), r) for r in results)
    valid = [(f, de) for f, de, _ in series if de is not None]
    if len(valid) < 3:
        return Verdict(False, "fewer than 3 F values with a ΔE")
    rho = stats.spearmanr([f for f, _ in valid], [de for _, de in valid]).statistic
    darkest = series[0][2]
    n_total = sum(p["n_xy_valid"] + p["n_xy_undefined"] for p in darkest["patches"])
    undefined = sum(p["n_xy_undefined"] for p in darkest["patches"]) / max(1, n_total)
    de_dark = _mean_delta_e(darkest)
    fails = undefined > 0.5 or (de_dark is not None and de_dark > fail_delta_e)
    holds = rho < -0.8 and fails
    de_text = "undefined" if de_dark is None else f"{de_dark:.1f}"
    return Verdict(holds, f"Spearman ρ(F, mean ΔE) = {rho:.2f} (criterion < −0.8); at the lowest F = "
                          f"{darkest['intensity_factor']:g}: mean ΔE {de_text}, {100 * undefined:.0f} % of samples "
                          f"undefined (criterion: ΔE > {fail_delta_e:g} or > 50 % undefined)")


def _saturated(patch) -> bool:
    return any(ch["saturated_pixels"] for ch in patch["channels"])


def drift_to_black_point(results, black_xy) -> Verdict:
    """II.1: the ellipse centres move toward the camera black point as F falls.

    Frames in which a point has saturated pixels are left out for that point: clipping moves its chromaticity
    for another reason (scenario III's saturation finding).
    """
    if black_xy is None:
        return Verdict(False, "no dark current, no black point")
    bx, by = black_xy
    monotone, ratios, skipped = 0, [], 0
    table = _by_point(results)
    for series in table.values():
        d = [(f, np.hypot(p["center_x"] - bx, p["center_y"] - by), p) for f, p in series
             if p["center_x"] is not None and not _saturated(p)]
        skipped += len(series) - len(d)
        steps_ok = all(d2 <= d1 + 2 * (p2["size_xy"] or 0) / np.sqrt(max(1, p2["n_xy_valid"]))
                       for (_, d1, _), (_, d2, p2) in zip(d, d[1:]))
        monotone += steps_ok
        if len(d) >= 2 and d[0][1] > 0:
            ratios.append(d[-1][1] / d[0][1])
    median_ratio = float(np.median(ratios)) if ratios else np.inf
    holds = monotone >= 0.9 * len(table) and median_ratio < 0.5
    return Verdict(holds, f"distance to the black point ({bx:.4f}, {by:.4f}) never grows as F falls for "
                          f"{monotone} of {len(table)} points; lowest-F / highest-F distance: median "
                          f"{median_ratio:.2f} (criteria: ≥ 90 % of points, median < 0.5)"
                          + (f"; {skipped} saturated point × F cases left out" if skipped else ""))


def centre_shifts(results, reference_factor=1.0) -> dict:
    """Median shift of the ellipse centres from their position at ``reference_factor``, per F."""
    reference = next((r for r in results if r["intensity_factor"] == reference_factor), None)
    out = {}
    if reference is None:
        return out
    ref = {p["index"]: p for p in reference["patches"]}
    for result in results:
        shifts = [np.hypot(p["center_x"] - ref[p["index"]]["center_x"], p["center_y"] - ref[p["index"]]["center_y"])
                  for p in result["patches"] if p["center_x"] is not None and ref[p["index"]]["center_x"] is not None]
        if shifts:
            out[result["intensity_factor"]] = float(np.median(shifts))
    return out


def drift_visible_from(results, factor=0.1, visible=0.005) -> Verdict:
    """II.2: the drift is visible from F ≤ ``factor`` (median centre shift ≥ ``visible`` in xy)."""
    shifts = centre_shifts(results)
    if factor not in shifts:
        return Verdict(False, f"no frame at F = {factor:g}")
    text = ", ".join(f"F {f:g}: {s:.4f}" for f, s in sorted(shifts.items(), reverse=True))
    return Verdict(shifts[factor] >= visible, f"median centre shift from F = 1 — {text} (criterion: ≥ {visible:g} "
                                              f"at F = {factor:g})")


def saturation_at_high_light(results, high=1.0, low_max=0.1) -> Verdict:
    """III.2: saturation shows at high F and not at low F."""
    def saturated_points(result):
        return sum(_saturated(p) for p in result["patches"])

    by_f = {r["intensity_factor"]: saturated_points(r) for r in results}
    high_n = by_f.get(high, 0)
    low_n = sum(n for f, n in by_f.items() if f <= low_max)
    return Verdict(high_n > 0 and low_n == 0,
                   f"points with saturated pixels: {high_n} at F = {high:g}, {low_n} in all frames at F ≤ {low_max:g}")


def quantised_samples_sparse(results, ratio_max=0.25) -> Verdict:
    """III.3: at low F the samples are sparse and quantised: few distinct digital values per patch."""
    by_f = {}
    for r in results:
        counts = [p["n_distinct_values"] for p in r["patches"] if p["n_distinct_values"] is not None]
        if counts:
            by_f[r["intensity_factor"]] = float(np.median(counts))
    if len(by_f) < 2:
        return Verdict(False, "needs quantised frames at two F values at least")
    hi, lo = max(by_f), min(by_f)
    return Verdict(by_f[lo] <= ratio_max * by_f[hi],
                   f"median distinct (R, G, B) values per patch: {by_f[hi]:.0f} at F = {hi:g}, {by_f[lo]:.0f} at "
                   f"F = {lo:g} (criterion: ≤ {100 * ratio_max:.0f} %)")


def snr_sensitivity(rows, variant, low=None, high=None, above=None) -> Verdict:
    """SNR: |ΔSNR| (model, %) of a variant within [low, high] on average, or above another variant's everywhere."""
    values = [abs(r["delta_snr_model_pct"]) for r in rows if r["variant"] == variant
              and r["delta_snr_model_pct"] is not None]
    if not values:
        return Verdict(False, f"no ΔSNR for {variant}")
    mean, top = float(np.mean(values)), float(np.max(values))
    text = f"|ΔSNR| (Eq. 13 model) for {variant}: mean {mean:.2f} %, max {top:.2f} %, min {min(values):.2f} %"
    for key, label in (("delta_snr_model_variance_pct", "model with the 1/12 DN² quantisation variance"),
                       ("delta_snr_empirical_pct", "empirical, from the pixels")):
        others = [r[key] for r in rows if r["variant"] == variant and r.get(key) is not None]
        if others:  # signed: sampling noise averages out instead of adding up
            text += f"; {label}: signed mean {np.mean(others):+.2f} %"
    if above is not None:
        others = {}
        for r in rows:
            if r["variant"] == above and r["delta_snr_model_pct"] is not None:
                others.setdefault(r["intensity_factor"], []).append(abs(r["delta_snr_model_pct"]))
        mine = {}
        for r in rows:
            if r["variant"] == variant and r["delta_snr_model_pct"] is not None:
                mine.setdefault(r["intensity_factor"], []).append(abs(r["delta_snr_model_pct"]))
        wins = all(np.mean(mine[f]) > np.mean(others[f]) for f in mine if f in others)
        return Verdict(wins, text + f"; larger on average than {above} at every F: {wins}")
    ok = (low is None or mean >= low) and (high is None or top <= high)
    return Verdict(ok, text + f" (criterion: mean ≥ {low}, max ≤ {high})".replace("None", "—"))
