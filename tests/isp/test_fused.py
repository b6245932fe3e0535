"""The ISP's compiled kernel (:mod:`camsim.isp.fused`, issue 26 "Speed") against independent references.

- the kernel's development against the stages written out here in float64 (normalise → white balance →
  colour-demosaicing's bilinear on the mirrored mosaic → matrix → gain → clip → the sRGB formula), on all four Bayer
  patterns, odd crop offsets, the borders and three chips, and against the numpy path (``develop_pair``);
- its power and its sRGB curve against numpy's in float64;
- ``srgb`` pairs: made by the kernel (the record says so), within the bound of the numpy path's pairs, the same seed
  giving the same batch bit for bit.

The bound: both paths normalise and demosaic in float32 (the same operations in the same order: the same numbers),
so they differ only in the matrix product (the numpy path's float32 sums, the kernel's float64 sum rounded once: a few
float32 units of the linear value Σ_j |A_cj x_j|, through the curve's slope of at most 12.92) and the curve (each
within a few float32 units of the formula: the kernel's within CURVE_ERROR). Against float64 the float32
normalisation's rounding (about 6e-8 of |raw · s| + |b · s| per value) adds, times Σ_j |A_cj| and the slope. On the
frames here (gains up to 30, values near black) both come to below 5e-6 (the bound of tests/isp/test_fast_paths.py
for the numpy path)."""

import numpy as np
import pytest

import camsim.isp as isp
from camsim.sensor.cfa import CFA_PATTERNS
from tests.support.isp_reference import made_up_facts as _facts
from tests.support.isp_reference import reference_development as _reference

fused = pytest.importorskip("camsim.isp.fused")
pytest.importorskip("numba")

BOUND = 5e-6


def _kernel(raw, facts, settings):
    from camsim.isp.develop import _plan

    assert fused.fused_applies(facts, settings, np.shape(raw)) and fused.fused_kernels() is not None
    plan = _plan(facts, settings)
    out = np.empty((3, *np.shape(raw)[-2:]), dtype=np.float32)
    fused.develop_into(np.asarray(raw), facts, settings, plan, out)
    return out, plan.record


@pytest.mark.parametrize("pattern", [None, *CFA_PATTERNS])
@pytest.mark.parametrize("settings", [isp.IspSettings(demosaic="bilinear", gain="auto"),
                                      isp.IspSettings(demosaic="bilinear", gain=3.0, white_balance="A"),
                                      isp.IspSettings(demosaic="bilinear", matrix="none", white_balance="none"),
                                      isp.IspSettings(demosaic="bilinear", black=False, gain=30.0),
                                      isp.IspSettings(demosaic="bilinear", gain=2.0, tone="linear"),
                                      isp.IspSettings(demosaic="bilinear", gain=4.0, tone="filmic")])
def test_kernel_is_the_stages_in_float64_and_the_numpy_path(pattern, settings):
    """Noisy frames near black, odd sizes (borders on every side, both parities), gains up to 30: within BOUND of
    the float64 stages and of develop's numpy path."""
    facts = _facts(pattern)
    rng = np.random.default_rng(11)
    shape = (3, 23, 30) if pattern is None else (23, 31)
    raw = (64.0 + rng.normal(0.0, 3.0, shape) + rng.random(shape) * 150.0).astype(np.float32)
    out, record = _kernel(raw, facts, settings)
    assert np.max(np.abs(out - _reference(raw, facts, record, settings.tone))) < BOUND
    assert np.max(np.abs(out - isp.develop(raw, facts, settings).image)) < BOUND
    assert out.min() >= 0.0 and out.max() <= 1.0


def _shifted(pattern, dy, dx):
    """The 2 × 2 pattern seen from a crop at (dy, dx)."""
    cells = [[pattern[0], pattern[1]], [pattern[2], pattern[3]]]
    return "".join(cells[(dy + i) % 2][(dx + j) % 2] for i in range(2) for j in range(2))


@pytest.mark.parametrize("pattern", CFA_PATTERNS)
@pytest.mark.parametrize("offset", [(1, 0), (0, 1), (1, 1), (3, 5)])
def test_kernel_at_odd_crop_offsets(pattern, offset):
    """A crop of a mosaic at an odd offset is a mosaic of the pattern seen from there: the kernel with that pattern
    is the float64 stages with it, over the whole range up to clipping."""
    dy, dx = offset
    rng = np.random.default_rng(dy * 7 + dx)
    whole = (64.0 + rng.random((40, 44)) * 900.0).astype(np.float32)
    crop = whole[dy:dy + 30, dx:dx + 32]
    facts = _facts(_shifted(pattern, dy, dx))
    settings = isp.IspSettings(demosaic="bilinear", gain=1.5)
    out, record = _kernel(crop, facts, settings)
    assert np.max(np.abs(out - _reference(crop, facts, record))) < BOUND


