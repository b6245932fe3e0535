"""The time-averaged bilinear warp (:mod:`camsim.render.warp`): its compiled kernel and its numpy path against an
independent closed form, against each other, and across worker counts.

The closed form: bilinear interpolation between pixel centres reproduces exactly any f = a + b x + c y + d x y (each
cell's four corners determine it), so the warp of an image sampled from such an f is Σ_s w_s f(clamp(H⁻¹_s p)),
computed here in float64 from the homographies (the edge clamp written out). The implementations compute the
coordinates in float32 (module docstring), so they meet that value to the coordinates' float32 rounding (≈ 1e-7 of
the largest coordinate term, times f's gradient) plus the float32 rounding of the sums: about 2e-7 of the largest value
here, the bound 2e-6.

Kernel against numpy: the same float32 operations on the same values in the same order, so within a few float32
units in the last place of the values (here they agree bit for bit; the tests allow 4 ulp of the largest value).
"""

import numpy as np
import pytest

from camsim.core.errors import CamsimError
from camsim.render import warp

pytest.importorskip("numba")


def _bilinear_field(shape, channels, rng):
    """An image (H, W, C) float32 of f_c = a + b x + c y + d x y at the pixel centres, and the float64 f."""
    height, width = shape
    coef = rng.uniform(-3.0, 3.0, (channels, 4)) + np.array([50.0, 0.0, 0.0, 0.0])

    def f(x, y):
        return np.stack([k[0] + k[1] * x + k[2] * y + k[3] * x * y / max(width, height) for k in coef], axis=-1)

    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    return f(x, y).astype(np.float32), f


def _closed_form(f, shape, inverses, weights):
    """Σ_s w[s, r] f(clamp(H⁻¹[s, r] (x, r, 1))) in float64, (H, W, C)."""
    height, width = shape
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    p = np.stack([x, y, np.ones_like(x)], axis=-1)  # (H, W, 3)
    total = 0.0
    for s in range(inverses.shape[0]):
        inv = np.broadcast_to(inverses[s], (height, 3, 3))
        q = np.einsum("rij,rxj->rxi", inv, p)
        qx = np.clip(q[..., 0] / q[..., 2], 0, width - 1)
        qy = np.clip(q[..., 1] / q[..., 2], 0, height - 1)
        total = total + np.broadcast_to(weights[s], (height,))[:, None, None] * f(qx, qy)
    return total


def _motion(rng, samples, *, per_row=0, perspective=False, big=False):
    """(S, 1|H, 3, 3) inverses of small rotations and translations (some beyond the edges when ``big``), with a
    perspective row when asked; per_row = H gives each row its own (a rolling shutter's)."""
    rows = max(per_row, 1)
    out = np.empty((samples, rows, 3, 3))
    for s in range(samples):
        for r in range(rows):
            theta = rng.normal(0, 0.02)
            t = rng.normal(0, 8.0 if big else 0.7, 2)
            m = np.array([[np.cos(theta), -np.sin(theta), t[0]], [np.sin(theta), np.cos(theta), t[1]], [0, 0, 1.0]])
            if perspective:
                m[2, :2] = rng.normal(0, 2e-3, 2)
            out[s, r] = m
    return out


CASES = [  # (H, W, C, S, per-row inverses, perspective, per-row weights, big)
    (37, 53, 3, 4, False, False, False, False),
    (37, 53, 3, 3, False, True, False, True),
    (40, 29, 1, 5, True, False, True, False),
    (31, 44, 4, 2, True, True, True, True),
    (1, 40, 3, 3, False, False, False, True),
    (40, 1, 3, 3, True, True, True, True),
    (1, 1, 2, 2, False, True, False, True),
    (2, 2, 3, 3, True, False, True, True),
]


def _case(case, seed):
    height, width, channels, samples, per_row, perspective, weight_rows, big = case
    rng = np.random.default_rng(seed)
    pixels, f = _bilinear_field((height, width), channels, rng)
    inverses = _motion(rng, samples, per_row=height if per_row else 0, perspective=perspective, big=big)
    weights = rng.uniform(0.1, 1.0, (samples, height if weight_rows else 1))
    weights /= weights.sum(axis=0)
    return pixels, f, inverses, weights


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("case", CASES)
def test_warp_of_a_bilinear_field_is_the_closed_form(case, compiled):
    """Affine and perspective inverses, per-row ones and weights, motion beyond the edges (clamped), 1 × N, N × 1,
    1 × 1 and 2 × 2 images, 1 to 4 channels: both paths give Σ_s w f(clamp(H⁻¹ p))."""
    pixels, f, inverses, weights = _case(case, 5)
    got = warp.average_warp(pixels, inverses, weights, compiled=compiled)
    want = _closed_form(f, pixels.shape[:2], inverses, weights)
    assert got.dtype == np.float32 and got.shape == pixels.shape
    scale = np.abs(want).max()
    assert np.max(np.abs(got - want)) <= 2e-6 * scale, np.max(np.abs(got - want)) / scale


