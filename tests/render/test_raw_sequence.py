"""Raw scenes in motion (issue 29, point 1 for ``[raw]`` scenes): a raw scene's ``[sequence]`` through ``camsim
render``, against expectations computed here.

The sources are DNGs written by the tests' own writer (:mod:`tests.support.phone_dng`, which does not import camsim).
The closed forms are this file's own:

* a static sequence under ``add`` at F (the source's exposure, f = F): at each site of a constant-per-site source
  s, each frame's DN is floor(P + ½ + K · Poisson(f s) + read + row), so over the frames, per pixel,
  mean = P + K f s and variance = K² f s + σ_read² + σ_row² + 1/12 (the row offset is a new draw per frame; the
  ADC's floor adds 1/12 DN², Sheppard); the preset's σ_read from the Tukey law's scale and λ (scipy);
* a source with its own photon noise N ~ Poisson(λ) per site: about the scene's truth P + K f λ, two frames of a
  static sequence covary by K² f² Var(s) (Var s = λ + 1 / (12 K²): the source's Poisson and its ADC's rounding),
  and not at all about their own clean layers (the frames' own noise is independent);
* a pure translation H = [[1, 0, dx], [0, 1, dy]] of a smooth blob moves the clean layer by (dx, dy): measured by
  this file's phase correlation (a least-squares fit of the cross-power spectrum's phase plane), within 0.05 px;
* the saturated sites' mask moves with the scene: by an even integer shift exactly, and a half-pixel shift flags the
  border's sites as partly masked (1 … 254 in the mask file).
"""

import json
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
import rawpy
from scipy import stats

from camsim.cli import main
from camsim.io.exr import read_exr
from camsim.render.sidecar_schema import check_sidecar
from camsim.sensor.presets import camera_preset
from tests.end_to_end.test_raw_scene import BLACK, EXPOSURE_S, ISO, SITE_E, WHITE, write_source
from tests.support.phone_dng import write_phone_dng

SIGMAS = 5.0


def k_source() -> float:
    return camera_preset("sony-a7s2").point_at(ISO).k_dn_per_e


def write_mosaic(path: Path, mosaic_e: np.ndarray, saturated=None) -> Path:
    """A DNG of ``mosaic_e`` electrons (H, W) at the A7S2's gain over BLACK (RGGB, orientation 1); ``saturated``
    sites (bool (H, W)) at the white level."""
    dn = np.rint(BLACK + mosaic_e * k_source())
    if saturated is not None:
        dn[saturated] = WHITE
    write_phone_dng(path, np.clip(dn, 0, WHITE).astype(np.uint16), pattern="RGGB", black_per_site=[[BLACK] * 2] * 2,
                    white=WHITE, iso=ISO, exposure_s=EXPOSURE_S, make="SONY", model="ILCE-7SM2")
    return path


def write_sequence_scene(folder: Path, raw: str, factor: float, sequence: str, extra: str = "") -> Path:
    path = folder / "seq.toml"
    path.write_text(f'name = "seq"\n[raw]\npath = "{raw}"\n{extra}\n[light]\nintensity_factors = [{factor!r}]\n'
                    f'[sequence]\n{sequence}\n', encoding="utf-8")
    return path


def render(scene: Path, out: Path) -> int:
    return main(["render", str(scene), "--out", str(out), "-q"])


def homographies(*shifts) -> str:
    rows = [f"[[1, 0, {dx}], [0, 1, {dy}], [0, 0, 1]]" for dx, dy in shifts]
    return f"homographies = [{', '.join(rows)}]"


