"""The domains of on-the-fly pairs (camsim.pairs): ``dn`` is the default and what a source always gave; ``raw`` is
the normalised mosaic packed R, G1, G2, B (checked against an independent pack, for each Bayer pattern, and the
normalised planes of a three-chip camera); ``srgb`` is noisy and clean developed through one ISP — checked against an
independent development from the record's gains and matrix on a three-chip camera, and against the ISP's development
of the clean mosaic on a Bayer one. Every batch says its domain and how it was made; the same seed gives the same
bytes."""

import numpy as np
import pytest

from camsim.core.errors import CamsimError
from camsim.pairs import PAIR_DOMAINS, PairSource, pair_isp
from tests.support.helpers import ROOT

IMAGES = ROOT / "scenes" / "images"

#: (row, column) of R, G1 (the green on R's row), G2, B in the 2 × 2 cell, written out per pattern.
PACKED_SITES = {"RGGB": [(0, 0), (0, 1), (1, 0), (1, 1)], "BGGR": [(1, 1), (1, 0), (0, 1), (0, 0)],
                "GRBG": [(0, 1), (0, 0), (1, 1), (1, 0)], "GBRG": [(1, 0), (1, 1), (0, 0), (0, 1)]}
#: The channel of each cell site (row-major) per pattern.
SITE_CHANNEL = {p: ["RGB".index(c) for c in p] for p in PACKED_SITES}


def source(domain="dn", cfa=None, **settings):
    base = {"crop": (32, 24), "batch_size": 2, "cameras": ("sony-a7s2",), "intensity": (2e-3, 0.2), "seed": 11}
    src = PairSource.from_scene("macbeth_26", IMAGES, domain=domain, **(base | settings))
    if cfa is not None:
        src = PairSource(src.scene.with_sensor(cfa=cfa), src.images, domain=domain, **(base | settings))
    return src


def float_white(p) -> float:
    """The DN before quantisation that the ADC turns into the white level: 2^nb − 1 − pedestal (the ADC rounds and
    adds the pedestal), 2^nb − ½ without a pedestal (the ADC's floor)."""
    top = 2 ** p["bits"] - 1
    assert p["white_level_dn"] == top
    return float(top - p["pedestal_dn"]) if p["pedestal_dn"] else top + 0.5


def dark_level(p) -> np.ndarray:
    """The pair's black level before the ADC, per channel (the sensor model's, not the ISP's)."""
    from camsim.sensor.presets import sensor_preset

    return np.asarray(sensor_preset(p["preset"], p["iso"]).dark_level_dn, dtype=np.float64)


def test_dn_is_the_default_domain_and_unchanged():
    default, dn = source().batch(1), source("dn").batch(1)
    assert default.domain == "dn" and default.isp is None
    assert np.array_equal(default.noisy, dn.noisy) and np.array_equal(default.clean, dn.clean)
    assert np.array_equal(default.digital, dn.digital) and default.params == dn.params
    assert PAIR_DOMAINS == ("dn", "raw", "srgb")


@pytest.mark.parametrize("pattern", ["RGGB", "BGGR", "GRBG", "GBRG"])
def test_raw_pairs_are_the_normalised_mosaic_packed(pattern):
    """The same draws in both domains (the domain changes nothing before the conversion): packed raw plane k is the
    mosaic's site k of (dn − black_c) / (white − black_c), black the dark level before the ADC, white the DN the
    ADC turns into 2^nb − 1."""
    dn, raw = source(cfa=pattern).batch(0), source("raw", cfa=pattern).batch(0)
    assert raw.domain == "raw" and raw.digital is None
    assert raw.noisy.shape == raw.clean.shape == (2, 4, 12, 16) and raw.noisy.dtype == np.float32
    for i, p in enumerate(dn.params):
        assert p["cfa_pattern"] == pattern
        black, white = dark_level(p), float_white(p)
        for layer, packed in ((dn.noisy, raw.noisy), (dn.clean, raw.clean)):
            mosaic = layer[i, 0].astype(np.float64)
            for k, (dy, dx) in enumerate(PACKED_SITES[pattern]):
                c = SITE_CHANNEL[pattern][2 * dy + dx]
                assert c == (0, 1, 1, 2)[k]
                expected = (mosaic[dy::2, dx::2] - black[c]) / (white - black[c])
                np.testing.assert_allclose(packed[i, k], expected, rtol=1e-6, atol=1e-7)
        assert raw.isp[i]["packed"] == ["R", "G1", "G2", "B"]
        assert raw.isp[i]["white_dn"] == white and np.allclose(raw.isp[i]["black_dn"], black)


def test_raw_pairs_of_a_three_chip_camera_are_the_normalised_planes():
    dn, raw = source(cameras=("sony-imx174",)).batch(0), source("raw", cameras=("sony-imx174",)).batch(0)
    assert raw.noisy.shape == (2, 3, 24, 32) and raw.isp[0]["packed"] is None
    for i, p in enumerate(dn.params):
        black, white = dark_level(p), float_white(p)
        expected = (dn.clean[i].astype(np.float64) - black[:, None, None]) / (white - black[:, None, None])
        np.testing.assert_allclose(raw.clean[i], expected, rtol=1e-6, atol=1e-7)


