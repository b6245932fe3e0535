"""One camera under every light (MODEL.md §3) and auto exposure, end to end through ``camsim render``/``analyze``.

Independent checks: the chart's surround is a flat 5 % reflector, so its electrons are 5 % of the perfect white's
(the metered quantity) whatever the light; the white's response under each light against D65 comes from
colour-science's own 5 nm data; dark charge is σ²_dark · T with Table I's σ².
"""

import json

import numpy as np
import pytest

from camsim.cli import main
from tests.support.helpers import ROOT
from tests.support.theory import anchored_signal_e, white_response

SCENE = ROOT / "scenes" / "macbeth_26.toml"
TABLE1_DARK = np.array([195.0, 230.0, 218.0])  # e⁻/s
SURROUND = 0.05  # reflectance of the chart's surround


def _sidecars(folder):
    return {p.stem: json.loads(p.read_text()) for p in folder.glob("macbeth_26_*.json")}


def test_fixed_exposure_keeps_one_camera_under_every_light(tmp_path):
    """T fixed: the white under A reaches its own electrons, 0.80× the D65 anchor in the strongest channel (R 1.38×,
    G 0.76×, B 0.40× D65's channels); Qe is the same in both frames; the reference illuminant is recorded."""
    out = tmp_path / "fixed"
    assert main(["render", str(SCENE), "--illuminant", "D65", "A", "--intensity", "1", "--size", "120x80", "-q",
                 "--out", str(out)]) == 0
    d65, a = (_sidecars(out)[f"macbeth_26_{name}_F1"] for name in ("D65", "A"))
    assert d65["exposure"] == a["exposure"] == "fixed" and d65["exposure_s"] == a["exposure_s"] == 1.0
    assert a["scale"]["reference_illuminant"] == "D65"
    assert a["qe_e_m2_sr_per_photon"] == d65["qe_e_m2_sr_per_photon"]
    white_d65 = np.array(d65["surround"]["signal_e"]) / SURROUND
    white_a = np.array(a["surround"]["signal_e"]) / SURROUND
    assert white_d65.max() == pytest.approx(8000.0, rel=1e-9)
    theory = white_response("A") / white_response("D65")
    np.testing.assert_allclose(white_a / white_d65, theory, rtol=2e-3)
    # the white under A at 100 cd/m²: 8000 · max(response under A) / max(response under D65) e⁻ = 0.80 × 8000
    expected_a = 8000.0 * white_response("A").max() / white_response("D65").max()
    assert white_a.max() == pytest.approx(expected_a, rel=2e-3) and expected_a == pytest.approx(6411, rel=2e-3)
    for index in (0, 5, 11, 18):  # patches under A, against the fixed anchor integrated on colour-science's data
        np.testing.assert_allclose(a["patches"][index]["signal_e"], anchored_signal_e(index, "A"), rtol=0.01)


def test_auto_exposure_meters_every_frame_and_scales_dark_current(tmp_path, capsys):
    """``--exposure auto``: every frame's white reaches the target in its strongest channel; T = target / (F · the
    white's rate) so that F · T is the same for every F of one light; the dark charge is σ²_dark · T; ``analyze``
    takes the frames of one light as one series (their ΔE is measured against the F = 1 frame)."""
    out = tmp_path / "auto"
    assert main(["render", str(SCENE), "--illuminant", "D65", "A", "--intensity", "1", "0.25", "--size", "120x80",
                 "--exposure", "auto", "--exposure-target", "6000", "-q", "--out", str(out)]) == 0
    sidecars = _sidecars(out)
    assert len(sidecars) == 4
    for stem, meta in sidecars.items():
        assert meta["exposure"] == "auto" and meta["exposure_target_e"] == 6000.0
        white = np.array(meta["surround"]["signal_e"]) / SURROUND
        assert white.max() == pytest.approx(6000.0, rel=1e-9)
        np.testing.assert_allclose(meta["patches"][0]["dark_e"], TABLE1_DARK * meta["exposure_s"], rtol=1e-12)
        factor = meta["intensity_factor"]
        # e⁻/s of the white's strongest channel at F = 1: the anchor's 8000 under D65, scaled by the responses
        light = "A" if "_A_" in stem else "D65"
        rate = 8000.0 * white_response(light).max() / white_response("D65").max()
        assert meta["exposure_s"] == pytest.approx(6000.0 / (factor * rate), rel=2e-3)
    assert main(["analyze", str(out), "--out", str(tmp_path / "an"), "-q", "--no-figures"]) == 0  # the series
    summary = json.loads((tmp_path / "an" / "analysis.json").read_text())
    frames = summary["frames"] if "frames" in summary else summary["results"]
    low = [f for f in frames if f["intensity_factor"] == 0.25]
    assert len(low) == 2
    for frame in low:
        assert all(p["delta_e_status"] == "ok" for p in frame["patches"])


