"""The built-in ``dark`` and ``flat`` scenes and the calibration recipe of the docs (camera guide) (issue 23, point 8).

The recipe is read from the README or the docs' pages (the ``sh`` block after the ``calibration recipe`` marker) and run
as written, each line in a real ``camsim`` process, the renders at 384 × 256 instead of the scenes' 600 × 400. The
preset it renders with is ``sony-a7s2`` at ISO 3200 (K = 3.06 DN/e⁻, read noise 1.288 e⁻ Tukey λ = −0.0349, row noise
0.1454 e⁻, no DSNU, PRNU or dark current), so the calibration must give back those numbers. Margins at 384 × 256
(N = 24 576 pixels per Bayer plane, 8 darks, 5 flat pairs), from the standard errors ``calibration.json`` reported
in a run: K 0.31 % (tolerance 2 %), read σ 0.09 % (3 %), row σ 2.0 % (10 %), λ 0.0009 (0.03), black level
0.011 DN (0.1 DN); the test checks each tolerance is at least 4 of them. DSNU and PRNU, 0 in the preset, came out
0.11 DN and 0.09 % (bound 0.3 each): the estimators of a spread are biased upwards near 0.
"""

import json
import os
import re
import shlex
import sys
import tomllib

import numpy as np
import pytest

from camsim.cli import main
from camsim.core.errors import CamsimError
from camsim.render.frame_files import load_frame
from camsim.scene.scene_file import load_scene
from camsim.sensor.presets import sensor_preset
from tests.support import clock
from tests.support.helpers import ROOT

SIZE = "384x256"
PRESET, ISO = "sony-a7s2", 3200


