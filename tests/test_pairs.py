"""Training pairs on the fly (camsim.pairs), without torch: the batches' shapes and parameters, their seeds (a batch
is a function of the seed and its index), the physics (the clean target is the scene frame's clean layer, and
noisy − clean has mean zero at every pixel, saturated or not, with the model's variance) — on numpy, and on CuPy
where a GPU is."""

import numpy as np
import pytest

from camsim.core.errors import CamsimError
from camsim.core.xp import to_host
from camsim.pairs import PairBatches, PairSource
from tests.support.helpers import ROOT

IMAGES = ROOT / "scenes" / "images"


@pytest.fixture(params=["cpu", "cuda"], scope="module")
def device(request):
    if request.param == "cuda":
        from camsim.render.backends import cuda_module

        try:
            cuda_module()
        except CamsimError as exc:
            pytest.skip(f"no GPU: {exc}")
    return request.param


def source(device="cpu", **settings):
    base = {"crop": (64, 48), "batch_size": 3, "cameras": ("sony-a7s2", "nikon-d850"), "intensity": (1e-3, 0.1),
            "seed": 4, "device": device}
    return PairSource.from_scene("macbeth_26", IMAGES, **(base | settings))


def test_a_batch_has_its_arrays_and_parameters(device):
    batch = source(device, cameras_mode="virtual").batch(0)
    noisy, clean, digital = to_host(batch.noisy), to_host(batch.clean), to_host(batch.digital)
    assert noisy.shape == clean.shape == digital.shape == (3, 1, 48, 64)
    assert noisy.dtype == clean.dtype == np.float32 and digital.dtype == np.uint16
    assert len(batch.params) == 3 and batch.index == 0
    for p in batch.params:
        assert p["preset"] in ("sony-a7s2", "nikon-d850") and p["iso"] is None and p["cfa_pattern"] == "RGGB"
        assert 1e-3 <= p["intensity_factor"] <= 0.1 and p["image"] in ("astronaut.png", "chelsea.png", "coffee.png")
        assert {"crop_x", "crop_y", "flip_horizontal", "illuminant", "dn_per_electron", "read_noise_e",
                "tukey_lambda", "row_noise_e", "pedestal_dn", "white_level_dn"} <= set(p)
    assert np.all(digital <= 16383) and np.all(clean >= 0)


def test_a_batch_depends_on_the_seed_and_its_index_only(device):
    src = source(device)
    direct = [src.batch(i) for i in (0, 1, 2, 3)]
    again = list(PairBatches(source(device), start=1, stop=4, step=2))  # a worker's share: batches 1 and 3
    assert [b.index for b in again] == [1, 3] and len(PairBatches(src, 1, 4, 2)) == 2
    for b in again:
        assert np.array_equal(to_host(b.noisy), to_host(direct[b.index].noisy))
        assert np.array_equal(to_host(b.digital), to_host(direct[b.index].digital))
        assert b.params == direct[b.index].params
    assert not np.array_equal(to_host(direct[0].clean), to_host(direct[1].clean))
    other = source(device, seed=5).batch(0)
    assert other.params != direct[0].params


def test_presets_at_an_iso_range_and_three_plane_cameras(device):
    batch = source(device, cameras=("sony-imx174", "sony-icx625-basler"), iso=None, batch_size=2).batch(1)
    assert to_host(batch.noisy).shape == (2, 3, 48, 64)
    iso = source(device, cameras=("sony-a7s2",), iso=(800.0, 3200.0)).batch(0)
    assert all(800 <= p["iso"] <= 3200 for p in iso.params)


def test_bad_settings_are_refused():
    with pytest.raises(CamsimError, match="share their layout"):
        source(cameras=("sony-a7s2", "sony-imx174"))
    with pytest.raises(CamsimError, match="smaller than the crop"):
        source(crop=(1000, 48))
    with pytest.raises(CamsimError, match="virtual cameras need noise fits"):
        source(cameras=("sony-imx174",), cameras_mode="virtual")
    with pytest.raises(CamsimError, match="unknown camera preset"):
        source(cameras=("leica",))
    with pytest.raises(CamsimError, match="unknown pair device"):
        source(device="tpu")