def test_a_raw_sequence_renders_files_per_frame(tmp_path):
    write_source(tmp_path / "a.dng", 96, 128, orientation=1)
    scene = write_sequence_scene(tmp_path, "a.dng", 0.01, "frames = 3\nframe_interval_s = 0.2\nshake_px = 0.7\n"
                                                          "shake_deg = 0.1")
    assert render(scene, tmp_path / "out") == 0
    out, stem = tmp_path / "out", "seq_as-shot_F0.01"
    names = {p.name for p in out.iterdir()}
    for i in range(3):
        assert {f"{stem}_f{i:03d}.dng", f"{stem}_f{i:03d}.exr", f"{stem}_f{i:03d}.json"} <= names
    assert {f"{stem}_ref.exr", f"{stem}_ref.json"} <= names and f"{stem}_ref.dng" not in names
    metas = [json.loads((out / f"{stem}_f{i:03d}.json").read_text()) for i in range(3)]
    for i, meta in enumerate(metas):
        check_sidecar(meta, "frame")
        assert meta["frame_index"] == i and meta["time_s"] == pytest.approx(0.2 * i)
        assert meta["scene_source"] == "raw" and meta["method"] == "raw-add"
        assert meta["raw_source"]["fraction"] == pytest.approx(0.01)
        assert meta["sequence"]["stem"] == stem and meta["sequence"]["reference"] == f"{stem}_ref.exr"
        assert np.shape(meta["homography"]) == (3, 3)
    assert metas[0]["homography"] != metas[2]["homography"]  # the shake moved it
    # the same seed gives the same bits, on any number of threads
    assert main(["render", str(scene), "--out", str(tmp_path / "again"), "-q", "--workers", "1"]) == 0
    for name in names - {"manifest.json"}:
        assert (out / name).read_bytes() == (tmp_path / "again" / name).read_bytes(), name
    ref = json.loads((out / f"{stem}_ref.json").read_text())
    check_sidecar(ref, "ref")
    assert ref["sequence_reference"] is True and ref["homography"] == np.eye(3).tolist()
    manifest = json.loads((out / "manifest.json").read_text())
    assert sorted(e.get("frame_index", -1) for e in manifest["frames"]) == [-1, 0, 1, 2]
    # the reference is the source's expectation: K · f · s at each site (no fixed pattern in the preset's sensor;
    # its dark charge is below 1e-3 e⁻ here)
    _, clean, _ = read_exr(out / f"{stem}_ref.exr")
    k = camera_preset("sony-a7s2").point_at(ISO).k_dn_per_e
    source_e = (np.rint(BLACK + SITE_E * k) - BLACK) / k
    for dy, dx, c in ((0, 0, 0), (0, 1, 1), (1, 0, 1), (1, 1, 2)):
        assert np.allclose(clean[c, dy::2, dx::2], k * 0.01 * source_e[dy, dx], rtol=1e-4, atol=1e-3)