@pytest.mark.parametrize("case", CASES)
def test_kernel_and_numpy_agree_to_float32_rounding(case):
    """Random images (not smooth: every gather shows), the same inverses and weights: within 4 ulp of the values,
    and an identity sub-sample among them (taken as a copy by both)."""
    _, _, inverses, weights = _case(case, 9)
    rng = np.random.default_rng(3)
    pixels = (rng.random(case[:3]) * 1000.0).astype(np.float32)
    inverses = np.concatenate([inverses, np.broadcast_to(np.eye(3), (1,) + inverses.shape[1:])])
    weights = np.concatenate([weights, np.full((1, weights.shape[1]), 0.25)])
    compiled = warp.average_warp(pixels, inverses, weights, compiled=True)
    reference = warp.average_warp(pixels, inverses, weights, compiled=False)
    ulp = np.spacing(np.float32(np.abs(reference).max()))
    assert np.max(np.abs(compiled - reference)) <= 4 * ulp
    for path, channels_last in ((True, compiled), (False, reference)):  # channels first: the same values
        planar = warp.average_warp(pixels, inverses, weights, compiled=path, planar=True)
        assert planar.flags.c_contiguous and np.array_equal(planar, np.moveaxis(channels_last, -1, 0))
        for layout, want in ((True, planar), (False, channels_last)):  # into a given array, whatever it held
            out = np.full(want.shape, np.nan, dtype=np.float32)
            got = warp.average_warp(pixels, inverses, weights, compiled=path, planar=layout, out=out)
            assert got is out and np.array_equal(out, want)


def test_the_result_does_not_depend_on_the_workers(monkeypatch):
    """Row blocks of one row (the block size made small) on 1, 2 or 5 threads: the same bits, both paths."""
    monkeypatch.setattr(warp, "WARP_BLOCK_PIXELS", 64)
    rng = np.random.default_rng(4)
    pixels = (rng.random((70, 60, 3)) * 100.0).astype(np.float32)
    inverses = _motion(rng, 3, per_row=70, perspective=True)
    weights = rng.uniform(0.1, 1.0, (3, 70))
    for compiled in (True, False):
        runs = [warp.average_warp(pixels, inverses, weights, workers=n, compiled=compiled) for n in (1, 2, 5)]
        assert all(np.array_equal(runs[0], r) for r in runs[1:])


def test_without_numba_the_numpy_path(monkeypatch):
    """Where numba cannot be imported the default is the numpy path (bit for bit compiled=False's); asking for the
    compiled one is one line."""
    pixels, _, inverses, weights = _case(CASES[1], 2)
    reference = warp.average_warp(pixels, inverses, weights, compiled=False)
    assert warp.warp_path() == warp.COMPILED_PATH and warp.warp_path(False) == warp.NUMPY_PATH
    monkeypatch.setattr(warp._KERNELS, "state", {"kernels": None, "why": "no numba (test)"})
    assert warp.warp_path() == warp.NUMPY_PATH
    assert np.array_equal(warp.average_warp(pixels, inverses, weights), reference)
    with pytest.raises(CamsimError, match="numba"):
        warp.average_warp(pixels, inverses, weights, compiled=True)


def test_shapes_that_do_not_fit_are_refused():
    pixels = np.zeros((4, 5, 3), dtype=np.float32)
    with pytest.raises(ValueError, match="do not fit"):
        warp.average_warp(pixels, np.zeros((2, 3, 3, 3)), np.ones((2, 1)))
    with pytest.raises(ValueError, match="do not fit"):
        warp.average_warp(pixels, np.zeros((2, 1, 3, 3)), np.ones((3, 1)))
    with pytest.raises(ValueError, match="out must be"):
        warp.average_warp(pixels, np.eye(3)[None, None], np.ones((1, 1)), out=np.zeros((4, 5, 3)))
    with pytest.raises(ValueError, match="out must be"):
        warp.average_warp(pixels, np.eye(3)[None, None], np.ones((1, 1)), planar=True,
                          out=np.zeros((4, 5, 3), dtype=np.float32))
