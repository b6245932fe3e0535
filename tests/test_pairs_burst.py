"""Burst pairs (camsim.pairs with burst_frames, issue 29): N noisy frames of one crop seen by a moving camera and the
static crop's expectation. Checked against theory written here: the shapes; the temporal noise independent between
consecutive frames (correlation of noisy − expectation within ±3/√n); the per-pixel mean and variance over a burst
against Poisson + read noise (one fixed pattern for every frame); the reference against the scene renderer's clean
layer of the same crop; the homographies against a phase correlation of the frames' expectations (a pure
translation, within 0.05 px); the batches a function of the seed and index only; bad options refused on one line."""

import numpy as np
import pytest

from camsim.core.errors import CamsimError
from camsim.pairs import PairBatches, PairSource
from tests.support.helpers import ROOT

IMAGES = ROOT / "scenes" / "images"


def source(**settings):
    base = {"crop": (64, 48), "batch_size": 2, "cameras": ("sony-imx174",), "intensity": (0.05, 0.5), "seed": 11,
            "burst_frames": 4, "flips": False}
    return PairSource.from_scene("macbeth_26", IMAGES, **(base | settings))


def with_sensor(src: PairSource, **overrides) -> PairSource:
    """``src`` with sensor overrides on its scene (its other settings kept)."""
    keep = ("crop", "batch_size", "intensity", "cameras", "seed", "flips", "burst_frames", "shake_px", "shake_deg",
            "pan_px_per_s", "frame_interval_s", "blur_subsamples", "domain")
    return PairSource(src.scene.with_sensor(**overrides), src.images, **{k: getattr(src, k) for k in keep})