def _phase_shift(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(dx, dy) with b(x) ≈ a(x − d): the integer peak of the normalised cross-power spectrum, then the sub-pixel
    rest by a least-squares plane through the phase of the residual spectrum at the frequencies |k| ≤ 4 bins."""
    fa, fb = np.fft.fft2(a), np.fft.fft2(b)
    cross = fb * np.conj(fa)
    cross /= np.maximum(np.abs(cross), 1e-30)
    h, w = a.shape
    py, px = np.unravel_index(np.argmax(np.fft.ifft2(cross).real), cross.shape)
    py, px = (py - h if py > h // 2 else py), (px - w if px > w // 2 else px)
    ky, kx = np.meshgrid(np.fft.fftfreq(h), np.fft.fftfreq(w), indexing="ij")
    rest = cross * np.exp(2j * np.pi * (ky * py + kx * px))
    near = (np.abs(ky) * h <= 4) & (np.abs(kx) * w <= 4) & ((ky != 0) | (kx != 0))
    design = -2 * np.pi * np.stack([kx[near], ky[near]], axis=1)
    (fx, fy), *_ = np.linalg.lstsq(design, np.angle(rest[near]), rcond=None)
    return px + fx, py + fy


def test_a_pure_translation_moves_the_clean_layer_by_the_sidecars_homography(tmp_path):
    h, w = 96, 128
    y, x = np.mgrid[0:h, 0:w]
    blob = 6000.0 * np.exp(-((x - 61.0) ** 2 + (y - 47.0) ** 2) / (2 * 8.0 ** 2))
    write_mosaic(tmp_path / "b.dng", blob)
    scene = write_sequence_scene(tmp_path, "b.dng", 0.05, "frames = 2\nframe_interval_s = 0.2\n"
                                 + homographies((0, 0), (3.37, -2.18)))
    assert render(scene, tmp_path / "out") == 0
    out, stem = tmp_path / "out", "seq_as-shot_F0.05"
    cleans = [read_exr(out / f"{stem}_f{i:03d}.exr")[1] for i in range(2)]
    metas = [json.loads((out / f"{stem}_f{i:03d}.json").read_text()) for i in range(2)]
    step = np.array(metas[1]["homography"]) @ np.linalg.inv(np.array(metas[0]["homography"]))
    for c in range(3):
        dx, dy = _phase_shift(cleans[0][c].astype(np.float64), cleans[1][c].astype(np.float64))
        assert abs(dx - step[0, 2]) < 0.05 and abs(dy - step[1, 2]) < 0.05, (c, dx, dy, step)
    assert abs(step[0, 2] - 3.37) < 1e-12 and abs(step[1, 2] + 2.18) < 1e-12


def _tukey_read_sd(point) -> float:
    return float(point.tukey_scale_dn * stats.tukeylambda(point.tukey_lambda).std())


def test_static_sequence_moments_per_site_follow_the_add_law(tmp_path):
    write_source(tmp_path / "a.dng", 96, 128, orientation=1)
    factor, frames = 0.05, 10
    scene = write_sequence_scene(tmp_path, "a.dng", factor, f"frames = {frames}\nframe_interval_s = 0.2")
    assert render(scene, tmp_path / "out") == 0
    stem = tmp_path / "out" / "seq_as-shot_F0.05"
    stack = np.stack([rawpy.imread(f"{stem}_f{i:03d}.dng").raw_image.astype(np.float64) for i in range(frames)])
    preset = camera_preset("sony-a7s2")
    point = preset.point_at(ISO)
    k = point.k_dn_per_e
    read_var, row_var = _tukey_read_sd(point) ** 2, point.row_sigma_dn ** 2
    source_e = (np.rint(BLACK + SITE_E * k) - BLACK) / k
    for dy in (0, 1):
        for dx in (0, 1):
            site = stack[:, dy::2, dx::2]  # (frames, rows, columns)
            mu = factor * source_e[dy, dx]
            mean, var = preset.pedestal_dn + k * mu, k * k * mu + read_var + row_var + 1 / 12
            rows = site.shape[1]
            tol_mean = SIGMAS * np.sqrt((var - row_var) / site.size + row_var / (frames * rows))
            assert site.mean() == pytest.approx(mean, abs=tol_mean), (dy, dx)
            per_pixel = site.var(axis=0, ddof=1)  # each pixel's temporal variance over the frames
            row_means = per_pixel.mean(axis=1)  # a row's pixels share its row offsets: rows as the samples
            tol_var = SIGMAS * row_means.std(ddof=1) / np.sqrt(rows)
            assert per_pixel.mean() == pytest.approx(var, abs=tol_var), (dy, dx, per_pixel.mean(), var)
            assert tol_var < 0.06 * var  # can fail: a missing read-noise term is 20 % of var here


def test_the_sources_noise_is_common_to_the_frames_and_only_to_them(tmp_path):
    """Measured: about the scene's truth, two frames of a static sequence covary by K² f² Var(s) (the source's own
    noise, common to both); about their clean layers they are uncorrelated."""
    rng = np.random.default_rng(5)
    h, w, lam = 192, 192, 2000.0
    counts = rng.poisson(lam, (h, w)).astype(np.float64)
    write_mosaic(tmp_path / "n.dng", counts)
    factor = 0.5
    scene = write_sequence_scene(tmp_path, "n.dng", factor, "frames = 2\nframe_interval_s = 0.2")
    assert render(scene, tmp_path / "out") == 0
    stem = tmp_path / "out" / "seq_as-shot_F0.5"
    point = camera_preset("sony-a7s2").point_at(ISO)
    k, pedestal = point.k_dn_per_e, camera_preset("sony-a7s2").pedestal_dn
    raws = [rawpy.imread(f"{stem}_f{i:03d}.dng").raw_image.astype(np.float64) - pedestal for i in range(2)]
    cleans = [read_exr(f"{stem}_f{i:03d}.exr")[1] for i in range(2)]
    truth = k * factor * lam
    about_truth = [r - truth for r in raws]
    n = raws[0].size
    cov = np.mean(about_truth[0] * about_truth[1]) - about_truth[0].mean() * about_truth[1].mean()
    expected = k * k * factor ** 2 * (lam + 1 / (12 * k * k))
    var = k * k * factor * lam + expected + _tukey_read_sd(point) ** 2 + point.row_sigma_dn ** 2
    assert cov == pytest.approx(expected, abs=SIGMAS * np.sqrt((var * var + expected ** 2) / n)), (cov, expected)
    assert expected / var > 0.25  # the effect is large at f = 0.5: a third of the shot-noise variance
    own = []
    for r, c in zip(raws, cleans):  # about each frame's own clean layer (the sites' own colour)
        site_clean = np.empty_like(r)
        for dy, dx, ch in ((0, 0, 0), (0, 1, 1), (1, 0, 1), (1, 1, 2)):
            site_clean[dy::2, dx::2] = c[ch, dy::2, dx::2]
        own.append((r - site_clean).ravel())
    assert abs(np.corrcoef(own[0], own[1])[0, 1]) < 3 / np.sqrt(n)


@pytest.mark.parametrize("motion", ["shake_px = 0.5", homographies((0, 0), (1, 0))])
def test_thin_with_motion_is_refused_on_one_line(tmp_path, capsys, motion):
    write_source(tmp_path / "a.dng", 64, 64, orientation=1)
    scene = write_sequence_scene(tmp_path, "a.dng", 0.01, f"frames = 2\nframe_interval_s = 0.2\n{motion}",
                                 extra='photon_law = "thin"')
    capsys.readouterr()
    assert render(scene, tmp_path / "out") == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("camsim: error:") and "thin" in err and "\n" not in err, err
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())


def test_a_static_thin_sequence_follows_the_thin_law(tmp_path):
    """Per site over the frames: mean P + K p n, temporal variance K² n p (1 − p) + σ_read² + σ_row² + 1/12, n the
    source's rounded count (Binomial(n, p) per frame, each frame its own draw)."""
    write_source(tmp_path / "a.dng", 64, 64, orientation=1)
    factor, frames = 0.3, 6
    scene = write_sequence_scene(tmp_path, "a.dng", factor, f"frames = {frames}\nframe_interval_s = 0.2",
                                 extra='photon_law = "thin"')
    assert render(scene, tmp_path / "out") == 0
    stem = tmp_path / "out" / "seq_as-shot_F0.3"
    stack = np.stack([rawpy.imread(f"{stem}_f{i:03d}.dng").raw_image.astype(np.float64) for i in range(frames)])
    assert json.loads(Path(f"{stem}_f001.json").read_text())["method"] == "raw-thin"
    preset = camera_preset("sony-a7s2")
    point = preset.point_at(ISO)
    k = point.k_dn_per_e
    read_var, row_var = _tukey_read_sd(point) ** 2, point.row_sigma_dn ** 2
    count = np.rint((np.rint(BLACK + SITE_E * k) - BLACK) / k)
    for dy in (0, 1):
        for dx in (0, 1):
            site = stack[:, dy::2, dx::2]
            n = count[dy, dx]
            var = k * k * n * factor * (1 - factor) + read_var + row_var + 1 / 12
            rows = site.shape[1]
            tol_mean = SIGMAS * np.sqrt((var - row_var) / site.size + row_var / (frames * rows))
            assert site.mean() == pytest.approx(preset.pedestal_dn + k * factor * n, abs=tol_mean), (dy, dx)
            per_pixel = site.var(axis=0, ddof=1)
            tol_var = SIGMAS * per_pixel.mean(axis=1).std(ddof=1) / np.sqrt(rows)
            assert per_pixel.mean() == pytest.approx(var, abs=tol_var), (dy, dx, per_pixel.mean(), var)
            assert tol_var < 0.2 * k * k * n * factor  # can fail: add's variance (no 1 − p) is 43 % more here