def _srgb_encode(linear: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1's transfer function on values clipped to [0, 1], in float64."""
    x = np.clip(linear, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def test_srgb_pairs_of_a_three_chip_camera_against_an_independent_development():
    """Each developed plane equals tone(gain · M · (wb_c · (dn − black_c) / (white − black_c))) computed here in
    float64 from the DN pair and the record's gains, matrix and gain (1 / F): the clean target with the same gains
    and matrix as the noisy input."""
    settings = {"cameras": ("sony-imx174",), "intensity": (0.05, 0.5)}
    dn, srgb = source(**settings).batch(0), source("srgb", **settings).batch(0)
    assert srgb.domain == "srgb" and srgb.noisy.shape == srgb.clean.shape == (2, 3, 24, 32)
    for i, p in enumerate(dn.params):
        stages = srgb.isp[i]["stages"]
        gains = np.asarray(stages["white_balance"]["gains"])
        matrix = np.asarray(stages["matrix"]["matrix"])
        gain = stages["gain"]["value"]
        assert gain == pytest.approx(1 / p["intensity_factor"], rel=1e-12)
        assert srgb.isp[i]["settings"] == pair_isp().record()
        black, white = dark_level(p), float_white(p)
        for layer, developed in ((dn.noisy, srgb.noisy), (dn.clean, srgb.clean)):
            x = (layer[i].astype(np.float64) - black[:, None, None]) / (white - black[:, None, None])
            x = gains[:, None, None] * x
            x = np.einsum("cj,jhw->chw", matrix, x) * gain
            np.testing.assert_allclose(developed[i], _srgb_encode(x), atol=2e-5)


def test_srgb_clean_target_of_a_bayer_camera_is_the_isp_of_the_clean_mosaic():
    """On a Bayer camera the clean target is the clean mosaic through the same ISP, demosaicing included."""
    from camsim.isp import IspFacts, IspSettings, develop

    isp = IspSettings(gain="auto", demosaic="malvar2004")
    dn, srgb = source().batch(0), source("srgb", isp=isp).batch(0)
    src = source()
    for i, p in enumerate(dn.params):
        lit = src._lit(src.images[0], p["illuminant"])
        facts = IspFacts(cfa_pattern="RGGB", black_dn=dark_level(p), white_dn=float_white(p),
                         as_shot_neutral=lit.as_shot_neutral, intensity_factor=p["intensity_factor"],
                         illuminant=p["illuminant"], wavelengths_nm=lit.grid.wavelengths_nm, qe=lit.qe)
        for layer, developed in ((dn.noisy, srgb.noisy), (dn.clean, srgb.clean)):
            np.testing.assert_allclose(developed[i], develop(layer[i, 0], facts, isp).image, atol=1e-6)
        assert srgb.isp[i]["stages"]["demosaic"]["method"] == "malvar2004"


def test_same_seed_same_bytes_in_every_domain():
    for domain in PAIR_DOMAINS:
        a, b = source(domain).batch(3), source(domain).batch(3)
        assert a.noisy.tobytes() == b.noisy.tobytes() and a.clean.tobytes() == b.clean.tobytes()
        assert a.isp == b.isp


def test_bad_domains_and_settings_are_refused():
    from camsim.isp import IspSettings

    with pytest.raises(CamsimError, match="unknown pair domain"):
        source("linear")
    with pytest.raises(CamsimError, match="for the srgb domain"):
        source("raw", isp=IspSettings())
    with pytest.raises(CamsimError, match="IspSettings"):
        source("srgb", isp={"gain": "auto"})


def test_the_docs_domain_example_runs(monkeypatch, capsys):
    """The example of "On the fly: domain" (docs/guides/denoiser-datasets.md) runs and prints what the page says."""
    import re

    text = (ROOT / "docs" / "guides" / "denoiser-datasets.md").read_text(encoding="utf-8")
    section = text[text.index("### On the fly: `domain`"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    printed = re.search(r"```text\n(.*?)```", section, re.S).group(1).splitlines()
    monkeypatch.chdir(ROOT)
    exec(compile(code, "docs/guides/denoiser-datasets.md", "exec"), {})
    assert capsys.readouterr().out.splitlines() == printed == [
        "dn (4, 1, 48, 64) float32", "raw (4, 4, 24, 32) float32", "srgb (4, 3, 48, 64) float32"]


def test_the_default_gain_is_one_over_f_with_a_fixed_exposure_and_one_with_auto_exposure():
    fixed = source("srgb").batch(0)
    assert [r["stages"]["gain"]["value"] for r in fixed.isp] == pytest.approx(
        [1 / p["intensity_factor"] for p in fixed.params], rel=1e-12)
    base = source("srgb")
    auto = PairSource(base.scene.replace(exposure="auto"), base.images, crop=base.crop, batch_size=2,
                      cameras=base.cameras, intensity=base.intensity, seed=base.seed, domain="srgb").batch(0)
    assert [r["stages"]["gain"]["value"] for r in auto.isp] == [1.0, 1.0]
    assert auto.isp[0]["settings"] == pair_isp("auto").record() and pair_isp("auto").gain == 1.0


def test_torch_tensors_of_a_domain_batch():
    torch = pytest.importorskip("torch")
    from camsim.pairs_torch import batch_tensors, pair_dataset

    batch = source("raw").batch(2)
    tensors = batch_tensors(batch)
    assert tensors["domain"] == "raw" and tensors["isp"] == batch.isp and tensors["digital"] is None
    assert tensors["noisy"].shape == (2, 4, 12, 16) and tensors["noisy"].data_ptr() == batch.noisy.ctypes.data
    first = next(iter(pair_dataset(source("srgb"), start=1, stop=2)))
    assert first["domain"] == "srgb" and torch.equal(first["clean"], torch.from_numpy(source("srgb").batch(1).clean))