# ------------------------------------------------------------------------------------------------ phase correlation
def _upsampled(spectrum: np.ndarray, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """The inverse DFT of ``spectrum`` (H, W) at the real positions ys × xs (matrix-multiply DFT)."""
    h, w = spectrum.shape
    fy, fx = np.fft.fftfreq(h) * h, np.fft.fftfreq(w) * w
    ey = np.exp(2j * np.pi * np.outer(ys, fy) / h)
    ex = np.exp(2j * np.pi * np.outer(fx, xs) / w)
    return (ey @ spectrum @ ex).real


def _window(n: int, shift: float, margin: int) -> np.ndarray:
    """A Hann window over [margin + shift, n − 1 − margin + shift] (0 outside), sampled at 0 … n − 1."""
    x = np.arange(n) - shift - margin
    length = n - 1 - 2 * margin
    return np.where((x >= 0) & (x <= length), np.sin(np.pi * np.clip(x, 0, length) / length) ** 2, 0.0)


def phase_shift(a: np.ndarray, b: np.ndarray, sigma: float = 0.08, margin: int = 8) -> tuple[float, float]:
    """(dx, dy) with b(p) ≈ a(p − d): the peak of the normalised cross-power spectrum's inverse, found to 0.002 px
    by an upsampled DFT around the integer peak. The window of ``b`` follows the estimate (three rounds), so that
    both windows cut the same content (a window fixed on the sensor biases the shift towards 0 by ~0.02 px a px);
    the cross-power is weighted by a Gaussian of σ = ``sigma`` cycles/px: at high frequencies a bilinearly sampled
    scene's spectrum carries aliases whose phase is not the shift's."""
    h, w = a.shape
    fy, fx = np.meshgrid(np.fft.fftfreq(h), np.fft.fftfreq(w), indexing="ij")
    low = np.exp(-(fx**2 + fy**2) / (2 * sigma**2))
    d = (0.0, 0.0)
    for _ in range(3):
        wa = np.outer(_window(h, 0, margin), _window(w, 0, margin))
        wb = np.outer(_window(h, d[1], margin), _window(w, d[0], margin))
        fa = np.fft.fft2((a - (a * wa).sum() / wa.sum()) * wa)
        fb = np.fft.fft2((b - (b * wb).sum() / wb.sum()) * wb)
        cross = fb * np.conj(fa)
        cross *= low / (np.abs(cross) + 1e-12 * np.abs(cross).max())
        corr = np.fft.ifft2(cross).real
        iy, ix = np.unravel_index(np.argmax(corr), corr.shape)
        cy, cx = (iy + h // 2) % h - h // 2, (ix + w // 2) % w - w // 2
        for span, step in ((1.5, 0.05), (0.06, 0.002)):
            ys, xs = cy + np.arange(-span, span + step / 2, step), cx + np.arange(-span, span + step / 2, step)
            up = _upsampled(cross, ys, xs)
            jy, jx = np.unravel_index(np.argmax(up), up.shape)
            cy, cx = ys[jy], xs[jx]
        d = (float(cx), float(cy))
    return d


@pytest.mark.parametrize("d", [(1.37, -2.61), (0.3, 0.45), (-3.8, 1.1)])
def test_the_phase_correlation_finds_a_known_shift(d):
    """The test's own estimator: two crops of a band-limited random image, one shifted by a Fourier phase ramp
    (not periodic in the crop, as frames are not): within 0.02 px."""
    rng = np.random.default_rng(0)
    size = 256
    spectrum = np.fft.fft2(rng.standard_normal((size, size)))
    fy, fx = np.meshgrid(np.fft.fftfreq(size), np.fft.fftfreq(size), indexing="ij")
    spectrum *= np.exp(-(fx**2 + fy**2) / (2 * 0.15**2))
    a = np.fft.ifft2(spectrum).real[64:160, 64:192]
    b = np.fft.ifft2(spectrum * np.exp(-2j * np.pi * (fx * d[0] + fy * d[1]))).real[64:160, 64:192]
    assert np.allclose(phase_shift(a, b), d, atol=0.02)


# ------------------------------------------------------------------------------------------------ the tests
@pytest.mark.parametrize("domain, camera, tail", [
    ("dn", "sony-a7s2", (1, 48, 64)), ("raw", "sony-a7s2", (4, 24, 32)), ("srgb", "sony-a7s2", (3, 48, 64)),
    ("dn", "sony-imx174", (3, 48, 64)),
])
def test_a_burst_batch_has_its_shapes_and_records(domain, camera, tail):
    batch = source(cameras=(camera,), domain=domain, burst_frames=3, shake_px=0.5, shake_deg=0.1,
                   intensity=(1e-2, 0.1)).batch(0)
    assert batch.noisy.shape == batch.frames_clean.shape == (2, 3) + tail
    assert batch.clean.shape == (2,) + tail and batch.homographies.shape == (2, 3, 3, 3)
    assert batch.noisy.dtype == batch.clean.dtype == batch.frames_clean.dtype == np.float32
    assert (batch.digital is None) == (domain != "dn")
    if batch.digital is not None:
        assert batch.digital.shape == (2, 3) + tail and batch.digital.dtype == np.uint16
    assert (batch.isp is None) == (domain == "dn")
    for p in batch.params:
        burst = p["burst"]
        assert burst["frames"] == 3 and burst["frame_interval_s"] == p["exposure_s"]  # back to back by default
        assert burst["time_s"] == pytest.approx([0.0, p["exposure_s"], 2 * p["exposure_s"]])
        assert burst["margin_px"][0] >= burst["reach_px"] > 0 and not burst["clamped"]
        assert np.all(np.isfinite(batch.homographies)) and np.allclose(batch.homographies[:, :, 2], [0, 0, 1])
    single = PairSource(**{**{k: getattr(source(), k) for k in ("scene", "images", "crop", "batch_size")},
                           "cameras": (camera,), "domain": domain}).batch(0)
    assert single.homographies is None and single.frames_clean is None and single.noisy.ndim == 4


def test_consecutive_frames_have_independent_noise():
    """corr(noisy_j − E_j, noisy_{j+1} − E_{j+1}) over every pixel of the batch within ±3/√n of 0 (E_j the frame's
    own expectation), with shake, a pan and every fixed-pattern map on: what is fixed is in E_j, not in the noise."""
    src = with_sensor(source(burst_frames=5, batch_size=3, crop=(64, 64), shake_px=0.7, shake_deg=0.2,
                             pan_px_per_s=(0.6, -0.4)),
                      dsnu_e=15.0, prnu_percent=2.0, dark_current_e_per_s=300.0, dsnu_dark_current_percent=30.0)
    batch = src.batch(1)
    residual = batch.noisy.astype(np.float64) - batch.frames_clean
    n = residual[:, 0].size
    correlations = []
    for j in range(4):
        a, b = residual[:, j].ravel(), residual[:, j + 1].ravel()
        correlations.append(np.corrcoef(a, b)[0, 1])
    assert np.all(np.abs(correlations) < 3 / np.sqrt(n)), correlations
    # the frames differ (the noise, and the motion moves the expectations)
    assert not np.array_equal(batch.frames_clean[:, 0], batch.frames_clean[:, 1])


@pytest.mark.parametrize("overrides, variance", [
    ({"prnu_percent": 3.0, "dark_current_e_per_s": 400.0, "dsnu_dark_current_percent": 40.0}, True),
    ({"dsnu_e": 25.0, "prnu_percent": 3.0}, False),
])
def test_a_static_bursts_pixels_have_the_models_mean_and_variance(overrides, variance):
    """A burst of 48 frames without motion (IMX174: Gaussian read noise, no row noise): per pixel, the mean over
    the frames is the reference's k·λ (z-scores of mean square 1), and the sample variance k²(λ + σ_read²) (Poisson
    + read noise, λ = clean / k), with one fixed pattern for all frames (PRNU, dark-current DSNU; a DSNU offset
    redrawn per frame would move the mean by σ_DSNU / √N ≫ the mean's standard error)."""
    frames = 48
    src = with_sensor(source(burst_frames=frames, batch_size=2, crop=(32, 32)), **overrides)
    batch = src.batch(0)
    p = batch.params[0]
    k, read = p["dn_per_electron"], p["read_noise_e"]
    noisy = batch.noisy.astype(np.float64)  # (B, N, 3, H, W)
    clean = batch.clean.astype(np.float64)  # (B, 3, H, W)
    assert np.array_equal(batch.frames_clean, np.broadcast_to(batch.clean[:, None], batch.frames_clean.shape))
    assert np.allclose(batch.homographies, np.eye(3))
    far = clean < 0.5 * k * p["full_well_e"]
    assert far.mean() > 0.9
    model = k * np.maximum(clean, 0) + (k * read) ** 2  # k² (λ + σ²) with λ = clean / k
    mean = noisy.mean(axis=1)
    z = (mean - clean) / np.sqrt(model / frames)
    npix = far.sum()
    # with a DSNU offset o, E = k (λ + o): the model's λ = clean / k over-states the Poisson part by o, z² shrinks
    slack = 0.05 if "dsnu_e" in overrides else 0.0
    tolerance = 6 * np.sqrt(2 / npix)
    assert -tolerance - slack < np.mean(z[far] ** 2) - 1 < tolerance, np.mean(z[far] ** 2)
    assert abs(np.mean(z[far])) < 6 / np.sqrt(npix)
    if variance:
        ratio = noisy.var(axis=1, ddof=1)[far] / model[far]
        assert abs(ratio.mean() - 1) < 6 * np.sqrt(2 / (frames - 1) / npix) + 0.005, ratio.mean()


def test_the_reference_is_the_scene_frames_clean_layer_of_the_crop():
    """The burst's clean reference equals the clean layer of the same crop (its recorded offset) rendered as a
    scene frame (light_scene of the photograph's crop, clean_dn): the static crop's expectation."""
    from camsim.render.frame import clean_dn
    from camsim.render.pipeline import light_scene
    from camsim.scene.sources.image import ImageSource
    from camsim.sensor.presets import sensor_preset

    src = source(shake_px=1.5, pan_px_per_s=(2.0, 1.0), crop=(64, 48))
    batch = src.batch(3)
    for i, p in enumerate(batch.params):
        crop = ImageSource(path=IMAGES / p["image"], crop=(p["crop_x"], p["crop_y"], 64, 48))
        lit = light_scene(src.scene.replace(source=crop), p["illuminant"])
        sensor = sensor_preset(p["preset"], p["iso"])
        expected = lit.expected(sensor, p["intensity_factor"], "pixel")
        np.testing.assert_allclose(batch.clean[i], clean_dn(lit.labels, expected, sensor), rtol=2e-6, atol=1e-4)
        assert p["burst"]["margin_px"][0] >= 2  # the pan alone moves 2 px a second


def test_an_integer_pan_shows_the_neighbouring_crop_of_the_photograph():
    """A pan of (4, −2) px/s, T = 1 s, one sub-sample at each exposure's middle: frame j is translated by
    d = (4, −2)·(j + ½), whole pixels, so its expectation is the scene frame's clean layer of the photograph's crop at
    (x − dx, y − dy): the margin beyond the crop (11 px: the farthest frame moves 10) is the photograph's own scene,
    and H maps the reference to it."""
    from camsim.render.frame import clean_dn
    from camsim.render.pipeline import light_scene
    from camsim.scene.sources.image import ImageSource
    from camsim.sensor.presets import sensor_preset

    src = source(burst_frames=3, batch_size=2, pan_px_per_s=(4.0, -2.0), blur_subsamples=1)
    batch = src.batch(0)
    for i, p in enumerate(batch.params):
        assert p["exposure_s"] == 1.0 and p["burst"]["margin_px"] == [11, 11] and not p["burst"]["clamped"]
        sensor = sensor_preset(p["preset"], p["iso"])
        for j in range(3):
            dx, dy = batch.homographies[i, j, :2, 2]
            assert (dx, dy) == (4.0 * (j + 0.5), -2.0 * (j + 0.5))
            crop = ImageSource(path=IMAGES / p["image"], crop=(p["crop_x"] - int(dx), p["crop_y"] - int(dy), 64, 48))
            lit = light_scene(src.scene.replace(source=crop), p["illuminant"])
            expected = lit.expected(sensor, p["intensity_factor"], "pixel")
            np.testing.assert_allclose(batch.frames_clean[i, j], clean_dn(lit.labels, expected, sensor), rtol=1e-5,
                                       atol=1e-3)


def test_the_homographies_move_the_clean_content():
    """A pure pan: each frame's expectation is the reference shifted by its homography's translation (at the
    exposure's middle; the blur within the exposure is symmetric about it), by the test's phase correlation within
    0.05 px, frame to reference and frame to frame."""
    v = (1.3, -0.7)
    src = source(burst_frames=4, batch_size=2, crop=(128, 128), pan_px_per_s=v, intensity=(0.2, 0.4))
    batch = src.batch(0)
    for i, p in enumerate(batch.params):
        h = batch.homographies[i]
        exposure = p["exposure_s"]
        assert np.allclose(h[:, :2, :2], np.eye(2)) and np.allclose(h[:, 2], [0, 0, 1])
        for j in range(4):
            t = j * exposure + exposure / 2
            assert np.allclose(h[j, :2, 2], (v[0] * t, v[1] * t))
            d = phase_shift(batch.clean[i, 1], batch.frames_clean[i, j, 1])
            assert np.allclose(d, h[j, :2, 2], atol=0.05), (j, d, h[j, :2, 2])
            if j:
                d = phase_shift(batch.frames_clean[i, 0, 1], batch.frames_clean[i, j, 1])
                assert np.allclose(d, h[j, :2, 2] - h[0, :2, 2], atol=0.05), (j, d)


def test_a_burst_batch_depends_on_the_seed_and_its_index_only():
    """Bit-identical batches whichever worker draws them; the motion is the sequence model's, drawn from the item's
    recorded motion_seed (camsim.scene.sequence.Motion reproduces the homographies)."""
    from camsim.scene.sequence import Motion, SequenceParams

    settings = dict(shake_px=0.8, shake_deg=0.3, pan_px_per_s=(0.5, 0.2), cameras=("sony-a7s2", "nikon-d850"),
                    intensity=(1e-3, 0.1), flips=True)
    src = source(**settings)
    direct = [src.batch(i) for i in range(4)]
    again = list(PairBatches(source(**settings), start=1, stop=4, step=2))
    for b in again:
        d = direct[b.index]
        for name in ("noisy", "clean", "digital", "frames_clean", "homographies"):
            assert np.array_equal(getattr(b, name), getattr(d, name)), name
        assert b.params == d.params
    for b in direct:
        for i, p in enumerate(b.params):
            burst = p["burst"]
            seq = SequenceParams(frames=burst["frames"], frame_interval_s=burst["frame_interval_s"],
                                 shake_px=burst["shake_px"], shake_deg=burst["shake_deg"],
                                 pan_px_per_s=tuple(burst["pan_px_per_s"]))
            motion = Motion.of(seq, 64, 48, burst["motion_seed"])
            for j in range(burst["frames"]):
                assert np.array_equal(motion.mid_homography(j, p["exposure_s"]), b.homographies[i, j])
    seeds = {p["burst"]["motion_seed"] for b in direct for p in b.params}
    assert len(seeds) == 8  # every item its own motion
    assert not np.array_equal(direct[0].homographies[0], direct[0].homographies[1])


def test_a_photograph_too_small_for_the_motion_is_clamped_and_said():
    """coffee.png is 432 × 288: a 400 × 280 crop leaves a margin of 4 px across; a pan of 30 px needs more."""
    src = PairSource.from_scene(
        "macbeth_26", IMAGES / "coffee.png", crop=(400, 280), batch_size=1, cameras=("sony-imx174",), seed=1,
        burst_frames=2, pan_px_per_s=(15.0, 0.0), flips=False)
    p = src.batch(0).params[0]
    assert p["burst"]["margin_px"] == [16, 4] and p["burst"]["clamped"] and p["burst"]["reach_px"] > 29
    # a pan across that its 16 px cover: the 4 px down the frame are no clamp, as nothing moves that way
    src = PairSource.from_scene(
        "macbeth_26", IMAGES / "coffee.png", crop=(400, 280), batch_size=1, cameras=("sony-imx174",), seed=1,
        burst_frames=2, pan_px_per_s=(5.0, 0.0), flips=False)
    p = src.batch(0).params[0]
    assert 9 < p["burst"]["reach_px"] < 10 and p["burst"]["margin_px"] == [10, 4] and not p["burst"]["clamped"]


@pytest.mark.parametrize("settings, match", [
    ({"burst_frames": 0}, "burst_frames must be a positive integer"),
    ({"burst_frames": 2.5}, "burst_frames must be a positive integer"),
    ({"burst_frames": None, "shake_px": 1.0}, "shake_px set without burst_frames"),
    ({"burst_frames": None, "pan_px_per_s": "fast"}, "pan_px_per_s set without burst_frames"),
    ({"burst_frames": None, "pan_px_per_s": (1.0, 0.0), "frame_interval_s": 0.1},
     "pan_px_per_s, frame_interval_s set without burst_frames"),
    ({"shake_px": -1.0}, "shake_px must be a finite number ≥ 0"),
    ({"shake_deg": float("nan")}, "shake_deg must be a finite number ≥ 0"),
    ({"pan_px_per_s": (1.0,)}, "pan_px_per_s must be two finite numbers"),
    ({"pan_px_per_s": (1.0, float("inf"))}, "pan_px_per_s must be two finite numbers"),
    ({"frame_interval_s": 0.0}, "frame_interval_s must be a finite number > 0"),
    ({"frame_interval_s": 0.5}, "the exposure 1 s is longer than frame_interval_s 0.5 s"),
    ({"blur_subsamples": 0}, "blur_subsamples must be an integer from 1 to 1024"),
    ({"burst_frames": 20000}, "burst pairs: frames must be at most 10000"),
    ({"pan_px_per_s": (1e9, 0.0)}, "burst pairs: the camera would move the scene"),
    ({"device": "cuda"}, "burst pairs render on the CPU only"),
])
def test_bad_burst_settings_are_refused_on_one_line(settings, match):
    with pytest.raises(CamsimError, match=match) as info:
        source(**settings)
    assert "\n" not in str(info.value)


def test_the_docs_burst_example_runs_and_prints_what_they_say(monkeypatch, capsys):
    """The python block of "Burst pairs on the fly" (docs/guides/denoiser-datasets.md) prints
    the text block after it."""
    import re

    text = (ROOT / "docs" / "guides" / "denoiser-datasets.md").read_text(encoding="utf-8")
    section = text[text.index("### Burst pairs on the fly"):]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    printed = re.search(r"```text\n(.*?)```", section, re.S).group(1)
    monkeypatch.chdir(ROOT)
    exec(compile(code, "docs/guides/denoiser-datasets.md", "exec"), {})
    assert capsys.readouterr().out == printed