def test_a_raw_sequence_warns_where_the_sources_noise_is_a_visible_share(tmp_path):
    from camsim.render.raw_sequence import raw_sequence_warnings
    from camsim.scene.scene_file import load_scene

    write_source(tmp_path / "a.dng", 64, 64, orientation=1)
    for factor, law, warned in ((0.5, "add", True), (0.005, "add", False), (0.02, "thin", True)):
        scene = load_scene(write_sequence_scene(tmp_path, "a.dng", factor, "frames = 2\nframe_interval_s = 0.2",
                                                extra=f'photon_law = "{law}"'))
        lines = raw_sequence_warnings(scene)
        assert len(lines) == int(warned) and all("\n" not in line for line in lines), (factor, law, lines)
        if warned:  # the share it states: f / (1 + f) for add, p for thin
            share = factor / (1 + factor) if law == "add" else factor
            assert f"{100 * share:.3g} %" in lines[0], lines[0]


def test_the_mask_moves_with_the_scene(tmp_path):
    h, w = 64, 96
    saturated = np.zeros((h, w), dtype=bool)
    saturated[20:36, 30:50] = True
    write_mosaic(tmp_path / "m.dng", np.full((h, w), 3000.0), saturated)
    scene = write_sequence_scene(tmp_path, "m.dng", 0.05, "frames = 3\nframe_interval_s = 0.2\n"
                                 + homographies((0, 0), (4, 2), (0.5, 0)))
    assert render(scene, tmp_path / "out") == 0
    stem = tmp_path / "out" / "seq_as-shot_F0.05"
    masks = [iio.imread(f"{stem}_f{i:03d}_mask.png")[..., 0] for i in range(3)]
    metas = [json.loads(Path(f"{stem}_f{i:03d}.json").read_text()) for i in range(3)]
    assert np.array_equal(masks[0] == 255, saturated) and set(np.unique(masks[0])) == {0, 255}
    shifted = np.zeros_like(saturated)
    shifted[22:38, 34:54] = True  # sensor p = reference q + (4, 2)
    assert np.array_equal(masks[1] == 255, shifted) and set(np.unique(masks[1])) == {0, 255}
    assert metas[1]["raw_source"]["masked_px"] == shifted.sum()
    # half a pixel: the square's inside stays masked, its left and right borders are partly masked (and its top and
    # bottom rows' sites whose colour is interpolated from outside the square), nothing far from it is
    half = masks[2]
    partial = (half > 0) & (half < 255)
    assert np.all(half[21:35, 32:48] == 255)
    assert partial[21:35, 29:32].any() and partial[21:35, 48:51].any()
    away = np.ones_like(saturated)
    away[19:37, 28:52] = False
    assert np.all(half[away] == 0)
    assert metas[2]["raw_source"]["masked_partial_px"] == int(partial.sum())


