"""``camsim calibrate`` measures the effects of issue 28: the dark-shading map, hot pixels, column FPN and the
black-level error — each estimator of :mod:`camsim.calibration.fixed_pattern` on dark frames of known law drawn
here (:func:`draw_darks`, independent of camsim's renderer), then the command's round trip.

The synthetic darks: an RGGB mosaic, DN = floor(B + s + c_j + h + b_f,colour + ρ_f,i + ε), with s a smooth shading
plus a white per-pixel DSNU, c a per-column offset, h a hot pixel's extra (on a share of the pixels), b the frame's
offset per colour (R, G, B; the two greens share it), ρ row noise and ε Gaussian pixel noise.
"""

import numpy as np
import pytest

from camsim.calibration import dark, fixed_pattern as fp


def draw_darks(rng, *, frames=16, shape=(128, 256), black=512.0, shading=3.0, dsnu=1.5, column=0.0, hot=0.0,
               hot_dn=(40.0, 400.0), offset=0.0, row=0.0, sigma=2.0):
    """Dark frames of known law (module docstring), with their truth.

    Returns
    -------
    (numpy.ndarray, dict)
        The frames (n, H, W) int64 in DN, and the truth: ``shading`` (s, DN), ``columns`` (c, (W,)), ``hot``
        (h, (H, W), 0 where not hot), ``offsets`` (b, (n, 3)).
    """
    h, w = shape
    y, x = np.mgrid[0:h, 0:w]
    smooth = np.cos(np.pi * x / w) + 0.5 * ((y / h) - 0.5) * (x / w)  # a vignette-like shading
    s = shading * smooth / smooth.std() + rng.normal(0, dsnu, shape)
    c = rng.normal(0, column, w) if column else np.zeros(w)
    hot_map = np.zeros(shape)
    if hot:
        where = rng.random(shape) < hot
        hot_map[where] = rng.uniform(*hot_dn, np.count_nonzero(where))
    b = rng.normal(0, offset, (frames, 3)) if offset else np.zeros((frames, 3))
    colour = np.array([[0, 1], [1, 2]])[y % 2, x % 2]  # RGGB: R 0, G 1, B 2
    fixed = black + s + c[None, :] + hot_map
    out = np.empty((frames, h, w), np.int64)
    for f in range(frames):
        level = fixed + b[f][colour] + rng.normal(0, row, (h, 1)) + rng.normal(0, sigma, shape)
        out[f] = np.floor(level)
    return out, {"shading": s, "columns": c, "hot": hot_map, "offsets": b, "colour": colour}


def planes(image):
    """The four RGGB sites of a mosaic (R, Gr, Gb, B)."""
    return [image[..., dy::2, dx::2] for dy in (0, 1) for dx in (0, 1)]


def moments(x):
    n = x.shape[0]
    return dark.pixel_moments(x.sum(axis=0), (x * x).sum(axis=0), n)


def test_hot_pixels_found_with_recall_and_precision():
    """At a share of 10⁻³ and extras of 40–400 DN over a spread of √(1.5² + 2²/16) = 1.52 DN, every hot pixel is far
    above the 5 σ threshold (7.6 DN) and a normal pixel passes it with probability 3 × 10⁻⁷: recall and precision
    ≥ 0.95 (here 1), and each hot pixel's excess is its drawn extra within the mean's noise (2/√16 DN and the
    neighbourhood median's)."""
    rng = np.random.default_rng(1)
    x, truth = draw_darks(rng, shape=(256, 512), hot=1e-3)
    mean, var = moments(x)
    found = np.zeros(mean.shape, bool)
    excess = np.zeros(mean.shape)
    for (dy, dx), m, v in zip([(0, 0), (0, 1), (1, 0), (1, 1)], planes(mean), planes(var)):
        hot = fp.find_hot_pixels(m, float(np.mean(v)), x.shape[0])
        assert hot.spread_dn == pytest.approx(np.hypot(1.5, 2 / 4), rel=0.1)
        found[dy::2, dx::2] = hot.mask
        excess[dy::2, dx::2] = hot.excess_dn
    true = truth["hot"] > 0
    assert true.sum() > 80
    recall = np.count_nonzero(found & true) / np.count_nonzero(true)
    precision = np.count_nonzero(found & true) / np.count_nonzero(found)
    assert recall >= 0.95 and precision >= 0.95
    err = excess[found & true] - truth["hot"][found & true]
    assert abs(np.mean(err)) < 1.0 and np.std(err) < 2.5  # DSNU 1.5 and the local median's offset, not the extra


def test_a_normal_plane_has_few_hot_pixels():
    """Without hot pixels the 5 σ threshold (Gaussian tail 2.9 × 10⁻⁷) flags almost none of 131 072 pixels."""
    rng = np.random.default_rng(2)
    x, _ = draw_darks(rng, shape=(256, 512), dsnu=3.0)
    mean, var = moments(x)
    count = sum(fp.find_hot_pixels(m, float(np.mean(v)), x.shape[0]).count for m, v in zip(planes(mean), planes(var)))
    assert count <= 3