def test_the_clean_target_is_the_scene_frames_clean_layer(device):
    """A pair's clean planes equal the clean layer of the same crop rendered as a scene (an [images] dataset frame's
    scene: the photograph cropped, lit, seen by the camera), site by site for a Bayer camera."""
    from camsim.render.frame import clean_dn
    from camsim.render.pipeline import light_scene
    from camsim.scene.sources.image import ImageSource
    from camsim.sensor.presets import sensor_preset

    src = source(device, flips=False, cameras=("canon-eos-70d",), iso=(100.0, 6400.0), intensity=(0.05, 2.0))
    batch = src.batch(2)
    for i, p in enumerate(batch.params):
        crop = ImageSource(path=IMAGES / p["image"], crop=(p["crop_x"], p["crop_y"], 64, 48))
        lit = light_scene(src.scene.replace(source=crop), p["illuminant"])
        sensor = sensor_preset(p["preset"], p["iso"])
        expected = lit.expected(sensor, p["intensity_factor"], "pixel")
        rgb = clean_dn(lit.labels, expected, sensor)
        mosaic = np.empty((48, 64), np.float32)
        for dy, dx, c in ((0, 0, 0), (0, 1, 1), (1, 0, 1), (1, 1, 2)):  # RGGB
            mosaic[dy::2, dx::2] = rgb[c][dy::2, dx::2]
        np.testing.assert_allclose(to_host(batch.clean)[i, 0], mosaic, rtol=2e-6, atol=1e-4)


@pytest.mark.parametrize("intensity, overrides", [
    ((0.02, 0.2), {}),
    ((10.0, 40.0), {}),                                                   # many pixels at the full well
    ((0.05, 0.5), {"dsnu_e": 20.0, "prnu_percent": 3.0, "dark_current_e_per_s": 400.0,
                   "dsnu_dark_current_percent": 40.0}),                    # every fixed-pattern map
    ((0.05, 0.5), {"photon_noise": False, "dark_current_e_per_s": 50.0}),
])
def test_noisy_minus_clean_has_mean_zero_and_the_model_variance(device, intensity, overrides):
    """noisy − clean over every pixel of a batch (IMX174: Gaussian read noise 6.8 e⁻, no row noise, 12 bits):
    its mean is 0 within 5 standard errors, saturated pixels included, and, where the well is far, its variance is
    k² (λ + σ_read²) per pixel."""
    src = source(device, cameras=("sony-imx174",), intensity=intensity, batch_size=4, crop=(128, 96))
    src = PairSource(src.scene.with_sensor(**overrides), src.images, **{
        k: getattr(src, k) for k in ("crop", "batch_size", "intensity", "cameras", "seed", "device")})
    batch = src.batch(0)
    noisy, clean = to_host(batch.noisy).astype(np.float64), to_host(batch.clean).astype(np.float64)
    p = batch.params[0]
    k, read = p["dn_per_electron"], p["read_noise_e"]
    residual = noisy - clean
    far = clean < 0.5 * k * p["full_well_e"]
    # per pixel variance of the charge ≤ its mean (λ + offsets ≥ the Poisson part): a conservative standard error
    var = k * np.maximum(clean, 0) + (k * read) ** 2 + k * k * 1.0
    z = residual.sum() / np.sqrt(var.sum())
    assert abs(z) < 5, z
    if "dsnu_e" not in overrides and overrides.get("photon_noise", True) and far.sum() > 1000:
        model = k * clean[far] + (k * read) ** 2  # k² (λ + σ²) with λ = clean / k
        ratio = np.mean(residual[far] ** 2) / np.mean(model)
        assert abs(ratio - 1) < 5 * np.sqrt(2 / far.sum()) + 0.01, ratio


def test_readme_pairs_example_runs(monkeypatch, capsys):
    """The docs' numpy example of "Training pairs on the fly" (docs/guides/denoiser-datasets.md, the first python
    block of that section) runs."""
    import re

    text = (ROOT / "docs" / "guides" / "denoiser-datasets.md").read_text(encoding="utf-8")
    section = text[text.index("## Training pairs on the fly"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    monkeypatch.chdir(ROOT)
    exec(compile(code, "docs/guides/denoiser-datasets.md", "exec"), {})
    lines = capsys.readouterr().out.splitlines()
    assert lines == ["(4, 1, 48, 64) float32 True"] * 2