def test_a_raw_sequence_under_a_rolling_shutter_and_flicker_follows_the_closed_form(tmp_path):
    """A static add sequence of a flat raw under a flickering light with a rolling shutter: each frame's clean layer,
    row r, is the reference's times F_r = 1 + m / (ωT) · (sin(ω (t_r + T) + φ) − sin(ω t_r + φ)), t_r = tᵢ + r Δ
    (this file's closed form of (1/T) ∫ (1 + m cos(ωt + φ)) dt), and the sidecar gives the same factors."""
    write_source(tmp_path / "a.dng", 64, 64, orientation=1)
    m, f_hz, delta, interval = 0.6, 13.0, 1e-3, 0.2  # T = the source's 0.1 s: 1.3 periods, bands over 64 rows
    scene = write_sequence_scene(tmp_path, "a.dng", 0.01, f"frames = 2\nframe_interval_s = {interval}\n"
                                 f"rolling_shutter_row_s = {delta}\nflicker_hz = {f_hz}\nflicker_depth = {m}")
    assert render(scene, tmp_path / "out") == 0
    stem = tmp_path / "out" / "seq_as-shot_F0.01"
    _, ref, _ = read_exr(Path(f"{stem}_ref.exr"))
    omega = 2 * np.pi * f_hz
    for i in range(2):
        meta = json.loads(Path(f"{stem}_f{i:03d}.json").read_text())
        exposure = meta["exposure_s"]
        t = i * interval + np.arange(64) * delta
        factor = 1 + m / (omega * exposure) * (np.sin(omega * (t + exposure)) - np.sin(omega * t))
        assert np.allclose(meta["flicker_row_factor"], factor, rtol=1e-9, atol=1e-12)
        _, clean, _ = read_exr(Path(f"{stem}_f{i:03d}.exr"))
        measured = (clean / ref).mean(axis=(0, 2))
        assert np.allclose(measured, factor, rtol=2e-4), np.abs(measured / factor - 1).max()
        assert np.ptp(factor) > 0.05  # the bands are there to see


def test_thin_under_a_flickering_light_is_refused_on_one_line(tmp_path, capsys):
    write_source(tmp_path / "a.dng", 64, 64, orientation=1)
    scene = write_sequence_scene(tmp_path, "a.dng", 0.01, "frames = 2\nframe_interval_s = 0.2\nflicker_hz = 100\n"
                                 "flicker_depth = 0.5", extra='photon_law = "thin"')
    capsys.readouterr()
    assert render(scene, tmp_path / "out") == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("camsim: error:") and "flicker" in err and "\n" not in err, err


def test_a_raw_sequence_refuses_zarr_on_one_line(tmp_path, capsys):
    write_source(tmp_path / "a.dng", 64, 64, orientation=1)
    scene = write_sequence_scene(tmp_path, "a.dng", 0.01, "frames = 2\nframe_interval_s = 0.2\nshake_px = 0.5")
    capsys.readouterr()
    assert main(["render", str(scene), "--out", str(tmp_path / "out"), "-q", "--format", "zarr"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("camsim: error: --format zarr: a raw scene's sequence") and "\n" not in err, err
    assert not (tmp_path / "out").exists() or not any((tmp_path / "out").iterdir())