def readme_recipe() -> list[str]:
    """The command lines of the calibration recipe, wherever the README or the docs' Markdown pages hold it (the
    ``sh`` block after the ``<!-- calibration recipe: … -->`` marker)."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    texts = [p.read_text(encoding="utf-8") for p in pages if "_build" not in p.parts]
    pattern = re.compile(r"<!-- calibration recipe:[^\n]*-->\n```sh\n(.*?)```", re.S)
    block = next((found for found in map(pattern.search, texts) if found), None)
    assert block, "the calibration recipe (README.md or docs/**/*.md) is missing"
    return [line.split("  #")[0].strip() for line in block.group(1).splitlines() if line.strip()]


def test_the_scenes():
    flat, dark = load_scene("flat"), load_scene("dark")
    assert flat.source.reflectance == 1.0 and dark.source.reflectance == 0.0
    assert flat.intensity_factors == (0.03, 0.08, 0.15, 0.25, 0.4)
    assert len(dark.intensity_factors) == 8 and len(set(dark.intensity_factors)) == 8
    assert flat.illuminants == dark.illuminants == ("D65",)


def test_a_dark_frame_has_no_signal_electrons(tmp_path, capsys):
    """The dark scene gives 0 photo-electrons, exactly: its sidecar says so, and with the photon-noise-only sensor
    (``ideal``: electrons out, no dark current, no read noise) every value of the frame is 0, while the flat scene
    at a thousandth of its light is not."""
    for scene, factor in (("dark", "1"), ("flat", "0.001")):
        assert main(["render", scene, "--preset", "ideal", "-F", factor, "--size", "64x48", "-q",
                     "--out", str(tmp_path / scene)]) == 0
    dark = load_frame(tmp_path / "dark" / "dark_D65_F1.exr")
    flat = load_frame(tmp_path / "flat" / "flat_D65_F0.001.exr")
    assert dark.pixels_dn.shape == flat.pixels_dn.shape == (3, 48, 64)
    assert np.all(dark.pixels_dn == 0)
    assert flat.pixels_dn[1].mean() == pytest.approx(8.0, rel=0.1)  # 8000 e⁻ × 0.001 in G
    (patch,) = dark.meta["patches"]
    assert patch["name"] == "flat" and patch["rect_xywh"] == [0, 0, 64, 48]
    assert patch["signal_e"] == [0.0, 0.0, 0.0] and patch["xyz_cd_m2"] == [0.0, 0.0, 0.0]
    assert dark.meta["target"] == {"kind": "flat", "reflectance": 0.0}
    # with a real sensor the dark frame is the sensor's own signal: the 8 darks of the scene, each its own noise
    assert main(["render", "dark", "--preset", PRESET, "--iso", str(ISO), "--size", "64x48", "-q",
                 "--out", str(tmp_path / "real")]) == 0
    frames = [load_frame(tmp_path / "real" / f"dark_D65_F{i}.dng") for i in range(1, 9)]
    assert all(f.meta["patches"][0]["signal_e"] == [0.0, 0.0, 0.0] for f in frames)
    black = sensor_preset(PRESET, ISO).black_level_dn[0]
    stack = np.stack([f.pixels_dn for f in frames]).astype(float)
    assert stack.mean() == pytest.approx(black, abs=0.1)  # 8 × 3072 values of σ 3.9 DN: SE 0.03 DN
    assert not any(np.array_equal(stack[0], other) for other in stack[1:])


@pytest.mark.parametrize(("text", "message"), [
    ("reflectance = 1.5", r"\[target\] reflectance must be a reflectance in \[0, 1\], got 1\.5"),
    ("reflectance = true", r"\[target\] reflectance must be a reflectance in \[0, 1\] or a patch name"),
    ("levels = 4", r"\[target\] key\(s\) levels do not apply to kind = 'flat' \(its keys: reflectance, reflectances\)"),
])
def test_bad_flat_targets_are_refused(tmp_path, text, message):
    scene = tmp_path / "bad.toml"
    scene.write_text(f'[target]\nkind = "flat"\n{text}\n')
    with pytest.raises(CamsimError, match=message):
        load_scene(scene)


def test_a_named_patch_as_the_flat(tmp_path):
    scene = tmp_path / "grey.toml"
    scene.write_text('[target]\nkind = "flat"\nreflectance = "neutral 5 (.70 D)"\n')
    source = load_scene(scene).source
    spectra = source.spectra(load_scene("flat").grid, 8, 4)
    assert spectra.spectra.shape == (1, 101) and 0.15 < spectra.spectra.mean() < 0.25  # a 0.70 D grey: about 0.19
    scene.write_text('[target]\nkind = "flat"\nreflectance = "no such patch"\n')
    with pytest.raises(CamsimError, match="flat target: no patch 'no such patch'"):
        load_scene(scene).source.spectra(load_scene("flat").grid, 8, 4)


@pytest.mark.slow
def test_the_readme_recipe_calibrates_back_the_preset(tmp_path):
    lines = readme_recipe()
    assert [shlex.split(line)[:2] for line in lines] == [["camsim", "render"]] * 3 + [["camsim", "calibrate"],
                                                                                      ["camsim", "render"]]
    assert all(f"--preset {PRESET} --iso {ISO}" in line for line in lines[:3])
    # every render at SIZE, the chart too: a preset that names calibrate's maps (hot pixels, a dark shading: here a
    # pixel or two of the read noise's tail may pass the hot-pixel test) renders frames of the calibrated size only
    script = "\n".join(["set -e", 'camsim() { "$PYTHON" -m camsim "$@"; }']
                       + [line + (f" --size {SIZE}" if " render " in line else "") + " -q" for line in lines])
    env = {**os.environ, "PYTHON": sys.executable, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])])}
    done = clock.run(["bash", "-c", script], cpu_s=60, cwd=tmp_path, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    out = tmp_path / "cal" / "out"
    preset = tomllib.loads((out / "preset.toml").read_text(encoding="utf-8"))
    record = json.loads((out / "calibration.json").read_text(encoding="utf-8"))
    (iso,) = preset["iso"]
    truth = sensor_preset(PRESET, ISO)
    k = truth.dn_per_electron
    for key, json_key, true, tolerance in (("k_dn_per_e", "k_dn_per_e", k, 0.02 * k),
                                           ("gaussian_sigma_dn", "read_noise_dn", truth.read_noise_e * k,
                                            0.03 * truth.read_noise_e * k),
                                           ("row_sigma_dn", "row_noise_dn", truth.row_noise_e * k,
                                            0.10 * truth.row_noise_e * k),
                                           ("tukey_lambda", "tukey_lambda", truth.tukey_lambda, 0.03)):
        assert iso[key] == pytest.approx(true, abs=tolerance), key
        assert tolerance >= 4 * record[json_key]["standard_error"], f"{key}: too little margin"
    assert record["black_level_dn"]["value"] == pytest.approx(truth.black_level_dn[0], abs=0.1)
    assert 0.1 >= 4 * record["black_level_dn"]["standard_error"]
    assert 0 <= iso["dsnu_dn"] < 0.3 and 0 <= iso["prnu_percent"] < 0.3  # 0 in the preset
    assert (iso["iso"], preset["preset"]["bits"], preset["preset"]["cfa"]) == (ISO, truth.bits, truth.cfa)
    assert preset["preset"]["pedestal_dn"] == truth.pedestal_dn
    assert preset["preset"]["source"].startswith("camsim calibrate: 8 dark frames, 5 flat pairs at 5 levels")
    # the last line rendered with the calibrated preset
    chart = json.loads((tmp_path / "cal" / "chart" / "macbeth_26_D65_F0.1.json").read_text())
    assert chart["iso"] == ISO and chart["dn_per_electron"] == pytest.approx(k, rel=0.02)