def test_shading_map_and_its_standard_error():
    """The map (mean less the plane's black) correlates with the drawn shading above 0.95 at 16 darks (its noise
    σ/√n = 0.5 DN against a pattern of 3.4 DN RMS), and the RMS of map − truth is the stated standard error
    √(σ̄²/n) (σ² = 4 + 1/12 DN² with the quantiser; the map is less the black level, whose error is negligible)."""
    rng = np.random.default_rng(3)
    x, truth = draw_darks(rng, frames=16, hot=1e-3)
    mean, var = moments(x)
    full = np.zeros(mean.shape)
    for (dy, dx), m, v in zip([(0, 0), (0, 1), (1, 0), (1, 1)], planes(mean), planes(var)):
        hot = fp.find_hot_pixels(m, float(np.mean(v)), 16)
        black = float(np.mean(m[~hot.mask]))
        full[dy::2, dx::2] = fp.shading_map(m, black, hot)
    s = truth["shading"] - truth["shading"].mean()
    assert np.corrcoef(full.ravel(), s.ravel())[0, 1] > 0.95
    normal = truth["hot"] == 0
    err = (full - s)[normal]
    se = fp.map_standard_error(var[normal], 16)
    assert se == pytest.approx(np.sqrt((4 + 1 / 12) / 16), rel=0.03)
    assert np.sqrt(np.mean((err - err.mean()) ** 2)) == pytest.approx(se, rel=0.03)
    rms = fp.fixed_pattern_rms(full[normal], float(np.mean(var)), 16)
    assert abs(rms.value - s[normal].std()) < 4 * rms.standard_error


@pytest.mark.parametrize("column", [0.0, 0.8])
def test_column_fpn(column):
    """σ_c from the column means of the map less v_e/H: within 4 standard errors of the drawn columns' own spread,
    with a smooth shading across the columns (removed as the trend) and a DSNU of 1.5 DN whose share in a column
    mean, 1.5²/128 DN², would read as σ_c = 0.13 DN if not removed."""
    rng = np.random.default_rng(4 + int(10 * column))
    x, truth = draw_darks(rng, frames=16, shape=(128, 1024), column=column)
    mean, _ = moments(x)
    full = np.zeros(mean.shape)
    for (dy, dx), m in zip([(0, 0), (0, 1), (1, 0), (1, 1)], planes(mean)):
        full[dy::2, dx::2] = fp.shading_map(m, float(np.mean(m)))
    est = fp.column_fpn(full)
    c = truth["columns"]
    t = np.linspace(-1, 1, c.size)
    basis = np.polynomial.legendre.legvander(t, fp.COLUMN_TREND_DEGREE)
    resid = c - basis @ np.linalg.lstsq(basis, c, rcond=None)[0]
    drawn = np.sqrt(np.sum(resid**2) / (c.size - fp.COLUMN_TREND_DEGREE - 1))
    assert abs(est.value - drawn) < 4 * est.standard_error + 0.02
    naive = np.sqrt(max(np.var(full.mean(axis=0) - basis @ np.linalg.lstsq(basis, full.mean(axis=0), rcond=None)[0],
                               ddof=fp.COLUMN_TREND_DEGREE + 1), 0))
    if column == 0:
        assert est.value < 0.05 and naive > 0.1  # the correction matters


@pytest.mark.parametrize(("offset", "row"), [(0.0, 3.0), (0.7, 0.5)])
def test_black_level_error(offset, row):
    """Per-frame colour means over 300 small frames: σ_b² = s²(F) − σ_Y²/N − σ_row²/R. Without an offset but with
    row noise 3 DN, s²(F) of R (R = 16 rows of its sites) is 9/16 DN² — the estimate must remove it (within 4 SE of
    0); with σ_b = 0.7 DN it is within 4 SE of the drawn offsets' own variance."""
    rng = np.random.default_rng(5)
    frames = 300
    x, truth = draw_darks(rng, frames=frames, shape=(32, 64), offset=offset, row=row, shading=0, dsnu=0.5)
    colour = truth["colour"]
    means = np.stack([x[:, colour == c].mean(axis=1) for c in range(3)], axis=1)
    pixels = [np.count_nonzero(colour == c) for c in range(3)]
    rows = [16, 32, 16]
    var_y = [4 + 1 / 12] * 3
    est = fp.black_level_error_variance(means, var_y, pixels, row**2, rows)
    drawn = float(np.mean(np.var(truth["offsets"], axis=0, ddof=1)))
    assert abs(est.value - drawn) < 4 * est.standard_error
    if offset == 0:
        naive = float(np.mean(np.var(means, axis=0, ddof=1)))
        assert naive > 8 * est.standard_error
    sd = fp.black_level_error(means, var_y, pixels, row**2, rows)
    assert sd.value == pytest.approx(np.sqrt(max(est.value, 0)))


def test_hot_fraction_standard_error():
    est = fp.hot_fraction(100, 100_000)
    assert est.value == 1e-3 and est.standard_error == pytest.approx(np.sqrt(1e-3 * 0.999 / 1e5))
