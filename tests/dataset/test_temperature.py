"""A dataset draws the sensor's temperature like any parameter (issue 28): ``temperature_c`` in ``[random]`` gives
each frame its own temperature, and each frame's dark level follows D(T) = D_ref · 2^((T − T_ref)/T_d), the closed
form computed here."""

import numpy as np
import pytest

from camsim.dataset.frame_render import render_frame
from camsim.dataset.spec import plan_spec
from tests.support.helpers import ROOT, write_text_file

SCENE = (ROOT / "scenes" / "macbeth_26.toml").as_posix()
# emva-12bit: K = 0.4 DN/e⁻, 25 e⁻/s at its reference temperature, read noise 3 e⁻, DSNU 2 e⁻; a pedestal keeps the
# coldest dark level clear of the ADC's 0 (the ADC adds P + ½ before its floor: a dark mean of P + K · D · t)
SPEC = f"""
name = "warm"
scene = "{SCENE}"
seed = 3

[frame]
width = 64
height = 48

[fixed]
preset = "emva-12bit"
cfa = "none"
pedestal_dn = 64
exposure_s = 2.0
intensity_factor = 1e-30
illuminant = "D65"
dark_current_doubling_c = 7.0

[random]
count = 5
temperature_c = {{ uniform = [5.0, 45.0] }}
"""


def test_random_temperatures_give_dark_frames_that_follow_the_doubling_law(tmp_path):
    frames = list(plan_spec(write_text_file(tmp_path, "warm.toml", SPEC)).frames())
    temperatures = [f.record["temperature_c"] for f in frames]
    assert len(set(temperatures)) == 5 and all(5.0 <= t <= 45.0 for t in temperatures)
    for spec_frame, temperature in zip(frames, temperatures):
        frame, _ = render_frame(spec_frame)
        dn = frame.digital_dn.astype(np.float64)
        dark_e = 25.0 * 2.0 ** ((temperature - 25.0) / 7.0) * 2.0
        expected = 64 + 0.4 * dark_e
        # standard error of the mean over 3 · 64 · 48 values: √(σ²_read + D) K per value (temporal), the DSNU's
        # mean 2 K / √(3 · 64 · 48)
        error = np.sqrt(3.0**2 + dark_e) * 0.4 / np.sqrt(dn.size) + 2.0 * 0.4 / np.sqrt(dn.size)
        assert abs(dn.mean() - expected) < 5 * error, (temperature, dn.mean(), expected)


def test_a_grid_of_temperatures_orders_the_dark_levels(tmp_path):
    text = SPEC.replace("[random]\ncount = 5\ntemperature_c = { uniform = [5.0, 45.0] }\n",
                        "[grid]\ntemperature_c = [10.0, 24.0, 38.0]\n")
    frames = list(plan_spec(write_text_file(tmp_path, "grid.toml", text)).frames())
    assert [f.record["temperature_c"] for f in frames] == [10.0, 24.0, 38.0]
    means = [render_frame(f)[0].digital_dn.mean() - 64 for f in frames]
    # 14 °C = 2 doubling temperatures apart: each dark signal 2^2 = 4 times the last, within the noise
    assert means[1] / means[0] == pytest.approx(4.0, rel=0.05)
    assert means[2] / means[1] == pytest.approx(4.0, rel=0.02)


def test_a_specs_map_file_is_relative_to_the_spec_not_the_working_folder(tmp_path, monkeypatch):
    """dark_shading_map in a spec names a file beside the spec (as a scene file's or a preset file's maps do): the
    frame's dark level follows the map whatever the working folder."""
    folder = tmp_path / "spec"
    folder.mkdir()
    shading = np.zeros((48, 64))
    shading[:, 32:] = 200.0  # e⁻ on the right half: 80 DN at 0.4 DN/e⁻
    np.save(folder / "shading.npy", shading)
    text = SPEC.replace("[random]\ncount = 5\ntemperature_c = { uniform = [5.0, 45.0] }\n",
                        "dark_shading_map = \"shading.npy\"\n")
    spec = write_text_file(folder, "map.toml", text)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    (frame_spec,) = list(plan_spec(spec).frames())
    dn = render_frame(frame_spec)[0].digital_dn.astype(np.float64)
    step = dn[:, :, 32:].mean() - dn[:, :, :32].mean()
    assert abs(step - 80.0) < 2.0, step
