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
    """II.2: the drift is visible at every F ≤ ``factor`` of the series (median centre shift ≥ ``visible`` in xy).

    The evidence also names the largest F at which the shift first reaches ``visible`` (:func:`drift_onset`).
    """
    shifts = centre_shifts(results)
    low = {f: s for f, s in shifts.items() if f <= factor}
    if not low:
        return Verdict(False, f"no frame at F ≤ {factor:g}")
    text = ", ".join(f"F {f:g}: {s:.4f}" for f, s in sorted(shifts.items(), reverse=True))
    missing = [f for f, s in low.items() if s < visible]
    return Verdict(not missing, f"median centre shift from F = 1 — {text} (criterion: ≥ {visible:g} at every F ≤ "
                                f"{factor:g}" + (f"; below it at F = {', '.join(f'{f:g}' for f in missing)}"
                                                 if missing else "") + ")")


def first_visible_factor(results, visible=0.005) -> float | None:
    """The largest F at which the median centre shift from F = 1 reaches ``visible`` (None: at none)."""
    seen = [f for f, s in centre_shifts(results).items() if f < 1.0 and s >= visible]
    return max(seen) if seen else None


def drift_onset(results, factor=0.1, visible=0.005) -> Verdict:
    """II.2 onset: the drift "becomes visible for F ≤ ``factor``": not visible at any F between ``factor`` and 1."""
    shifts = centre_shifts(results)
    first = first_visible_factor(results, visible)
    where = "at no F" if first is None else f"first at F = {first:g} (shift {shifts[first]:.4f})"
    return Verdict(first is not None and first <= factor,
                   f"median centre shift reaches {visible:g} {where} (criterion: not before F = {factor:g})")
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


#: The model forms of the SNR findings: the verdict is judged on the first (Eqs. 13–14 as printed); the evidence
#: gives the others' numbers and what the verdict would be on each.
SNR_MODEL_COLUMNS = {"delta_snr_eq13_pct": "Eqs. 13–14 as printed",
                     "delta_snr_eq13_unquantised_numerator_pct": "numerator k S instead of [k S]_nb",
                     "delta_snr_statistics_variance_pct": "the statistics' own Var S instead of S"}
SNR_EMPIRICAL_COLUMN = "delta_snr_empirical_pct"


def average_curves(rows, variant, column="delta_snr_eq13_pct") -> tuple[dict, int]:
    """The paper's average SNR sensitivity curves: mean ΔSNR over the points, per (channel, F).

    Returns
    -------
    curves : dict of {(str, float): float}
        (channel, F) → mean of the defined values. Unit: %.
    n_undefined : int
        Values left out (None: an SNR₁ of 0, e.g. a quantised numerator of 0 DN, or not measurable).
    """
    by_cell, undefined = {}, 0
    for r in rows:
        if r["variant"] != variant:
            continue
        if r[column] is None:
            undefined += 1
        else:
            by_cell.setdefault((r["channel"], r["intensity_factor"]), []).append(r[column])
    return {cell: float(np.mean(v)) for cell, v in by_cell.items()}, undefined


def _values_text(rows, variant, column) -> str:
    values = [r[column] for r in rows if r["variant"] == variant and r[column] is not None]
    undefined = sum(r[column] is None for r in rows if r["variant"] == variant)
    text = (f"all values mean {np.mean(values):.2f} %, {min(values):.2f} to {max(values):.2f} %" if values
            else "no defined value")
    return text + (f", {undefined} of {len(values) + undefined} undefined" if undefined else "")


def _empirical_text(rows, variant) -> str:
    values = [r[SNR_EMPIRICAL_COLUMN] for r in rows if r["variant"] == variant and r[SNR_EMPIRICAL_COLUMN] is not None]
    undefined = sum(r[SNR_EMPIRICAL_COLUMN] is None for r in rows if r["variant"] == variant)
    if not values:
        return f"empirical, from the pixels: undefined ({undefined} values: constant pixels or no signal)"
    return (f"empirical, from the pixels: median {np.median(values):.2f} % over {len(values)} values"
            + (f", {undefined} undefined" if undefined else ""))


def _judged(rows, variant, judge) -> tuple[bool, str]:
    """``judge(curves) -> (ok, text)`` on each model column; the verdict is the first column's."""
    verdicts, parts = [], []
    for column, label in SNR_MODEL_COLUMNS.items():
        curves, _ = average_curves(rows, variant, column)
        ok, text = judge(column, curves)
        verdicts.append(ok)
        parts.append(f"{label}: {text} ({_values_text(rows, variant, column)}) → {'holds' if ok else 'fails'}")
    return verdicts[0], "; ".join(parts + [_empirical_text(rows, variant)])


def snr_average_within(rows, variant, low=None, high=None, below=None) -> Verdict:
    """S.1, S.2: every value of the average curves is ≥ ``low``, ≤ ``high`` and < ``below`` (as printed)."""
    def judge(column, curves):
        if not curves:
            return False, "no average curve"
        lo, hi = min(curves.values()), max(curves.values())
        ok = (low is None or lo >= low) and (high is None or hi <= high) and (below is None or hi < below)
        return ok, f"average curves {lo:.2f}–{hi:.2f} %"

    ok, text = _judged(rows, variant, judge)
    criterion = " and ".join([f"{sign} {v:g} %" for sign, v in (("≥", low), ("≤", high), ("<", below))
                              if v is not None])
    return Verdict(ok, f"{variant}: {text} (criterion: every value of the average curves {criterion}; judged on "
                       "Eqs. 13–14 as printed)")


def snr_largest(rows, variant, others) -> Verdict:
    """S.3: the average curve of ``variant`` lies above those of ``others`` at every channel and F (Eqs. 13–14 as
    printed), among the curves defined there; a channel × F where no other is defined is not counted."""
    def judge(column, curves):
        theirs = [average_curves(rows, other, column)[0] for other in others]
        cells = [cell for cell in curves if any(cell in t for t in theirs)]
        wins = sum(all(curves[cell] > t[cell] for t in theirs if cell in t) for cell in cells)
        text = (f"average curves {min(curves.values()):.2f}–{max(curves.values()):.2f} %, " if curves else "") + \
            f"the largest at {wins} of {len(cells)} channel × F"
        return bool(cells) and wins == len(cells), text

    ok, text = _judged(rows, variant, judge)
    return Verdict(ok, f"{variant}: {text} (criterion: larger than {' and '.join(others)} at every channel × F, "
                       "among those defined there; judged on Eqs. 13–14 as printed)")
