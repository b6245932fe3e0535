"""The ISP's fast paths (issue 26, "Speed") against independent references.

- bilinear demosaicing by slicing against colour-demosaicing's ``demosaicing_CFA_Bayer_bilinear`` on the mosaic
  mirrored as the ISP mirrors it (4 pixels, ``np.pad`` reflect), on every pattern and odd shapes;
- the sRGB curve against IEC 61966-2-1's formula taken branch by branch in float32 (bit for bit), and in float64;
- the development with the white balance, the colour matrix and the gain fused into one matrix after a bilinear
  demosaic (or a three-chip frame) against the stages written out here in float64 from the record's gains, matrix
  and gain, colour-demosaicing's bilinear and the formula;
- the gains and matrices kept per camera and illuminant against :func:`camsim.isp.srgb_matrix` and
  :func:`camsim.isp.white_balance_gains` computed afresh;
- ``srgb`` pairs developed into the batch against :func:`camsim.isp.develop_pair`.
"""

import numpy as np
import pytest

import camsim.isp as isp
from camsim.sensor.cfa import CFA_PATTERNS
from tests.support.isp_reference import colour_demosaicing_bilinear as _colour_demosaicing_bilinear
from tests.support.isp_reference import made_up_facts as _facts
from tests.support.isp_reference import reference_development as _reference_development

EPS32 = float(np.finfo(np.float32).eps)
THRESHOLD = np.float32(0.0031308)


@pytest.mark.parametrize("shape", [(5, 5), (5, 8), (7, 6), (9, 11), (16, 20), (33, 17), (64, 96)])
@pytest.mark.parametrize("pattern", CFA_PATTERNS)
def test_bilinear_by_slicing_is_colour_demosaicings_within_float32_rounding(shape, pattern):
    """Every site: the means of two sites are colour-demosaicing's numbers exactly (both are the exact mean
    rounded once to float32); the means of four are within one float32 unit in the last place of the largest
    value (three roundings instead of one); a site's own colour is its value."""
    rng = np.random.default_rng(sum(shape) + CFA_PATTERNS.index(pattern))
    mosaic = (rng.random(shape) * 1.5 - 0.25).astype(np.float32)
    fast = isp.demosaic(mosaic, pattern, "bilinear")
    expected = _colour_demosaicing_bilinear(mosaic, pattern)
    assert fast.shape == (3, *shape) and fast.dtype == np.float32
    assert np.max(np.abs(fast - expected)) <= EPS32 * np.max(np.abs(mosaic))
    for i, letter in enumerate(pattern):
        dy, dx = i // 2, i % 2
        own = "RGB".index(letter)
        assert np.array_equal(fast[own, dy::2, dx::2], mosaic[dy::2, dx::2])
        if letter == "G":  # red and blue here are means of two sites
            for c in (0, 2):
                assert np.array_equal(fast[c, dy::2, dx::2], expected[c, dy::2, dx::2].astype(np.float32))


def test_bilinear_of_a_stack_of_calls_does_not_share_memory():
    """Two calls in a row (the temporaries are reused) give two separate, correct images."""
    rng = np.random.default_rng(5)
    a, b = rng.random((2, 12, 14)).astype(np.float32)
    first = isp.demosaic(a, "GRBG", "bilinear")
    kept = first.copy()
    second = isp.demosaic(b, "GRBG", "bilinear")
    assert np.array_equal(first, kept) and not np.shares_memory(first, second)
    assert np.allclose(second, _colour_demosaicing_bilinear(b, "GRBG"), rtol=0, atol=EPS32)


def _srgb_branchwise(x):
    """IEC 61966-2-1 in float32 as the ISP defines it: clip to [0, 1], the power of x, then 12.92 x put in where
    x ≤ 0.0031308."""
    x = np.clip(np.asarray(x, dtype=np.float32), np.float32(0.0), np.float32(1.0))
    out = np.power(x, np.float32(1 / 2.4))
    out *= np.float32(1.055)
    out -= np.float32(0.055)
    np.multiply(x, np.float32(12.92), out=out, where=x <= THRESHOLD)
    return out


def test_srgb_curve_is_the_branchwise_formula_bit_for_bit():
    """Every float32 within 2^20 units in the last place of the threshold (where the branches meet), a million
    values over [−0.5, 1.5], and the ends. (Every float32 in [0, 1] was checked once too, 1 065 353 217 values,
    all equal: ``bits = np.arange(0, 0x3F800001, dtype=np.uint32)`` in chunks, viewed as float32.)"""
    bits = int(THRESHOLD.view(np.uint32))
    near = np.arange(bits - (1 << 20), bits + (1 << 20), dtype=np.uint32).view(np.float32)
    spread = np.random.default_rng(7).uniform(-0.5, 1.5, 1_000_000).astype(np.float32)
    ends = np.array([0.0, -0.0, 1.0, -1.0, 2.0, np.inf, -np.inf, THRESHOLD, np.float32(1e-38)], dtype=np.float32)
    for x in (near, spread, ends):
        assert np.array_equal(isp.tone_curve(x, "srgb"), _srgb_branchwise(x))
    assert np.isnan(isp.tone_curve(np.array([np.nan], dtype=np.float32), "srgb")[0])
    v = np.clip(spread.astype(np.float64), 0.0, 1.0)
    formula = np.where(v <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055)
    assert np.max(np.abs(isp.tone_curve(spread, "srgb") - formula)) < 2e-6