def test_power_against_numpy_in_float64():
    """The kernel's x^(5/12) (through the sRGB curve on [threshold, 1]) against 1.055 x^(1/2.4) − 0.055 in
    float64: within CURVE_ERROR of it on a million values and at the ends."""
    import dataclasses

    facts = dataclasses.replace(_facts(None), black_dn=np.zeros(3), white_dn=1.0)  # normalise: x · 1 − 0
    settings = isp.IspSettings(white_balance="none", matrix="none", demosaic="bilinear")
    x = np.concatenate([np.geomspace(0.0031309, 1.0, 999_990), [0.0031308, 0.0031309, 0.5, 2 ** -0.5, 1.0, 0.0,
                                                                1e-5, 0.003, 0.7, 0.25]])
    x = x[: (x.size // 3) * 3].astype(np.float32).reshape(3, 1, -1)
    out, _ = _kernel(x, facts, settings)
    v = x.astype(np.float64)
    expected = np.where(v <= np.float32(0.0031308), 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)
    assert np.max(np.abs(out - expected)) <= fused.CURVE_ERROR


def test_power_polynomial_within_its_stated_error():
    """The kernel's float32 x^(5/12) (range reduction, then the degree-8 polynomial) against numpy's power in
    float64 on every 64th float32 of [0.0031308, 1] and on all within 4096 units in the last place of the ends of
    the reduction intervals: within POWER_ERROR (every float32 was checked once: camsim.isp.fused's docstring)."""
    import numba

    power = fused.fused_kernels()["power"]

    @numba.njit
    def powers(x):
        out = np.empty(x.size, dtype=np.float32)
        for i in range(x.size):
            out[i] = power(x[i])
        return out

    lo, hi = (int(np.float32(v).view(np.uint32)) for v in (0.0031308, 1.0))
    edges = [int(np.float32(2.0 ** -k).view(np.uint32)) for k in (8, 4, 2, 1, 0.5)]
    bits = np.concatenate([np.arange(lo, hi + 1, 64), [hi], *[np.arange(e - 4096, e + 4096) for e in edges]])
    x = bits.astype(np.uint32).view(np.float32)
    assert np.max(np.abs(powers(x) - x.astype(np.float64) ** (5 / 12))) <= fused.POWER_ERROR


def _sources(**extra):
    from pathlib import Path

    from camsim.pairs import PairSource

    images = Path(__file__).resolve().parents[2] / "camsim" / "scenes" / "images"
    common = {"crop": (40, 32), "batch_size": 3, "cameras": ("sony-a7s2",), "intensity": (1e-3, 0.1), "seed": 4}
    return (PairSource.from_scene("macbeth_26", images, domain="dn", **common | extra),
            PairSource.from_scene("macbeth_26", images, domain="srgb", **common | extra))


@pytest.mark.parametrize("camera", ["sony-a7s2", "sony-imx174"])
def test_srgb_pairs_by_the_kernel(camera):
    """A Bayer and a three-chip camera's srgb pairs come from the kernel (the record says so), within BOUND of
    develop_pair's (at the pairs' gains, 1 / F up to 1000, the bound of the numpy path against float64 grows with
    the gain; the two paths' difference, matrix and curve rounding only, stays below it); the same seed gives the
    same batch, bit for bit."""
    from camsim.pairs import pair_isp
    from camsim.sensor.presets import sensor_preset

    dn, srgb = _sources(cameras=(camera,))
    dn_batch, batch = dn.batch(1), srgb.batch(1)
    again = _sources(cameras=(camera,))[1].batch(1)
    assert np.array_equal(batch.noisy, again.noisy) and np.array_equal(batch.clean, again.clean)
    for i, p in enumerate(dn_batch.params):
        facts = srgb._facts(p, sensor_preset(p["preset"], p["iso"]))
        planes = (lambda a: a[0]) if facts.cfa_pattern else (lambda a: a)
        noisy, clean = isp.develop_pair(planes(dn_batch.noisy[i]), planes(dn_batch.clean[i]), facts, pair_isp())
        assert batch.isp[i] == {"domain": "srgb", "path": fused.FUSED_PATH, **noisy.record}
        assert np.max(np.abs(batch.noisy[i] - noisy.image)) < BOUND
        assert np.max(np.abs(batch.clean[i] - clean.image)) < BOUND


def test_without_numba_the_pairs_take_the_numpy_stages(monkeypatch):
    """Where numba cannot be imported the pairs are develop_pair's, bit for bit, and say so."""
    from camsim.pairs import pair_isp
    from camsim.sensor.presets import sensor_preset

    monkeypatch.setattr(fused._KERNELS, "state", {"kernels": None, "why": "no numba (test)"})
    dn, srgb = _sources()
    dn_batch, batch = dn.batch(0), srgb.batch(0)
    for i, p in enumerate(dn_batch.params):
        facts = srgb._facts(p, sensor_preset(p["preset"], p["iso"]))
        noisy, _ = isp.develop_pair(dn_batch.noisy[i, 0], dn_batch.clean[i, 0], facts, pair_isp())
        assert batch.isp[i]["path"] == fused.STAGES_PATH
        assert np.array_equal(batch.noisy[i], noisy.image)


def test_malvar_pairs_take_the_stages():
    """Malvar 2004 on a mosaic, and a mosaic too small for the ISP's mirrored border, take the numpy stages; a
    three-chip frame takes the kernel whatever the demosaicing setting (it has none to do)."""
    facts = _facts("RGGB")
    assert not fused.fused_applies(facts, isp.IspSettings(demosaic="malvar2004"), (32, 32))
    assert not fused.fused_applies(facts, isp.IspSettings(demosaic="bilinear"), (4, 32))
    assert fused.fused_applies(_facts(None), isp.IspSettings(demosaic="malvar2004"), (3, 4, 4))
