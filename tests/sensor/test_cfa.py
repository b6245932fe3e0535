"""Bayer (CFA) sensors end to end: per-site statistics, CFA DNG through rawpy, EXR mosaic, analysis."""

import json

import numpy as np
import pytest
import rawpy

from camsim.analysis.analyze import analyse_paths
from camsim.analysis.patches import AnalysisSettings
from camsim.core.seeding import frame_seed_sequence
from camsim.io.exr import read_exr, read_exr_oiio
from camsim.render.run import render_scene
from camsim.sensor.cfa import CFA_PATTERNS, cfa_sites
from camsim.sensor.params import preset
from tests.support.helpers import WHITE, render, small_scene
from tests.support.theory import assert_mean_var, digital_pmf, pmf_moments

RAW_PATTERN = {"RGGB": [[0, 1], [3, 2]], "BGGR": [[2, 3], [1, 0]], "GRBG": [[1, 0], [2, 3]], "GBRG": [[3, 2], [0, 1]]}


@pytest.mark.parametrize("pattern", CFA_PATTERNS)
@pytest.mark.parametrize("method", ["poisson", "auto"])
def test_each_site_draws_its_own_channel(pattern, method):
    sensor = preset("paper-table1", cfa=pattern)
    frame, radiance = render(small_scene(), sensor, factor=0.5, method=method, seed=3)
    assert frame.noisy_dn.shape == (1, 480, 720) and frame.digital_dn.shape == (1, 480, 720)
    x, y, w, h = radiance.patch_rects[WHITE]
    k = sensor.dn_per_electron
    for dy, dx, c in cfa_sites(pattern):
        rows = slice(y + 4 + (dy - y - 4) % 2, y + h - 4, 2)
        cols = slice(x + 4 + (dx - x - 4) % 2, x + w - 4, 2)
        lam = frame.expected.signal_e[WHITE, c] + frame.expected.dark_e[c]
        assert_mean_var(frame.noisy_dn[0, rows, cols], k * lam, k * k * (lam + 16), what=f"{pattern} site {c}")
        mean, var = pmf_moments(digital_pmf(lam, k, 4.0, 9000.0, 8))
        assert_mean_var(frame.digital_dn[0, rows, cols], mean, var, what=f"{pattern} digital {c}")


def test_odd_frame_sizes_are_refused():
    from camsim.core.errors import CamsimError

    with pytest.raises(CamsimError, match="even frame size"):
        render(small_scene(width=121, height=80), preset("paper-table1", cfa="RGGB"))


@pytest.fixture(scope="module")
def cfa_frames(tmp_path_factory):
    out = tmp_path_factory.mktemp("cfa")
    scene = small_scene(width=360, height=240, intensity_factors=(1.0, 0.1), seed=5).with_sensor(cfa="GRBG")
    render_scene(scene, out, progress=False)
    return out, scene


def test_cfa_files_hold_the_mosaic_exactly(cfa_frames):
    out, scene = cfa_frames
    frame, _ = render(scene, scene.sensor, factor=0.1, seed=frame_seed_sequence(5, "D65", 0.1))
    with rawpy.imread(str(out / "test_D65_F0.1.dng")) as raw:
        np.testing.assert_array_equal(raw.raw_image, frame.digital_dn[0])
        np.testing.assert_array_equal(raw.raw_pattern, RAW_PATTERN["GRBG"])
        assert raw.postprocess().shape == (240, 360, 3)
    for reader in (read_exr, read_exr_oiio):
        noisy, clean, header = reader(out / "test_D65_F0.1.exr")
        np.testing.assert_array_equal(noisy, frame.noisy_dn)
        np.testing.assert_array_equal(clean, frame.clean_dn())
        assert noisy.shape == (1, 240, 360) and clean.shape == (3, 240, 360)
    sidecar = json.loads((out / "test_D65_F0.1.json").read_text())
    assert sidecar["sensor_layout"] == "bayer" and sidecar["cfa_pattern"] == "GRBG"


@pytest.mark.parametrize("source", ["dng", "exr"])
def test_analysis_reads_cfa_frames(cfa_frames, source):
    out, scene = cfa_frames
    results = analyse_paths([out], AnalysisSettings(), source=source, progress=False)
    for result in results:
        assert result["cfa_pattern"] == "GRBG" and "bilinear" in result["demosaicing"]
        sidecar = json.loads((out / f"test_D65_F{result['intensity_factor']:g}.json").read_text())
        k = sidecar["dn_per_electron"]
        for patch, model in zip(result["patches"], sidecar["patches"]):
            assert patch["ellipse_status"] == "ok" and patch["n_distinct_values"] is None
            for c, channel in enumerate(patch["channels"]):
                lam = model["signal_e"][c] + model["dark_e"][c]
                # per-site statistics: a quarter (R, B) or half (G) of the patch's pixels
                expected_n = 0.5 if c == 1 else 0.25
                assert abs(channel["n_pixels"] / patch["channels"][1]["n_pixels"] - expected_n / 0.5) < 0.1
                offset = 0.5 if source == "dng" else 0.0  # the integer part lowers quantised numbers by ½ DN
                se = np.sqrt(k * k * (lam + 16) / channel["n_pixels"]) + 0.01
                assert abs(channel["mean_dn"] - (k * lam - offset)) < 5 * se + 0.02
    de = {r["intensity_factor"]: np.mean([p["delta_e_ab_mean"] for p in r["patches"]]) for r in results}
    assert de[1.0] < de[0.1]


def test_row_noise_is_shared_by_the_whole_row_of_a_bayer_sensor():
    off = dict(photon_noise=False, dark_current=False, saturation=False, read_noise=False, quantisation=False)
    sensor = preset("paper-table1", cfa="RGGB", row_noise_e=5.0, **off)
    frame, radiance = render(small_scene(), sensor, factor=0.5, seed=2)
    clean = frame.clean_dn()
    x, y, w, h = radiance.patch_rects[WHITE]
    k = sensor.dn_per_electron
    mosaic_clean = np.zeros((h, w))
    for dy, dx, c in cfa_sites("RGGB"):
        mosaic_clean[(dy - y) % 2 :: 2, (dx - x) % 2 :: 2] = clean[c, y : y + h, x : x + w][(dy - y) % 2 :: 2,
                                                                                              (dx - x) % 2 :: 2]
    residual = (frame.noisy_dn[0, y : y + h, x : x + w] - mosaic_clean) / k
    np.testing.assert_allclose(residual, np.broadcast_to(residual[:, :1], residual.shape), atol=1e-3)  # per row
    assert_mean_var(residual[:, 0], 0.0, 25.0, what="row offsets")


@pytest.mark.parametrize("pattern", ["RGGB", "BGGR", "GRBG", "GBRG"])
def test_mosaic_of_takes_each_sites_own_channel(pattern):
    from camsim.sensor.cfa import mosaic_of

    planes = np.stack([np.full((4, 6), 10.0 * (c + 1), dtype=np.float32) for c in range(3)])
    mosaic = mosaic_of(planes, pattern)
    assert mosaic.shape == (4, 6) and mosaic.dtype == np.float32
    for i, colour in enumerate(pattern):
        assert np.all(mosaic[i // 2::2, i % 2::2] == 10.0 * ("RGB".index(colour) + 1))