def test_auto_exposure_limit_and_a_fixed_exposure_on_the_command_line(tmp_path):
    out = tmp_path / "limit"
    assert main(["render", str(SCENE), "--illuminant", "D65", "--intensity", "0.01", "--size", "120x80", "-q",
                 "--exposure", "auto", "--exposure-max", "20", "--out", str(out)]) == 0
    meta = _sidecars(out)["macbeth_26_D65_F0.01"]
    assert meta["exposure_s"] == 20.0 and meta["exposure_max_s"] == 20.0
    np.testing.assert_allclose(np.array(meta["surround"]["signal_e"]).max() / SURROUND, 8000.0 * 0.01 * 20,
                               rtol=1e-9)
    out = tmp_path / "fixed"
    assert main(["render", str(SCENE), "--illuminant", "D65", "--intensity", "0.01", "--size", "120x80", "-q",
                 "--exposure", "0.5", "--out", str(out)]) == 0
    meta = _sidecars(out)["macbeth_26_D65_F0.01"]
    assert meta["exposure"] == "fixed" and meta["exposure_s"] == 0.5


def test_auto_exposure_in_a_scene_file_and_bad_values(tmp_path, capsys):
    text = SCENE.read_text()
    scene = tmp_path / "auto.toml"
    assert 'exposure = "fixed"' in text and 'reference_illuminant = "D65"' in text
    scene.write_text(text.replace('exposure = "fixed"', 'exposure = "auto"\nexposure_target_e = 4000'))
    out = tmp_path / "out"
    assert main(["render", str(scene), "--illuminant", "D65", "--intensity", "0.5", "--size", "120x80", "-q",
                 "--out", str(out)]) == 0
    meta = _sidecars(out)["macbeth_26_D65_F0.5"]
    assert meta["exposure"] == "auto" and meta["exposure_s"] == pytest.approx(4000 / (0.5 * 8000), rel=1e-9)
    bad = tmp_path / "bad.toml"
    bad.write_text(scene.read_text().replace('exposure = "auto"', 'exposure = "sometimes"'))
    capsys.readouterr()
    assert main(["render", str(bad), "--out", str(tmp_path / "x"), "-q"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "camsim: error:" in err and "exposure" in err
    assert main(["render", str(SCENE), "--exposure", "soon", "--out", str(tmp_path / "y")]) == 2
    assert "--exposure" in capsys.readouterr().err
    scale = tmp_path / "scale.toml"
    scale.write_text(text.replace('reference_illuminant = "D65"', 'reference_illuminant = "nope"'))
    capsys.readouterr()
    assert main(["render", str(scale), "--out", str(tmp_path / "z"), "-q"]) == 2
    assert "nope" in capsys.readouterr().err


def test_a_dataset_with_auto_exposure(tmp_path):
    """``exposure = "auto"`` in a dataset spec: each frame's T meters its own light and F (its white reaches the
    target), the dark charge follows T, and the manifest says how T was chosen."""
    from camsim.dataset import run_dataset

    spec = tmp_path / "auto.toml"
    spec.write_text(f"""
name = "auto"
scene = "{SCENE.as_posix()}"
seed = 3

[frame]
width = 64
height = 48

[fixed]
preset = "emva-12bit"
exposure = "auto"
exposure_target_e = 5000

[grid]
illuminants = ["D65", "A"]

[random]
count = 2
intensity_factor = {{ log_uniform = [0.01, 1.0] }}
""", encoding="utf-8")
    out = tmp_path / "out"
    run_dataset(spec, out, workers=1, progress=False)
    sidecars = [json.loads(p.read_text()) for p in (out / "frames").rglob("*.json")]
    assert len(sidecars) == 4
    exposures = set()
    for meta in sidecars:
        assert meta["exposure"] == "auto"
        assert np.array(meta["surround"]["signal_e"]).max() / SURROUND == pytest.approx(5000.0, rel=1e-9)
        np.testing.assert_allclose(meta["patches"][0]["dark_e"], 25.0 * meta["exposure_s"], rtol=1e-12)
        exposures.add(meta["exposure_s"])
    assert len(exposures) == 4  # four lights × F: four exposure times
    records = [json.loads(line) for line in (out / "manifest.jsonl").read_text().splitlines()]
    assert all(r["exposure"] == "auto" and r["exposure_target_e"] == 5000.0 for r in records)
