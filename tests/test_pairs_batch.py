"""A batch's pairs are drawn together (camsim.pairs: one chain of array calls per batch, each pair's sensor figures
broadcast). Checked against theory written here: in a batch mixing very different virtual cameras, each pair's
noisy DN has its own camera's mean k·λ and variance k²(λ + σ_read²) + (k σ_row)² (λ the crop's mean signal from the
scene renderer, k, σ_read, σ_row the pair's recorded figures), and the pairs' noise is independent (correlations
within ±3/√N); and on a stand-in for CuPy (tests/support/fake_cupy.py: numpy behind CuPy's rules) a batch makes no
implicit transfer and as many array calls for 8 pairs as for 2."""

import numpy as np
import pytest

from camsim.pairs import PairSource
from tests.support import fake_cupy
from tests.support.helpers import ROOT

IMAGES = ROOT / "scenes" / "images"
#: Cameras with noise fits: K ranges from 0.2 to 20 DN/e⁻ between them (with k_range "union").
CAMERAS = ("sony-a7s2", "nikon-d850", "canon-eos-5d4", "canon-eos-70d", "canon-eos-700d", "sony-a7m4")
#: The channel of each site of an RGGB cell.
RGGB = ((0, 0, 0), (0, 1, 1), (1, 0, 1), (1, 1, 2))


def mixed_batch(crop=(128, 96), batch_size=8):
    src = PairSource.from_scene("macbeth_26", IMAGES, crop=crop, batch_size=batch_size, cameras=CAMERAS,
                                cameras_mode="virtual", k_range="union", intensity=(0.01, 0.3), seed=21, flips=False)
    return src, src.batch(0)


def signal_mosaic(src, p, width: int, height: int) -> np.ndarray:
    """λ per site of the pair's crop (RGGB): the scene renderer's mean signal S̄ = T·F·Σ g Qe of the same crop
    (light_scene of the photograph's crop), each site its channel's. Unit: e⁻."""
    from camsim.render.pipeline import light_scene
    from camsim.scene.sources.image import ImageSource
    from camsim.sensor.presets import sensor_preset

    crop = ImageSource(path=IMAGES / p["image"], crop=(p["crop_x"], p["crop_y"], width, height))
    lit = light_scene(src.scene.replace(source=crop), p["illuminant"])
    sensor = sensor_preset(p["preset"], None)
    assert sensor.exposure_s == p["exposure_s"]
    signal = lit.expected(sensor, p["intensity_factor"], "pixel").signal_e  # (K, 3)
    per_pixel = signal[lit.labels]  # (H, W, 3)
    out = np.empty((height, width))
    for dy, dx, c in RGGB:
        out[dy::2, dx::2] = per_pixel[dy::2, dx::2, c]
    return out


def test_each_pair_of_a_mixed_batch_has_its_own_cameras_mean_and_variance_and_the_pairs_are_independent():
    width, height = 128, 96
    src, batch = mixed_batch((width, height))
    params = batch.params
    ks = [p["dn_per_electron"] for p in params]
    assert max(ks) / min(ks) > 5 and len({p["preset"] for p in params}) >= 3  # very different cameras
    assert len({p["tukey_lambda"] for p in params}) > 1 and all(p["dark_e"] == [0.0] * 3 for p in params)
    noisy = batch.noisy[:, 0].astype(np.float64)
    standardised = []
    for i, p in enumerate(params):
        k, read, row = p["dn_per_electron"], p["read_noise_e"], p["row_noise_e"]
        lam = signal_mosaic(src, p, width, height)
        assert np.all(k * lam < 0.5 * k * p["full_well_e"])  # far from the full well: no saturation
        mean = k * lam
        variance = k * k * (lam + read**2) + (k * row) ** 2
        residual = noisy[i] - mean
        # the mean: the sum of residuals, whose variance has each row's offset W times over
        var_sum = (k * k * (lam + read**2)).sum() + height * (width * k * row) ** 2
        z = residual.sum() / np.sqrt(var_sum)
        assert abs(z) < 5, (i, p["preset"], z)
        # the variance: mean of the squared residuals against the model's, rows (independent) as the samples
        ratio_rows = (residual**2).mean(axis=1) / variance.mean(axis=1)
        error = ratio_rows.std(ddof=1) / np.sqrt(height)
        assert abs(ratio_rows.mean() - 1) < 5 * error + 0.005, (i, p["preset"], ratio_rows.mean(), error)
        # and read noise matters: the test tells σ_read from the Poisson part
        assert (k * read) ** 2 > 0.05 * variance.mean()
        standardised.append((residual / np.sqrt(variance)).ravel())
    n = standardised[0].size
    correlations = np.corrcoef(np.array(standardised))[np.triu_indices(len(params), 1)]
    assert np.all(np.abs(correlations) < 3 / np.sqrt(n)), correlations


@pytest.mark.slow
def test_a_batch_on_a_stand_in_for_cupy_makes_no_implicit_transfer_and_its_calls_do_not_grow_with_its_size():
    """On fake CuPy (numpy behind CuPy's rules) batches render in every domain and with every kind of camera —
    Bayer and three-chip (KAF-3200ME), fixed-pattern maps (IMX363's PRNU), a black-level error (KAF-3200ME's),
    virtual cameras —
    and a batch of 8 pairs makes as many kernel-launching calls as one of 2 (the pairs drawn together; F low
    enough that no pixel nears its full well, where the saturation's branches would add calls), the same bits as
    the same batch drawn again."""
    settings = [dict(cameras_mode="virtual", cameras=CAMERAS), dict(cameras=("kodak-kaf3200me",)),
                dict(cameras=("sony-imx363",), iso=(100.0, 800.0)), dict(cameras=("sony-a7s2",), domain="raw"),
                dict(cameras=("sony-a7s2",), domain="srgb")]
    with fake_cupy.installed():
        for setting in settings:
            calls = {}
            for size in (2, 8):
                src = PairSource.from_scene("macbeth_26", IMAGES, crop=(32, 24), batch_size=size, seed=3,
                                            device="cuda", intensity=(1e-3, 1e-2), **setting)
                src.batch(0)
                fake_cupy.reset()
                batch = src.batch(1)
                calls[size] = fake_cupy.COUNTS["calls"]
                assert type(batch.noisy).__name__ == "DeviceArray" and batch.noisy.shape[0] == size
                again = src.batch(1)
                assert np.array_equal(batch.noisy.get(), again.noisy.get())
                assert np.array_equal(batch.clean.get(), again.clean.get())
            # (4 more where a pair's Tukey shape is 0, the logistic law, which the larger batch may hold)
            assert calls[2] <= calls[8] <= calls[2] + 4, (setting, calls)