@pytest.mark.parametrize("pattern", [None, *CFA_PATTERNS])
@pytest.mark.parametrize("settings", [isp.IspSettings(demosaic="bilinear", gain="auto"),
                                      isp.IspSettings(demosaic="bilinear", gain=3.0, white_balance="A"),
                                      isp.IspSettings(demosaic="bilinear", matrix="none", white_balance="none"),
                                      isp.IspSettings(demosaic="bilinear", black=False, gain=30.0)])
def test_fused_development_against_the_stages_in_float64(pattern, settings):
    """The white balance, the matrix and the gain as one matrix after a bilinear demosaic are the stages one by
    one (exact in exact arithmetic: per-channel gains commute with a per-channel linear demosaic). In float32, on a
    noisy frame near black at gains up to 30: within 5e-6 of the float64 stages on [0, 1], as the stage-by-stage
    float32 result is (both up to about 4.6e-6 here: float32 rounding of the linear values times the gain, through
    the curve's slope of up to 12.92), and within 1e-6 of the stage-by-stage result; a pair's two images are
    develop's, bit for bit."""
    facts = _facts(pattern)
    rng = np.random.default_rng(11)
    shape = (3, 24, 30) if pattern is None else (24, 30)
    raw = 64.0 + rng.normal(0.0, 3.0, shape) + rng.random(shape) * 150.0
    developed = isp.develop(raw, facts, settings)
    expected = _reference_development(raw, facts, developed.record)
    staged = isp.develop_stages(raw, facts, settings)["toned"]
    assert np.max(np.abs(developed.image - expected)) < 5e-6
    assert np.max(np.abs(staged - expected)) < 5e-6
    assert np.max(np.abs(developed.image - staged)) < 1e-6
    noisy, clean = isp.develop_pair(raw, raw + 1.0, facts, settings)
    assert np.array_equal(noisy.image, developed.image)
    assert np.array_equal(clean.image, isp.develop(raw + 1.0, facts, settings).image)


def test_gains_and_matrices_kept_per_camera_and_illuminant_are_the_fresh_ones():
    """The kept numbers are srgb_matrix's and white_balance_gains' for those facts; another illuminant, neutral
    or camera gets its own."""
    from camsim.isp.develop import _plan

    settings = isp.IspSettings(demosaic="bilinear")
    for illuminant, neutral in (("D65", (0.5, 1.0, 0.8)), ("A", (0.9, 1.0, 0.4)), ("A", (0.8, 1.0, 0.45))):
        facts = _facts("RGGB", illuminant, neutral)
        for _ in range(2):  # computed, then kept
            stages = _plan(facts, settings).record["stages"]
            assert stages["white_balance"]["gains"] == isp.white_balance_gains(facts, "as-shot").tolist()
            assert stages["matrix"]["matrix"] == isp.srgb_matrix(facts, "as-shot", "camera").tolist()
    narrow = _facts("RGGB")
    narrow = isp.IspFacts(cfa_pattern="RGGB", black_dn=narrow.black_dn, white_dn=narrow.white_dn,
                          as_shot_neutral=narrow.as_shot_neutral, illuminant="D65",
                          wavelengths_nm=narrow.wavelengths_nm, qe=narrow.qe ** 2)
    assert (_plan(narrow, settings).record["stages"]["matrix"]["matrix"]
            == isp.srgb_matrix(narrow, "as-shot", "camera").tolist())


@pytest.mark.slow
def test_srgb_pairs_developed_into_the_batch_are_develop_pairs():
    """The CPU batch writes each pair's images into its slots; they are develop_pair's: bit for bit where the numpy
    stages made them, within 5e-6 where the compiled kernel did (camsim.isp.fused: the matrix and the curve rounded
    once from float64 instead of in float32; tests/isp/test_fused.py)."""
    from pathlib import Path

    from camsim.pairs import PairSource, pair_isp

    images = Path(__file__).resolve().parents[2] / "camsim" / "scenes" / "images"
    common = {"crop": (40, 32), "batch_size": 3, "cameras": ("sony-a7s2",), "intensity": (1e-3, 0.1), "seed": 4}
    dn = PairSource.from_scene("macbeth_26", images, domain="dn", **common)
    srgb = PairSource.from_scene("macbeth_26", images, domain="srgb", **common)
    dn_batch, srgb_batch = dn.batch(1), srgb.batch(1)
    from camsim.sensor.presets import sensor_preset

    for i, p in enumerate(dn_batch.params):
        facts = srgb._facts(p, sensor_preset(p["preset"], p["iso"]))
        noisy, clean = isp.develop_pair(dn_batch.noisy[i, 0], dn_batch.clean[i, 0], facts, pair_isp())
        path = srgb_batch.isp[i]["path"]
        if path == "stages (numpy, one pass per operation)":
            assert np.array_equal(srgb_batch.noisy[i], noisy.image)
            assert np.array_equal(srgb_batch.clean[i], clean.image)
        else:
            assert np.max(np.abs(srgb_batch.noisy[i] - noisy.image)) < 5e-6
            assert np.max(np.abs(srgb_batch.clean[i] - clean.image)) < 5e-6
        assert srgb_batch.isp[i] == {"domain": "srgb", "path": path, **noisy.record}
